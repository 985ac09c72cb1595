//! The validation report: one self-contained HTML file (`<out>/report/index.html`, plots as
//! inline SVG drawn by plotters with the embedded DejaVu Sans for text layout, no external
//! resources), rebuilt from what `railgrip run` wrote: `campaign.json`, the per-run estimates
//! tables and the model files. Beyond [`INLINE_RUNS`] runs (or when asked, [`RunSections`])
//! each run's own charts go on a page of their own, `report/runs/<run>.html`.
//!
//! Figures follow seed 002 (002_8d8769283f5e9cb6.txt): per run, vehicle speed against wheel
//! peripheral speeds (Fig. 3), brake pressures (Fig. 4) and μ against Δv per axle (Fig. 7);
//! across runs, μ against Δv by initial speed (Fig. 8) and by ambient temperature; for the
//! network, training and validation error per epoch (Fig. 9), network against estimated μ on
//! validation data (Fig. 10), the hysteresis loop of a slip ramp 0 → 9 m/s → 0 (Fig. 11) and
//! μ over the (Δv, dΔv/dt) plane; then the Polach fits and k_A(T), k_S(T) (seed 004 eq. 3).

mod choice;
mod data;
mod network;
pub(crate) mod plot;
mod polach;

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use plotters::style::RGBColor;

use crate::atomic::Scratch;
use crate::format::AXLES;
use crate::identify::polach::PolachReport;
use crate::model::{Model, ModelError, ModelFile};
use crate::outdir::{CampaignRecord, OutDir, RecordError, RunRecord};
use crate::score::SpeedBands;
use data::{count_valid, read_run, RunData, ValidPoint};
use plot::{chart, chart_thinned, Series, Thinned, PALETTE};

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
    /// A table of the output folder that the table reader refuses.
    #[error("{file}: {source}")]
    Table {
        file: String,
        #[source]
        source: polars::error::PolarsError,
    },
    /// A file of another campaign generation than `campaign.json`'s.
    #[error("{file}: written by campaign generation {found}, but campaign.json is generation {campaign} (an interrupted or concurrent `railgrip run`). Hint: rerun `railgrip run` into this folder")]
    Stale {
        file: String,
        found: String,
        campaign: String,
    },
    #[error("plot \"{plot}\": {source}")]
    Plot {
        plot: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
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
    /// The model choice and the chosen model, when the campaign wrote them.
    choice: Option<crate::identify::choice::Choice>,
    chosen: Option<Model>,
    /// Runs that were estimated (their tables read).
    estimated: usize,
    /// Each run's section on a page of its own (`report/runs/<run>.html`) instead of in
    /// `sections`.
    pages: bool,
    /// What the sections across runs draw, gathered as the runs were read.
    across: Across<'a>,
    /// Each estimated run's own section, in run order ([`run_section`]), written out as the
    /// runs were read and copied into the page last.
    sections: Scratch,
}

/// What the sections across runs draw from the runs' samples, gathered one run at a time so
/// that the report keeps no run's samples (bar the first run's, for Fig. 10): the charts' clouds
/// as they draw them ([`Thinned`]) and the chosen model's errors per speed band as sums.
/// Everything is over axle 2's valid samples (seed 002's training axle) of the runs of the
/// training condition, in run order.
struct Across<'a> {
    /// μ against Δv per initial speed and per ambient temperature: (key, cloud), keys
    /// ascending.
    by_speed: Vec<(f64, Thinned)>,
    by_temperature: Vec<(f64, Thinned)>,
    /// The same samples in one cloud (the Polach fits' chart).
    all: Thinned,
    /// The chosen model replayed at each sample against the estimate, per speed band.
    bands: Option<SpeedBands>,
    /// The first run of the training condition and its valid samples on every axle (Fig. 10
    /// draws its validation axle).
    first: Option<(&'a RunRecord, [Vec<ValidPoint>; AXLES])>,
}

fn initial_speed(r: &RunRecord) -> Option<f64> {
    r.initial_speed_kmh
}

fn ambient_temperature(r: &RunRecord) -> Option<f64> {
    r.ambient_temperature_c
}

