//! The study's timing harness: evaluation time per μ of each cell's model file, measured after
//! all training, one cell at a time (nothing else running), on points of the held-out runs —
//! the Rust evaluator's single call and batch, and for networks the peer a user would write by
//! hand: a plain scalar loop over the file's layers ([`PlainNet`]), with the C library's tanh
//! and with the evaluators' fast one.

use std::time::Instant;

use super::cells::{to_json, Keyed};
use super::{write_text, CellResult, EvalTiming, Event, StudyError, StudyProgress};
use crate::identify::dataset::RunTable;
use crate::model::{Model, ModelFile};
use crate::outdir::StudyPaths;

/// Times the evaluators of every trained cell not timed yet (its result saved again with the
/// times); a model file that no longer loads is the cell's error.
pub(super) fn time_cells(
    cells: &[Keyed<'_>],
    results: Vec<CellResult>,
    paths: &StudyPaths,
    points: &Points,
    progress: StudyProgress<'_>,
) -> Result<Vec<CellResult>, StudyError> {
    let mut out = Vec::with_capacity(results.len());
    for (c, mut r) in cells.iter().zip(results) {
        if r.ok() && r.eval.is_none() {
            match Model::load(&paths.cell_model(&c.key)) {
                Ok(m) => {
                    r.eval = Some(time_model(&m, points));
                    write_text(&paths.cell(&c.key), &to_json(&r))?;
                }
                Err(e) => r.error = Some(format!("model file: {e}")),
            }
            progress.event(Event::Timed(&r));
        }
        out.push(r);
    }
    Ok(out)
}

/// Inputs (Δv, dΔv/dt, v, T) of the held-out runs, every k-th sample so that about `n` remain.
pub(super) struct Points {
    pub(super) dv: Vec<f64>,
    ddv: Vec<f64>,
    v: Vec<f64>,
    t: Vec<f64>,
}

pub(super) fn timing_points(tables: &[RunTable], n: usize) -> Points {
    let total: usize = tables.iter().map(|t| t.len()).sum();
    let step = (total / n.max(1)).max(1);
    let mut p = Points {
        dv: vec![],
        ddv: vec![],
        v: vec![],
        t: vec![],
    };
    for t in tables {
        let t_c = t.metadata.ambient_temperature_c.unwrap_or(f64::NAN);
        for k in (0..t.len()).step_by(step) {
            p.dv.push(t.dv_mps[k]);
            p.ddv.push(t.ddv_mps2[k]);
            p.v.push(t.v_mps[k]);
            p.t.push(t_c);
        }
    }
    p
}

/// ns per point of `f` (which evaluates every point once): best of 5 repetitions of ≥ 20 ms.
pub(super) fn ns_per_point(points: usize, mut f: impl FnMut() -> f64) -> f64 {
    std::hint::black_box(f());
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t0 = Instant::now();
        let mut loops = 0usize;
        while t0.elapsed().as_secs_f64() < 0.02 {
            std::hint::black_box(f());
            loops += 1;
        }
        let ns = t0.elapsed().as_secs_f64() * 1e9 / (loops * points.max(1)) as f64;
        best = best.min(ns);
    }
    best
}

fn time_model(m: &Model, p: &Points) -> EvalTiming {
    let n = p.dv.len();
    let single_ns = ns_per_point(n, || {
        let mut s = 0.0;
        for i in 0..n {
            s += m.mu_vt(std::hint::black_box(p.dv[i]), p.ddv[i], p.v[i], p.t[i]);
        }
        s
    });
    let mut out = vec![0.0; n];
    let batch_ns = ns_per_point(n, || {
        m.mu_batch_t(&p.dv, &p.ddv, &p.v, &p.t, &mut out);
        out[n / 2]
    });
    let (mut plain_libm_ns, mut libm_max_diff) = (None, None);
    if let Some(net) = PlainNet::of(&m.file) {
        plain_libm_ns = Some(ns_per_point(n, || {
            let mut s = 0.0;
            for i in 0..n {
                s += net.mu(
                    [std::hint::black_box(p.dv[i]), p.ddv[i], p.v[i], p.t[i]],
                    f64::tanh,
                );
            }
            s
        }));
        libm_max_diff = Some((0..n).fold(0.0f64, |d, i| {
            let x = [p.dv[i], p.ddv[i], p.v[i], p.t[i]];
            d.max((net.mu(x, crate::model::tanh_fast) - net.mu(x, f64::tanh)).abs())
        }));
    }
    EvalTiming {
        single_ns,
        batch_ns,
        plain_libm_ns,
        libm_max_diff,
    }
}

