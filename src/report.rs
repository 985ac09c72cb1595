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

use std::fmt::Write as _;
use std::io::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::campaign::{CampaignError, CampaignRecord, RunRecord};
use crate::contact::polach::{horner, polach, ContactPatch, PolachParams};
use crate::format::AXLES;
use crate::identify::polach_fit::PolachReport;
use crate::model::{Model, ModelFile};

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Campaign(#[from] CampaignError),
    #[error("{file}: {message}")]
    Data { file: String, message: String },
    #[error("plot \"{plot}\": {message}")]
    Plot { plot: String, message: String },
    #[error("{file}: cannot write: {message}")]
    Write { file: String, message: String },
}

const FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");
const SIZE: (u32, u32) = (620, 340);
/// Most points drawn per line and per scatter series (evenly strided).
const MAX_LINE: usize = 500;
const MAX_SCATTER: usize = 400;

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known to parse; a failure would only leave text unset.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One series of a plot.
struct Series {
    name: String,
    color: RGBColor,
    pts: Vec<(f64, f64)>,
    /// Dots instead of a line.
    dots: bool,
}

fn stride<T: Copy>(v: &[T], max: usize) -> Vec<T> {
    let step = v.len().div_ceil(max.max(1)).max(1);
    v.iter().step_by(step).copied().collect()
}

/// Axis range covering every point, padded by 4 %.
fn range_of(vals: impl Iterator<Item = f64>) -> Range<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return 0.0..1.0;
    }
    let pad = ((hi - lo) * 0.04).max(1e-9);
    (lo - pad)..(hi + pad)
}

fn plot_err(plot: &str) -> impl Fn(String) -> ReportError + '_ {
    move |message| ReportError::Plot {
        plot: plot.to_string(),
        message,
    }
}

/// An x–y chart as SVG text; `log_y` for positive data spanning decades.
fn chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    log_y: bool,
) -> Result<String, ReportError> {
    register_font();
    let err = plot_err(title);
    let xr = range_of(series.iter().flat_map(|s| s.pts.iter().map(|p| p.0)));
    let yr = range_of(series.iter().flat_map(|s| {
        s.pts
            .iter()
            .map(|p| if log_y { p.1.max(1e-300).log10() } else { p.1 })
    }));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut b = ChartBuilder::on(&root);
        b.caption(title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(38)
            .y_label_area_size(62);
        macro_rules! draw {
            ($chart:expr, $map:expr) => {{
                let mut c = $chart;
                c.configure_mesh()
                    .x_desc(x_desc)
                    .y_desc(y_desc)
                    .x_label_formatter(&|x: &f64| tick(*x))
                    .y_label_formatter(&|y: &f64| tick(*y))
                    .label_style(("sans-serif", 11))
                    .axis_desc_style(("sans-serif", 12))
                    .light_line_style(RGBColor(235, 235, 235))
                    .draw()
                    .map_err(|e| err(e.to_string()))?;
                for s in series {
                    let color = s.color;
                    let pts: Vec<(f64, f64)> = s.pts.iter().map(|&(x, y)| (x, $map(y))).collect();
                    let anno = if s.dots {
                        c.draw_series(stride(&pts, MAX_SCATTER).into_iter().map(move |p| {
                            // A few points (fit results) stand out; clouds stay light.
                            if pts.len() < 50 {
                                Circle::new(p, 4, color.filled())
                            } else {
                                Circle::new(p, 1, color.mix(0.5).filled())
                            }
                        }))
                        .map_err(|e| err(e.to_string()))?
                    } else {
                        c.draw_series(LineSeries::new(
                            stride(&pts, MAX_LINE),
                            color.stroke_width(1),
                        ))
                        .map_err(|e| err(e.to_string()))?
                    };
                    if !s.name.is_empty() {
                        anno.label(s.name.clone()).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
                        });
                    }
                }
                if series.iter().any(|s| !s.name.is_empty()) {
                    c.configure_series_labels()
                        .label_font(("sans-serif", 11))
                        .background_style(WHITE.mix(0.85))
                        .border_style(RGBColor(180, 180, 180))
                        .position(SeriesLabelPosition::UpperRight)
                        .draw()
                        .map_err(|e| err(e.to_string()))?;
                }
            }};
        }
        if log_y {
            let c = b
                .build_cartesian_2d(xr, (10f64.powf(yr.start)..10f64.powf(yr.end)).log_scale())
                .map_err(|e| err(e.to_string()))?;
            draw!(c, |y: f64| y);
        } else {
            let c = b
                .build_cartesian_2d(xr, yr)
                .map_err(|e| err(e.to_string()))?;
            draw!(c, |y: f64| y);
        }
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(svg)
}