impl<'a> Across<'a> {
    /// Empty clouds sized for the runs `runs` (the training condition's, with their numbers of
    /// valid axle-2 samples).
    fn new(runs: &[(&RunRecord, usize)], chosen: Option<&Model>) -> Across<'a> {
        let groups = |key: fn(&RunRecord) -> Option<f64>| -> Vec<(f64, Thinned)> {
            let mut keys: Vec<f64> = runs.iter().filter_map(|(r, _)| key(r)).collect();
            keys.sort_by(f64::total_cmp);
            keys.dedup();
            keys.iter()
                .map(|kv| {
                    let total = runs
                        .iter()
                        .filter(|(r, _)| key(r) == Some(*kv))
                        .map(|(_, n)| n)
                        .sum();
                    (*kv, Thinned::new(total))
                })
                .collect()
        };
        Across {
            by_speed: groups(initial_speed),
            by_temperature: groups(ambient_temperature),
            all: Thinned::new(runs.iter().map(|(_, n)| n).sum()),
            bands: chosen.map(|_| SpeedBands::new(&crate::score::SPEED_BANDS_KMH)),
            first: None,
        }
    }

    /// A run of the training condition, its valid samples per axle.
    fn add(&mut self, r: &'a RunRecord, valid: [Vec<ValidPoint>; AXLES], chosen: Option<&Model>) {
        let group = |groups: &[(f64, Thinned)], key: Option<f64>| {
            groups.iter().position(|(kv, _)| key == Some(*kv))
        };
        let ks = group(&self.by_speed, initial_speed(r));
        let kt = group(&self.by_temperature, ambient_temperature(r));
        let t_c = r.ambient_temperature_c.unwrap_or(f64::NAN);
        for &(dv, ddv, mu, _, v) in &valid[1] {
            if let Some(k) = ks {
                self.by_speed[k].1.push((dv, mu));
            }
            if let Some(k) = kt {
                self.by_temperature[k].1.push((dv, mu));
            }
            self.all.push((dv, mu));
            if let (Some(b), Some(m)) = (&mut self.bands, chosen) {
                let e = m.mu_vt(dv, ddv, v, t_c) - mu;
                if e.is_finite() {
                    b.push(v * 3.6, e);
                }
            }
        }
        if self.first.is_none() {
            self.first = Some((r, valid));
        }
    }
}

impl<'a> Inputs<'a> {
    fn load(
        out: &OutDir,
        camp: &'a CampaignRecord,
        pages: bool,
    ) -> Result<Inputs<'a>, ReportError> {
        let models = out.models();
        let fits: Option<PolachReport> = optional_json(&models.polach_fits())?;
        if let Some(f) = &fits {
            same_generation(camp, &models.polach_fits(), f.generation.as_deref())?;
        }
        let held_out_file: Option<crate::identify::HeldOutFile> =
            optional_json(&models.leave_one_run_out())?;
        let held_out = match held_out_file {
            Some(f) => {
                same_generation(camp, &models.leave_one_run_out(), f.generation.as_deref())?;
                f.runs
            }
            None => Vec::new(),
        };
        let choice: Option<crate::identify::choice::Choice> = optional_json(&models.choice())?;
        if let Some(c) = &choice {
            same_generation(camp, &models.choice(), c.generation.as_deref())?;
        }
        let chosen = match &camp.chosen_model {
            Some(rel) => {
                let path = out.root().join(rel);
                let m = optional_model(&path)?;
                if let Some(m) = &m {
                    same_generation(camp, &path, m.file.provenance.generation.as_deref())?;
                }
                m
            }
            None => None,
        };
        let mlp = optional_model(&models.mlp())?;
        let polach = optional_model(&models.polach())?;
        for (path, m) in [(models.mlp(), &mlp), (models.polach(), &polach)] {
            if let Some(m) = m {
                same_generation(camp, &path, m.file.provenance.generation.as_deref())?;
            }
        }
        // One run at a time: its own section is drawn and written out, and the sections across
        // runs take what they draw of its samples (sized beforehand from the runs' numbers of
        // valid axle-2 samples), so that the report's memory does not grow with the runs.
        let in_condition =
            |r: &RunRecord| camp.condition.is_none() || r.condition == camp.condition;
        let mut sized = Vec::new();
        for r in camp.runs.iter().filter(|r| r.ok() && in_condition(r)) {
            sized.push((r, count_valid(&out.run_estimates(&r.run), 2)?));
        }
        let mut across = Across::new(&sized, chosen.as_ref());
        drop(sized);
        let html = out.report_html();
        let werr = |source: std::io::Error| ReportError::Write {
            file: html.display().to_string(),
            source,
        };
        std::fs::create_dir_all(if pages {
            pages_dir(out)
        } else {
            out.report_dir()
        })
        .map_err(werr)?;
        let mut sections = Scratch::beside(&html, "sections").map_err(werr)?;
        let mut estimated = 0;
        {
            let mut w = std::io::BufWriter::new(sections.file());
            for r in camp.runs.iter().filter(|r| r.ok()) {
                let mut d = read_run(&out.run_estimates(&r.run))?;
                let section = run_section(r, &mut d)?;
                if pages {
                    write_page(out, r, &section)?;
                } else {
                    w.write_all(section.as_bytes()).map_err(werr)?;
                }
                if in_condition(r) {
                    across.add(r, d.valid, chosen.as_ref());
                }
                estimated += 1;
            }
            w.flush().map_err(werr)?;
        }
        Ok(Inputs {
            camp,
            mlp,
            polach,
            fits,
            held_out,
            choice,
            chosen,
            estimated,
            pages,
            across,
            sections,
        })
    }
}

