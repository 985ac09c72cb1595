//! The validation report: one self-contained HTML file (`<out>/report/index.html`, plots as
//! inline SVG drawn by plotters with the embedded DejaVu Sans for text layout, no external
//! resources), rebuilt from what `railgrip run` wrote: `campaign.json`, the per-run estimates
//! tables and the model files.
//!
//! Figures follow seed 002 (002_8d8769283f5e9cb6.txt): per run, vehicle speed against wheel
//! peripheral speeds (Fig. 3), brake pressures (Fig. 4) and μ against Δv per axle (Fig. 7);
//! across runs, μ against Δv by initial speed (Fig. 8) and by ambient temperature; for the
//! network, training and validation error per epoch (Fig. 9), network against estimated μ on
//! validation data (Fig. 10), the hysteresis loop of a slip ramp 0 → 9 m/s → 0 (Fig. 11) and
//! μ over the (Δv, dΔv/dt) plane; then the Polach fits and k_A(T), k_S(T) (seed 004 eq. 3).

mod data;
pub(crate) mod plot;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use plotters::style::RGBColor;

use crate::contact::polach::{horner, polach, ContactPatch, PolachParams};
use crate::format::AXLES;
use crate::identify::polach::{PolachReport, PROFILE_LIMIT};
use crate::model::{Model, ModelError, ModelFile};
use crate::outdir::{CampaignRecord, OutDir, RecordError, RunRecord};
use data::{read_run, RunData};
use plot::{chart, heatmap, Series, PALETTE};

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Record(#[from] RecordError),
    /// A model file of the campaign exists but cannot be used.
    #[error("{0}")]
    Model(#[from] ModelError),
    /// The Polach fits file exists but does not parse.
    #[error("{file}: not a file railgrip wrote (its JSON does not parse: {source}). Hint: rerun `railgrip run` to rewrite it")]
    Fits {
        file: String,
        #[source]
        source: serde_json::Error,
    },
    #[error(
        "{file}: cannot read: {source}. Hint: rerun `railgrip run` to rewrite the output folder"
    )]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: {message}")]
    Data { file: String, message: String },
    /// A file of another campaign generation than `campaign.json`'s.
    #[error("{file}: written by campaign generation {found}, but campaign.json is generation {campaign} (an interrupted or concurrent `railgrip run`). Hint: rerun `railgrip run` into this folder")]
    Stale {
        file: String,
        found: String,
        campaign: String,
    },
    #[error("plot \"{plot}\": {message}")]
    Plot { plot: String, message: String },
    #[error("{file}: cannot write: {source}")]
    Write {
        file: String,
        #[source]
        source: std::io::Error,
    },
}

/// Everything the report is built from.
struct Inputs<'a> {
    camp: &'a CampaignRecord,
    mlp: Option<Model>,
    polach: Option<Model>,
    fits: Option<PolachReport>,
    /// Leave-one-run-out scores of the network, when the campaign computed them.
    held_out: Vec<crate::identify::HeldOut>,
    /// The runs that were estimated, with their tables.
    data: Vec<(&'a RunRecord, RunData)>,
}