/// A tick label: three significant digits, exponent form for very small or large values.
fn tick(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{x:.1e}")
    } else {
        let d = (2 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{x:.d$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    }
}

/// Viridis-like colour for t in [0, 1].
fn colormap(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = t.clamp(0.0, 1.0) * 4.0;
    let i = (t.floor() as usize).min(3);
    let f = t - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// μ over the (Δv, dΔv/dt) plane as a heat map with a colour bar.
fn heatmap(model: &Model) -> Result<String, ReportError> {
    register_font();
    let title = "Network μ over (Δv, dΔv/dt)";
    let err = plot_err(title);
    let i0 = &model.file.inputs[0];
    let i1 = &model.file.inputs[1];
    let (nx, ny) = (80, 50);
    let xs = |i: usize| i0.domain_max * i as f64 / nx as f64;
    let ys = |j: usize| i1.domain_min + (i1.domain_max - i1.domain_min) * j as f64 / ny as f64;
    let mut grid = vec![0.0; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            grid[j * nx + i] = model.mu(0.5 * (xs(i) + xs(i + 1)), 0.5 * (ys(j) + ys(j + 1)));
        }
    }
    let lo = grid.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = grid.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let span = (hi - lo).max(1e-12);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let (left, right) = root.split_horizontally(SIZE.0 - 90);
        let mut c = ChartBuilder::on(&left)
            .caption(title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(38)
            .y_label_area_size(62)
            .build_cartesian_2d(0.0..i0.domain_max, i1.domain_min..i1.domain_max)
            .map_err(|e| err(e.to_string()))?;
        c.configure_mesh()
            .x_desc("Δv (m/s)")
            .y_desc("dΔv/dt (m/s²)")
            .label_style(("sans-serif", 11))
            .axis_desc_style(("sans-serif", 12))
            .disable_mesh()
            .draw()
            .map_err(|e| err(e.to_string()))?;
        c.draw_series((0..ny).flat_map(|j| {
            let grid = &grid;
            (0..nx).map(move |i| {
                Rectangle::new(
                    [(xs(i), ys(j)), (xs(i + 1), ys(j + 1))],
                    colormap((grid[j * nx + i] - lo) / span).filled(),
                )
            })
        }))
        .map_err(|e| err(e.to_string()))?;
        let mut bar = ChartBuilder::on(&right)
            .margin_top(40)
            .margin_bottom(46)
            .margin_right(8)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(|e| err(e.to_string()))?;
        bar.configure_mesh()
            .disable_x_axis()
            .disable_mesh()
            .y_desc("μ")
            .label_style(("sans-serif", 10))
            .draw()
            .map_err(|e| err(e.to_string()))?;
        bar.draw_series((0..100).map(|k| {
            let (a, b) = (
                lo + span * k as f64 / 100.0,
                lo + span * (k + 1) as f64 / 100.0,
            );
            Rectangle::new([(0.0, a), (1.0, b)], colormap(k as f64 / 99.0).filled())
        }))
        .map_err(|e| err(e.to_string()))?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(svg)
}

/// The columns of an estimates table the report draws, per axle.
struct RunData {
    time_s: Vec<f64>,
    v_mps: Vec<f64>,
    /// Per axle: (t, rω), (t, p), and the valid (Δv, dΔv/dt, μ).
    wheel: [Vec<(f64, f64)>; AXLES],
    pressure: [Vec<(f64, f64)>; AXLES],
    valid: [Vec<(f64, f64, f64, f64)>; AXLES],
}

fn read_run(path: &Path) -> Result<RunData, ReportError> {
    use polars::prelude::*;
    let bad = |message: String| ReportError::Data {
        file: path.display().to_string(),
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| bad(e.to_string()))?;
    let df = ParquetReader::new(file)
        .finish()
        .map_err(|e| bad(e.to_string()))?;
    let f = |name: &str| -> Result<Vec<f64>, ReportError> {
        let c = df
            .column(name)
            .map_err(|_| bad(format!("no column {name}")))?
            .cast(&DataType::Float64)
            .map_err(|e| bad(e.to_string()))?;
        let ca = c.f64().map_err(|e| bad(e.to_string()))?;
        Ok(ca.iter().map(|x| x.unwrap_or(f64::NAN)).collect())
    };
    let (t, axle, v, p, dv, ddv, mu) = (
        f("time_s")?,
        f("axle")?,
        f("v_mps")?,
        f("p_bar")?,
        f("dv_mps")?,
        f("ddv_mps2")?,
        f("mu")?,
    );
    let vcol = df
        .column("valid")
        .map_err(|_| bad("no column valid".into()))?
        .bool()
        .map_err(|e| bad(e.to_string()))?
        .clone();
    let valid: Vec<bool> = vcol.iter().map(|x| x.unwrap_or(false)).collect();
    let mut d = RunData {
        time_s: vec![],
        v_mps: vec![],
        wheel: Default::default(),
        pressure: Default::default(),
        valid: Default::default(),
    };
    for k in 0..t.len() {
        let a = (axle[k] as usize).clamp(1, AXLES) - 1;
        if a == 0 {
            d.time_s.push(t[k]);
            d.v_mps.push(v[k]);
        }
        if v[k].is_finite() && dv[k].is_finite() {
            d.wheel[a].push((t[k], v[k] - dv[k]));
        }
        d.pressure[a].push((t[k], p[k]));
        if valid[k] {
            d.valid[a].push((dv[k], ddv[k], mu[k], t[k]));
        }
    }
    Ok(d)
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn opt(v: Option<f64>, d: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.d$}"))
}

/// Writes `<out>/report/index.html` from `<out>/campaign.json` and what it points to; returns
/// its path.
pub fn write_report(out: &Path) -> Result<PathBuf, ReportError> {
    let camp = CampaignRecord::read(out)?;
    let models = out.join("models");
    let mlp = ModelFile::read(&models.join("mlp.json"))
        .ok()
        .and_then(|f| Model::new(f).ok());
    let polach_model = ModelFile::read(&models.join("mlp.polach.json"))
        .ok()
        .and_then(|f| Model::new(f).ok());
    let fits: Option<PolachReport> = std::fs::read_to_string(models.join("mlp.polach-fits.json"))
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    let ok: Vec<&RunRecord> = camp.runs.iter().filter(|r| r.status == "ok").collect();
    let mut data = Vec::new();
    for r in &ok {
        let p = out.join("runs").join(&r.run).join("estimates.parquet");
        data.push((*r, read_run(&p)?));
    }

    let mut h = String::new();
    let _ = write!(
        h,
        r#"<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>railgrip report — {title}</title>
<style>
body {{ font-family: "DejaVu Sans", Verdana, sans-serif; margin: 1.5em auto; max-width: 1300px; color: #222; padding: 0 1em; }}
h1 {{ font-size: 1.5em; }} h2 {{ font-size: 1.25em; border-bottom: 1px solid #ccc; margin-top: 2em; }}
h3 {{ font-size: 1.05em; margin-bottom: 0.3em; }}
table {{ border-collapse: collapse; margin: 0.5em 0 1em; font-size: 0.85em; }}
th, td {{ border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }}
th {{ background: #f2f2f2; }} td.l, th.l {{ text-align: left; }}
.failed {{ color: #b00; }} .figs {{ display: flex; flex-wrap: wrap; gap: 6px; }}
.figs svg {{ border: 1px solid #eee; }} p.note {{ font-size: 0.9em; color: #555; }}
</style></head><body>
<h1>railgrip validation report</h1>
<p>Campaign <code>{archive}</code>: {n} run(s), {nok} estimated, {nf} failed. Models trained on
<b>{cond}</b> rail. Pipeline <code>{pipe}</code>. railgrip {ver}.</p>
"#,
        title = esc(&camp.archive),
        archive = esc(&camp.archive),
        n = camp.runs.len(),
        nok = ok.len(),
        nf = camp.runs.len() - ok.len(),
        cond = esc(camp.condition.as_deref().unwrap_or("–")),
        pipe = esc(&camp.pipeline),
        ver = env!("CARGO_PKG_VERSION"),
    );

    // Runs table.
    h.push_str("<h2>Runs</h2>\n<table><tr><th class=\"l\">run</th><th>status</th><th>initial speed km/h</th><th>ambient °C</th><th class=\"l\">condition</th><th>peak μ axles 1–4</th><th>max Δv m/s axles 1–4</th><th>time s</th></tr>\n");
    for r in &camp.runs {
        let axles = |v: &[Option<f64>; AXLES], d| {
            v.iter().map(|x| opt(*x, d)).collect::<Vec<_>>().join(" / ")
        };
        let _ = writeln!(
            h,
            "<tr><td class=\"l\">{}</td><td class=\"{}\">{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.2}</td></tr>",
            esc(&r.run),
            if r.status == "ok" { "" } else { "failed" },
            if r.status == "ok" { if r.reused { "ok (reused)" } else { "ok" } } else { "FAILED" },
            opt(r.initial_speed_kmh, 0),
            opt(r.ambient_temperature_c, 0),
            esc(r.condition.as_deref().unwrap_or("–")),
            axles(&r.peak_mu, 3),
            axles(&r.max_dv_mps, 2),
            r.duration_s
        );
    }
    h.push_str("</table>\n");
    let failed: Vec<&RunRecord> = camp.runs.iter().filter(|r| r.status != "ok").collect();
    if !failed.is_empty() {
        h.push_str("<h3 class=\"failed\">Failed runs</h3>\n<table><tr><th class=\"l\">run</th><th class=\"l\">error</th></tr>\n");
        for r in failed {
            let _ = writeln!(
                h,
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
                    h,
                    "<tr><td class=\"l\">{}</td><td class=\"l\">{}</td></tr>",
                    esc(&r.run),
                    esc(w)
                );
            }
        }
        for n in &camp.notes {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">campaign</td><td class=\"l\">{}</td></tr>",
                esc(n)
            );
        }
        if let Some(e) = &camp.model_error {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">models</td><td class=\"l failed\">{}</td></tr>",
                esc(e)
            );
        }
        h.push_str("</table>\n");
    }

    // Across runs.
    h.push_str("<h2>Across runs</h2>\n<p class=\"note\">Valid estimates, axle 2 (the training axle of seed 002), every run of the training condition.</p>\n<div class=\"figs\">\n");
    let in_condition = |r: &RunRecord| camp.condition.is_none() || r.condition == camp.condition;
    let group = |key: &dyn Fn(&RunRecord) -> Option<f64>, unit: &str| -> Vec<Series> {
        let mut keys: Vec<f64> = data
            .iter()
            .filter(|(r, _)| in_condition(r))
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
                    .filter(|(r, _)| in_condition(r) && key(r) == Some(*kv))
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

    // The network.
    if let Some(m) = &mlp {
        h.push_str("<h2>Network μ(Δv, dΔv/dt)</h2>\n");
        let mt = &m.file.metrics;
        let _ = writeln!(
            h,
            "<table><tr><th class=\"l\">inputs</th><th>hidden</th><th>training samples</th><th>validation samples</th><th>training RMSE μ</th><th>validation RMSE μ</th><th>epochs</th><th class=\"l\">stop</th></tr>\n<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.5}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr></table>",
            esc(&m.file.inputs.iter().map(|i| i.name.as_str()).collect::<Vec<_>>().join(", ")),
            m.file.layers[0].shape[0],
            mt.train_samples,
            mt.val_samples,
            mt.train_mse.sqrt(),
            opt(mt.val_mse.map(f64::sqrt), 5),
            mt.epochs,
            esc(&mt.stop_reason)
        );
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
        // Fig. 10: the first training-condition run, the first validation axle.
        let va = camp.validation_axles.first().copied().unwrap_or(3) as usize;
        if let Some((r, d)) = data.iter().find(|(r, _)| in_condition(r)) {
            let pts = &d.valid[(va.clamp(1, AXLES)) - 1];
            let est: Vec<(f64, f64)> = pts.iter().map(|p| (p.3, p.2)).collect();
            let net: Vec<(f64, f64)> = pts.iter().map(|p| (p.3, m.mu(p.0, p.1))).collect();
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
        // Fig. 11: slip ramp 0 → 9 → 0 m/s at ±2 m/s².
        let ramp = |up: bool| -> Vec<(f64, f64)> {
            (0..=180)
                .map(|k| {
                    let dv = 9.0 * k as f64 / 180.0;
                    let dv = if up { dv } else { 9.0 - dv };
                    (dv, m.mu(dv, if up { 2.0 } else { -2.0 }))
                })
                .collect()
        };
        h.push_str(&chart(
            "Slip ramp 0 → 9 → 0 m/s at ±2 m/s² (Fig. 11)",
            "Δv (m/s)",
            "μ",
            &[
                Series {
                    name: "rising slip".into(),
                    color: PALETTE[0],
                    pts: ramp(true),
                    dots: false,
                },
                Series {
                    name: "falling slip".into(),
                    color: PALETTE[1],
                    pts: ramp(false),
                    dots: false,
                },
            ],
            false,
        )?);
        h.push_str(&heatmap(m)?);
        h.push_str("</div>\n<p class=\"note\">Outside the trained domain the network holds its boundary value (inputs clamped); Δv beyond ");
        let _ = writeln!(
            h,
            "{:.2} m/s and dΔv/dt outside [{:.2}, {:.2}] m/s² were not seen in training.</p>",
            m.file.inputs[0].domain_max, m.file.inputs[1].domain_min, m.file.inputs[1].domain_max
        );
    }

    // Polach.
    if let Some(f) = &fits {
        h.push_str("<h2>Polach fits (seed 004 eq. 1–3)</h2>\n<table><tr><th class=\"l\">group</th><th>μ0</th><th>A</th><th>B s/m</th><th>k_A</th><th>k_S</th><th>RMSE μ</th><th>samples</th></tr>\n");
        let se = |x: f64, s: f64| {
            if s.is_finite() {
                format!("{x:.4} ± {s:.4}")
            } else {
                format!("{x:.4} (not identifiable)")
            }
        };
        for p in f.pooled.iter().chain(&f.per_temperature).chain(&f.per_run) {
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.4}</td><td>{}</td></tr>",
                esc(&p.group),
                se(p.mu0, p.se[0]),
                se(p.a_ratio, p.se[1]),
                se(p.b_s_per_m, p.se[2]),
                se(p.k_a, p.se[3]),
                se(p.k_s, p.se[4]),
                p.rmse,
                p.samples
            );
        }
        h.push_str("</table>\n<div class=\"figs\">\n");
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
            .filter(|(r, _)| in_condition(r))
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
        if let Some(t) = &f.temperature {
            let (lo, hi) = t.fitted_range_c;
            let grid: Vec<f64> = (0..=100)
                .map(|k| lo + (hi - lo) * k as f64 / 100.0)
                .collect();
            let pts = |k: usize| -> Vec<(f64, f64)> {
                f.per_temperature
                    .iter()
                    .filter_map(|p| {
                        p.ambient_temperature_c
                            .map(|tc| (tc, if k == 0 { p.k_a } else { p.k_s }))
                    })
                    .collect()
            };
            h.push_str(&chart(
                "k_A(T), k_S(T) (seed 004 eq. 3)",
                "ambient temperature (°C)",
                "k (–)",
                &[
                    Series {
                        name: format!("k_A(T), degree {}", t.degree),
                        color: PALETTE[0],
                        pts: grid.iter().map(|&x| (x, horner(&t.k_a, x))).collect(),
                        dots: false,
                    },
                    Series {
                        name: format!("k_S(T), degree {}", t.degree),
                        color: PALETTE[1],
                        pts: grid.iter().map(|&x| (x, horner(&t.k_s, x))).collect(),
                        dots: false,
                    },
                    Series {
                        name: "per-temperature fits".into(),
                        color: RGBColor(60, 60, 60),
                        pts: [pts(0), pts(1)].concat(),
                        dots: true,
                    },
                ],
                false,
            )?);
        }
        h.push_str("</div>\n");
        if let Some(n) = &f.temperature_note {
            let _ = writeln!(h, "<p class=\"note\">k(T): {}</p>", esc(n));
        }
    }

    // Per run.
    h.push_str("<h2>Per run</h2>\n");
    for (r, d) in &data {
        let _ = writeln!(
            h,
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

    // Provenance.
    if let Some(m) = &mlp {
        let p = &m.file.provenance;
        h.push_str("<h2>Provenance</h2>\n<table>");
        let _ = writeln!(
            h,
            "<tr><th class=\"l\">pipeline</th><td class=\"l\">{} (SHA-256 {})</td></tr>\n<tr><th class=\"l\">seed</th><td class=\"l\">{}</td></tr>\n<tr><th class=\"l\">railgrip</th><td class=\"l\">{}</td></tr>\n<tr><th class=\"l\">created</th><td class=\"l\">{}</td></tr>",
            esc(&p.pipeline),
            esc(&p.pipeline_sha256),
            p.seed,
            esc(&p.crate_version),
            esc(&p.created)
        );
        for i in &p.inputs {
            let _ = writeln!(
                h,
                "<tr><th class=\"l\">input</th><td class=\"l\">{} <small>{}</small></td></tr>",
                esc(&i.path),
                esc(&i.sha256)
            );
        }
        h.push_str("</table>\n");
    }
    h.push_str("</body></html>\n");

    let dir = out.join("report");
    let werr = |e: std::io::Error| ReportError::Write {
        file: dir.join("index.html").display().to_string(),
        message: e.to_string(),
    };
    std::fs::create_dir_all(&dir).map_err(werr)?;
    let path = dir.join("index.html");
    crate::atomic::write_atomically(&path, |w| w.write_all(h.as_bytes())).map_err(werr)?;
    Ok(path)
}