/// A file the report reads must come from the campaign generation of `campaign.json` (a killed
/// re-run could otherwise leave new models beside an old campaign record). Records written
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

/// The JSON file at `path` when the campaign wrote one (`None` when it is absent); a file that
/// is there but cannot be read or parsed is an error naming it.
fn optional_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<Option<T>, ReportError> {
    let file = || path.display().to_string();
    match std::fs::read_to_string(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(ReportError::Read {
            file: file(),
            source,
        }),
        Ok(t) => serde_json::from_str(&t)
            .map(Some)
            .map_err(|source| ReportError::Fits {
                file: file(),
                source,
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

/// Campaigns of more estimated runs than this get a page per run with [`RunSections::Auto`]:
/// each run's three charts take ~250 KB, so one page for hundreds of runs would be more than a
/// browser opens comfortably.
pub const INLINE_RUNS: usize = 32;

/// Where each run's own section (speeds, pressures, μ against Δv) goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RunSections {
    /// In `index.html` up to [`INLINE_RUNS`] estimated runs, on pages of their own beyond.
    #[default]
    Auto,
    /// In `index.html`.
    Inline,
    /// On pages of their own, `report/runs/<run>.html`, linked from `index.html`.
    Pages,
}

/// Writes the report of the output folder `out` with [`RunSections::Auto`].
pub fn write_report(out: &OutDir) -> Result<PathBuf, ReportError> {
    write_report_as(out, RunSections::Auto)
}

/// Writes `<out>/report/index.html` from `<out>/campaign.json` and what it points to, each
/// run's section where `sections` says; returns its path. Pages of runs the report no longer has (or all of them, inline) are removed once
/// `index.html` is written.
pub fn write_report_as(out: &OutDir, sections: RunSections) -> Result<PathBuf, ReportError> {
    let camp = CampaignRecord::read(out)?;
    let pages = match sections {
        RunSections::Auto => camp.runs.iter().filter(|r| r.ok()).count() > INLINE_RUNS,
        RunSections::Inline => false,
        RunSections::Pages => true,
    };
    let i = Inputs::load(out, &camp, pages)?;
    let mut h = String::new();
    head(&mut h, &i);
    if let Some(m) = &i.mlp {
        audit_line(&mut h, m);
    }
    if let Some(c) = &i.choice {
        choice::campaign_model(&mut h, &i, c, i.chosen.as_ref());
    }
    calibration(&mut h, out, i.camp);
    runs(&mut h, &i);
    across_runs(&mut h, &i)?;
    if let Some(m) = &i.mlp {
        network::network(&mut h, &i, m)?;
    }
    if let Some(f) = &i.fits {
        polach::polach_fits(&mut h, &i, f)?;
    }
    h.push_str("<h2>Per run</h2>\n");
    if pages {
        run_links(&mut h, &i);
    }
    let mut tail = String::new();
    if let Some(m) = &i.mlp {
        provenance(&mut tail, m);
    }
    tail.push_str("</body></html>\n");

    let path = out.report_html();
    let werr = |source: std::io::Error| ReportError::Write {
        file: path.display().to_string(),
        source,
    };
    let mut sections = i.sections;
    crate::atomic::write_atomically(&path, |w| {
        w.write_all(h.as_bytes())?;
        per_run(w, &mut sections)?;
        w.write_all(tail.as_bytes())
    })
    .map_err(werr)?;
    remove_stale_pages(out, if pages { camp.runs.as_slice() } else { &[] });
    Ok(path)
}

/// The folder of the runs' own pages, `report/runs`.
fn pages_dir(out: &OutDir) -> PathBuf {
    out.report_dir().join("runs")
}

/// A run's own page: `report/runs/<run>.html`.
fn page_name(run: &str) -> String {
    format!("{run}.html")
}

/// `name` as a relative URL path segment: every byte but the unreserved ones (RFC 3986)
/// percent-encoded.
fn href_segment(name: &str) -> String {
    let mut s = String::new();
    for b in name.bytes() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b'_' | b'~') {
            s.push(b as char);
        } else {
            let _ = write!(s, "%{b:02X}");
        }
    }
    s
}

/// Removes the runs' pages that are not of the estimated runs in `runs` (all of them when it
/// is empty), and the folder when nothing else is left in it. Errors are ignored: a page that
/// cannot be removed stays, unlinked.
fn remove_stale_pages(out: &OutDir, runs: &[RunRecord]) {
    let dir = pages_dir(out);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return;
    };
    let keep: std::collections::HashSet<String> = runs
        .iter()
        .filter(|r| r.ok())
        .map(|r| page_name(&r.run))
        .collect();
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".html") && !keep.contains(&name) {
            let _ = std::fs::remove_file(e.path());
        }
    }
    let _ = std::fs::remove_dir(&dir);
}

