//! Scoring a learned adhesion curve against the truth of simulated runs, only where the runs
//! hold data: a model is judged on the (Δv, dΔv/dt, v) cells its training data
//! could have taught it, not on validation MSE alone, and not where it extrapolates.
//!
//! **Cells.** Centres every 0.1 m/s in slip Δv, at ±{0.25, 0.5, 1, 2, 4, 8} m/s² in slip rate
//! dΔv/dt and every 10 km/h in speed v. A truth sample of axle i belongs to a cell when
//! |Δv − Δv_c| ≤ 0.1 m/s, dΔv/dt / q_c ∈ [0.5, 1.5] (so the same sign) and |v − v_c| ≤ 15 km/h;
//! cells overlap. A cell of axle i is **supported** when at least 20 truth samples of axle i
//! fall in it.
//!
//! **Errors.** On each supported (axle, cell) the error is the mean over its samples of
//! μ̂(Δv, dΔv/dt, v) − μ (the model at the sample's true inputs against the sample's true μ) —
//! no interpolation of the truth, so any law can be scored, whatever effects made the run.
//! [`Score::rmse`] and [`Score::max_error`] are over the supported cells.
//!
//! **Hysteresis.** Over supported pairs (Δv_c, +q_c) and (Δv_c, −q_c) of one axle and speed
//! with 0.5 ≤ Δv_c ≤ 3 m/s: the mean of μ(Δv, +q) − μ(Δv, −q), true (cell means of the truth)
//! and predicted (cell means of the model) — a law whose recovery branch lies below its loss
//! branch has a positive value, and a model must reproduce its sign. Several runs (a speed
//! band) pool their pairs: [`pooled_hysteresis_ratio`].
//!
//! Two further views of one run, each reported per speed band with RMSE, **bias** (mean
//! μ̂ − μ: a model 8 % high where braking matters is biased, not only noisy) and max error:
//! - [`curve`]: the model on the run's supported (Δv, dΔv/dt) cells (support counted over the
//!   run's whole speed range, per axle) at the run's **initial speed and ambient temperature**,
//!   against the true law there — what a simulator that starts a brake from that speed asks.
//!   Its hysteresis ratio is predicted over true loss − recovery difference. Each cell at its
//!   nominal centre, or ([`Grid::at_sample_means`]) at its samples' mean slip and slip rate.
//! - [`replay`]: the model at every sample's own inputs (samples in a supported cell of their
//!   axle), against the sample's μ, binned by the sample's speed — what a simulator replaying
//!   the run sees.

use std::collections::BTreeMap;

/// One true sample: slip Δv (m/s), slip rate dΔv/dt (m/s²), speed v (m/s), the run's
/// ambient temperature (°C), adhesion μ and the axle (1-based).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub axle: u8,
    pub dv_mps: f64,
    pub ddv_mps2: f64,
    pub v_mps: f64,
    /// The run's ambient temperature, °C (NaN when unknown: models take their reference).
    pub t_c: f64,
    pub mu: f64,
}

/// Cell geometry and the support threshold (defaults: the module text).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    /// Slip centre spacing and half-width, m/s.
    pub dv_step_mps: f64,
    pub dv_half_mps: f64,
    /// Slip-rate centres (positive; each is used with both signs), m/s², and the window as
    /// factors of the centre.
    pub q_centres_mps2: Vec<f64>,
    pub q_window: (f64, f64),
    /// Speed centre spacing and half-width, km/h.
    pub v_step_kmh: f64,
    pub v_half_kmh: f64,
    /// Samples of one axle a cell needs to count.
    pub min_samples: usize,
    /// [`curve`] evaluates each cell at its samples' mean slip and slip rate (those of the
    /// axle with the most samples there) instead of its nominal centre: where the run's states
    /// are. A slip-rate window spans 0.5–1.5 times its centre, so at the fast rates its samples
    /// can lie far from it (on the top-speed scenes, at q = −8 m/s² mostly between −4 and −6).
    /// The loss − recovery pairs stay those of the nominal cells; each member is evaluated at
    /// its own samples' means, the model and the truth at the same points.
    pub at_sample_means: bool,
}

impl Default for Grid {
    fn default() -> Self {
        Grid {
            dv_step_mps: 0.1,
            dv_half_mps: 0.1,
            q_centres_mps2: vec![0.25, 0.5, 1.0, 2.0, 4.0, 8.0],
            q_window: (0.5, 1.5),
            v_step_kmh: 10.0,
            v_half_kmh: 15.0,
            min_samples: 20,
            at_sample_means: false,
        }
    }
}

