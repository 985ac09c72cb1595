//! The report's plots: x–y charts and the μ heat map as inline SVG text (plotters, with DejaVu
//! Sans embedded for text layout).

use std::ops::Range;

use plotters::prelude::*;

use super::ReportError;
use crate::model::Model;

const FONT: &[u8] = include_bytes!("../../../../assets/fonts/DejaVuSans.ttf");
pub(super) const SIZE: (u32, u32) = (620, 340);
/// Most points drawn per line and per scatter series (evenly strided).
const MAX_LINE: usize = 500;
const MAX_SCATTER: usize = 400;

pub(crate) const PALETTE: [RGBColor; 8] = [
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
pub(crate) struct Series {
    pub name: String,
    pub color: RGBColor,
    pub pts: Vec<(f64, f64)>,
    /// Dots instead of a line.
    pub dots: bool,
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

fn plot_err<E: std::error::Error + Send + Sync + 'static>(
    plot: &str,
) -> impl Fn(E) -> ReportError + '_ {
    move |e| ReportError::Plot {
        plot: plot.to_string(),
        source: Box::new(e),
    }
}

/// An x–y chart as SVG text; `log_y` for positive data spanning decades.
pub(super) fn chart(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    log_y: bool,
) -> Result<String, ReportError> {
    chart_axes(title, x_desc, y_desc, series, false, log_y, &[])
}

/// [`chart`] (linear axes) with scatter clouds gathered by [`Thinned`] first: each cloud's
/// strided points are drawn as its series (`series[k]` for the k-th cloud's position), and the
/// axes also cover each cloud's full extent, so the chart is the one its whole cloud would draw.
pub(super) fn chart_thinned(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    clouds: &[&Thinned],
) -> Result<String, ReportError> {
    let bounds: Vec<(f64, f64)> = clouds.iter().flat_map(|c| c.corners()).collect();
    chart_axes(title, x_desc, y_desc, series, false, false, &bounds)
}

/// A scatter cloud gathered one point at a time and kept as a chart draws it: every
/// `step`-th point, `step` = ⌈`total` / [`MAX_SCATTER`]⌉ as [`stride`] takes it from the whole
/// cloud, and the cloud's finite extent in x and y (the axes cover every point). `total`, the
/// number of points the cloud will get, must be known before the first.
#[derive(Debug, Clone)]
pub(super) struct Thinned {
    step: usize,
    seen: usize,
    pts: Vec<(f64, f64)>,
    x: (f64, f64),
    y: (f64, f64),
}

impl Thinned {
    pub fn new(total: usize) -> Thinned {
        Thinned {
            step: total.div_ceil(MAX_SCATTER).max(1),
            seen: 0,
            pts: Vec::new(),
            x: (f64::INFINITY, f64::NEG_INFINITY),
            y: (f64::INFINITY, f64::NEG_INFINITY),
        }
    }

    pub fn push(&mut self, p: (f64, f64)) {
        if self.seen.is_multiple_of(self.step) {
            self.pts.push(p);
        }
        self.seen += 1;
        if p.0.is_finite() {
            self.x = (self.x.0.min(p.0), self.x.1.max(p.0));
        }
        if p.1.is_finite() {
            self.y = (self.y.0.min(p.1), self.y.1.max(p.1));
        }
    }

    /// The kept points.
    pub fn points(&self) -> &[(f64, f64)] {
        &self.pts
    }

    /// Two points spanning the cloud's extent (non-finite where it has no finite value, which
    /// the axes' range leaves out).
    fn corners(&self) -> [(f64, f64); 2] {
        [(self.x.0, self.y.0), (self.x.1, self.y.1)]
    }
}