/// The list of the runs' own pages, in place of their sections.
fn run_links(h: &mut String, i: &Inputs) {
    let _ = writeln!(
        *h,
        "<p class=\"note\">Each run's speeds (Fig. 3), pressures (Fig. 4) and μ against Δv per axle (Fig. 7) are on a page of their own ({} runs).</p>\n<ul>",
        i.estimated
    );
    for r in i.camp.runs.iter().filter(|r| r.ok()) {
        let _ = writeln!(
            *h,
            "<li><a href=\"runs/{}\">{}</a> — {} km/h, {} °C, {}</li>",
            href_segment(&page_name(&r.run)),
            esc(&r.run),
            opt(r.initial_speed_kmh, 0),
            opt(r.ambient_temperature_c, 0),
            esc(r.condition.as_deref().unwrap_or("condition unknown"))
        );
    }
    h.push_str("</ul>\n");
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
    let camp = i.camp;
    let _ = write!(
        *h,
        r#"{head}<h1>railgrip validation report</h1>
<p>Campaign <code>{archive}</code>: {n} run(s), {nok} estimated, {nf} failed. Models trained on
<b>{cond}</b> rail. Pipeline <code>{pipe}</code>. railgrip {ver}.</p>
"#,
        head = page_head(&format!("railgrip report — {}", camp.archive)),
        archive = esc(&camp.archive),
        n = camp.runs.len(),
        nok = i.estimated,
        nf = camp.runs.len() - i.estimated,
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
            if i.pages && r.ok() {
                format!(
                    "<a href=\"runs/{}\">{}</a>",
                    href_segment(&page_name(&r.run)),
                    esc(&r.run)
                )
            } else {
                esc(&r.run)
            },
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
    h.push_str("<h2>Across runs</h2>\n<p class=\"note\">Valid estimates, axle 2 (the training axle of seed 002), every run of the training condition.</p>\n<div class=\"figs\">\n");
    for (title, groups, unit) in [
        (
            "μ against Δv by initial speed (seed 002 Fig. 8)",
            &i.across.by_speed,
            "km/h",
        ),
        (
            "μ against Δv by ambient temperature",
            &i.across.by_temperature,
            "°C",
        ),
    ] {
        let series: Vec<Series> = groups
            .iter()
            .enumerate()
            .map(|(k, (kv, cloud))| Series {
                name: format!("{kv} {unit}"),
                color: PALETTE[k % PALETTE.len()],
                pts: cloud.points().to_vec(),
                dots: true,
            })
            .collect();
        let clouds: Vec<&Thinned> = groups.iter().map(|(_, c)| c).collect();
        h.push_str(&chart_thinned(title, "Δv (m/s)", "μ", &series, &clouds)?);
    }
    h.push_str("</div>\n");
    Ok(())
}

/// Per run: speeds (Fig. 3), pressures (Fig. 4) and μ against Δv per axle (Fig. 7), each
/// drawn when the run was read ([`run_section`]) and kept in the scratch file `sections`,
/// copied into the page here.
fn per_run(w: &mut impl std::io::Write, sections: &mut Scratch) -> std::io::Result<()> {
    use std::io::Seek;
    let f = sections.file();
    f.rewind()?;
    std::io::copy(f, w)?;
    Ok(())
}

/// A run's section of the report (see [`per_run`]); its time series are moved into the
/// charts, its valid samples left.
fn run_section(r: &RunRecord, d: &mut RunData) -> Result<String, ReportError> {
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<h3>{} — {} km/h, {} °C, {}</h3>\n<div class=\"figs\">",
        esc(&r.run),
        opt(r.initial_speed_kmh, 0),
        opt(r.ambient_temperature_c, 0),
        esc(r.condition.as_deref().unwrap_or("condition unknown"))
    );
    // One series per axle, named `{prefix}axle N`.
    let per_axle = |prefix: &str, pts: &mut dyn FnMut(usize) -> Vec<(f64, f64)>, dots| {
        (0..AXLES)
            .map(|a| Series {
                name: format!("{prefix}axle {}", a + 1),
                color: PALETTE[a],
                pts: pts(a),
                dots,
            })
            .collect::<Vec<_>>()
    };
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
    speeds.extend(per_axle(
        "rω ",
        &mut |a| std::mem::take(&mut d.wheel[a]),
        false,
    ));
    let pressures = per_axle("", &mut |a| std::mem::take(&mut d.pressure[a]), false);
    let mus = per_axle(
        "",
        &mut |a| d.valid[a].iter().map(|v| (v.0, v.2)).collect(),
        true,
    );
    for (title, x, y, series) in [
        (
            "Vehicle and wheel peripheral speeds (Fig. 3)",
            "time (s)",
            "speed (m/s)",
            &speeds,
        ),
        (
            "Brake-cylinder pressures (Fig. 4)",
            "time (s)",
            "pressure (bar)",
            &pressures,
        ),
        ("μ against Δv per axle (Fig. 7)", "Δv (m/s)", "μ", &mus),
    ] {
        h.push_str(&chart(title, x, y, series, false)?);
    }
    h.push_str("</div>\n");
    Ok(h)
}

