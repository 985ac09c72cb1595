//! The report's Polach section (seed 004 eq. 1–3): every fit with its standard errors and
//! profile-likelihood intervals, the fitted curves over the estimates, the pooled fit's profiles,
//! and the temperature law with the forms it was chosen from.

use std::fmt::Write as _;

use plotters::style::RGBColor;

use super::plot::{chart, chart_thinned, Series, PALETTE};
use super::{esc, Inputs, ReportError};
use crate::contact::polach::{horner, polach, ContactPatch, PolachParams};
use crate::identify::polach::{ParamStatus, PolachFit, PolachReport, PARAMETERS, PROFILE_LIMIT};

/// The Polach fits (seed 004 eq. 1–3) over the estimates, and k_A(T), k_S(T).
pub(super) fn polach_fits(h: &mut String, i: &Inputs, f: &PolachReport) -> Result<(), ReportError> {
    fits_table(h, f);
    creepage_note(h, f);
    h.push_str("<div class=\"figs\">\n");
    fit_curves(h, i, f)?;
    profiles(h, f)?;
    law_chart(h, f)?;
    speed_chart(h, f)?;
    h.push_str("</div>\n");
    forms_table(h, f);
    Ok(())
}

/// Every fit's parameters: each as estimated ± se with its profile-likelihood 95 % interval, or
/// held: at its bound, or at its least-squares value where the data do not identify it.
fn fits_table(h: &mut String, f: &PolachReport) {
    h.push_str("<h2>Polach fits (seed 004 eq. 1–3)</h2>\n<table><tr><th class=\"l\">group</th><th>μ0</th><th>A</th><th>B s/m</th><th>k_A</th><th>k_S</th><th>RMSE μ</th><th>samples</th></tr>\n");
    // Each parameter as estimated ± se, or held: at its bound, or at the prior where the data
    // do not identify it.
    // Each parameter as estimated ± se with its profile-likelihood 95 % interval, or held: at
    // its bound, or at its least-squares value where the data do not identify it.
    let cell = |p: &PolachFit, k: usize, x: f64| {
        let s = p.se[k];
        let ci = p
            .profiles
            .iter()
            .find(|q| q.parameter == PARAMETERS[k])
            .map(|q| {
                let side = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.4}"));
                format!("<br><small>[{}, {}]</small>", side(q.lower), side(q.upper))
            })
            .unwrap_or_default();
        match p.status[k] {
            ParamStatus::Estimated if s.is_finite() => format!("{x:.4} ± {s:.4}{ci}"),
            ParamStatus::Estimated => format!("{x:.4}{ci}"),
            ParamStatus::AtBound => format!("{x:.4} <em>(at bound)</em>"),
            ParamStatus::NotIdentifiable => format!("{x:.4} <em>(not identifiable: held)</em>"),
        }
    };
    let mut notes = Vec::new();
    for p in f.pooled.iter().chain(&f.per_temperature).chain(&f.per_run) {
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{}</td></tr>",
            esc(&p.group),
            cell(p, 0, p.mu0),
            cell(p, 1, p.a_ratio),
            cell(p, 2, p.b_s_per_m),
            cell(p, 3, p.k_a),
            cell(p, 4, p.k_s),
            p.rmse,
            p.samples
        );
        notes.extend(p.notes.iter().map(|n| format!("{}: {n}", p.group)));
    }
    h.push_str("</table>\n<p>± one standard error (Wald, corrected for the residuals' autocorrelation); in brackets the 95 % interval from the profile likelihood (pooled and per-temperature fits; – where the data do not bound it before the parameter's limit).</p>\n");
    if !notes.is_empty() {
        h.push_str(
            "<p>What the data could not identify (held, the rest refitted; seed 004):</p>\n<ul>\n",
        );
        for n in &notes {
            let _ = writeln!(*h, "<li>{}</li>", esc(n));
        }
        h.push_str("</ul>\n");
    }
}