/// One supported cell of one axle: its centre, sample count, and mean true and predicted μ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    pub axle: u8,
    pub dv_mps: f64,
    /// Signed slip-rate centre, m/s².
    pub ddv_mps2: f64,
    pub v_kmh: f64,
    pub samples: usize,
    pub true_mu: f64,
    pub predicted_mu: f64,
}

impl Cell {
    /// Mean error μ̂ − μ over the cell's samples.
    pub fn error(&self) -> f64 {
        self.predicted_mu - self.true_mu
    }
}

/// What [`score`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct Score {
    /// The supported cells, ordered by axle, speed, slip rate and slip.
    pub cells: Vec<Cell>,
    pub rmse: f64,
    pub max_error: f64,
    /// Supported cells where the model predicts μ < 0.
    pub negative_cells: usize,
    /// Mean μ(Δv, +q) − μ(Δv, −q) over the supported pairs: true and predicted; `None`
    /// without such pairs.
    pub hysteresis: Option<(f64, f64)>,
    /// Pairs behind [`Score::hysteresis`].
    pub hysteresis_pairs: usize,
}

/// Errors of [`score`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ScoreError {
    #[error("no cell has {min} samples of one axle: nothing to score (give longer runs, or lower the threshold)")]
    NoSupport { min: usize },
    #[error("sample {index}: {what} is not finite (truth files hold finite values only)")]
    NotFinite { index: usize, what: &'static str },
    #[error("the model gave a non-finite μ at Δv = {dv} m/s, dΔv/dt = {ddv} m/s², v = {v} m/s")]
    Model { dv: f64, ddv: f64, v: f64 },
}

/// Sums of one (axle, cell).
#[derive(Default, Clone, Copy)]
struct Acc {
    n: usize,
    truth: f64,
    predicted: f64,
}

/// Cell key: axle, speed index, signed slip-rate index (±(i + 1)), slip index.
type Key = (u8, i64, i64, i64);

/// Scores `predict(Δv, dΔv/dt, v, T)` (μ) against `samples` on `grid`'s supported cells.
pub fn score(
    samples: &[Sample],
    grid: &Grid,
    predict: impl Fn(f64, f64, f64, f64) -> f64,
) -> Result<Score, ScoreError> {
    let mut acc: BTreeMap<Key, Acc> = BTreeMap::new();
    for (index, s) in samples.iter().enumerate() {
        check_finite(index, s)?;
        let keys = cells_of(grid, s);
        if keys.is_empty() {
            continue;
        }
        let p = predict(s.dv_mps, s.ddv_mps2, s.v_mps, s.t_c);
        if !p.is_finite() {
            return Err(ScoreError::Model {
                dv: s.dv_mps,
                ddv: s.ddv_mps2,
                v: s.v_mps,
            });
        }
        for k in keys {
            let a = acc.entry(k).or_default();
            a.n += 1;
            a.truth += s.mu;
            a.predicted += p;
        }
    }
    let centre = |(axle, vi, qi, di): Key, a: &Acc| Cell {
        axle,
        dv_mps: di as f64 * grid.dv_step_mps,
        ddv_mps2: qi.signum() as f64 * grid.q_centres_mps2[qi.unsigned_abs() as usize - 1],
        v_kmh: vi as f64 * grid.v_step_kmh,
        samples: a.n,
        true_mu: a.truth / a.n as f64,
        predicted_mu: a.predicted / a.n as f64,
    };
    let supported: BTreeMap<Key, Cell> = acc
        .iter()
        .filter(|(_, a)| a.n >= grid.min_samples)
        .map(|(k, a)| (*k, centre(*k, a)))
        .collect();
    if supported.is_empty() {
        return Err(ScoreError::NoSupport {
            min: grid.min_samples,
        });
    }
    let cells: Vec<Cell> = supported.values().copied().collect();
    let rmse = (cells.iter().map(|c| c.error().powi(2)).sum::<f64>() / cells.len() as f64).sqrt();
    let max_error = cells.iter().map(|c| c.error().abs()).fold(0.0, f64::max);
    let negative_cells = cells.iter().filter(|c| c.predicted_mu < 0.0).count();
    let (mut dt, mut dp, mut pairs) = (0.0, 0.0, 0usize);
    for ((axle, vi, qi, di), up) in &supported {
        let dv = *di as f64 * grid.dv_step_mps;
        if *qi <= 0 || !(0.5 - 1e-9..=3.0 + 1e-9).contains(&dv) {
            continue;
        }
        if let Some(down) = supported.get(&(*axle, *vi, -qi, *di)) {
            dt += up.true_mu - down.true_mu;
            dp += up.predicted_mu - down.predicted_mu;
            pairs += 1;
        }
    }
    Ok(Score {
        cells,
        rmse,
        max_error,
        negative_cells,
        hysteresis: (pairs > 0).then(|| (dt / pairs as f64, dp / pairs as f64)),
        hysteresis_pairs: pairs,
    })
}