impl<'a> Inputs<'a> {
    fn load(out: &OutDir, camp: &'a CampaignRecord) -> Result<Inputs<'a>, ReportError> {
        let models = out.models();
        let fits: Option<PolachReport> = match std::fs::read_to_string(models.polach_fits()) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(source) => {
                return Err(ReportError::Read {
                    file: models.polach_fits().display().to_string(),
                    source,
                })
            }
            Ok(t) => Some(
                serde_json::from_str(&t).map_err(|source| ReportError::Fits {
                    file: models.polach_fits().display().to_string(),
                    source,
                })?,
            ),
        };
        let held_out = match std::fs::read_to_string(models.leave_one_run_out()) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(source) => {
                return Err(ReportError::Read {
                    file: models.leave_one_run_out().display().to_string(),
                    source,
                })
            }
            Ok(t) => {
                let f: crate::identify::HeldOutFile =
                    serde_json::from_str(&t).map_err(|source| ReportError::Fits {
                        file: models.leave_one_run_out().display().to_string(),
                        source,
                    })?;
                same_generation(camp, &models.leave_one_run_out(), f.generation.as_deref())?;
                f.runs
            }
        };
        if let Some(f) = &fits {
            same_generation(camp, &models.polach_fits(), f.generation.as_deref())?;
        }
        let mut data = Vec::new();
        for r in camp.runs.iter().filter(|r| r.ok()) {
            data.push((r, read_run(&out.run_estimates(&r.run))?));
        }
        let mlp = optional_model(&models.mlp())?;
        let polach = optional_model(&models.polach())?;
        for (path, m) in [(models.mlp(), &mlp), (models.polach(), &polach)] {
            if let Some(m) = m {
                same_generation(camp, &path, m.file.provenance.generation.as_deref())?;
            }
        }
        Ok(Inputs {
            camp,
            mlp,
            polach,
            fits,
            held_out,
            data,
        })
    }

    /// True for the runs of the condition the models were trained on.
    fn in_condition(&self, r: &RunRecord) -> bool {
        self.camp.condition.is_none() || r.condition == self.camp.condition
    }
}

/// A file the report reads must come from the campaign generation of `campaign.json` (issue
/// 17: a killed re-run could leave new models beside an old campaign record). Records written
/// before generations existed are not checked.
fn same_generation(
    camp: &CampaignRecord,
    path: &Path,
    found: Option<&str>,
) -> Result<(), ReportError> {
    match (&camp.generation, found) {
        (None, _) => Ok(()),
        (Some(g), Some(f)) if g == f => Ok(()),
        (Some(g), f) => Err(ReportError::Stale {
            file: path.display().to_string(),
            found: f.unwrap_or("none").to_string(),
            campaign: g.clone(),
        }),
    }
}

/// The model at `path` when the campaign wrote one; a file that is there but cannot be used is
/// an error naming it.
fn optional_model(path: &Path) -> Result<Option<Model>, ReportError> {
    if !path.exists() {
        return Ok(None);
    }
    let file = ModelFile::read(path)?;
    Ok(Some(Model::named(file, &path.display().to_string())?))
}

/// Writes `<out>/report/index.html` from `<out>/campaign.json` and what it points to; returns
/// its path.
pub fn write_report(out: &OutDir) -> Result<PathBuf, ReportError> {
    let camp = CampaignRecord::read(out)?;
    let i = Inputs::load(out, &camp)?;
    let mut h = String::new();
    head(&mut h, &i);
    if let Some(m) = &i.mlp {
        audit_line(&mut h, m);
    }
    runs(&mut h, &i);
    across_runs(&mut h, &i)?;
    if let Some(m) = &i.mlp {
        network(&mut h, &i, m)?;
    }
    if let Some(f) = &i.fits {
        polach_fits(&mut h, &i, f)?;
    }
    h.push_str("<h2>Per run</h2>\n");
    per_run(&mut h, &i)?;
    if let Some(m) = &i.mlp {
        provenance(&mut h, m);
    }
    h.push_str("</body></html>\n");

    let path = out.report_html();
    let werr = |source: std::io::Error| ReportError::Write {
        file: path.display().to_string(),
        source,
    };
    std::fs::create_dir_all(out.report_dir()).map_err(werr)?;
    crate::atomic::write_atomically(&path, |w| w.write_all(h.as_bytes())).map_err(werr)?;
    Ok(path)
}

pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn opt(v: Option<f64>, d: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.d$}"))
}

/// The document head, styles and the campaign line.
fn head(h: &mut String, i: &Inputs) {
    let (camp, data) = (i.camp, &i.data);
    let _ = write!(
        *h,
        r#"{head}<h1>railgrip validation report</h1>
<p>Campaign <code>{archive}</code>: {n} run(s), {nok} estimated, {nf} failed. Models trained on
<b>{cond}</b> rail. Pipeline <code>{pipe}</code>. railgrip {ver}.</p>
"#,
        head = page_head(&format!("railgrip report — {}", camp.archive)),
        archive = esc(&camp.archive),
        n = camp.runs.len(),
        nok = data.len(),
        nf = camp.runs.len() - data.len(),
        cond = esc(camp.condition.as_deref().unwrap_or("–")),
        pipe = esc(&camp.pipeline),
        ver = env!("CARGO_PKG_VERSION"),
    );
}