/// [`chart`] with a choice of logarithmic axes for x and y (positive data spanning decades),
/// whose axes also cover the points `bounds` (not drawn; empty for most charts).
pub(crate) fn chart_axes(
    title: &str,
    x_desc: &str,
    y_desc: &str,
    series: &[Series],
    log_x: bool,
    log_y: bool,
    bounds: &[(f64, f64)],
) -> Result<String, ReportError> {
    register_font();
    let err = plot_err(title);
    // log10 of the data on a linear axis, labelled with 10^tick (as for y below).
    let logged: Vec<Series>;
    let series = if log_x {
        logged = series
            .iter()
            .map(|s| Series {
                name: s.name.clone(),
                color: s.color,
                pts: s
                    .pts
                    .iter()
                    .map(|&(x, y)| (x.max(1e-300).log10(), y))
                    .collect(),
                dots: s.dots,
            })
            .collect();
        &logged[..]
    } else {
        series
    };
    let xfmt = |x: &f64| {
        if log_x {
            tick(10f64.powf(*x))
        } else {
            tick(*x)
        }
    };
    let bx = |x: f64| if log_x { x.max(1e-300).log10() } else { x };
    let xr = range_of(
        series
            .iter()
            .flat_map(|s| s.pts.iter().map(|p| p.0))
            .chain(bounds.iter().map(|p| p.0).filter(|x| x.is_finite()).map(bx)),
    );
    let by = |y: f64| if log_y { y.max(1e-300).log10() } else { y };
    let yr = range_of(
        series
            .iter()
            .flat_map(|s| s.pts.iter().map(|p| by(p.1)))
            .chain(bounds.iter().map(|p| p.1).filter(|y| y.is_finite()).map(by)),
    );
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(&err)?;
        let mut b = ChartBuilder::on(&root);
        b.caption(title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(38)
            .y_label_area_size(62);
        macro_rules! draw {
            ($chart:expr, $map:expr, $ylabel:expr) => {{
                let mut c = $chart;
                c.configure_mesh()
                    .x_desc(x_desc)
                    .y_desc(y_desc)
                    .x_label_formatter(&xfmt)
                    .y_label_formatter(&$ylabel)
                    .label_style(("sans-serif", 11))
                    .axis_desc_style(("sans-serif", 12))
                    .light_line_style(RGBColor(235, 235, 235))
                    .draw()
                    .map_err(&err)?;
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
                        .map_err(&err)?
                    } else {
                        c.draw_series(LineSeries::new(
                            stride(&pts, MAX_LINE),
                            color.stroke_width(1),
                        ))
                        .map_err(&err)?
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
                        .map_err(&err)?;
                }
            }};
        }
        let c = b.build_cartesian_2d(xr, yr).map_err(&err)?;
        if log_y {
            // log10 of the data on a linear axis, labelled with 10^tick: plotters' own log
            // axis labels powers of ten only, so a range inside one decade had no labels.
            draw!(c, |y: f64| y.max(1e-300).log10(), |y: &f64| tick(
                10f64.powf(*y)
            ));
        } else {
            draw!(c, |y: f64| y, |y: &f64| tick(*y));
        }
        root.present().map_err(&err)?;
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
pub(super) fn heatmap(model: &Model) -> Result<String, ReportError> {
    register_font();
    let title = if model.file.support.is_some() {
        "Network μ over (Δv, dΔv/dt); grey: outside the data"
    } else {
        "Network μ over (Δv, dΔv/dt)"
    };
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
        root.fill(&WHITE).map_err(&err)?;
        let (left, right) = root.split_horizontally(SIZE.0 - 90);
        let mut c = ChartBuilder::on(&left)
            .caption(title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(38)
            .y_label_area_size(62)
            .build_cartesian_2d(0.0..i0.domain_max, i1.domain_min..i1.domain_max)
            .map_err(&err)?;
        c.configure_mesh()
            .x_desc("Δv (m/s)")
            .y_desc("dΔv/dt (m/s²)")
            .label_style(("sans-serif", 11))
            .axis_desc_style(("sans-serif", 12))
            .disable_mesh()
            .draw()
            .map_err(&err)?;
        c.draw_series((0..ny).flat_map(|j| {
            let grid = &grid;
            (0..nx).map(move |i| {
                Rectangle::new(
                    [(xs(i), ys(j)), (xs(i + 1), ys(j + 1))],
                    colormap((grid[j * nx + i] - lo) / span).filled(),
                )
            })
        }))
        .map_err(&err)?;
        // Cells outside the data support (the model blends to its fallback there) shaded grey
        // in proportion to 1 − w.
        c.draw_series((0..ny).flat_map(|j| {
            (0..nx).filter_map(move |i| {
                let (x, y) = (0.5 * (xs(i) + xs(i + 1)), 0.5 * (ys(j) + ys(j + 1)));
                let w = model.support_weight(x, y, f64::NAN)?;
                (w < 1.0).then(|| {
                    Rectangle::new(
                        [(xs(i), ys(j)), (xs(i + 1), ys(j + 1))],
                        RGBColor(110, 110, 110).mix(0.75 * (1.0 - w)).filled(),
                    )
                })
            })
        }))
        .map_err(&err)?;
        let mut bar = ChartBuilder::on(&right)
            .margin_top(40)
            .margin_bottom(46)
            .margin_right(8)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..1.0, lo..hi)
            .map_err(&err)?;
        bar.configure_mesh()
            .disable_x_axis()
            .disable_mesh()
            .y_desc("μ")
            .label_style(("sans-serif", 10))
            .draw()
            .map_err(&err)?;
        bar.draw_series((0..100).map(|k| {
            let (a, b) = (
                lo + span * k as f64 / 100.0,
                lo + span * (k + 1) as f64 / 100.0,
            );
            Rectangle::new([(0.0, a), (1.0, b)], colormap(k as f64 / 99.0).filled())
        }))
        .map_err(&err)?;
        root.present().map_err(&err)?;
    }
    Ok(svg)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Text lines of an SVG chart that are numbers in (0, 0.01): the y tick labels of an MSE
    /// axis (the x ticks are whole epochs).
    fn small_labels(svg: &str) -> usize {
        svg.lines()
            .filter_map(|l| l.trim().parse::<f64>().ok())
            .filter(|v| *v > 0.0 && *v < 0.01)
            .count()
    }

    #[test]
    fn a_log_axis_inside_one_decade_still_has_tick_labels() {
        // Fig. 9 of a training whose MSE stays inside one decade (2.2e-4 … 8e-4): no power
        // of ten in the data range.
        let pts: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64, 6e-4 * (-(i as f64) / 10.0).exp() + 2e-4))
            .collect();
        let svg = chart(
            "Error per epoch",
            "epoch",
            "MSE",
            &[Series {
                name: "training".into(),
                color: RGBColor(0, 0, 0),
                pts,
                dots: false,
            }],
            true,
        )
        .unwrap();
        assert!(small_labels(&svg) >= 2, "{svg}");
    }

    type Points = Vec<(f64, f64)>;

    /// A cloud of `n` points, some of them with a non-finite coordinate, and a line beside it.
    fn cloud(n: usize, seed: u64) -> (Points, Points) {
        let mut rng = crate::rng::Rng::new(seed);
        let pts = (0..n)
            .map(|k| {
                let x = 9.0 * rng.uniform();
                let y = 0.3 * rng.uniform() - 0.05;
                match k % 97 {
                    13 => (f64::NAN, y),
                    41 => (x, f64::INFINITY),
                    _ => (x, y),
                }
            })
            .collect();
        let line = (0..=20)
            .map(|k| (k as f64 * 0.5, 0.1 + 0.01 * k as f64))
            .collect();
        (pts, line)
    }

    #[test]
    fn a_cloud_gathered_point_by_point_draws_the_chart_of_the_whole_cloud() {
        // Sizes around the stride's edges: below the small-dot limit, at and above MAX_SCATTER,
        // and many strides; extremes inside and outside the kept points.
        for (n, seed) in [
            (0, 1),
            (7, 2),
            (49, 3),
            (400, 4),
            (401, 5),
            (1200, 6),
            (45_679, 7),
        ] {
            let (pts, line) = cloud(n, seed);
            let series = |pts: Vec<(f64, f64)>| {
                vec![
                    Series {
                        name: "cloud".into(),
                        color: PALETTE[0],
                        pts,
                        dots: true,
                    },
                    Series {
                        name: "curve".into(),
                        color: PALETTE[1],
                        pts: line.clone(),
                        dots: false,
                    },
                ]
            };
            let whole = chart("c", "x", "y", &series(pts.clone()), false).unwrap();
            let mut t = Thinned::new(pts.len());
            for p in &pts {
                t.push(*p);
            }
            assert!(t.points().len() <= MAX_SCATTER, "n = {n}");
            let thinned =
                chart_thinned("c", "x", "y", &series(t.points().to_vec()), &[&t]).unwrap();
            assert!(thinned == whole, "n = {n}: the charts differ");
        }
    }
}