/// Error statistics of μ̂ − μ over `n` cells or samples.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Stats {
    pub n: usize,
    pub rmse: f64,
    /// Mean μ̂ − μ.
    pub bias: f64,
    /// Largest |μ̂ − μ|.
    pub max_error: f64,
}

impl Stats {
    /// Statistics of `errors` (μ̂ − μ); all zero for none.
    pub fn of(errors: impl IntoIterator<Item = f64>) -> Stats {
        let mut acc = StatsAcc::default();
        for e in errors {
            acc.push(e);
        }
        acc.stats()
    }
}

/// [`Stats`] gathered one error at a time (the same sums in the same order as
/// [`Stats::of`], so the same figures to the last bit).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StatsAcc {
    n: usize,
    sum: f64,
    sq: f64,
    max: f64,
}

impl StatsAcc {
    pub fn push(&mut self, e: f64) {
        self.n += 1;
        self.sum += e;
        self.sq += e * e;
        self.max = self.max.max(e.abs());
    }

    /// The statistics so far; all zero for none.
    pub fn stats(&self) -> Stats {
        if self.n == 0 {
            return Stats::default();
        }
        Stats {
            n: self.n,
            rmse: (self.sq / self.n as f64).sqrt(),
            bias: self.sum / self.n as f64,
            max_error: self.max,
        }
    }
}

/// One supported (Δv, dΔv/dt) cell of a run in the [`curve`] view: where it is evaluated (its
/// centre, or with [`Grid::at_sample_means`] its samples' mean slip and slip rate), the samples
/// behind its support (the best-supported axle's), and the true and predicted μ there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CurveCell {
    pub dv_mps: f64,
    pub ddv_mps2: f64,
    pub samples: usize,
    pub true_mu: f64,
    pub predicted_mu: f64,
}

/// What [`curve`] found for one run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CurveScore {
    /// The speed (m/s) and ambient temperature (°C) the curve is taken at.
    pub v_mps: f64,
    pub t_c: f64,
    pub cells: Vec<CurveCell>,
    pub stats: Stats,
    /// Mean μ(Δv, +q) − μ(Δv, −q) over supported pairs with 0.5 ≤ Δv ≤ 3 m/s: true and
    /// predicted; `None` without pairs.
    pub hysteresis: Option<(f64, f64)>,
    /// Pairs behind [`CurveScore::hysteresis`].
    pub hysteresis_pairs: usize,
}

impl CurveScore {
    /// Predicted over true loss − recovery difference, where the true one is at least
    /// `min_true` (the ratio of two near-zero differences means nothing).
    pub fn hysteresis_ratio(&self, min_true: f64) -> Option<f64> {
        self.hysteresis
            .filter(|(t, _)| t.abs() >= min_true)
            .map(|(t, p)| p / t)
    }

    /// [`CurveScore::hysteresis`] with its pairs: (true, predicted, pairs).
    pub fn hysteresis_with_pairs(&self) -> Option<(f64, f64, usize)> {
        self.hysteresis.map(|(t, p)| (t, p, self.hysteresis_pairs))
    }
}

/// The hysteresis ratio of several runs' curves taken together (a speed band's): the sum of
/// the predicted loss − recovery differences over the sum of the true ones, each run's mean
/// weighted by its pairs — as a band's bias pools its runs' cells. `runs` gives each run's
/// [`CurveScore::hysteresis_with_pairs`]; runs whose own true difference is below `min_true`
/// (no ratio of their own) are left out; `None` when none is left. The runs' true differences
/// are meant to share a sign (one law family's branches): of opposite signs they cancel in the
/// sum, and the ratio means nothing. Pair weights give a run that slides more (a slippery
/// rail: more supported cells) more say; the mean of the runs' own ratios gives each one.
pub fn pooled_hysteresis_ratio(
    runs: impl IntoIterator<Item = Option<(f64, f64, usize)>>,
    min_true: f64,
) -> Option<f64> {
    let (mut t, mut p, mut any) = (0.0, 0.0, false);
    for (tr, pr, n) in runs.into_iter().flatten() {
        if tr.abs() >= min_true {
            t += tr * n as f64;
            p += pr * n as f64;
            any = true;
        }
    }
    any.then(|| p / t)
}