/// A report page's document head up to and including `<body>`: `title` (escaped here) and the
/// shared style sheet.
pub(crate) fn page_head(title: &str) -> String {
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>\n{STYLE}</style></head><body>\n",
        esc(title)
    )
}

/// The reports' style sheet (validation report, study report).
const STYLE: &str = r#"body { font-family: "DejaVu Sans", Verdana, sans-serif; margin: 1.5em auto; max-width: 1300px; color: #222; padding: 0 1em; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; border-bottom: 1px solid #ccc; margin-top: 2em; }
h3 { font-size: 1.05em; margin-bottom: 0.3em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.85em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f2f2f2; } td.l, th.l { text-align: left; }
.failed { color: #b00; } .figs { display: flex; flex-wrap: wrap; gap: 6px; }
.figs svg { border: 1px solid #eee; } p.note { font-size: 0.9em; color: #555; }
"#;

/// The plausibility audit at the top: a red line with the failures when the network failed
/// it, one quiet line when it passed (docs/model-files.md#plausibility-audit).
fn audit_line(h: &mut String, m: &Model) {
    let Some(a) = &m.file.audit else {
        return;
    };
    if a.passed {
        let _ = writeln!(
            *h,
            "<p class=\"note\">Plausibility audit passed: 0 ≤ μ ≤ {} on every supported cell of the network{}.</p>",
            a.mu_max,
            match (a.hysteresis_data, a.hysteresis_model) {
                (Some(d), Some(m)) => format!(
                    "; loss − recovery difference {m:+.4} (data {d:+.4})"
                ),
                _ => String::new(),
            }
        );
        return;
    }
    let _ = writeln!(
        *h,
        "<p class=\"failed\" style=\"border: 2px solid #b00; padding: 0.4em\"><b>Plausibility audit FAILED</b> ({} problem(s)): the network model is written but marked <code>audit.passed = false</code>; do not hand it to a simulator unchecked.</p>\n<ul class=\"failed\">",
        a.failing_cells
    );
    for f in &a.failures {
        let _ = writeln!(*h, "<li>{}</li>", esc(f));
    }
    h.push_str("</ul>\n");
}

/// The runs table, failed runs, warnings and notes.
fn runs(h: &mut String, i: &Inputs) {
    let camp = i.camp;
    // Runs table.
    h.push_str("<h2>Runs</h2>\n<table><tr><th class=\"l\">run</th><th>status</th><th>initial speed km/h</th><th>ambient °C</th><th class=\"l\">condition</th><th>peak μ axles 1–4</th><th>max Δv m/s axles 1–4</th></tr>\n");
    for r in &camp.runs {
        let axles = |v: &[Option<f64>; AXLES], d| {
            v.iter().map(|x| opt(*x, d)).collect::<Vec<_>>().join(" / ")
        };
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{}</td><td class=\"{}\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td></tr>",
            esc(&r.run),
            if r.ok() { "" } else { "failed" },
            if r.ok() { "ok" } else { "FAILED" },
            opt(r.initial_speed_kmh, 0),
            opt(r.ambient_temperature_c, 0),
            esc(r.condition.as_deref().unwrap_or("–")),
            axles(&r.peak_mu, 3),
            axles(&r.max_dv_mps, 2),
        );
    }
    h.push_str("</table>\n");
    let failed: Vec<&RunRecord> = camp.runs.iter().filter(|r| !r.ok()).collect();
    if !failed.is_empty() {
        h.push_str("<h3 class=\"failed\">Failed runs</h3>\n<table><tr><th class=\"l\">run</th><th class=\"l\">error</th></tr>\n");
        for r in failed {
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">{}</td><td class=\"l failed\">{}</td></tr>",
                esc(&r.run),
                esc(r.error.as_deref().unwrap_or(""))
            );
        }
        h.push_str("</table>\n");
    }
    let warned: Vec<&RunRecord> = camp
        .runs
        .iter()
        .filter(|r| !r.warnings.is_empty())
        .collect();
    if !warned.is_empty() || !camp.notes.is_empty() || camp.model_error.is_some() {
        h.push_str("<h3>Warnings and notes</h3>\n<table><tr><th class=\"l\">where</th><th class=\"l\">what</th></tr>\n");
        for r in warned {
            for w in &r.warnings {
                let _ = writeln!(
                    *h,
                    "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                    esc(&r.run),
                    esc(w)
                );
            }
        }
        for n in &camp.notes {
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">campaign</td><td class=\"l\">{}</td></tr>",
                esc(n)
            );
        }
        if let Some(e) = &camp.model_error {
            let _ = writeln!(
                *h,
                "<tr><td class=\"l\">models</td><td class=\"l failed\">{}</td></tr>",
                esc(e)
            );
        }
        h.push_str("</table>\n");
    }
}

