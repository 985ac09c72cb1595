//! The data support and the plausibility audit of a trained network (docs/model-files.md "Data
//! support", "Plausibility audit"): where the training samples lie, what the evaluators fall
//! back to elsewhere, the ensemble's spread, and the checks a network passes before export.

use std::collections::VecDeque;

use crate::model::{gain_offset, AuditSpec, Model, ModelFile, SupportSpec, MAX_INPUTS};
use crate::score::{score, Grid, Sample};

/// Most failing cells an audit lists by name.
pub const LISTED_FAILURES: usize = 50;
/// Loss-minus-recovery differences of the data below this (in μ) set no sign to check.
pub const HYSTERESIS_FLOOR: f64 = 0.002;

/// What a support grid is built from: the grid, the threshold and the samples per cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Occupancy {
    pub cells: Vec<usize>,
    pub min_samples: u64,
    pub counts: Vec<u64>,
}

/// Counts the samples `x` (row-major, `k` physical inputs per sample) per cell: each sample
/// mirrored as the evaluators mirror it (Δv < 0: (−Δv, −dΔv/dt)), clamped to `domain`,
/// normalised by `norm` ((min, max) per input) and put in cell ⌊(x_n + 1) · n/2⌋ (limited to
/// n − 1) along each input.
pub fn occupancy(
    x: &[f64],
    k: usize,
    norm: &[(f64, f64)],
    domain: &[(f64, f64)],
    cells: &[usize],
    min_samples: u64,
) -> Occupancy {
    assert!(cells.len() == k && norm.len() == k && domain.len() == k);
    let total: usize = cells.iter().product();
    let mut counts = vec![0u64; total];
    let go: Vec<(f64, f64)> = norm.iter().map(|&(lo, hi)| gain_offset(lo, hi)).collect();
    for row in x.chunks_exact(k) {
        let mut r = [0.0; MAX_INPUTS];
        r[..k].copy_from_slice(row);
        if r[0] < 0.0 {
            r[0] = -r[0];
            r[1] = -r[1];
        }
        let mut j = 0;
        for c in 0..k {
            let (g, o) = go[c];
            let xn = g.mul_add(r[c].clamp(domain[c].0, domain[c].1), o);
            let n = cells[c];
            let i = ((xn + 1.0) * (n as f64 / 2.0))
                .floor()
                .clamp(0.0, (n - 1) as f64) as usize;
            j = j * n + i;
        }
        counts[j] += 1;
    }
    Occupancy {
        cells: cells.to_vec(),
        min_samples,
        counts,
    }
}

/// `occ` with every cell's count replaced by the sum over its column along speed and
/// temperature (the inputs after Δv and dΔv/dt): a (Δv, dΔv/dt) cell seen at any speed and
/// temperature is supported at all of them. A residual network's support: its law carries the
/// speed and temperature structure, so the residual it learnt at one speed holds at the
/// others, where a per-speed grid would fade it to the law alone at the top speed of every
/// run that started there (docs/model-files.md, "Residual networks"). Two-input grids are
/// unchanged.
pub fn projected_onto_slip(occ: &Occupancy) -> Occupancy {
    let inner: usize = occ.cells.iter().skip(2).product();
    let mut counts = occ.counts.clone();
    for column in counts.chunks_mut(inner) {
        let sum: u64 = column.iter().sum();
        column.fill(sum);
    }
    Occupancy {
        counts,
        ..occ.clone()
    }
}

/// The physical inputs (Δv, dΔv/dt, v, T) at the centre of every cell, in flat order; v and T
/// are NaN (the reference values) where the model does not take them.
pub fn cell_centres(file: &ModelFile, cells: &[usize]) -> Vec<[f64; MAX_INPUTS]> {
    let k = cells.len();
    let total: usize = cells.iter().product();
    let go: Vec<(f64, f64)> = file
        .inputs
        .iter()
        .map(|i| gain_offset(i.norm_min, i.norm_max))
        .collect();
    (0..total)
        .map(|flat| {
            let mut x = [0.0, 0.0, f64::NAN, f64::NAN];
            let mut rest = flat;
            for c in (0..k).rev() {
                let n = cells[c];
                let i = rest % n;
                rest /= n;
                let xn = 2.0 * (i as f64 + 0.5) / n as f64 - 1.0;
                x[c] = (xn - go[c].1) / go[c].0;
            }
            x
        })
        .collect()
}