/// Each fit's curve at the reference speed over the estimates (axle 2 of the runs of the
/// training condition).
fn fit_curves(h: &mut String, i: &Inputs, f: &PolachReport) -> Result<(), ReportError> {
    let polach_model = &i.polach;
    let patch = ContactPatch {
        a_m: f.patch[0],
        b_m: f.patch[1],
        g_pa: f.patch[2],
        c11: f.patch[3],
        c22: f.patch[4],
    };
    let v_ref = polach_model
        .as_ref()
        .and_then(|m| m.file.polach.as_ref().map(|p| p.reference_speed_mps))
        .unwrap_or(25.0);
    // The creepage at the speed the fits took it: at v_ref, or the fixed speed (then the curve
    // is the same at every speed).
    let v_creepage = f.creepage.as_ref().and_then(|c| c.speed()).unwrap_or(v_ref);
    let dv_max = f.dv_range_mps.1.max(0.5);
    let curve = |p: &PolachParams| -> Vec<(f64, f64)> {
        (1..=200)
            .filter_map(|k| {
                let dv = dv_max * k as f64 / 200.0;
                polach(&patch, p, f.wheel_load_n, v_creepage, dv, 0.0)
                    .ok()
                    .map(|r| (dv, r.fx_n / f.wheel_load_n))
            })
            .collect()
    };
    let mut series = Vec::new();
    for (k, p) in f.per_temperature.iter().enumerate() {
        series.push(Series {
            name: p.group.clone(),
            color: PALETTE[k % PALETTE.len()],
            pts: curve(&p.params()),
            dots: false,
        });
    }
    if let Some(p) = &f.pooled {
        series.push(Series {
            name: "all runs".into(),
            color: RGBColor(0, 0, 0),
            pts: curve(&p.params()),
            dots: false,
        });
    }
    let scatter = i.across.all.points().to_vec();
    series.insert(
        0,
        Series {
            name: String::new(),
            color: RGBColor(170, 170, 170),
            pts: scatter,
            dots: true,
        },
    );
    h.push_str(&chart_thinned(
        &format!("Polach fits at {v_ref:.1} m/s over the estimates"),
        "Δv (m/s)",
        "μ",
        &series,
        &[&i.across.all],
    )?);
    Ok(())
}

/// Profile likelihood of the pooled fit (when it has profiles): each parameter's statistic
/// against its distance from the estimate in Wald standard errors, beside the Wald parabola z².
fn profiles(h: &mut String, f: &PolachReport) -> Result<(), ReportError> {
    // Profile likelihood of the pooled fit: each parameter's statistic against its distance
    // from the estimate in Wald standard errors, beside the Wald parabola z².
    if let Some(p) = f.pooled.as_ref().filter(|p| !p.profiles.is_empty()) {
        let mut series: Vec<Series> = p
            .profiles
            .iter()
            .enumerate()
            .filter_map(|(k, q)| {
                let i = PARAMETERS.iter().position(|n| *n == q.parameter)?;
                let se = p.se[i];
                Some(Series {
                    name: q.parameter.clone(),
                    color: PALETTE[k % PALETTE.len()],
                    pts: q
                        .points
                        .iter()
                        .map(|(x, d)| ((x - q.estimate) / se, d.min(12.0)))
                        .collect(),
                    dots: false,
                })
            })
            .collect();
        series.push(Series {
            name: "Wald z²".into(),
            color: RGBColor(150, 150, 150),
            pts: (0..=60)
                .map(|k| {
                    let z = -3.0 + 0.1 * k as f64;
                    (z, z * z)
                })
                .collect(),
            dots: false,
        });
        series.push(Series {
            name: "χ²₁(0.95) = 3.84".into(),
            color: RGBColor(200, 0, 0),
            pts: vec![(-3.0, PROFILE_LIMIT), (3.0, PROFILE_LIMIT)],
            dots: false,
        });
        h.push_str(&chart(
            "Profile likelihood of the pooled fit (95 % interval where Δ ≤ 3.84)",
            "(value − estimate) / Wald se",
            "Δ (profile statistic)",
            &series,
            false,
        )?);
    }
    Ok(())
}

/// The chosen temperature law μ0(T), k_A(T), k_S(T) over the per-temperature fits, when there
/// is one.
fn law_chart(h: &mut String, f: &PolachReport) -> Result<(), ReportError> {
    if let Some(t) = &f.temperature {
        let (lo, hi) = t.fitted_range_c;
        let grid: Vec<f64> = (0..=100)
            .map(|k| lo + (hi - lo) * k as f64 / 100.0)
            .collect();
        let dots = |k: usize| -> Vec<(f64, f64)> {
            f.per_temperature
                .iter()
                .filter_map(|p| {
                    p.ambient_temperature_c
                        .map(|tc| (tc, [p.mu0, p.k_a, p.k_s][k]))
                })
                .collect()
        };
        let line = |c: &[f64]| grid.iter().map(|&x| (x, horner(c, x))).collect();
        h.push_str(&chart(
            &format!("Temperature law: {} (seed 004 eq. 3, Fig. 2)", t.form()),
            "ambient temperature (°C)",
            "μ0, k (–)",
            &[
                Series {
                    name: "μ0(T)".into(),
                    color: PALETTE[2],
                    pts: line(&t.mu0),
                    dots: false,
                },
                Series {
                    name: "k_A(T)".into(),
                    color: PALETTE[0],
                    pts: line(&t.k_a),
                    dots: false,
                },
                Series {
                    name: "k_S(T)".into(),
                    color: PALETTE[1],
                    pts: line(&t.k_s),
                    dots: false,
                },
                Series {
                    name: "per-temperature fits".into(),
                    color: RGBColor(60, 60, 60),
                    pts: [dots(0), dots(1), dots(2)].concat(),
                    dots: true,
                },
            ],
            false,
        )?);
    }
    Ok(())
}