/// μ against Δv across runs, by initial speed (seed 002 Fig. 8) and by ambient temperature.
fn across_runs(h: &mut String, i: &Inputs) -> Result<(), ReportError> {
    let data = &i.data;
    // Across runs.
    h.push_str("<h2>Across runs</h2>\n<p class=\"note\">Valid estimates, axle 2 (the training axle of seed 002), every run of the training condition.</p>\n<div class=\"figs\">\n");
    let group = |key: &dyn Fn(&RunRecord) -> Option<f64>, unit: &str| -> Vec<Series> {
        let mut keys: Vec<f64> = data
            .iter()
            .filter(|(r, _)| i.in_condition(r))
            .filter_map(|(r, _)| key(r))
            .collect();
        keys.sort_by(f64::total_cmp);
        keys.dedup();
        keys.iter()
            .enumerate()
            .map(|(k, kv)| Series {
                name: format!("{kv} {unit}"),
                color: PALETTE[k % PALETTE.len()],
                pts: data
                    .iter()
                    .filter(|(r, _)| i.in_condition(r) && key(r) == Some(*kv))
                    .flat_map(|(_, d)| d.valid[1].iter().map(|v| (v.0, v.2)))
                    .collect(),
                dots: true,
            })
            .collect()
    };
    h.push_str(&chart(
        "μ against Δv by initial speed (seed 002 Fig. 8)",
        "Δv (m/s)",
        "μ",
        &group(&|r| r.initial_speed_kmh, "km/h"),
        false,
    )?);
    h.push_str(&chart(
        "μ against Δv by ambient temperature",
        "Δv (m/s)",
        "μ",
        &group(&|r| r.ambient_temperature_c, "°C"),
        false,
    )?);
    h.push_str("</div>\n");
    Ok(())
}