/// The cells a run supports in the [`curve`] view: per (slip rate, slip) cell of `grid`'s
/// geometry (speed ignored), the moments of the axle with the most samples there. Computed once
/// per run, it serves every curve table of that run ([`CurveSupport::curve`]).
#[derive(Debug, Clone)]
pub struct CurveSupport {
    grid: Grid,
    best: BTreeMap<(i64, i64), Moments>,
}

impl CurveSupport {
    /// The support of the run's `samples` on `grid`'s cells; an error when a sample is not
    /// finite or no cell has `grid.min_samples` samples of one axle.
    pub fn of(samples: &[Sample], grid: &Grid) -> Result<CurveSupport, ScoreError> {
        // Support of (axle, q, Δv) over all speeds: one speed cell holding every speed.
        let wide = Grid {
            v_step_kmh: 1e9,
            v_half_kmh: 0.5e9,
            ..grid.clone()
        };
        let counts = support(samples, &wide)?;
        // Per (slip rate, slip) cell the axle with the most samples (the first of equals).
        let mut best: BTreeMap<(i64, i64), Moments> = BTreeMap::new();
        for ((_, _, qi, di), m) in &counts {
            if m.n >= grid.min_samples {
                let b = best.entry((*qi, *di)).or_default();
                if m.n > b.n {
                    *b = *m;
                }
            }
        }
        if best.is_empty() {
            return Err(ScoreError::NoSupport {
                min: grid.min_samples,
            });
        }
        Ok(CurveSupport {
            grid: grid.clone(),
            best,
        })
    }

    /// The curve view on these cells (see [`curve`]), each cell at its nominal centre or, with
    /// `at_sample_means`, at its samples' mean slip and slip rate.
    pub fn curve(
        &self,
        at_sample_means: bool,
        v_mps: f64,
        t_c: f64,
        predict: impl Fn(f64, f64, f64, f64) -> f64,
        law: impl Fn(f64, f64, f64, f64) -> f64,
    ) -> Result<CurveScore, ScoreError> {
        let (grid, best) = (&self.grid, &self.best);
        let mut cells = Vec::with_capacity(best.len());
        for ((qi, di), m) in best {
            let (dv, q) = if at_sample_means {
                (m.dv / m.n as f64, m.ddv / m.n as f64)
            } else {
                (
                    *di as f64 * grid.dv_step_mps,
                    qi.signum() as f64 * grid.q_centres_mps2[qi.unsigned_abs() as usize - 1],
                )
            };
            let (p, t) = (predict(dv, q, v_mps, t_c), law(dv, q, v_mps, t_c));
            if !p.is_finite() || !t.is_finite() {
                return Err(ScoreError::Model {
                    dv,
                    ddv: q,
                    v: v_mps,
                });
            }
            cells.push(CurveCell {
                dv_mps: dv,
                ddv_mps2: q,
                samples: m.n,
                true_mu: t,
                predicted_mu: p,
            });
        }
        let stats = Stats::of(cells.iter().map(|c| c.predicted_mu - c.true_mu));
        // The cells are in `best`'s key order: the index of a key is its cell's.
        let index: BTreeMap<(i64, i64), usize> =
            best.keys().enumerate().map(|(i, k)| (*k, i)).collect();
        let (mut dt, mut dp, mut pairs) = (0.0, 0.0, 0usize);
        for (&(qi, di), &i) in &index {
            let up = &cells[i];
            // The slip range by the cells' nominal slip (at the samples' means too).
            let dv = di as f64 * grid.dv_step_mps;
            if qi <= 0 || !(0.5 - 1e-9..=3.0 + 1e-9).contains(&dv) {
                continue;
            }
            if let Some(&j) = index.get(&(-qi, di)) {
                dt += up.true_mu - cells[j].true_mu;
                dp += up.predicted_mu - cells[j].predicted_mu;
                pairs += 1;
            }
        }
        Ok(CurveScore {
            v_mps,
            t_c,
            cells,
            stats,
            hysteresis: (pairs > 0).then(|| (dt / pairs as f64, dp / pairs as f64)),
            hysteresis_pairs: pairs,
        })
    }
}

