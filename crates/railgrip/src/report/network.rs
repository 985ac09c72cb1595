//! The report's network section: its metrics and leave-one-run-out scores, the error per epoch
//! (seed 002 Fig. 9), the network against the estimate (Fig. 10), the slip ramp (Fig. 11) and μ
//! over the (Δv, dΔv/dt) plane.

use std::fmt::Write as _;

use plotters::style::RGBColor;

use super::plot::{chart, heatmap, Series, PALETTE};
use super::{esc, opt, Inputs, ReportError};
use crate::format::AXLES;
use crate::model::Model;

/// A point of the slip ramp: Δv (m/s), μ, the support weight, the ensemble's spread.
type RampPoint = (f64, f64, f64, f64);

/// The network: metrics, error per epoch (Fig. 9), against the estimate (Fig. 10), the slip
/// ramp (Fig. 11) and μ over the (Δv, dΔv/dt) plane.
pub(super) fn network(h: &mut String, i: &Inputs, m: &Model) -> Result<(), ReportError> {
    h.push_str("<h2>Network μ(Δv, dΔv/dt)</h2>\n");
    metrics(h, m);
    leave_one_run_out(h, i);
    h.push_str("<div class=\"figs\">\n");
    training(h, m)?;
    against_estimate(h, i, m)?;
    slip_ramp(h, m)?;
    h.push_str(&heatmap(m)?);
    h.push_str("</div>\n<p class=\"note\">Outside the trained domain the network holds its boundary value (inputs clamped); Δv beyond ");
    let _ = writeln!(
        *h,
        "{:.2} m/s and dΔv/dt outside [{:.2}, {:.2}] m/s² were not seen in training.</p>",
        m.file.inputs[0].domain_max, m.file.inputs[1].domain_min, m.file.inputs[1].domain_max
    );
    Ok(())
}

/// The network's shape, samples, errors and stop reason.
fn metrics(h: &mut String, m: &Model) {
    let mt = &m.file.metrics;
    let _ = writeln!(
        *h,
        "<table><tr><th class=\"l\">inputs</th><th>network</th><th>training samples</th><th>validation samples</th><th>training RMSE μ</th><th>validation RMSE μ</th><th>epochs</th><th class=\"l\">stop</th></tr>\n<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.5}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr></table>",
        esc(&m.file.inputs.iter().map(|i| i.name.as_str()).collect::<Vec<_>>().join(", ")),
        m.file.architecture(),
        mt.train_samples,
        mt.val_samples,
        mt.train_mse.sqrt(),
        opt(mt.val_mse.map(f64::sqrt), 5),
        mt.epochs,
        esc(&mt.stop_reason)
    );
}

/// Each leave-one-run-out fold's score on its held-out run.
fn leave_one_run_out(h: &mut String, i: &Inputs) {
    if !i.held_out.is_empty() {
        h.push_str("<h3>Leave-one-run-out</h3>\n<p class=\"note\">Each row: a network trained (one start) on the other runs (beyond train.folds runs: on the runs of the other folds), scored against this run's own estimates (all axles) — generalisation across runs, which the axle split above cannot show.</p>\n<table><tr><th class=\"l\">held-out run</th><th>samples</th><th>RMSE μ</th></tr>\n");
        for r in &i.held_out {
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{:.5}</td></tr>",
                esc(&r.run),
                r.samples,
                r.rmse_mu
            );
        }
        h.push_str("</table>\n");
    }
}

/// The error per epoch (Fig. 9) and, with Bayesian regularisation, γ per epoch.
fn training(h: &mut String, m: &Model) -> Result<(), ReportError> {
    let hist = &m.file.history;
    h.push_str(&chart(
        "Error per epoch (seed 002 Fig. 9)",
        "epoch",
        "MSE of μ",
        &[
            Series {
                name: "training".into(),
                color: PALETTE[0],
                pts: hist.iter().map(|e| (e.epoch as f64, e.train_mse)).collect(),
                dots: false,
            },
            Series {
                name: "validation".into(),
                color: PALETTE[1],
                pts: hist
                    .iter()
                    .filter(|e| e.val_mse.is_finite())
                    .map(|e| (e.epoch as f64, e.val_mse))
                    .collect(),
                dots: false,
            },
        ],
        true,
    )?);
    if hist.iter().any(|e| e.gamma.is_some()) {
        h.push_str(&chart(
            &format!(
                "Effective parameters γ per epoch (trainbr; {} weights)",
                m.file.n_weights()
            ),
            "epoch",
            "γ",
            &[Series {
                name: "γ".into(),
                color: PALETTE[2],
                pts: hist
                    .iter()
                    .filter_map(|e| e.gamma.map(|g| (e.epoch as f64, g)))
                    .collect(),
                dots: false,
            }],
            false,
        )?);
    }
    Ok(())
}