/// The network's |μ| at each cell centre's nearest supported cell — nearest in steps across
/// cell faces (a breadth-first search from every supported cell at once, sources in flat
/// order, so ties go to the lower flat index); supported cells keep their own value.
fn nearest_supported(occ: &Occupancy, own: &[f64]) -> Vec<f64> {
    let k = occ.cells.len();
    let total = occ.counts.len();
    let mut stride = vec![1usize; k];
    for c in (0..k.saturating_sub(1)).rev() {
        stride[c] = stride[c + 1] * occ.cells[c + 1];
    }
    let mut value = vec![f64::NAN; total];
    let mut queue = VecDeque::new();
    for j in 0..total {
        if occ.counts[j] >= occ.min_samples {
            value[j] = own[j];
            queue.push_back(j);
        }
    }
    while let Some(j) = queue.pop_front() {
        for (&st, &n) in stride.iter().zip(&occ.cells) {
            let i = j / st % n;
            let mut next = Vec::with_capacity(2);
            if i > 0 {
                next.push(j - st);
            }
            if i + 1 < n {
                next.push(j + st);
            }
            for m in next {
                if value[m].is_nan() {
                    value[m] = value[j];
                    queue.push_back(m);
                }
            }
        }
    }
    value
}

/// A residual network's fallback (`law_held`): each unsupported cell takes the mean of the
/// residuals `own` of the supported cells along the slip-rate axis (input 1) at the same slip,
/// speed and temperature whose slip rate (`centres[j][1]`, m/s²) has the cell's sign, weighted
/// by their counts; 0 where that side holds none. Supported cells keep their own value.
///
/// Why: the law has one branch, so a fallback of 0 (the law alone) erases the loss/recovery
/// hysteresis wherever the data's slip rates end, while the hysteresis saturates with the slip
/// rate (the contact is on one branch or the other once the slip changes fast: seed 002 feeds
/// dΔv/dt to the network for it). The branch's mean residual over the slip rates the data
/// reach is the estimate that assumes least beyond them; the edge cell alone, the network's
/// least certain value, carried its errors far (measured: docs/training.md, "The residual
/// held along the slip rate"). The side is that of the cell centre's slip rate, so a cell
/// that straddles 0 counts with its centre's sign. Beyond the grid's edge the evaluators take
/// the edge cells' values: there a supported edge cell's own residual is held.
fn held_along_slip_rate(occ: &Occupancy, own: &[f64], centres: &[[f64; MAX_INPUTS]]) -> Vec<f64> {
    let st: usize = occ.cells.iter().skip(2).product();
    let nq = occ.cells[1];
    let ok = |j: usize| occ.counts[j] >= occ.min_samples;
    (0..occ.counts.len())
        .map(|j| {
            if ok(j) {
                return own[j];
            }
            let i = j / st % nq;
            let first = j - i * st;
            let side = centres[j][1] >= 0.0;
            let (mut sw, mut swy) = (0.0, 0.0);
            for m in (0..nq).map(|d| first + d * st) {
                if ok(m) && (centres[m][1] >= 0.0) == side {
                    let w = occ.counts[m] as f64;
                    sw += w;
                    swy += w * own[m];
                }
            }
            if sw > 0.0 {
                swy / sw
            } else {
                0.0
            }
        })
        .collect()
}