/// The curve view of one run (module text): `predict` and the true `law`, both
/// μ(Δv, dΔv/dt, v, T), on the (Δv, dΔv/dt) cells the run's `samples` support, at speed
/// `v_mps` (m/s) and temperature `t_c` (°C). Several views of one run: [`CurveSupport`].
pub fn curve(
    samples: &[Sample],
    grid: &Grid,
    v_mps: f64,
    t_c: f64,
    predict: impl Fn(f64, f64, f64, f64) -> f64,
    law: impl Fn(f64, f64, f64, f64) -> f64,
) -> Result<CurveScore, ScoreError> {
    let support = CurveSupport::of(samples, grid)?;
    support.curve(grid.at_sample_means, v_mps, t_c, predict, law)
}

/// One speed band of the [`replay`] view: [lo, hi) km/h and the statistics of its samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Band {
    pub lo_kmh: f64,
    pub hi_kmh: f64,
    pub stats: Stats,
}

/// The speed bands of the per-band tables, km/h: 0–40, 40–80, 80–120, 120–145, 145–170,
/// 170–210 (a band's lower edge belongs to it: a run braking from 80 or 120 km/h fills the
/// bands below its initial speed, one from 160 or 200 km/h reaches into the 145–170 or
/// 170–210 band with its first seconds of brake).
pub const SPEED_BANDS_KMH: [f64; 7] = [0.0, 40.0, 80.0, 120.0, 145.0, 170.0, 210.0];

/// The replay view (module text): μ̂ − μ of every sample in a supported cell of its axle,
/// binned by the sample's speed over `edges_kmh` (ascending; samples outside are left out).
/// Bands without samples are left out.
pub fn replay(
    samples: &[Sample],
    grid: &Grid,
    edges_kmh: &[f64],
    predict: impl Fn(f64, f64, f64, f64) -> f64,
) -> Result<Vec<Band>, ScoreError> {
    let counts = support(samples, grid)?;
    let mut errors = Vec::new();
    for s in samples {
        // Samples outside every band, or in no supported cell, are not scored (nor predicted).
        if band_of(edges_kmh, s.v_mps * 3.6).is_none()
            || !cells_of(grid, s)
                .iter()
                .any(|k| counts.get(k).is_some_and(|m| m.n >= grid.min_samples))
        {
            continue;
        }
        let p = predict(s.dv_mps, s.ddv_mps2, s.v_mps, s.t_c);
        if !p.is_finite() {
            return Err(ScoreError::Model {
                dv: s.dv_mps,
                ddv: s.ddv_mps2,
                v: s.v_mps,
            });
        }
        errors.push((s.v_mps * 3.6, p - s.mu));
    }
    let bands = by_speed_band(edges_kmh, errors);
    if bands.is_empty() {
        return Err(ScoreError::NoSupport {
            min: grid.min_samples,
        });
    }
    Ok(bands)
}

/// Errors (speed km/h, μ̂ − μ) binned by speed over `edges_kmh` (ascending; a band's lower
/// edge belongs to it; errors outside every band are left out), the [`Stats`] of each band
/// that has errors.
pub fn by_speed_band(edges_kmh: &[f64], errors: impl IntoIterator<Item = (f64, f64)>) -> Vec<Band> {
    let mut acc = SpeedBands::new(edges_kmh);
    for (v_kmh, e) in errors {
        acc.push(v_kmh, e);
    }
    acc.bands()
}

/// [`by_speed_band`] gathered one error at a time, without keeping the errors.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedBands {
    edges_kmh: Vec<f64>,
    acc: Vec<StatsAcc>,
}

impl SpeedBands {
    /// Bands over `edges_kmh` (ascending, km/h).
    pub fn new(edges_kmh: &[f64]) -> SpeedBands {
        SpeedBands {
            edges_kmh: edges_kmh.to_vec(),
            acc: vec![StatsAcc::default(); edges_kmh.len().saturating_sub(1)],
        }
    }

    /// One error μ̂ − μ at speed `v_kmh` (left out outside every band).
    pub fn push(&mut self, v_kmh: f64, e: f64) {
        if let Some(b) = band_of(&self.edges_kmh, v_kmh) {
            self.acc[b].push(e);
        }
    }

    /// The [`Stats`] of each band that has errors.
    pub fn bands(&self) -> Vec<Band> {
        self.acc
            .iter()
            .enumerate()
            .filter(|(_, a)| a.n > 0)
            .map(|(b, a)| Band {
                lo_kmh: self.edges_kmh[b],
                hi_kmh: self.edges_kmh[b + 1],
                stats: a.stats(),
            })
            .collect()
    }
}