/// A network as a user would evaluate the model file in a plain scalar loop: inputs clamped to
/// the domain and normalised (mapminmax), layers z = b + W t (row-major, in order) with tanh on
/// the hidden ones, output reversed; two stack buffers, no allocation — and no creep region or
/// support blend (docs/model-files.md).
struct PlainNet {
    k: usize,
    lo: [f64; 4],
    hi: [f64; 4],
    gx: [f64; 4],
    ox: [f64; 4],
    gy: f64,
    oy: f64,
    /// (inputs, outputs, weights row-major, biases) per layer.
    layers: Vec<(usize, usize, Vec<f64>, Vec<f64>)>,
}

impl PlainNet {
    fn of(f: &ModelFile) -> Option<PlainNet> {
        if f.layers.is_empty()
            || f.layers
                .iter()
                .any(|l| l.biases.len() > crate::model::MAX_HIDDEN)
        {
            return None;
        }
        let mut n = PlainNet {
            k: f.inputs.len().min(4),
            lo: [0.0; 4],
            hi: [0.0; 4],
            gx: [1.0; 4],
            ox: [0.0; 4],
            gy: 1.0,
            oy: 0.0,
            layers: f
                .layers
                .iter()
                .map(|l| {
                    let cols = l.weights.first().map_or(0, Vec::len);
                    (cols, l.biases.len(), l.weights.concat(), l.biases.clone())
                })
                .collect(),
        };
        for (c, i) in f.inputs.iter().take(4).enumerate() {
            n.lo[c] = i.domain_min;
            n.hi[c] = i.domain_max;
            (n.gx[c], n.ox[c]) = crate::model::gain_offset(i.norm_min, i.norm_max);
        }
        (n.gy, n.oy) = crate::model::gain_offset(f.output.norm_min, f.output.norm_max);
        Some(n)
    }

    /// μ at `x`, with buffers as wide as the widest layer needs (a hand-written evaluator
    /// sizes its arrays to its network).
    fn mu(&self, x: [f64; 4], tanh: fn(f64) -> f64) -> f64 {
        match self
            .layers
            .iter()
            .map(|l| l.1)
            .max()
            .unwrap_or(1)
            .max(self.k)
        {
            0..=16 => self.mu_in::<16>(x, tanh),
            17..=64 => self.mu_in::<64>(x, tanh),
            _ => self.mu_in::<{ crate::model::MAX_HIDDEN }>(x, tanh),
        }
    }

    fn mu_in<const W: usize>(&self, x: [f64; 4], tanh: fn(f64) -> f64) -> f64 {
        let (mut a, mut b) = ([0.0f64; W], [0.0f64; W]);
        for c in 0..self.k {
            a[c] = self.gx[c] * x[c].clamp(self.lo[c], self.hi[c]) + self.ox[c];
        }
        let last = self.layers.len() - 1;
        for (l, (cols, rows, w, bias)) in self.layers.iter().enumerate() {
            for j in 0..*rows {
                let row = &w[j * cols..(j + 1) * cols];
                let mut z = bias[j];
                for (w, t) in row.iter().zip(&a[..*cols]) {
                    z += w * t;
                }
                b[j] = if l < last { tanh(z) } else { z };
            }
            std::mem::swap(&mut a, &mut b);
        }
        (a[0] - self.oy) / self.gy
    }
}