/// The network: metrics, error per epoch (Fig. 9), against the estimate (Fig. 10), the slip
/// ramp (Fig. 11) and μ over the (Δv, dΔv/dt) plane.
fn network(h: &mut String, i: &Inputs, m: &Model) -> Result<(), ReportError> {
    let (camp, data) = (i.camp, &i.data);
    h.push_str("<h2>Network μ(Δv, dΔv/dt)</h2>\n");
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
    if !i.held_out.is_empty() {
        h.push_str("<h3>Leave-one-run-out</h3>\n<p class=\"note\">Each row: a network trained (one start) on the other runs, scored against this run's own estimates (all axles) — generalisation across runs, which the axle split above cannot show.</p>\n<table><tr><th class=\"l\">held-out run</th><th>samples</th><th>RMSE μ</th></tr>\n");
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
    h.push_str("<div class=\"figs\">\n");
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
    // Fig. 10: the first training-condition run, the first validation axle.
    let va = camp.validation_axles.first().copied().unwrap_or(3) as usize;
    if let Some((r, d)) = data.iter().find(|(r, _)| i.in_condition(r)) {
        let pts = &d.valid[(va.clamp(1, AXLES)) - 1];
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
    // Fig. 11: slip ramp 0 → 9 → 0 m/s at ±2 m/s²; the ensemble's ±2σ band, and the parts
    // outside the data support (where the model blends to its fallback) marked.
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
    // Each branch drawn over in grey where it leaves the data support (contiguous pieces).
    let mut labelled = false;
    for branch in [&up, &down] {
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
    if up.iter().any(|p| p.3.is_finite()) {
        let light = |c: RGBColor| {
            let l = |v: u8| v + ((255 - v) as f64 * 0.6) as u8;
            RGBColor(l(c.0), l(c.1), l(c.2))
        };
        for sign in [2.0, -2.0] {
            for (k, (branch, c)) in [(&up, PALETTE[0]), (&down, PALETTE[1])]
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
    h.push_str(&chart(
        "Slip ramp 0 → 9 → 0 m/s at ±2 m/s² (Fig. 11)",
        "Δv (m/s)",
        "μ",
        &series,
        false,
    )?);
    h.push_str(&heatmap(m)?);
    h.push_str("</div>\n<p class=\"note\">Outside the trained domain the network holds its boundary value (inputs clamped); Δv beyond ");
    let _ = writeln!(
        *h,
        "{:.2} m/s and dΔv/dt outside [{:.2}, {:.2}] m/s² were not seen in training.</p>",
        m.file.inputs[0].domain_max, m.file.inputs[1].domain_min, m.file.inputs[1].domain_max
    );
    Ok(())
}

/// The Polach fits (seed 004 eq. 1–3) over the estimates, and k_A(T), k_S(T).
fn polach_fits(h: &mut String, i: &Inputs, f: &PolachReport) -> Result<(), ReportError> {
    let (data, polach_model) = (&i.data, &i.polach);
    h.push_str("<h2>Polach fits (seed 004 eq. 1–3)</h2>\n<table><tr><th class=\"l\">group</th><th>μ0</th><th>A</th><th>B s/m</th><th>k_A</th><th>k_S</th><th>RMSE μ</th><th>samples</th></tr>\n");
    use crate::identify::polach::ParamStatus;
    // Each parameter as estimated ± se, or held: at its bound, or at the prior where the data
    // do not identify it.
    // Each parameter as estimated ± se with its profile-likelihood 95 % interval, or held: at
    // its bound, or at its least-squares value where the data do not identify it.
    let cell = |p: &crate::identify::polach::PolachFit, k: usize, x: f64| {
        let s = p.se[k];
        let ci = p
            .profiles
            .iter()
            .find(|q| q.parameter == crate::identify::polach::PARAMETERS[k])
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
        h.push_str("<p>What the data could not identify (held, the rest refitted; seed 004, issue 16):</p>\n<ul>\n");
        for n in &notes {
            let _ = writeln!(*h, "<li>{}</li>", esc(n));
        }
        h.push_str("</ul>\n");
    }
    h.push_str("<div class=\"figs\">\n");
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
    let dv_max = f.dv_range_mps.1.max(0.5);
    let curve = |p: &PolachParams| -> Vec<(f64, f64)> {
        (1..=200)
            .filter_map(|k| {
                let dv = dv_max * k as f64 / 200.0;
                polach(&patch, p, f.wheel_load_n, v_ref, dv, 0.0)
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
    let scatter: Vec<(f64, f64)> = data
        .iter()
        .filter(|(r, _)| i.in_condition(r))
        .flat_map(|(_, d)| d.valid[1].iter().map(|v| (v.0, v.2)))
        .collect();
    series.insert(
        0,
        Series {
            name: String::new(),
            color: RGBColor(170, 170, 170),
            pts: scatter,
            dots: true,
        },
    );
    h.push_str(&chart(
        &format!("Polach fits at {v_ref:.1} m/s over the estimates"),
        "Δv (m/s)",
        "μ",
        &series,
        false,
    )?);
    // Profile likelihood of the pooled fit: each parameter's statistic against its distance
    // from the estimate in Wald standard errors, beside the Wald parabola z².
    if let Some(p) = f.pooled.as_ref().filter(|p| !p.profiles.is_empty()) {
        let mut series: Vec<Series> = p
            .profiles
            .iter()
            .enumerate()
            .filter_map(|(k, q)| {
                let i = crate::identify::polach::PARAMETERS
                    .iter()
                    .position(|n| *n == q.parameter)?;
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
    h.push_str("</div>\n");
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
            let chosen = c.mu0_degree == t.mu0_degree && c.k_degree == t.k_degree;
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
    Ok(())
}

/// Per run: speeds (Fig. 3), pressures (Fig. 4) and μ against Δv per axle (Fig. 7).
fn per_run(h: &mut String, i: &Inputs) -> Result<(), ReportError> {
    let data = &i.data;
    for (r, d) in data {
        let _ = writeln!(
            *h,
            "<h3>{} — {} km/h, {} °C, {}</h3>\n<div class=\"figs\">",
            esc(&r.run),
            opt(r.initial_speed_kmh, 0),
            opt(r.ambient_temperature_c, 0),
            esc(r.condition.as_deref().unwrap_or("condition unknown"))
        );
        let mut speeds = vec![Series {
            name: "vehicle v".into(),
            color: RGBColor(0, 0, 0),
            pts: d
                .time_s
                .iter()
                .copied()
                .zip(d.v_mps.iter().copied())
                .collect(),
            dots: false,
        }];
        for (a, w) in d.wheel.iter().enumerate() {
            speeds.push(Series {
                name: format!("rω axle {}", a + 1),
                color: PALETTE[a],
                pts: w.clone(),
                dots: false,
            });
        }
        h.push_str(&chart(
            "Vehicle and wheel peripheral speeds (Fig. 3)",
            "time (s)",
            "speed (m/s)",
            &speeds,
            false,
        )?);
        let pressures: Vec<Series> = (0..AXLES)
            .map(|a| Series {
                name: format!("axle {}", a + 1),
                color: PALETTE[a],
                pts: d.pressure[a].clone(),
                dots: false,
            })
            .collect();
        h.push_str(&chart(
            "Brake-cylinder pressures (Fig. 4)",
            "time (s)",
            "pressure (bar)",
            &pressures,
            false,
        )?);
        let mus: Vec<Series> = (0..AXLES)
            .map(|a| Series {
                name: format!("axle {}", a + 1),
                color: PALETTE[a],
                pts: d.valid[a].iter().map(|v| (v.0, v.2)).collect(),
                dots: true,
            })
            .collect();
        h.push_str(&chart(
            "μ against Δv per axle (Fig. 7)",
            "Δv (m/s)",
            "μ",
            &mus,
            false,
        )?);
        h.push_str("</div>\n");
    }
    Ok(())
}

/// Where the network came from.
fn provenance(h: &mut String, m: &Model) {
    let p = &m.file.provenance;
    h.push_str("<h2>Provenance</h2>\n<table>");
    let _ = writeln!(
        *h,
        "<tr><th class=\"l\">pipeline</th><td class=\"l\">{} (SHA-256 {})</td></tr>\n<tr><th class=\"l\">seed</th><td class=\"l\">{}</td></tr>\n<tr><th class=\"l\">railgrip</th><td class=\"l\">{}</td></tr>\n<tr><th class=\"l\">generation</th><td class=\"l\">{}</td></tr>",
        esc(&p.pipeline),
        esc(&p.pipeline_sha256),
        p.seed,
        esc(&p.crate_version),
        esc(p.generation.as_deref().unwrap_or("–"))
    );
    for i in &p.inputs {
        let _ = writeln!(
            *h,
            "<tr><th class=\"l\">input</th><td class=\"l\">{} <small>{}</small></td></tr>",
            esc(&i.path),
            esc(&i.sha256)
        );
    }
    h.push_str("</table>\n");
}