/// Fig. 10: the network against the estimate on the first training-condition run's first
/// validation axle.
fn against_estimate(h: &mut String, i: &Inputs, m: &Model) -> Result<(), ReportError> {
    let camp = i.camp;
    let va = camp.validation_axles.first().copied().unwrap_or(3) as usize;
    if let Some((r, valid)) = &i.across.first {
        let pts = &valid[(va.clamp(1, AXLES)) - 1];
        let est: Vec<(f64, f64)> = pts.iter().map(|p| (p.3, p.2)).collect();
        // The network at each sample's own speed and the run's ambient temperature (models
        // without those inputs ignore them).
        let t_c = r.ambient_temperature_c.unwrap_or(f64::NAN);
        let net: Vec<(f64, f64)> = pts
            .iter()
            .map(|p| (p.3, m.mu_vt(p.0, p.1, p.4, t_c)))
            .collect();
        h.push_str(&chart(
            &format!("Network against estimate, {} axle {va} (Fig. 10)", r.run),
            "time (s)",
            "μ",
            &[
                Series {
                    name: "estimated".into(),
                    color: PALETTE[0],
                    pts: est,
                    dots: true,
                },
                Series {
                    name: "network".into(),
                    color: PALETTE[1],
                    pts: net,
                    dots: true,
                },
            ],
            false,
        )?);
    }
    Ok(())
}

/// Fig. 11: slip ramp 0 → 9 → 0 m/s at ±2 m/s²; the ensemble's ±2σ band, and the parts outside
/// the data support (where the model blends to its fallback) marked.
fn slip_ramp(h: &mut String, m: &Model) -> Result<(), ReportError> {
    let ramp = |up: bool| -> Vec<(f64, f64, f64, f64)> {
        (0..=180)
            .map(|k| {
                let dv = 9.0 * k as f64 / 180.0;
                let dv = if up { dv } else { 9.0 - dv };
                let q = if up { 2.0 } else { -2.0 };
                let w = m.support_weight(dv, q, f64::NAN).unwrap_or(1.0);
                let sd = m.spread(dv, q, f64::NAN).unwrap_or(f64::NAN);
                (dv, m.mu(dv, q), w, sd)
            })
            .collect()
    };
    let (up, down) = (ramp(true), ramp(false));
    let mut series = vec![
        Series {
            name: "rising slip".into(),
            color: PALETTE[0],
            pts: up.iter().map(|p| (p.0, p.1)).collect(),
            dots: false,
        },
        Series {
            name: "falling slip".into(),
            color: PALETTE[1],
            pts: down.iter().map(|p| (p.0, p.1)).collect(),
            dots: false,
        },
    ];
    outside_support(&mut series, &up, &down);
    ensemble_band(&mut series, &up, &down);
    h.push_str(&chart(
        "Slip ramp 0 → 9 → 0 m/s at ±2 m/s² (Fig. 11)",
        "Δv (m/s)",
        "μ",
        &series,
        false,
    )?);
    Ok(())
}

/// Each ramp branch drawn over in grey where it leaves the data support (contiguous pieces).
fn outside_support(series: &mut Vec<Series>, up: &[RampPoint], down: &[RampPoint]) {
    let mut labelled = false;
    for branch in [up, down] {
        let mut piece: Vec<(f64, f64)> = Vec::new();
        for (k, p) in branch.iter().enumerate() {
            if p.2 < 1.0 {
                piece.push((p.0, p.1));
            }
            if (p.2 >= 1.0 || k + 1 == branch.len()) && !piece.is_empty() {
                series.push(Series {
                    name: if labelled {
                        String::new()
                    } else {
                        "outside the data support".into()
                    },
                    color: RGBColor(150, 150, 150),
                    pts: std::mem::take(&mut piece),
                    dots: false,
                });
                labelled = true;
            }
        }
    }
}

/// The ensemble's ±2σ band around each branch (networks averaged from several starts).
fn ensemble_band(series: &mut Vec<Series>, up: &[RampPoint], down: &[RampPoint]) {
    if up.iter().any(|p| p.3.is_finite()) {
        let light = |c: RGBColor| {
            let l = |v: u8| v + ((255 - v) as f64 * 0.6) as u8;
            RGBColor(l(c.0), l(c.1), l(c.2))
        };
        for sign in [2.0, -2.0] {
            for (k, (branch, c)) in [(up, PALETTE[0]), (down, PALETTE[1])]
                .into_iter()
                .enumerate()
            {
                series.push(Series {
                    name: if sign > 0.0 && k == 0 {
                        "ensemble ±2σ".into()
                    } else {
                        String::new()
                    },
                    color: light(c),
                    pts: branch.iter().map(|p| (p.0, p.1 + sign * p.3)).collect(),
                    dots: false,
                });
            }
        }
    }
}