/// The support grid of `file` (a network without one yet): counts from `occ`, the fallback
/// — for a residual network (a file with a `base` law) its residual held along the slip rate
/// ([`held_along_slip_rate`], `law_held`), else from `polach` (|μ| of that model at each
/// cell centre, at the network's reference speed for two-input networks, at the centre's
/// temperature for four-input networks — the base k_A, k_S without) or else the nearest
/// supported cell's network value — and the spread of `members` (the ensemble's networks as
/// model files; fewer than two: none).
pub fn support_spec(
    file: &ModelFile,
    occ: &Occupancy,
    polach: Option<&Model>,
    members: &[ModelFile],
) -> Result<SupportSpec, crate::model::ModelError> {
    // Built first also to refuse a file the evaluators cannot take, whatever its fallback.
    let net = Model::named(file.clone(), "trained network")?;
    let centres = cell_centres(file, &occ.cells);
    let v_ref = file
        .creep
        .as_ref()
        .map_or(f64::NAN, |c| c.reference_speed_mps);
    let (fallback, fallback_mu) = match polach {
        // A residual network fades to its law plus its residual held along dΔv/dt: the
        // residual N at each centre is the network without its law and without the creep
        // region (step 4 applies to the sum; the fallback enters at step 3).
        _ if file.base.is_some() => {
            let mut plain = file.clone();
            (plain.base, plain.support, plain.audit) = (None, None, None);
            if let Some(c) = plain.creep.as_mut() {
                c.blend_mps = f64::MIN_POSITIVE;
            }
            let n = Model::named(plain, "residual network")?;
            let res: Vec<f64> = centres
                .iter()
                .map(|x| n.mu_vt(x[0], x[1], x[2], x[3]))
                .collect();
            ("law_held", held_along_slip_rate(occ, &res, &centres))
        }
        Some(p) => (
            "polach",
            centres
                .iter()
                .map(|x| {
                    let v = if x[2].is_finite() { x[2] } else { v_ref };
                    p.mu_vt(x[0], x[1], v, x[3]).abs()
                })
                .collect(),
        ),
        None => {
            let own: Vec<f64> = centres
                .iter()
                .map(|x| net.mu_vt(x[0], x[1], x[2], x[3]).abs())
                .collect();
            ("nearest", nearest_supported(occ, &own))
        }
    };
    let spread = if members.len() < 2 {
        Vec::new()
    } else {
        let models: Vec<Model> = members
            .iter()
            .map(|m| Model::named(m.clone(), "ensemble member"))
            .collect::<Result<_, _>>()?;
        centres
            .iter()
            .map(|x| {
                let mu: Vec<f64> = models
                    .iter()
                    .map(|m| m.mu_vt(x[0], x[1], x[2], x[3]))
                    .collect();
                let mean = mu.iter().sum::<f64>() / mu.len() as f64;
                (mu.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / mu.len() as f64).sqrt()
            })
            .collect()
    };
    Ok(SupportSpec {
        cells: occ.cells.clone(),
        min_samples: occ.min_samples,
        counts: occ.counts.clone(),
        fallback: fallback.into(),
        fallback_mu,
        spread,
    })
}