/// The level's speed law when the chosen form has one: μ0(T) × g(v) over the fitted speeds at
/// the lowest, the reference and the highest fitted temperature (one line without a
/// temperature law), g(v_ref) = 1 marked.
fn speed_chart(h: &mut String, f: &PolachReport) -> Result<(), ReportError> {
    let Some(t) = &f.temperature else {
        return Ok(());
    };
    let Some(law) = &t.speed else {
        return Ok(());
    };
    let (v0, v1) = law.fitted_range_mps;
    let grid: Vec<f64> = (0..=100)
        .map(|k| v0 + (v1 - v0) * k as f64 / 100.0)
        .collect();
    let (lo, hi) = t.fitted_range_c;
    let temps: Vec<f64> = if t.mu0.len() > 1 {
        vec![lo, t.reference_temperature_c, hi]
    } else {
        vec![t.reference_temperature_c]
    };
    let mut series: Vec<Series> = temps
        .iter()
        .enumerate()
        .map(|(k, &tc)| {
            let mu0 = horner(&t.mu0, tc);
            Series {
                name: if temps.len() > 1 {
                    format!("μ0 g(v) at {tc:.1} °C")
                } else {
                    "μ0 g(v)".into()
                },
                color: PALETTE[k % PALETTE.len()],
                pts: grid
                    .iter()
                    .map(|&v| (v * 3.6, mu0 * law.factor(v)))
                    .collect(),
                dots: false,
            }
        })
        .collect();
    let v_ref = law.reference_speed_mps;
    series.push(Series {
        name: format!("reference speed {:.0} km/h (g = 1)", v_ref * 3.6),
        color: RGBColor(60, 60, 60),
        pts: vec![(v_ref * 3.6, horner(&t.mu0, t.reference_temperature_c))],
        dots: true,
    });
    h.push_str(&chart(
        &format!("Speed law of the level: {}", t.form()),
        "speed (km/h)",
        "μ0 g(v) (–)",
        &series,
        false,
    )?);
    Ok(())
}

/// Which creepage the fits took and why: Polach's w/v, or w over one fixed speed where BIC
/// prefers it by more than 10.
fn creepage_note(h: &mut String, f: &PolachReport) {
    let Some(c) = &f.creepage else { return };
    let fixed = c.speed().is_some();
    let _ = write!(
        *h,
        "<p>Creepage: {}",
        if fixed {
            format!(
                "<strong>w over a fixed speed of {:.1} km/h</strong> (the runs' median; the creep slope per m/s of slip the same at every speed, as curves measured over slip velocity show — not Polach's w/v, whose slope falls as 1/v)",
                c.fixed_speed_mps * 3.6
            )
        } else {
            "Polach's w/v (seed 004 eq. 2)".to_string()
        }
    );
    if let (Some(b), Some(r)) = (c.bic, c.rmse) {
        let _ = write!(
            *h,
            ". Pooled fits: w/v RMSE μ {:.5}, BIC {:.1}; w over {:.1} km/h RMSE μ {:.5}, BIC {:.1} (the fixed speed is taken where its BIC is lower by more than 10)",
            r[0],
            b[0],
            c.fixed_speed_mps * 3.6,
            r[1],
            b[1]
        );
    }
    h.push_str(".</p>\n");
}

/// The temperature forms the law was chosen from (BIC), and why there is no law when there is
/// none.
fn forms_table(h: &mut String, f: &PolachReport) {
    if let Some(t) = &f.temperature {
        let best = t
            .candidates
            .iter()
            .filter(|c| c.rejected.is_none())
            .map(|c| c.bic)
            .fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            *h,
            "<p>Temperature forms, each fitted jointly to all {} samples (A, B shared; n_eff = {:.0}); the least BIC whose law stays valid is chosen:</p>\n<table><tr><th class=\"l\">form</th><th>parameters</th><th>RMSE μ</th><th>AIC</th><th>BIC</th><th>ΔBIC</th><th class=\"l\"></th></tr>",
            t.samples, t.effective_samples
        );
        for c in &t.candidates {
            // The same degrees and the same speed law (the names carry both).
            let chosen = c.form() == t.form();
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{:.5}</td><td>{:.1}</td><td>{:.1}</td><td>{:.1}</td><td class=\"l\">{}</td></tr>",
                esc(&c.form()),
                c.parameters,
                c.rmse,
                c.aic,
                c.bic,
                c.bic - best,
                if chosen {
                    "<strong>chosen</strong>".to_string()
                } else {
                    c.rejected.as_deref().map(esc).unwrap_or_default()
                }
            );
        }
        h.push_str("</table>\n");
        for n in t.notes.iter().chain(&t.excluded) {
            let _ = writeln!(*h, "<p class=\"note\">{}</p>", esc(n));
        }
    }
    if let Some(n) = &f.temperature_note {
        let _ = writeln!(*h, "<p class=\"note\">Temperature law: {}</p>", esc(n));
    }
}