/// The band of `edges_kmh` (ascending) speed `v_kmh` falls in: [lo, hi), `None` outside.
fn band_of(edges_kmh: &[f64], v_kmh: f64) -> Option<usize> {
    edges_kmh
        .windows(2)
        .position(|w| v_kmh >= w[0] && v_kmh < w[1])
}

/// Samples per (axle, cell), the samples checked finite.
fn support(samples: &[Sample], grid: &Grid) -> Result<BTreeMap<Key, Moments>, ScoreError> {
    let mut counts: BTreeMap<Key, Moments> = BTreeMap::new();
    for (index, s) in samples.iter().enumerate() {
        check_finite(index, s)?;
        for k in cells_of(grid, s) {
            let m = counts.entry(k).or_default();
            m.n += 1;
            m.dv += s.dv_mps;
            m.ddv += s.ddv_mps2;
        }
    }
    Ok(counts)
}

/// A cell's sample count and the sums of its samples' slip and slip rate.
#[derive(Debug, Default, Clone, Copy)]
struct Moments {
    n: usize,
    dv: f64,
    ddv: f64,
}

/// Sample `index` has finite inputs and μ (truth files hold finite values only).
fn check_finite(index: usize, s: &Sample) -> Result<(), ScoreError> {
    for (x, what) in [
        (s.dv_mps, "Δv"),
        (s.ddv_mps2, "dΔv/dt"),
        (s.v_mps, "v"),
        (s.mu, "μ"),
    ] {
        if !x.is_finite() {
            return Err(ScoreError::NotFinite { index, what });
        }
    }
    Ok(())
}