/// The plausibility audit of a network with its support grid:
/// 1. on every supported cell centre (where the evaluators return the network, up to the
///    rounding of the centre's coordinates) μ is finite and 0 ≤ μ ≤ `mu_max`;
/// 2. the loss/recovery order: over the data-supported cells of [`crate::score`] (the training
///    and validation samples `data` as truth), the mean μ(Δv, +q) − μ(Δv, −q) of the model has
///    the sign of the data's wherever the data's is at least [`HYSTERESIS_FLOOR`].
pub fn audit(model: &Model, data: &[Sample], mu_max: f64) -> AuditSpec {
    let mut failures = Vec::new();
    let mut failing = 0;
    let file = &model.file;
    if let Some(sup) = &file.support {
        let centres = cell_centres(file, &sup.cells);
        for (j, x) in centres.iter().enumerate() {
            if !sup.supported(j) {
                continue;
            }
            let mu = model.mu_vt(x[0], x[1], x[2], x[3]);
            if !(mu.is_finite() && (0.0..=mu_max).contains(&mu)) {
                failing += 1;
                if failures.len() < LISTED_FAILURES {
                    let mut v = if x[2].is_finite() {
                        format!(", v {:.1} km/h", x[2] * 3.6)
                    } else {
                        String::new()
                    };
                    if x[3].is_finite() {
                        v += &format!(", {:.1} °C", x[3]);
                    }
                    failures.push(format!(
                        "cell Δv {:.3} m/s, dΔv/dt {:.3} m/s²{v} (support count {}): μ = {mu:.4} outside [0, {mu_max}]",
                        x[0], x[1], sup.counts[j]
                    ));
                }
            }
        }
    }
    let (h_data, h_model) = match score(data, &Grid::default(), |dv, q, v, t| {
        model.mu_vt(dv, q, v, t)
    }) {
        Ok(s) => match s.hysteresis {
            Some((d, m)) => (Some(d), Some(m)),
            None => (None, None),
        },
        Err(_) => (None, None),
    };
    if let (Some(d), Some(m)) = (h_data, h_model) {
        if d.abs() >= HYSTERESIS_FLOOR && d.signum() != m.signum() {
            failing += 1;
            failures.truncate(LISTED_FAILURES - 1);
            failures.insert(0, format!(
                "hysteresis: the data's loss-minus-recovery difference is {d:+.4}, the model's {m:+.4} (the loss and recovery branches are swapped)"
            ));
        }
    }
    AuditSpec {
        passed: failing == 0,
        mu_max,
        hysteresis_data: h_data,
        hysteresis_model: h_model,
        failing_cells: failing,
        failures,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occupancy_mirrors_clamps_and_counts() {
        // Δv in [0, 4], dΔv/dt in [−2, 2], 4 × 2 cells.
        let norm = [(0.0, 4.0), (-2.0, 2.0)];
        let x = [
            0.1, 1.0, // cell (0, 1)
            -0.1, -1.0, // mirrored: the same cell
            3.9, -1.5, // cell (3, 0)
            9.0, 9.0, // clamped: cell (3, 1)
        ];
        let o = occupancy(&x, 2, &norm, &norm, &[4, 2], 2);
        assert_eq!(o.counts, vec![0, 2, 0, 0, 0, 0, 1, 1]);
    }

    #[test]
    fn projection_sums_each_slip_column_over_speed_and_temperature() {
        // 2 × 1 (Δv, dΔv/dt) cells × 3 speeds × 2 temperatures.
        let occ = Occupancy {
            cells: vec![2, 1, 3, 2],
            min_samples: 5,
            counts: vec![1, 0, 3, 0, 0, 2, 0, 0, 0, 0, 4, 0],
        };
        let p = projected_onto_slip(&occ);
        assert_eq!(p.counts, vec![6, 6, 6, 6, 6, 6, 4, 4, 4, 4, 4, 4]);
        assert_eq!((p.cells, p.min_samples), (occ.cells.clone(), 5));
        // Two inputs: nothing to project.
        let two = Occupancy {
            cells: vec![2, 2],
            min_samples: 1,
            counts: vec![0, 3, 1, 0],
        };
        assert_eq!(projected_onto_slip(&two), two);
    }

    #[test]
    fn a_residual_is_held_per_slip_rate_sign_along_its_slip_and_speed() {
        // 2 slips × 6 slip rates (−5 … +5 m/s²) × 2 speeds; support projected onto the slip.
        let q = [-5.0, -3.0, -1.0, 1.0, 3.0, 5.0];
        let mut centres = Vec::new();
        let mut counts = Vec::new();
        let mut own = Vec::new();
        // Slip 0: supported at −3 (count 10), −1 (30) and +1 (20); slip 1: only at +3 (5).
        let slip0 = [0, 10, 30, 20, 0, 0];
        let slip1 = [0, 0, 0, 0, 5, 0];
        for (s, support) in [slip0, slip1].iter().enumerate() {
            for (k, &qk) in q.iter().enumerate() {
                for v in 0..2 {
                    centres.push([0.5 + s as f64, qk, 10.0 + 20.0 * v as f64, f64::NAN]);
                    counts.push(support[k]);
                    // The residual differs per speed, so the mean must stay in its speed.
                    own.push(
                        if qk < 0.0 { -0.01 } else { 0.004 } * (1 + v) as f64 + 0.001 * k as f64,
                    );
                }
            }
        }
        let occ = Occupancy {
            cells: vec![2, 6, 2],
            min_samples: 5,
            counts,
        };
        let held = held_along_slip_rate(&occ, &own, &centres);
        let at = |s: usize, k: usize, v: usize| (s * 6 + k) * 2 + v;
        for v in 0..2 {
            let recovery = (10.0 * own[at(0, 1, v)] + 30.0 * own[at(0, 2, v)]) / 40.0;
            // Beyond the data on the falling side: the falling side's count-weighted mean.
            assert!((held[at(0, 0, v)] - recovery).abs() < 1e-15, "{held:?}");
            // On the rising side: its one supported cell's value, at +3 and +5 m/s².
            let close = |a: f64, b: f64| assert!((a - b).abs() <= 1e-15, "{a} against {b}");
            close(held[at(0, 4, v)], own[at(0, 3, v)]);
            close(held[at(0, 5, v)], own[at(0, 3, v)]);
            // Slip 1 has no falling side: 0 (the law alone); its rising side holds +3.
            for k in 0..3 {
                assert_eq!(held[at(1, k, v)], 0.0);
            }
            close(held[at(1, 3, v)], own[at(1, 4, v)]);
            close(held[at(1, 5, v)], own[at(1, 4, v)]);
            // Supported cells keep their own value.
            for k in 1..4 {
                assert_eq!(held[at(0, k, v)], own[at(0, k, v)]);
            }
        }
        assert_ne!(held[at(0, 0, 0)], held[at(0, 0, 1)]);
    }

    #[test]
    fn nearest_supported_fills_by_steps_and_keeps_supported_values() {
        let occ = Occupancy {
            cells: vec![1, 5],
            min_samples: 1,
            counts: vec![0, 1, 0, 0, 1],
        };
        let own = [10.0, 11.0, 12.0, 13.0, 14.0];
        // Cell 0 and 2 are one step from cell 1, cell 3 one step from cell 4.
        assert_eq!(
            nearest_supported(&occ, &own),
            vec![11.0, 11.0, 11.0, 14.0, 14.0]
        );
    }
}