/// A run's own page, `report/runs/<run>.html`: its section under a link back to the campaign's
/// report.
fn write_page(out: &OutDir, r: &RunRecord, section: &str) -> Result<(), ReportError> {
    let path = pages_dir(out).join(page_name(&r.run));
    let page = format!(
        "{}<p><a href=\"../index.html\">← the campaign's report</a></p>\n{section}</body></html>\n",
        page_head(&format!("railgrip report — {}", r.run))
    );
    crate::atomic::write_atomically(&path, |w| w.write_all(page.as_bytes())).map_err(|source| {
        ReportError::Write {
            file: path.display().to_string(),
            source,
        }
    })
}

/// The campaign's calibration, when its runs were estimated with one (`calibration.json`, read
/// as plain JSON: the report does not depend on the campaign module that writes it): what was
/// fitted, its standard errors, the pad-friction forms compared, what it does to each axle's
/// brake force (so to μ) and to the slip, and its notes.
fn calibration(h: &mut String, out: &OutDir, camp: &CampaignRecord) {
    let Some(cal) = &camp.calibration else {
        return;
    };
    let c = &cal.corrections;
    let rec: serde_json::Value = std::fs::read_to_string(out.root().join("calibration.json"))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or(serde_json::Value::Null);
    let fit = &rec["campaign"];
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    // A dry-run calibration has one α with one standard error and no radar fit.
    let alpha_se = |a: usize| match fit.is_null() {
        true => num(&rec["dry_run"]["alpha_se"]),
        false => num(&fit["alpha_se"][a]),
    };
    let se = |x: f64, digits: usize| {
        if x.is_finite() {
            format!("{x:.digits$}")
        } else {
            "–".to_string()
        }
    };
    let _ = writeln!(
        *h,
        "<h2>Calibration</h2>\n<p>The runs were estimated with a <b>{}</b> calibration fitted on {} (<code>calibration.json</code>; see docs/calibration.md).</p>\n<table><tr><th class=\"l\">axle</th><th>α at {:.0} km/h, N·m/bar</th><th>± 1σ</th><th>pipeline's</th><th>brake force at {:.0} km/h</th><th>at 10 km/h</th></tr>",
        esc(&cal.source),
        cal.runs_fitted(),
        c.pad.v_ref_mps * 3.6,
        c.pad.v_ref_mps * 3.6
    );
    for a in 0..crate::format::AXLES {
        let base = num(&rec["pipeline_alpha_nm_per_bar"][a]);
        let at = |v: f64| (c.alpha_nm_per_bar[a] * c.pad.factor(v) / base - 1.0) * 100.0;
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{}</td><td>{:.1}</td><td>{}</td><td>{}</td><td>{} %</td><td>{} %</td></tr>",
            a + 1,
            c.alpha_nm_per_bar[a],
            se(alpha_se(a), 1),
            se(base, 1),
            se(at(c.pad.v_ref_mps), 2),
            se(at(10.0 / 3.6), 2)
        );
    }
    h.push_str("</table>\n");
    // The running resistance the balance fitted (a dry-run calibration fits none).
    let resistance = if fit["resistance_c1_n_s_per_m"].is_number() {
        format!(
            " Running resistance: {} + ({} ± {}) N·s/m · v + ({} ± {}) N·s²/m² · v².",
            if fit["per_run_constants"].as_bool() == Some(true) {
                "a constant per run"
            } else {
                "one constant"
            },
            se(num(&fit["resistance_c1_n_s_per_m"]), 2),
            se(num(&fit["resistance_c1_se"]), 2),
            se(num(&fit["resistance_c2_n_s2_per_m2"]), 3),
            se(num(&fit["resistance_c2_se"]), 3)
        )
    } else {
        String::new()
    };
    let _ = writeln!(
        *h,
        "<p>Pad friction law: {}, γ = {:+.4} ± {:.4} ({:+.2} % from {:.0} km/h to standstill). Radar: scale {:.5} ± {}, latency {:.1} ± {} ms — the slip Δv moves by −v (1 − 1/s) = {:+.3} m/s at 100 km/h. Tachometers: delay {:.1} {}.{} μ of an axle moves with its brake force (the columns above).</p>",
        c.pad.label(),
        c.pad.gamma,
        c.pad.gamma_se,
        c.pad.rise_to_standstill() * 100.0,
        c.pad.v_ref_mps * 3.6,
        c.radar_scale,
        se(num(&fit["radar_scale_se"]), 5),
        c.radar_latency_s * 1e3,
        se(num(&fit["radar_latency_se"]) * 1e3, 1),
        -(100.0 / 3.6) * (1.0 - 1.0 / c.radar_scale),
        c.tacho_delay_s * 1e3,
        match fit["tacho_window_s"].as_f64() {
            Some(w) => format!(
                "ms, half their {:.1} ms counting window (read from their quantisation)",
                w * 1e3
            ),
            None => format!("± {} ms", se(num(&fit["tacho_delay_se"]) * 1e3, 1)),
        },
        resistance
    );
    // A candidate's form with a mixture's weight (written where it is not 0), "–" where the
    // mixture was not fitted, as the CLI prints it — read as the chosen law's type reads it,
    // so labelled alike.
    let label = |cand: &serde_json::Value| match read_like(&c.pad.form, &cand["form"]) {
        Some(form) if form.mixes() && !cand["gamma"].is_number() => {
            format!("{}, w = –", form.name())
        }
        Some(form) => form.label(cand["mix"].as_f64().unwrap_or(0.0)),
        None => cand["form"].as_str().unwrap_or("?").to_string(),
    };
    pad_candidates(h, fit, c.pad.form.name(), &label);
    run_constants(h, fit);
    if let Some(notes) = rec["notes"].as_array() {
        for n in notes {
            let _ = writeln!(
                *h,
                "<p class=\"note\">{}</p>",
                esc(n.as_str().unwrap_or(""))
            );
        }
    }
}