/// The cells a sample belongs to.
fn cells_of(grid: &Grid, s: &Sample) -> Vec<Key> {
    let mut out = Vec::new();
    let around = |x: f64, step: f64, half: f64| {
        let lo = ((x - half) / step).ceil() as i64;
        let hi = ((x + half) / step).floor() as i64;
        lo..=hi
    };
    let v_kmh = s.v_mps * 3.6;
    let qs: Vec<i64> = grid
        .q_centres_mps2
        .iter()
        .enumerate()
        .filter(|(_, c)| {
            let r = s.ddv_mps2.abs() / **c;
            r >= grid.q_window.0 && r <= grid.q_window.1 && s.ddv_mps2 != 0.0
        })
        .map(|(i, _)| (i as i64 + 1) * s.ddv_mps2.signum() as i64)
        .collect();
    if qs.is_empty() {
        return out;
    }
    for vi in around(v_kmh, grid.v_step_kmh, grid.v_half_kmh) {
        if vi < 0 {
            continue;
        }
        for di in around(s.dv_mps, grid.dv_step_mps, grid.dv_half_mps) {
            if di <= 0 {
                continue;
            }
            for qi in &qs {
                out.push((s.axle, vi, *qi, di));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A law with branches: loss (q > 0) above recovery.
    fn law(dv: f64, q: f64, v: f64, _t: f64) -> f64 {
        let base = 0.1 * (1.0 - (-2.0 * dv).exp()) * (1.0 - 0.002 * v);
        base * if q > 0.0 { 1.0 } else { 0.8 }
    }

    fn samples(n: usize) -> Vec<Sample> {
        let mut rng = crate::rng::Rng::new(2);
        (0..n)
            .map(|i| {
                let (dv, q, v) = (
                    3.0 * rng.uniform(),
                    if i % 2 == 0 { 1.0 } else { -1.0 } * (0.3 + 2.0 * rng.uniform()),
                    30.0 + 5.0 * rng.uniform(),
                );
                Sample {
                    axle: 1 + ((i / 2) % 2) as u8,
                    dv_mps: dv,
                    ddv_mps2: q,
                    v_mps: v,
                    t_c: f64::NAN,
                    mu: law(dv, q, v, f64::NAN),
                }
            })
            .collect()
    }

    #[test]
    fn truth_scores_zero_and_an_offset_scores_the_offset() {
        let s = samples(40_000);
        let g = Grid::default();
        let exact = score(&s, &g, law).unwrap();
        assert!(exact.rmse < 1e-15 && exact.max_error < 1e-15);
        assert!(exact.cells.len() > 100, "{}", exact.cells.len());
        let (t, p) = exact.hysteresis.unwrap();
        assert!(t > 0.0 && (t - p).abs() < 1e-15, "{t} {p}");
        let off = score(&s, &g, |a, b, c, t| law(a, b, c, t) - 0.01).unwrap();
        assert!((off.rmse - 0.01).abs() < 1e-12 && (off.max_error - 0.01).abs() < 1e-12);
        // One branch for both: no hysteresis predicted; negative somewhere near zero slip.
        let flat = score(&s, &g, |a, _, c, t| law(a, 1.0, c, t) - 0.02).unwrap();
        let (t, p) = flat.hysteresis.unwrap();
        assert!(p.abs() < 0.1 * t, "{t} {p}");
        assert!(flat.negative_cells > 0);
    }

    /// With `at_sample_means` each curve cell is evaluated at its samples' mean slip and slip
    /// rate: samples at slip rates 5–6 m/s² fill the q = 8 window (4–12) far below its centre,
    /// and a law linear in the slip rate is scored there at their mean, not at 8.
    #[test]
    fn curve_cells_at_the_samples_means() {
        let mut rng = crate::rng::Rng::new(5);
        let s1: Vec<Sample> = (0..400)
            .map(|_| Sample {
                axle: 1,
                dv_mps: 0.95 + 0.1 * rng.uniform(),
                ddv_mps2: 5.0 + rng.uniform(),
                v_mps: 30.0,
                t_c: f64::NAN,
                mu: 0.0,
            })
            .collect();
        // Axle 2 in the same cells with fewer samples and other means: not the one scored.
        let s2 = (0..300).map(|_| Sample {
            axle: 2,
            dv_mps: 0.91 + 0.02 * rng.uniform(),
            ddv_mps2: 4.1 + 0.1 * rng.uniform(),
            v_mps: 30.0,
            t_c: f64::NAN,
            mu: 0.0,
        });
        let s: Vec<Sample> = s1.iter().copied().chain(s2).collect();
        let linear = |_: f64, q: f64, _: f64, _: f64| 0.01 * q;
        let nominal = curve(&s, &Grid::default(), 30.0, f64::NAN, linear, linear).unwrap();
        let g = Grid {
            at_sample_means: true,
            ..Grid::default()
        };
        let means = curve(&s, &g, 30.0, f64::NAN, linear, linear).unwrap();
        assert_eq!(nominal.cells.len(), means.cells.len());
        // The cells holding every sample of axle 1: Δv = 1.0 m/s (±0.1) at q = 4 (2–6) and
        // q = 8 (4–12).
        let full = |c: &CurveScore| -> Vec<CurveCell> {
            c.cells
                .iter()
                .filter(|x| x.samples == s1.len())
                .copied()
                .collect()
        };
        let at_centres: Vec<(f64, f64)> = full(&nominal)
            .iter()
            .map(|x| (x.dv_mps, x.ddv_mps2))
            .collect();
        assert_eq!(at_centres, vec![(1.0, 4.0), (1.0, 8.0)]);
        let mean_q = s1.iter().map(|x| x.ddv_mps2).sum::<f64>() / s1.len() as f64;
        let mean_dv = s1.iter().map(|x| x.dv_mps).sum::<f64>() / s1.len() as f64;
        let at_means = full(&means);
        assert_eq!(at_means.len(), 2);
        for c in at_means {
            assert!((c.ddv_mps2 - mean_q).abs() < 1e-12, "{c:?} {mean_q}");
            assert!((c.dv_mps - mean_dv).abs() < 1e-12, "{c:?} {mean_dv}");
            assert!((c.true_mu - 0.01 * mean_q).abs() < 1e-12);
        }
        // One support serves both views with the same cells as computing it per view.
        let once = CurveSupport::of(&s, &Grid::default()).unwrap();
        for (at_means, per_view) in [(false, &nominal), (true, &means)] {
            let c = once
                .curve(at_means, 30.0, f64::NAN, linear, linear)
                .unwrap();
            assert_eq!(
                (&c.cells, c.stats, c.hysteresis),
                (&per_view.cells, per_view.stats, per_view.hysteresis)
            );
        }
    }

    #[test]
    fn curve_and_replay_views_report_the_bias_per_band() {
        let s = samples(40_000);
        let g = Grid::default();
        // The law itself: no error, the hysteresis ratio 1.
        let c = curve(&s, &g, 33.0, f64::NAN, law, law).unwrap();
        assert!(
            c.stats.n > 50 && c.stats.rmse == 0.0 && c.stats.bias == 0.0,
            "{c:?}"
        );
        let ratio = c.hysteresis_ratio(0.002).unwrap();
        assert!((ratio - 1.0).abs() < 1e-12, "{ratio}");
        // An offset is a bias of that size, at any speed the curve is taken at.
        for v in [10.0, 33.0, 60.0] {
            let off = curve(
                &s,
                &g,
                v,
                f64::NAN,
                |a, b, c, t| law(a, b, c, t) + 0.01,
                law,
            )
            .unwrap();
            assert!((off.stats.bias - 0.01).abs() < 1e-12 && (off.stats.rmse - 0.01).abs() < 1e-12);
        }
        // A model without branches has hysteresis ratio 0; below the threshold there is none.
        let flat = curve(&s, &g, 33.0, f64::NAN, |a, _, c, t| law(a, 1.0, c, t), law).unwrap();
        assert!(flat.hysteresis_ratio(0.002).unwrap().abs() < 1e-12);
        assert!(flat.hysteresis_ratio(1.0).is_none());
        // Pooled over runs: the predicted differences over the true ones, pair-weighted. The
        // exact law and the flat model, both on the same pairs, pool to ½; a run below the
        // threshold counts for nothing; none left, none.
        assert!(c.hysteresis_pairs > 10 && flat.hysteresis_pairs == c.hysteresis_pairs);
        let pool = |runs: &[&CurveScore]| {
            pooled_hysteresis_ratio(runs.iter().map(|c| c.hysteresis_with_pairs()), 0.002)
        };
        let half = pool(&[&c, &flat]).unwrap();
        assert!((half - 0.5).abs() < 1e-12, "{half}");
        let twice = CurveScore {
            hysteresis: c.hysteresis.map(|(t, p)| (t, 2.0 * p)),
            hysteresis_pairs: 3 * c.hysteresis_pairs,
            ..c.clone()
        };
        let w = pool(&[&c, &twice]).unwrap();
        assert!((w - 7.0 / 4.0).abs() < 1e-12, "pair-weighted: {w}");
        let tiny = CurveScore {
            hysteresis: Some((0.001, 5.0)),
            ..c.clone()
        };
        assert!((pool(&[&c, &tiny]).unwrap() - ratio).abs() < 1e-12);
        assert_eq!(pool(&[&tiny]), None);
        // Replay: samples at 30–35 m/s (108–126 km/h) fall in two bands; a model 10 % high is
        // biased by 10 % of the mean μ there, per band.
        let r = replay(&s, &g, &SPEED_BANDS_KMH, |a, b, c, t| 1.1 * law(a, b, c, t)).unwrap();
        assert_eq!(r.len(), 2, "{r:?}");
        assert_eq!(
            (r[0].lo_kmh, r[0].hi_kmh, r[1].lo_kmh),
            (80.0, 120.0, 120.0)
        );
        for b in &r {
            assert!(b.stats.bias > 0.002 && b.stats.bias < 0.01, "{b:?}");
            assert!(b.stats.max_error >= b.stats.rmse && b.stats.rmse >= b.stats.bias);
        }
        // Nothing supported: an error, not an empty table.
        assert!(replay(&s[..30], &g, &SPEED_BANDS_KMH, law).is_err());
        assert!(curve(&s[..30], &g, 33.0, 0.0, law, law).is_err());
    }

    #[test]
    fn support_needs_the_threshold_of_one_axle() {
        let s = samples(40_000);
        let few = &s[..30];
        assert_eq!(
            score(few, &Grid::default(), law).unwrap_err(),
            ScoreError::NoSupport { min: 20 }
        );
        let full = score(&s, &Grid::default(), law).unwrap();
        assert!(full.cells.iter().all(|c| c.samples >= 20));
        // Support is counted per axle: samples that support cells on one axle support
        // nothing when spread over 40.
        let one: Vec<Sample> = s[..3000].iter().map(|x| Sample { axle: 1, ..*x }).collect();
        assert!(score(&one, &Grid::default(), law).is_ok());
        let spread: Vec<Sample> = one
            .iter()
            .enumerate()
            .map(|(i, x)| Sample {
                axle: (i % 40) as u8,
                ..*x
            })
            .collect();
        assert!(score(&spread, &Grid::default(), law).is_err());
        // A model that is not finite where a sample lies: an error naming the inputs.
        let e = score(
            &s,
            &Grid::default(),
            |dv, _, _, _| if dv > 2.0 { f64::NAN } else { 0.1 },
        )
        .unwrap_err();
        assert!(matches!(e, ScoreError::Model { dv, .. } if dv > 2.0), "{e}");
        let mut bad = s.clone();
        bad[7].mu = f64::NAN;
        assert!(matches!(
            score(&bad, &Grid::default(), law),
            Err(ScoreError::NotFinite { index: 7, .. })
        ));
    }
}