/// `value` read as the type of the first argument (only its type is used): a type the report
/// reaches through the records it is given, not by its module.
fn read_like<T: serde::de::DeserializeOwned>(_like: &T, value: &serde_json::Value) -> Option<T> {
    serde_json::from_value(value.clone()).ok()
}

/// The pad-friction forms the calibration compared (`fit`: `calibration.json`'s "campaign"),
/// each with its resistance constants, γ, BIC, and whether it was chosen or why refused;
/// `chosen_form` is the chosen form's name, `label` a candidate's label.
fn pad_candidates(
    h: &mut String,
    fit: &serde_json::Value,
    chosen_form: &str,
    label: &dyn Fn(&serde_json::Value) -> String,
) {
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let Some(cands) = fit["pad_candidates"].as_array() else {
        return;
    };
    h.push_str("<table><tr><th class=\"l\">pad form</th><th class=\"l\">resistance constants</th><th>γ</th><th>BIC</th><th class=\"l\"></th></tr>\n");
    for cand in cands {
        let per_run = cand["per_run_constants"].as_bool().unwrap_or(false);
        let chosen = cand["form"].as_str() == Some(chosen_form)
            && fit["per_run_constants"].as_bool() == Some(per_run);
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{:+.4}</td><td>{:.1}</td><td class=\"l\">{}{}</td></tr>",
            esc(&label(cand)),
            if per_run { "one per run" } else { "one" },
            num(&cand["gamma"]),
            num(&cand["bic"]),
            if chosen { "chosen" } else { "" },
            esc(cand["refused"].as_str().unwrap_or(""))
        );
    }
    h.push_str("</table>\n");
}

/// The balance's constant per run (the running resistance's constant and the run's gradient
/// force), folded: a campaign of hundreds of runs has as many rows.
fn run_constants(h: &mut String, fit: &serde_json::Value) {
    let Some(rows) = fit["resistance_constants"]
        .as_array()
        .filter(|r| !r.is_empty())
    else {
        return;
    };
    // Newtons to the unit; null (NaN in the fit) as a dash.
    let newtons = |v: &serde_json::Value| opt(v.as_f64().filter(|x| x.is_finite()), 0);
    let per_run = fit["per_run_constants"].as_bool() == Some(true);
    let _ = writeln!(
        *h,
        "<details><summary>The balance's constant {} (the running resistance's constant and the gradient force M g i, N)</summary>\n<table><tr><th class=\"l\">run</th><th>constant, N</th><th>± 1σ</th></tr>",
        if per_run { "per run" } else { "(one for the campaign)" }
    );
    // One constant for the campaign: one row.
    let rows = if per_run { &rows[..] } else { &rows[..1] };
    for r in rows {
        let run = if per_run {
            esc(r["run"].as_str().unwrap_or("?"))
        } else {
            "every run".to_string()
        };
        let _ = writeln!(
            *h,
            "<tr><td class=\"l\">{run}</td><td>{}</td><td>{}</td></tr>",
            newtons(&r["constant_n"]),
            newtons(&r["se_n"])
        );
    }
    h.push_str("</table></details>\n");
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
