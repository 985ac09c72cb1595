//! Self-calibration from a campaign's own data: per-axle brake coefficients α_i, a speed law
//! for the pad friction, the running resistance, the radar's scale and its latency, pooled
//! over the runs, with standard errors; and the corrections that re-estimate a run with them.
//!
//! **The balance.** The vehicle's longitudinal balance with the wheels' torque balance (seed
//! 002 002_8d8769283f5e9cb6.txt eq. 9–10) substituted for the contact forces,
//! M v̇ = −Σ_i T_i − R, T_i = (J ω̇_i + α_i(v) p_i)/r, holds at every sample — sliding or
//! not, since both sides are forces on the same bodies — and gives
//!
//! y = −(M v̇ + (J/r) Σ_i ω̇_i) = Σ_i α_i (1 + γ φ(v)) p_i / r + c_run + c1 v + c2 v²   [N]
//!
//! with M the translating mass (kg), v the vehicle speed (m/s), ω̇_i (rad/s²), p_i (bar),
//! r (m), J (kg·m²); c_run (N) one constant per run (running resistance and that run's
//! gradient), c1 (N·s/m) and c2 (N·s²/m²) the speed-dependent resistance of the Davis form.
//! The fit's unknowns are the ratios α_i / α_i,pipeline. Where the axles' pressures differ —
//! a wheel-slide protection at work, a brake applied axle by axle — the four separate; where
//! two axles' pressures never differ, only their sum is identifiable and the pair is fitted
//! with one ratio (named in [`CampaignCalibration::shared`]). The separated ratios are pooled
//! partially (empirical Bayes, see `partial_pooling`); one ratio that, with the pad law's
//! speed term, is not told from (1, none) by a likelihood ratio on the force balance keeps the
//! pipeline's α and a constant pad friction. Samples near a locked wheel are left out: its
//! brake holds it with less than α p.
//!
//! **Integrated over time.** The coefficients (α_i, the pad law, the resistance and the run
//! constants) come from the same balance integrated from the first sample of each stretch of
//! consecutive samples t₀ to t ([`Balance::integrated_rows`]):
//!
//! −(M v(t) + (J/r) Σ_i ω_i(t)) = Σ_i α_i ∫ (1 + γ φ) p_i / r dt + c_run (t − t₀)
//!                                 + c1 ∫ v dt + c2 ∫ v² dt + K   [N·s]
//!
//! with one constant of integration K per stretch. The force balance differentiates the radar's
//! noise, whose spectrum then rises with frequency; integrated, the noise is the radar's own,
//! and the slow content of the pressures — what tells the axles and the pad law apart — is
//! measured against it at the frequencies where it lies. On the mismatch scenes (12 runs, noise
//! seeds 1–3) the α_i's standard errors fall from ~0.8 % to ~0.45 % and γ's from 0.96 % to
//! 0.12 % (the pad rise +4.8 … +5.0 % where it is +5 %, against +4.5 … +5.6 % from the force
//! balance). The delays and the radar's scale are profiled on the force balance (below), which
//! also decides whether the data call for leaving the pipeline's α at all ([`ForceBalance`]).
//! The errors of the coefficients are taken over γ ([`Fit::over_gamma`]).
//!
//! **The pad friction** α_i(v) = α_i (1 + γ φ(v)), φ(v_ref) = 0 at the campaign's top speed
//! v_ref, so α_i is the coefficient there and γ φ(0) the rise to standstill. Forms
//! ([`PadForm`]): constant (φ = 0); linear, φ = 1 − v/v_ref (the first-order form of a friction
//! that rises as the sliding speed falls [assumed for disc pads]); quadratic and cubic,
//! φ = max(0, 1 − v/v_ref)^2 and ^3 (rises gathered towards standstill) — low-order members of
//! the polynomial-in-speed laws train-dynamics codes fit to brake bench data (the UIC's TrainDy
//! for LL tread-brake blocks: Cantone and Ottati, The Open Transportation Journal 12 (2018)
//! 114, read in its abstract), their coefficients fitted here, not taken; the mixtures of
//! neighbouring powers, (1 − w) φ_linear + w φ_quadratic
//! and (1 − w) φ_quadratic + w φ_cubic, w in [0, 1] fitted ([`best_mix`]; a shape between two
//! powers would otherwise leak into the per-axle α, where each axle's pressure differences
//! lie, [assumed]: smooth, rising towards standstill); Karwatzki's, φ = k(v)/k(v_ref) −
//! 1 with k(v) = (v + 100)/(5 v + 100), v in km/h — the speed factor of Karwatzki's empirical
//! formula for cast-iron blocks (as given in Wende, *Fahrdynamik des Schienenverkehrs*,
//! Teubner 2003). The form is chosen by BIC = n_eff ln(RSS/n) + k ln(n_eff) with n_eff
//! the residuals' effective number of samples, as the Polach temperature forms are; a mixture
//! counts w as one parameter more, and one whose w ends at 0 or 1 is refused (a pure power
//! fits as well).
//!
//! **The radar.** It reads v_radar(t) = s v(t − τ). The scale s comes from the coasts before
//! each run's first brake application, where the wheels roll with only the creep the running
//! resistance gives them: the least-squares fit of v_radar(t + τ) = s r ω̄ − q r ω̄ d (d the
//! wheels' deceleration, q that creep's coefficient; s r ω̄ alone where the coasts all
//! decelerate alike), pooled over the runs (the wheel radius of the pipeline taken as known). The latency τ comes from the balance
//! itself: the radar's deceleration shifted by τ against the wheels' brake torques, which
//! carry no delay, minimises the balance's residual at the true τ. (Matching the radar's
//! deceleration with the wheels' instead is biased by the creep, which grows with the brake
//! force; see [`super::radar`].) The two are iterated: s at τ = 0, τ, s at τ.
//!
//! **Filters.** Every channel is low-passed with the radar's cut-off here (the same 4th-order
//! zero-phase filter on both sides of a linear balance keeps it exact), so that the pressures'
//! faster content has no counterpart missing in the radar's deceleration.
//!
//! **Weights.** Each run enters the least squares of α, the pad law and the resistance with
//! the weight 1/σ_r² (its residual variance from a first fit, relative to the runs' mean,
//! clamped to 0.1–10): runs logged with other rates or noisier sensors would otherwise read as
//! a scatter between the axles. The delays and the radar's scale are profiled before, with
//! equal weights.
//!
//! Standard errors: σ²(XᵀWX)⁻¹ inflated by √(n/n_eff), the coefficients' taken over γ; for γ
//! and τ, from the curvature of
//! the profiled residual sum of squares, se² = 2 σ² n/n_eff / RSS''; for the delays, the
//! larger of that and the jackknife over runs (each run left out in turn), and delays not
//! told from 0 with those errors (both together by a Wald test, one alone within 1.96
//! standard errors) are taken as 0 ([`drop_insignificant_delays`]). The α's errors then carry
//! the delays' and the radar scale's (the delta method, [`Balance::alpha_spread`]): the
//! balance is fitted again with each moved by one standard error, and half the change of each
//! α is added (the scale's in quadrature, the two delays' with the same sign).

// `!(x >= lo)` is deliberate: a NaN fails the check instead of passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::config::calibrated::is_zero;
use crate::config::Pipeline;
use crate::format::AXLES;
use crate::ingest::RunLog;
use crate::linalg::{cho_solve, cholesky, effective_samples};
use crate::signal;
use crate::vehicle::total_mass_kg;

use super::{counting, noise, EstimateError};
pub use crate::config::calibrated::{Corrections, PadForm, PadLaw};

/// The fewest runs with samples in the balance that a campaign's calibration is fitted on.
/// Below it the delays cannot be tested against the runs' scatter (the jackknife needs 3),
/// and a profile over one or two runs follows their noise: each of the 12 clean mismatch
/// scenes calibrated on itself came out 0.70–4.28× the uncalibrated μ RMSE (tachometer
/// delays up to 82 ms where the truth is 10, one axle's α 6 % low), groups of 3 runs
/// 0.77–1.018×, of 6 runs 0.74–0.997× (seed 1, measured 2026-11-27).
pub const MIN_RUNS: usize = 3;

/// Every `DECIMATE`-th sample enters the balance (52 Hz at 417 Hz, well above the 1.5 Hz the
/// signals are filtered to).
const DECIMATE: usize = 8;
/// The latencies searched, s.
pub const LATENCY_RANGE_S: (f64, f64) = (-0.05, 0.2);
/// The tachometers' delays searched, s.
pub const TACHO_DELAY_RANGE_S: (f64, f64) = (-0.05, 0.1);
/// The pad friction's γ searched (relative to α at the top speed).
const GAMMA_RANGE: (f64, f64) = (-0.5, 0.5);
/// An axle whose α has a relative standard error above this is fitted together with the axle
/// its estimate is most negatively correlated with.
pub const MAX_ALPHA_REL_SE: f64 = 0.05;

/// One pad-friction form as fitted.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PadCandidate {
    pub form: PadForm,
    /// A mixture's fitted weight w ([`PadForm::phi`]); 0, and not written, for the other
    /// forms.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub mix: f64,
    /// With one resistance constant per run (else one for the campaign).
    pub per_run_constants: bool,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub gamma: f64,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub rss: f64,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub bic: f64,
    /// Why the form was refused, when it was (besides a higher BIC).
    pub refused: Option<String>,
}

/// What a campaign's self-calibration found.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CampaignCalibration {
    /// α_i at the top speed, N·m/bar.
    pub alpha_nm_per_bar: [f64; AXLES],
    /// One standard error of each α_i, N·m/bar.
    #[serde(with = "crate::config::calibrated::nan_as_null_axles")]
    pub alpha_se: [f64; AXLES],
    /// Each axle's (or group's) α as the balance gives it, before the partial pooling, and
    /// its standard error, N·m/bar.
    #[serde(with = "crate::config::calibrated::nan_as_null_axles")]
    pub alpha_fitted: [f64; AXLES],
    #[serde(with = "crate::config::calibrated::nan_as_null_axles")]
    pub alpha_fitted_se: [f64; AXLES],
    /// The spread of the true α_i between axles the pooling found (N·m/bar, 1σ; 0 when the
    /// fitted α_i differ no more than their errors); None with one group.
    pub alpha_between_sd: Option<f64>,
    /// Groups of axles (0-based) whose pressures never differ enough to tell their α apart:
    /// each fitted with one α.
    pub shared: Vec<Vec<usize>>,
    pub pad: PadLaw,
    pub pad_candidates: Vec<PadCandidate>,
    /// The resistance's constant is fitted per run (a run's gradient), else once.
    pub per_run_constants: bool,
    /// c1, N·s/m.
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub resistance_c1_n_s_per_m: f64,
    /// c2, N·s²/m².
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub resistance_c2_n_s2_per_m2: f64,
    /// One standard error of c1, N·s/m, from σ² times the inverse of the normal equations taken
    /// over the pad law's γ ([`Fit::over_gamma`]), at the fitted delays (conditional on those);
    /// null in files written before it was reported.
    #[serde(
        default = "crate::config::calibrated::nan",
        with = "crate::config::calibrated::nan_as_null"
    )]
    pub resistance_c1_se: f64,
    /// One standard error of c2, N·s²/m², likewise.
    #[serde(
        default = "crate::config::calibrated::nan",
        with = "crate::config::calibrated::nan_as_null"
    )]
    pub resistance_c2_se: f64,
    /// Each run's constant of the balance (the resistance's constant and the run's gradient
    /// force), in the campaign's order; every run has the campaign's one constant where
    /// `per_run_constants` is false. Empty in files written before they were reported.
    #[serde(default)]
    pub resistance_constants: Vec<RunConstant>,
    /// Radar reading / true speed (1 when no run coasts before its brake).
    pub radar_scale: f64,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub radar_scale_se: f64,
    /// Runs whose coast the scale rests on.
    pub radar_scale_runs: usize,
    /// The radar's delay, s.
    pub radar_latency_s: f64,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub radar_latency_se: f64,
    /// The tachometers' delay (a counting window's half, for pulse counters), s.
    pub tacho_delay_s: f64,
    /// Not a number where the delay is not fitted: taken as 0, or half the counting window.
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub tacho_delay_se: f64,
    /// The tachometers' counting window read from their quantisation (s), whose half is
    /// then their delay instead of the balance's fit ([`counting`]); None where the runs do
    /// not show one (and in files written before it was read).
    #[serde(default)]
    pub tacho_window_s: Option<f64>,
    /// Runs in the balance.
    pub runs: usize,
    /// Samples in the balance (after decimation).
    pub samples: usize,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub effective_samples: f64,
    /// RMS of the force balance's residual at its own fit, N, each run's squares weighted as in
    /// the fit (the runs' weights average about 1: close to the plain RMS when the runs are
    /// alike).
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub rms_residual_n: f64,
    /// The balance integrated over time, which every coefficient but the delays and the
    /// radar's scale comes from (`samples`, `effective_samples` and `rms_residual_n` above
    /// are the force balance's, which the delays come from).
    #[serde(default)]
    pub integrated: IntegratedBalance,
    /// What could not be calibrated and what was done instead, in plain words.
    pub notes: Vec<String>,
}

/// The integrated balance's rows and residual ([`CampaignCalibration::integrated`]); zeros and
/// NaN in files written before it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IntegratedBalance {
    /// Rows in its stretches of two or more rows.
    pub samples: usize,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub effective_samples: f64,
    /// RMS of its residual, N·s (momentum), each run's squares weighted as in the fit.
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub rms_residual_n_s: f64,
    /// The radar's white noise, m/s rms per sample, over the runs whose radar shows it (their
    /// rows' mean square; [`super::noise`]); None where none does, or in files written before
    /// it was reported.
    #[serde(default)]
    pub radar_noise_mps: Option<f64>,
    /// The balance's residual RMS over what the radar's noise, through the same low-pass,
    /// leaves on those runs' rows ([`residual_over_radar_noise`]): about 1 where the residual
    /// shows nothing but the radar's noise (which then sets the coefficients' statistical
    /// errors: more runs or a quieter radar narrow them), above 1 by what else it leaves (the
    /// wheel loads' fluctuation, another sensor's noise, a force the balance's model lacks),
    /// well below 1 where the radar shows more than white noise in its band. None where no
    /// run's noise could be read or it is 0 (below the radar's resolution).
    #[serde(default)]
    pub residual_over_radar_noise: Option<f64>,
    /// Runs whose radar noise could be read (logged at the time base's rate, with 1 000 or
    /// more samples above the lowest speed); the two figures above are over these.
    #[serde(default)]
    pub radar_noise_runs: usize,
}

impl Default for IntegratedBalance {
    fn default() -> Self {
        IntegratedBalance {
            samples: 0,
            effective_samples: f64::NAN,
            rms_residual_n_s: f64::NAN,
            radar_noise_mps: None,
            residual_over_radar_noise: None,
            radar_noise_runs: 0,
        }
    }
}

impl CampaignCalibration {
    pub fn corrections(&self) -> Corrections {
        Corrections {
            alpha_nm_per_bar: self.alpha_nm_per_bar,
            pad: self.pad,
            radar_scale: self.radar_scale,
            radar_latency_s: self.radar_latency_s,
            tacho_delay_s: self.tacho_delay_s,
        }
    }
}

/// One run's signals as the balance needs them (matched filters).
struct RunSignals {
    /// The run's name (the log's file name unless [`PreparedRun::named`]), for the per-run
    /// resistance constants.
    name: String,
    fs: f64,
    /// Radar speed and its rate at every sample, m/s and m/s² (shifted by τ when used).
    v_radar: Vec<f64>,
    a_radar: Vec<f64>,
    ok: Vec<bool>,
    /// r ω̄ (m/s) and Σ_i ω̇_i (rad/s²) at every sample (shifted by the tachometers' delay
    /// when used).
    w_mean: Vec<f64>,
    wd_sum: Vec<f64>,
    /// Samples of the balance: index, pressures (bar).
    rows: Vec<(usize, [f64; AXLES])>,
    /// Samples of the coast before the first brake.
    coast: Vec<usize>,
    /// Each axle's deepest trough of its raw tachometer's quantisation residual
    /// ([`counting::deepest_trough`]).
    troughs: Vec<Option<counting::Trough>>,
    /// The radar's white noise per sample and what the calibration's low-pass leaves of it,
    /// m/s rms ([`super::noise`]), or why it could not be read.
    radar_noise: Result<(f64, f64), noise::Unknown>,
}

/// A log's file name for notes (not its whole path: a campaign's calibration must not depend
/// on how the archive's path was spelled).
fn log_name(log: &RunLog) -> String {
    log.source.file_name().map_or_else(
        || log.source.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Samples within `settle_s` (s) of a wheel locked above the lowest speed the estimates use
/// (r ω < `est.locked_wheel_speed_mps` on a valid raw tachometer sample while the radar
/// reads more than `est.min_speed_mps`; pulse counting and the radar's noise make a rolling
/// wheel read 0 only well below that): a locked wheel's brake holds it with less than α p,
/// so the balance does not hold there, nor in the filtered signals around it. Returns the
/// mask and the number of locked samples.
fn near_locked_wheel(
    log: &RunLog,
    r: f64,
    est: &crate::config::EstimateConfig,
    settle_s: f64,
) -> (Vec<bool>, usize) {
    let (locked_mps, min_mps) = (est.locked_wheel_speed_mps, est.min_speed_mps);
    let n = log.len();
    let reach = (settle_s * log.sample_rate_hz).ceil() as usize;
    // +1 at the first sample a lock reaches, −1 after the last: the running sum is positive
    // near a lock.
    let mut edges = vec![0i64; n + 1];
    let mut locked = 0usize;
    for k in 0..n {
        let moving = log.valid[k] && log.v_radar_mps[k] > min_mps;
        if moving && (0..AXLES).any(|a| r * log.omega_radps[a][k] < locked_mps) {
            locked += 1;
            edges[k.saturating_sub(reach)] += 1;
            edges[(k + reach + 1).min(n)] -= 1;
        }
    }
    let mut depth = 0i64;
    let mask = edges[..n]
        .iter()
        .map(|e| {
            depth += e;
            depth > 0
        })
        .collect();
    (mask, locked)
}

/// The end of a note on a run the calibration leaves out.
const LEFT_OUT: &str = "left out of the calibration";

/// Why a campaign of `runs` runs with samples for the balance is not calibrated (with the
/// `notes` on the runs left out, and why), and what to do; None from [`MIN_RUNS`] on.
fn too_few_runs(runs: usize, notes: &[String]) -> Option<(String, String)> {
    let left_out: Vec<&str> = notes
        .iter()
        .filter(|n| n.ends_with(LEFT_OUT))
        .map(String::as_str)
        .collect();
    let left_out = if left_out.is_empty() {
        String::new()
    } else {
        format!("; {}", left_out.join("; "))
    };
    if runs == 0 {
        return Some((
            format!("no run has a usable sample for the calibration{left_out}"),
            "check that the logs hold braking runs above estimate.min_speed_mps".into(),
        ));
    }
    (runs < MIN_RUNS).then(|| {
        (
            format!(
                "only {runs} run{} with samples for the balance: a campaign's calibration needs at least {MIN_RUNS} (with fewer, its delays follow the runs' noise and can make the estimates several times worse){left_out}",
                if runs == 1 { "" } else { "s" }
            ),
            format!("calibrate over {MIN_RUNS} or more braking runs of the same vehicle, or set estimate.calibration = \"pipeline\" (or \"dry-run\" with a full-adhesion run)"),
        )
    })
}

/// One run as the calibration keeps it (none when it is left out), and a note on it.
pub struct PreparedRun {
    signals: Option<RunSignals>,
    note: Option<String>,
    /// The log's name and how long it has a wheel locked (s), when it has.
    locked: Option<(String, f64)>,
}

impl PreparedRun {
    /// The run under the campaign's name for it (else its log's file name): the name its
    /// resistance constant and the locked-wheel note give.
    pub fn named(mut self, name: &str) -> PreparedRun {
        if let Some(s) = &mut self.signals {
            s.name = name.to_string();
        }
        if let Some(l) = &mut self.locked {
            l.0 = name.to_string();
        }
        self
    }
}

/// Collects a campaign's runs one at a time (each log can be dropped after [`Self::add`]),
/// then fits ([`Self::finish`]).
pub struct CampaignCalibrator<'p> {
    pipeline: &'p Pipeline,
    runs: Vec<RunSignals>,
    notes: Vec<String>,
    /// Runs with a locked wheel: the log's name and how long (s).
    locked: Vec<(String, f64)>,
}

impl<'p> CampaignCalibrator<'p> {
    pub fn new(pipeline: &'p Pipeline) -> Self {
        CampaignCalibrator {
            pipeline,
            runs: Vec::new(),
            notes: Vec::new(),
            locked: Vec::new(),
        }
    }

    /// Conditions `log` and keeps what the balance needs ([`Self::prepare`], then
    /// [`Self::add_prepared`]).
    pub fn add(&mut self, log: &RunLog) -> Result<(), EstimateError> {
        let p = self.prepare(log)?;
        self.add_prepared(p);
        Ok(())
    }

    /// Notes a run that could not be read or conditioned (`why` names it): left out, and
    /// named if the campaign then has too few runs.
    pub fn left_out(&mut self, why: &str) {
        self.notes.push(format!("{why}; {LEFT_OUT}"));
    }

    /// Adds a prepared run (in the campaign's order: the fit sums over the runs in the order
    /// they were added).
    pub fn add_prepared(&mut self, p: PreparedRun) {
        self.runs.extend(p.signals);
        self.notes.extend(p.note);
        self.locked.extend(p.locked);
    }

    /// Conditions `log` with matched filters and keeps what the balance needs; a run without
    /// a usable sample becomes a note and is left out. Needs only `&self`: runs can be
    /// prepared in parallel.
    pub fn prepare(&self, log: &RunLog) -> Result<PreparedRun, EstimateError> {
        let mut filters = self.pipeline.filters.clone();
        filters.tacho_cutoff_hz = filters.radar_cutoff_hz;
        filters.pressure_cutoff_hz = filters.radar_cutoff_hz;
        let c = signal::condition(log, &filters).map_err(|source| EstimateError::Filter {
            file: log.source.clone(),
            source,
        })?;
        let est = &self.pipeline.estimate;
        let r = self.pipeline.vehicle.wheel_radius_m;
        let n = c.v_mps.len();
        let first_brake = (0..n)
            .find(|&k| (0..AXLES).any(|a| c.p_bar[a][k] >= est.min_pressure_bar))
            .unwrap_or(n);
        let (near_lock, locked_samples) = near_locked_wheel(log, r, est, c.settle_s);
        let mut rows = Vec::new();
        let mut coast = Vec::new();
        for k in (0..n).step_by(DECIMATE) {
            let v = c.v_mps[k];
            if !c.settled[k] || !(v >= est.min_speed_mps) || near_lock[k] {
                continue;
            }
            let rolling = (0..AXLES).all(|a| r * c.omega_radps[a][k] >= est.locked_wheel_speed_mps);
            if !rolling {
                continue;
            }
            let p: [f64; AXLES] = std::array::from_fn(|a| c.p_bar[a][k]);
            if p.iter().all(|x| x.is_finite()) {
                rows.push((k, p));
            }
            let w = r * (0..AXLES).map(|a| c.omega_radps[a][k]).sum::<f64>() / AXLES as f64;
            if k < first_brake && w >= est.min_speed_mps {
                coast.push(k);
            }
        }
        if rows.is_empty() {
            return Ok(PreparedRun {
                signals: None,
                locked: None,
                note: Some(format!(
                    "{}: no settled sample above {} m/s with every wheel rolling; {LEFT_OUT}",
                    log_name(log),
                    est.min_speed_mps
                )),
            });
        }
        // A dropout (a channel without data) leaves its samples and the filters' settling
        // around them out; the rest of the run counts.
        let missing = c.has_data.iter().filter(|h| !**h).count();
        let note = (missing > 0).then(|| {
            let mut on: Vec<_> = log
                .gaps
                .iter()
                .filter(|g| !g.bridged)
                .map(|g| g.signal)
                .collect();
            on.sort_by_key(|s| s.index());
            on.dedup();
            let on = match on.len() {
                0 => "a channel".to_string(),
                n if n == crate::format::Signal::ALL.len() => "every channel".to_string(),
                _ => on.iter().map(ToString::to_string).collect::<Vec<_>>().join(", "),
            };
            format!(
                "{}: {:.2} s without data on {on} (a dropout); those samples and {:.2} s of filter settling on each side are left out of the calibration",
                log_name(log),
                missing as f64 / c.sample_rate_hz,
                c.settle_s
            )
        });
        let locked =
            (locked_samples > 0).then(|| (log_name(log), locked_samples as f64 / c.sample_rate_hz));
        let w_mean = (0..n)
            .map(|k| r * (0..AXLES).map(|a| c.omega_radps[a][k]).sum::<f64>() / AXLES as f64)
            .collect();
        let wd_sum = (0..n)
            .map(|k| (0..AXLES).map(|a| c.omega_dot_radps2[a][k]).sum())
            .collect();
        // A sample enters the balance only where every signal is finite.
        let ok = (0..n)
            .map(|k| {
                c.settled[k]
                    && c.v_mps[k].is_finite()
                    && c.accel_mps2[k].is_finite()
                    && (0..AXLES).all(|a| c.omega_dot_radps2[a][k].is_finite())
            })
            .collect();
        Ok(PreparedRun {
            locked,
            signals: Some(RunSignals {
                name: log_name(log),
                fs: c.sample_rate_hz,
                v_radar: c.v_mps,
                a_radar: c.accel_mps2,
                ok,
                w_mean,
                wd_sum,
                rows,
                coast,
                troughs: (0..AXLES)
                    .map(|a| counting::deepest_trough(&log.omega_radps[a], log.sample_rate_hz))
                    .collect(),
                radar_noise: noise::radar_white_noise(log, filters.despike, est.min_speed_mps)
                    .and_then(|sd| {
                        let gain = noise::lowpass_noise_gain(
                            filters.radar_cutoff_hz,
                            c.sample_rate_hz,
                            filters.mode,
                        )
                        .ok_or(noise::Unknown::OtherRate)?;
                        Ok((sd, sd * gain.sqrt()))
                    }),
            }),
            note,
        })
    }

    /// The campaign's tachometer counting window ([`counting::campaign_window`]), said in a
    /// note where one is read or where some axles show one and too few agree.
    fn counting_window(runs: &[RunSignals], notes: &mut Vec<String>) -> Option<counting::Window> {
        let per_run: Vec<(f64, Vec<Option<counting::Trough>>)> =
            runs.iter().map(|r| (r.fs, r.troughs.clone())).collect();
        match counting::campaign_window(&per_run) {
            Ok(Some(w)) => {
                let fs = runs[0].fs;
                let samples = if runs.iter().all(|r| r.fs == fs) {
                    format!(" ({:.0} samples at {fs:.0} Hz)", w.window_s * fs)
                } else {
                    String::new()
                };
                notes.push(format!(
                    "the tachometers count pulses over {:.1} ms{samples}: their quantisation error's autocorrelation is {:+.2} at that lag on {} of {} axles ({} runs), so their delay is taken as half of it, {:.1} ms, not fitted from the balance (assuming the tachometer chain adds no other latency)",
                    w.window_s * 1e3,
                    w.mean_acf,
                    w.showing,
                    w.looked_at,
                    runs.len(),
                    w.delay_s() * 1e3
                ));
                Some(w)
            }
            Ok(None) => None,
            Err((agree, looked_at)) => {
                notes.push(format!(
                    "only {agree} of {looked_at} axles ({} runs) show the same tachometer counting window in their quantisation (at least {:.0} % must; a window set in samples differs in time between logging rates): the tachometers' delay is fitted from the balance",
                    runs.len(),
                    counting::AGREEING * 100.0
                ));
                None
            }
        }
    }

    /// The balance over `runs`, unweighted, each run with its own constant, its reference
    /// speed the fastest sample's radar speed.
    fn balance<'r>(pipeline: &Pipeline, runs: &'r [RunSignals]) -> Balance<'r> {
        let veh = &pipeline.vehicle;
        let v_ref = runs
            .iter()
            .flat_map(|run| run.rows.iter().map(|(k, ..)| run.v_radar[*k]))
            .fold(0.0f64, f64::max);
        Balance {
            runs,
            r: veh.wheel_radius_m,
            inv_r: 1.0 / veh.wheel_radius_m,
            mass: total_mass_kg(veh),
            j_r: veh.axle_inertia_kgm2 / veh.wheel_radius_m,
            v_ref,
            per_run: true,
            alpha_pipeline: veh.brake_torque_nm_per_bar,
            weights: &[],
            integrated: false,
            pad_mix: 0.0,
        }
    }

    /// One note for the runs with a locked wheel, if any.
    fn locked_note(&self) -> Option<String> {
        let longest = self.locked.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
        let shortest = self
            .locked
            .iter()
            .map(|l| l.1)
            .fold(f64::INFINITY, f64::min);
        let est = &self.pipeline.estimate;
        let how_long = if self.locked.len() == 1 {
            format!("{:.2} s, in {}", longest.1, longest.0)
        } else {
            format!(
                "{shortest:.2}–{:.2} s each, the longest in {}",
                longest.1, longest.0
            )
        };
        Some(format!(
            "{} of {} runs have a wheel locked while the train moves ({how_long}): a locked wheel's brake holds it with less than α p, so those samples and the filters' settling on each side are left out of the calibration (locked: r ω below estimate.locked_wheel_speed_mps = {} m/s with the radar above estimate.min_speed_mps = {} m/s)",
            self.locked.len(),
            self.runs.len(),
            est.locked_wheel_speed_mps,
            est.min_speed_mps
        ))
    }

    /// Why the runs added so far are too few for a calibration ([`MIN_RUNS`] with samples for
    /// the balance; the runs left out named), or None: what [`Self::finish`] would refuse.
    pub fn too_few(&self) -> Option<String> {
        too_few_runs(self.runs.len(), &self.notes).map(|(what, _)| what)
    }

    /// The balance `b`'s coefficients at `at`: the runs weighed by their residuals
    /// ([`Balance::run_weights`]; equal, with a note in `notes`, where no first fit can be
    /// made), the pad form and the resistance's constants chosen by BIC ([`select_model`]),
    /// and the chosen fit's Gram matrix, effective samples and σ² (per unit weight, inflated by
    /// n/n_eff: N² on the force balance, N²·s² on the integrated one). The error says what
    /// failed and what to do.
    fn coefficients(
        b: &Balance,
        at: &At,
        runs_n: usize,
        notes: &mut Vec<String>,
    ) -> Result<Coefficients, (String, &'static str)> {
        let weights = b.run_weights(at).unwrap_or_else(|| {
            notes.push(
                "no first fit of the balance to weigh the runs by: every run weighs the same"
                    .into(),
            );
            vec![1.0; b.runs.len()]
        });
        let weighted = Balance {
            weights: &weights,
            ..*b
        };
        let (best, candidates) = select_model(&weighted, at, runs_n);
        let Some((fit, _, per_run)) = best else {
            return Err((
                "no form of the pad friction could be fitted".into(),
                "the pressures do not vary enough; calibrate on runs with brake applications",
            ));
        };
        let chosen = Balance {
            per_run,
            pad_mix: fit.mix,
            ..weighted
        };
        let g = chosen.gram(at, fit.form);
        let fit = fit.over_gamma(&g);
        let n = g.n as f64;
        let n_eff = chosen.n_eff(at, fit.form, &fit);
        // γ, and a mixture's weight.
        let shape = 1.0 + f64::from(u8::from(fit.form.mixes()));
        let dof = (n - runs_n as f64 - fit.beta.len() as f64 - shape).max(1.0);
        let sigma2 = fit.rss / dof * n / n_eff;
        Ok(Coefficients {
            weights,
            fit,
            per_run,
            candidates,
            g,
            n_eff,
            sigma2,
        })
    }

    /// Fits the campaign (see the module's documentation). `what` names the campaign in
    /// errors.
    pub fn finish(self, what: &std::path::Path) -> Result<CampaignCalibration, EstimateError> {
        let fail = |what_failed: String, hint: &str| EstimateError::Calibration {
            file: what.to_path_buf(),
            what: what_failed,
            hint: hint.to_string(),
        };
        let locked = self.locked_note();
        let mut notes = self.notes;
        notes.extend(locked);
        if let Some((what_failed, hint)) = too_few_runs(self.runs.len(), &notes) {
            return Err(fail(what_failed, &hint));
        }
        let b = Self::balance(self.pipeline, &self.runs);
        let v_ref = b.v_ref;
        let samples: usize = self.runs.iter().map(|r| r.rows.len()).sum();
        if samples < 200 {
            return Err(fail(
                format!("only {samples} samples for the balance"),
                "calibrate on braking runs of several seconds each",
            ));
        }

        let window = Self::counting_window(&self.runs, &mut notes);
        let (at, d) = fit_radar_and_delays(&b, &mut notes, window.map(|w| w.delay_s()));
        // The delays' standard errors from the force balance they were fitted on (its chosen
        // model); every coefficient from the balance integrated over time, at those delays.
        let tau = at.radar_s;
        let runs_n = self.runs.len();
        let force = ForceBalance::at(&b, &at, &d, runs_n);
        let integrated = Balance {
            integrated: true,
            ..b
        };
        let c = Self::coefficients(&integrated, &at, runs_n, &mut notes)
            .map_err(|(what_failed, hint)| fail(what_failed, hint))?;
        let Coefficients {
            weights: _,
            fit,
            per_run,
            candidates,
            g,
            n_eff,
            sigma2,
        } = &c;
        let (fit, per_run, g, n_eff, sigma2) = (fit, *per_run, g, *n_eff, *sigma2);
        let b = c.balance(&integrated);
        let n = g.n as f64;
        let runs = self.runs.len() as f64;
        let shared: Vec<Vec<usize>> = fit.groups.iter().filter(|g| g.len() > 1).cloned().collect();
        notes.extend(shared.iter().map(|grp| shared_note(grp)));
        let A {
            alpha,
            alpha_se,
            fitted: alpha_fitted,
            fitted_se: alpha_fitted_se,
            between_sd: pooling,
            kept,
            ..
        } = b.axle_alphas_at(
            g,
            fit,
            sigma2,
            &at,
            (force.keeps, force.tau_se, force.tacho_se, d.scale_se),
            &mut notes,
        );
        let constants = if per_run { runs } else { 1.0 };
        let res = Resistance::applied(fit, sigma2, kept.is_some(), g, n / n_eff, constants);
        // The pipeline's α kept: with the pad friction constant.
        let (pad_form, pad_gamma, gamma_se, pad_mix) = if kept.is_some() {
            (PadForm::Constant, 0.0, 0.0, 0.0)
        } else {
            (
                fit.form,
                fit.gamma,
                gamma_error_over_mix(&b, &at, g, fit, sigma2),
                fit.mix,
            )
        };
        let run_constants = b.run_constants(&at, res.fit.form, &res);
        notes.extend(kept);
        placed(&alpha, &alpha_fitted, &alpha_fitted_se).map_err(|(w, h)| fail(w, h))?;
        Ok(CampaignCalibration {
            alpha_nm_per_bar: alpha,
            alpha_se,
            alpha_fitted,
            alpha_fitted_se,
            alpha_between_sd: pooling,
            shared,
            pad: PadLaw {
                form: pad_form,
                gamma: pad_gamma,
                gamma_se,
                v_ref_mps: v_ref,
                mix: pad_mix,
            },
            pad_candidates: candidates.clone(),
            per_run_constants: per_run,
            resistance_c1_n_s_per_m: res.c[0],
            resistance_c2_n_s2_per_m2: res.c[1],
            resistance_c1_se: res.se[0],
            resistance_c2_se: res.se[1],
            resistance_constants: run_constants,
            radar_scale: at.scale,
            radar_scale_se: d.scale_se,
            radar_scale_runs: d.scale_runs,
            radar_latency_s: tau,
            radar_latency_se: force.tau_se,
            tacho_delay_s: at.tacho_s,
            tacho_delay_se: force.tacho_se,
            tacho_window_s: window.map(|w| w.window_s),
            runs: self.runs.len(),
            samples: force.samples,
            effective_samples: force.n_eff,
            rms_residual_n: force.rms_n,
            integrated: IntegratedBalance {
                samples: g.n,
                effective_samples: n_eff,
                rms_residual_n_s: (res.rss / n).sqrt(),
                ..Default::default()
            }
            .with_radar_noise(&b, &at, fit),
            notes,
        })
    }
}

/// The balance's residual RMS over what the radar's noise leaves on its rows, over the runs
/// whose noise could be read: with y = −(M v_radar / s + (J/r) Σ ω) (N·s) and the radar's
/// white noise through the calibration's low-pass σ_f,r (m/s rms per sample) on run r, the
/// noise alone leaves each row of run r a variance (M σ_f,r / s)²; the ratio is
/// √(Σ_r Σ e² / Σ_r n_r (M σ_f,r / s)²) over those runs' residuals e (the fit's, after the
/// stretches' and runs' constants; n_r rows; the coefficients' fit, before the resistance's
/// constants are applied). On noise alone it reads low by the share of the effective samples
/// the stretches' constants, the runs' slopes and the coefficients take (~1–3 % on 12-run
/// campaigns). It says how much of the residual is the radar's noise, not how well another
/// estimator could do, nor a model error the regressors absorb (that leaves no residual).
/// Returns the runs' noise (rows' mean square, m/s), the ratio (None where the noise is 0) and
/// how many runs it is over.
fn residual_over_radar_noise(b: &Balance, at: &At, fit: &Fit) -> (Option<f64>, Option<f64>, usize) {
    let residuals = b.residuals(at, fit.form, fit);
    let (mut runs, mut rows, mut msq, mut sse, mut expected) = (0, 0.0, 0.0, 0.0, 0.0);
    for (run, e) in b.runs.iter().zip(&residuals) {
        let (Ok((sd, filtered)), false) = (run.radar_noise, e.is_empty()) else {
            continue;
        };
        let n = e.len() as f64;
        runs += 1;
        rows += n;
        msq += n * sd * sd;
        sse += e.iter().map(|x| x * x).sum::<f64>();
        expected += n * (b.mass * filtered / at.scale).powi(2);
    }
    if runs == 0 {
        return (None, None, 0);
    }
    let ratio = (expected > 0.0 && sse.is_finite()).then(|| (sse / expected).sqrt());
    (Some((msq / rows).sqrt()), ratio, runs)
}

impl IntegratedBalance {
    /// With the radar's noise and the residual over it ([`residual_over_radar_noise`]).
    fn with_radar_noise(self, b: &Balance, at: &At, fit: &Fit) -> Self {
        let (noise, ratio, runs) = residual_over_radar_noise(b, at, fit);
        IntegratedBalance {
            radar_noise_mps: noise,
            residual_over_radar_noise: ratio,
            radar_noise_runs: runs,
            ..self
        }
    }
}

/// Whether the balance placed the α: an error when a fitted α's standard error spans its
/// value (said first: its sign then means nothing) or an applied α is not positive; the error
/// says what failed and what to do.
fn placed(
    alpha: &[f64; AXLES],
    alpha_fitted: &[f64; AXLES],
    alpha_fitted_se: &[f64; AXLES],
) -> Result<(), (String, &'static str)> {
    // An α whose error spans its value says so first (its sign then means nothing).
    if let Some(worst) = vague_alpha(alpha_fitted, alpha_fitted_se) {
        return Err((
            format!("the balance cannot place the brake coefficients: α {:.1} ± {:.1} N·m/bar, one standard error {:.0} % of it (at most {:.0} %)", alpha_fitted[worst], alpha_fitted_se[worst], alpha_fitted_se[worst] / alpha_fitted[worst].abs() * 100.0, MAX_CALIBRATED_ALPHA_REL_SE * 100.0),
            "the runs hold too little braking with changing pressures; calibrate on longer brake applications, or estimate with the pipeline's α (estimate.calibration = \"pipeline\")",
        ));
    }
    if alpha.iter().any(|a| !(*a > 0.0)) {
        return Err((
            format!("the balance gives a non-positive brake coefficient {alpha:?}"),
            "check the pressure channels' mapping to the axles and the vehicle's mass",
        ));
    }
    Ok(())
}

/// The running resistance's speed terms c1 (N·s/m) and c2 (N·s²/m²) with their standard
/// errors, and the balance's weighted residual sum of squares (N²) they leave; `fit` is the
/// balance as applied (the pipeline's α with ratio 1 where they are kept) with `sigma2` (N²,
/// a row of weight 1), for the constants.
struct Resistance {
    c: [f64; 2],
    se: [f64; 2],
    rss: f64,
    fit: Fit,
    sigma2: f64,
}

impl Resistance {
    /// The resistance and the residual that go with the α applied: `fit`'s (σ² = `sigma2`), or
    /// with the pipeline's α `kept`, the balance `g` solved again at them
    /// ([`resistance_at_ratio_1`]; `fit`'s where that cannot be solved).
    fn applied(
        fit: &Fit,
        sigma2: f64,
        kept: bool,
        g: &Gram,
        inflate: f64,
        constants: f64,
    ) -> Resistance {
        let k = fit.groups.len();
        let own = || Resistance {
            c: [fit.beta[k], fit.beta[k + 1]],
            se: [
                (sigma2 * fit.var_unit(k)).sqrt(),
                (sigma2 * fit.var_unit(k + 1)).sqrt(),
            ],
            rss: fit.rss,
            fit: fit.clone(),
            sigma2,
        };
        if kept {
            resistance_at_ratio_1(g, inflate, constants).unwrap_or_else(own)
        } else {
            own()
        }
    }
}

/// One run's constant of the balance (N): the running resistance's constant and the run's
/// gradient force, M g i for a gradient i (positive uphill), together — on the balance
/// integrated over time the slope on t − t₀ of the run's −(M v + (J/r) Σ ω) − Σ α_i ∫(1 + γ φ)
/// p_i/r dt − c1 ∫v dt − c2 ∫v² dt, each stretch centred (on the force balance, the run's mean
/// of y − Σ α_i (1 + γ φ) p_i/r − c1 v − c2 v²), with the α as the balance fitted them (before
/// the partial pooling), or the pipeline's where those are kept.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunConstant {
    /// The run's name (the campaign's name for it, else its log's file name).
    pub run: String,
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub constant_n: f64,
    /// One standard error, N: the slope's own (σ²/Σw t² over its rows, σ² with the residuals'
    /// correlation; the mean's σ²/Σw on the force balance) and the fitted coefficients' (x̄ᵀ
    /// Cov x̄ with x̄ the columns' slopes on t, or their means, and γ's column among them: over γ
    /// as c1's error is; where the pipeline's α are kept, with the one common ratio's error),
    /// conditional on the delays.
    #[serde(with = "crate::config::calibrated::nan_as_null")]
    pub se_n: f64,
}

impl Balance<'_> {
    /// Each run's constant at `res`'s fit, with its standard error; with one constant for the
    /// campaign (`per_run` false) every run gets that one. On the force balance the constant
    /// is the weighted mean of the residual y − x·β over the run's rows, c_r = Σ w e / Σ w; on
    /// the integrated balance the slope of the stretch-centred residual on t − t₀, c_r =
    /// Σ w e t / Σ w t². Either is uncorrelated with the other coefficients' estimates (they
    /// are fitted about the runs' means, or with the time columns partialled out), so its
    /// variance is σ²/D + x̄ᵀ (σ² Cov) x̄, D the denominator, x̄ the columns' means (or slopes on
    /// t) with γ's column among them, Cov over γ where the fit has it ([`Fit::combination_var`]).
    fn run_constants(&self, at: &At, form: PadForm, res: &Resistance) -> Vec<RunConstant> {
        let fit = &res.fit;
        let k = fit.beta.len();
        // Per run: D, the numerator, and the columns' sums (the γ column's last).
        let sums: Vec<(f64, f64, Vec<f64>)> = self
            .runs
            .iter()
            .enumerate()
            .map(|(ri, run)| {
                let w = self.weights.get(ri).copied().unwrap_or(1.0);
                let (mut d, mut num, mut sx) = (0.0, 0.0, vec![0.0; k + 1]);
                let mut add = |z: &[f64; Z], by: f64| {
                    d += w * by * by;
                    num += w * (z[Y] - fit.predict(z)) * by;
                    let (x, _) = fit.columns(z);
                    for (s, x) in sx.iter_mut().zip(x) {
                        *s += w * x * by;
                    }
                    sx[k] += w * fit.gamma_column(z) * by;
                };
                if self.integrated {
                    // Centred e and x against centred t: the same as the centred t against
                    // uncentred e and x, which is what `add` sums.
                    let rows = self.integrated_rows(run, at, form);
                    for part in stretches(&rows) {
                        let tm = part.iter().map(|r| r.1).sum::<f64>() / part.len() as f64;
                        for (_, t, z) in part {
                            add(z, t - tm);
                        }
                    }
                } else {
                    for row in &run.rows {
                        if let Some(z) = self.z_row(run, row, at, form) {
                            add(&z, 1.0);
                        }
                    }
                }
                (d, num, sx)
            })
            .collect();
        let constant = |(sw, se, sx): &(f64, f64, Vec<f64>)| {
            let xbar: Vec<f64> = sx.iter().map(|x| x / sw).collect();
            let var = res.sigma2 / sw + res.sigma2 * fit.combination_var(&xbar[..k], xbar[k]);
            (se / sw, var.max(0.0).sqrt())
        };
        let campaign = (!self.per_run).then(|| {
            let mut all = (0.0, 0.0, vec![0.0; k + 1]);
            for (sw, se, sx) in &sums {
                all.0 += sw;
                all.1 += se;
                all.2.iter_mut().zip(sx).for_each(|(a, x)| *a += x);
            }
            constant(&all)
        });
        self.runs
            .iter()
            .zip(&sums)
            .map(|(run, s)| {
                let (c, se) = campaign.unwrap_or_else(|| {
                    if s.0 > 0.0 {
                        constant(s)
                    } else {
                        (f64::NAN, f64::NAN)
                    }
                });
                RunConstant {
                    run: run.name.clone(),
                    constant_n: c,
                    se_n: se,
                }
            })
            .collect()
    }
}

/// The balance solved for the resistance alone with every axle's α at the pipeline's (ratio 1,
/// the pad friction constant): y − Σ_i z_i = c + c1 v + c2 v² (the constants already
/// eliminated in `g`). The standard errors from σ² (XᵀWX)⁻¹ of the balance with one common
/// ratio free, σ² = RSS/dof × `inflate` (n/n_eff) and dof = n − `constants` − 2. None where it
/// cannot be solved.
fn resistance_at_ratio_1(g: &Gram, inflate: f64, constants: f64) -> Option<Resistance> {
    let at = |p: usize, q: usize| g.g[p * Z + q];
    let fixed = 0..AXLES;
    let mut h = g.g.clone();
    for p in (0..Z).filter(|&p| p != Y) {
        let v = at(p, Y) - fixed.clone().map(|i| at(p, i)).sum::<f64>();
        h[p * Z + Y] = v;
        h[Y * Z + p] = v;
    }
    h[Y * Z + Y] = at(Y, Y) - 2.0 * fixed.clone().map(|i| at(i, Y)).sum::<f64>()
        + fixed
            .clone()
            .flat_map(|i| fixed.clone().map(move |j| (i, j)))
            .map(|(i, j)| at(i, j))
            .sum::<f64>();
    let moved = Gram { g: h, n: g.n };
    let cols = [vec![(2 * AXLES, 1.0)], vec![(2 * AXLES + 1, 1.0)]];
    let (beta, _, rss) = moved.solve(&cols)?;
    let n = g.n as f64;
    let sigma2 = rss / (n - constants - 2.0).max(1.0) * inflate;
    // The pipeline's α are kept because one common ratio is within its errors of 1, not
    // because they are known: the errors are those of the balance with that common ratio free
    // (ratio, c1, c2), the values those at ratio 1.
    let common = g.rss_at(&together(), PadForm::Constant, 0.0)?;
    Some(Resistance {
        c: [beta[0], beta[1]],
        se: [
            (sigma2 * common.var_unit(1)).sqrt(),
            (sigma2 * common.var_unit(2)).sqrt(),
        ],
        rss,
        fit: Fit {
            beta: vec![1.0, beta[0], beta[1]],
            rss,
            ..common
        },
        sigma2,
    })
}

/// What the delays' profiles give: the curvatures of the residual sum of squares at the
/// radar's latency and the tachometers' delay (NaN where a delay was taken as 0), and the radar
/// scale's standard error and the runs it rests on.
struct Delays {
    radar_d2: f64,
    tacho_d2: f64,
    /// The delays' jackknife standard errors over runs (s; NaN where not computed).
    jack_se: (f64, f64),
    scale_se: f64,
    scale_runs: usize,
}

/// The largest one-standard-error share of a brake coefficient a campaign's fit may have
/// (the fitted α before pooling): beyond it the balance did not place them. The simulated
/// 12-run campaigns give 0.5–1.6 %; three runs cut to 1.8 s of braking gave 1 900 %, with a
/// resistance of 2.9 MN·s/m to match.
pub const MAX_CALIBRATED_ALPHA_REL_SE: f64 = 0.10;

/// The axle whose fitted α (N·m/bar) has the largest relative standard error beyond
/// [`MAX_CALIBRATED_ALPHA_REL_SE`], if any (a non-finite error counts as beyond).
fn vague_alpha(alpha: &[f64; AXLES], se: &[f64; AXLES]) -> Option<usize> {
    let rel = |a: usize| se[a] / alpha[a].abs();
    (0..AXLES)
        .filter(|&a| !(rel(a) <= MAX_CALIBRATED_ALPHA_REL_SE))
        .max_by(|a, b| rel(*a).total_cmp(&rel(*b)))
}

/// The radar's scale without delays, the two delays at that scale (coordinate descent, three
/// rounds), the scale at those delays; notes for what could not be fitted. With the
/// tachometers' delay known (`known_tacho`, s: half their counting window), only the radar's
/// latency is profiled and tested, the tachometers' delay held.
fn fit_radar_and_delays(
    b: &Balance,
    notes: &mut Vec<String>,
    known_tacho: Option<f64>,
) -> (At, Delays) {
    // The scale without delays; the two delays at that scale (coordinate descent); the
    // scale at those delays.
    let coast_note = "no run coasts before its first brake application, so the radar's scale is not calibrated (taken as 1, the pipeline's radar trusted) and the pad friction's speed law is hard to tell from the running resistance's; log a second or more of coasting before the brake";
    let mut at = At {
        radar_s: 0.0,
        tacho_s: known_tacho.unwrap_or(0.0),
        scale: 1.0,
    };
    match b.radar_scale(&at) {
        Some((s, _, _)) => at.scale = s,
        None => notes.push(coast_note.into()),
    }
    let free = |at: &At| b.gram(at, PadForm::Linear).rss_free();
    let (mut radar_d2, mut tacho_d2) = (f64::NAN, f64::NAN);
    if known_tacho.is_some() {
        (at.radar_s, radar_d2) = profile_delay(LATENCY_RANGE_S, |t| free(&At { radar_s: t, ..at }));
    } else {
        for _ in 0..3 {
            (at.radar_s, radar_d2) =
                profile_delay(LATENCY_RANGE_S, |t| free(&At { radar_s: t, ..at }));
            (at.tacho_s, tacho_d2) =
                profile_delay(TACHO_DELAY_RANGE_S, |t| free(&At { tacho_s: t, ..at }));
        }
    }
    let (scale_se, scale_runs) = match b.radar_scale(&at) {
        Some((s, se, runs)) => {
            at.scale = s;
            (se, runs)
        }
        None => (0.0, 0),
    };
    // A delay at the end of its range is no fit (smooth runs without the wheel-slide
    // protection's pressure changes barely tell delays apart): it is taken as 0.
    // So is one where the balance's residual has no minimum (a curvature that is not
    // positive: runs without pressure changes to time).
    let mut at_edge = false;
    let tacho_fitted = known_tacho.is_none();
    for (name, t, d2, range) in [
        (RADAR_DELAY, &mut at.radar_s, radar_d2, LATENCY_RANGE_S),
        (TACHO_DELAY, &mut at.tacho_s, tacho_d2, TACHO_DELAY_RANGE_S),
    ]
    .into_iter()
    .take(if tacho_fitted { 2 } else { 1 })
    {
        if let Some(note) = unidentified(name, *t, d2, range) {
            notes.push(note);
            *t = 0.0;
            at_edge = true;
        }
    }
    if at_edge {
        // The other delay again with this one at 0 (and checked again), then the scale.
        if at.radar_s != 0.0 {
            (at.radar_s, radar_d2) =
                profile_delay(LATENCY_RANGE_S, |t| free(&At { radar_s: t, ..at }));
            if let Some(note) = unidentified(RADAR_DELAY, at.radar_s, radar_d2, LATENCY_RANGE_S) {
                notes.push(note);
                at.radar_s = 0.0;
            }
        }
        if tacho_fitted && at.tacho_s != 0.0 {
            (at.tacho_s, tacho_d2) =
                profile_delay(TACHO_DELAY_RANGE_S, |t| free(&At { tacho_s: t, ..at }));
            let range = TACHO_DELAY_RANGE_S;
            if let Some(note) = unidentified(TACHO_DELAY, at.tacho_s, tacho_d2, range) {
                notes.push(note);
                at.tacho_s = 0.0;
            }
        }
        if let Some((s, _, _)) = b.radar_scale(&at) {
            at.scale = s;
        }
    }
    let jack = drop_insignificant_delays(b, &mut at, notes, tacho_fitted);
    // No standard error for a delay taken as 0 or held (not fitted).
    let jack = (
        if at.radar_s == 0.0 { f64::NAN } else { jack.0 },
        if at.tacho_s == 0.0 || !tacho_fitted {
            f64::NAN
        } else {
            jack.1
        },
    );
    // The scale's standard error at the final delays.
    let (scale_se, scale_runs) = b
        .radar_scale(&at)
        .map_or((scale_se, scale_runs), |(_, se, runs)| (se, runs));
    if at.radar_s == 0.0 {
        radar_d2 = f64::NAN;
    }
    if at.tacho_s == 0.0 || !tacho_fitted {
        tacho_d2 = f64::NAN;
    }

    (
        at,
        Delays {
            radar_d2,
            tacho_d2,
            jack_se: jack,
            scale_se,
            scale_runs,
        },
    )
}

/// Takes as 0 the fitted delays not told from 0, by two errors: the jackknife's over runs
/// ([`jackknife_delays`]) and the profile's curvature's ([`curvature_cov`], marginal). Both
/// fitted: tested together, the Wald statistic tᵀV⁻¹t — the smaller of the jackknife's and
/// the curvature's — against
/// χ²₂'s 95 % quantile, both taken as 0 below it (one note) and both kept above — the two
/// shift the radar and the wheels against the pressures and are often told apart less well
/// than together. One fitted (or no covariance): |τ| against 1.96 standard errors, the least
/// significant first (each delay's error the larger of the two), the other then profiled
/// again without it and tested again. The radar's
/// scale is fitted again after a drop. Both kept together means a delay near 0 beside a strong
/// one stays (the two shift the same balance; the runs judged their pair). Returns the last
/// jackknife's standard errors (s; NaN where not computed: fewer than 3 runs tell them, or
/// none fitted — and meaningless for a delay taken as 0, which the caller reports as NaN).
/// With `tacho_fitted` false the tachometers' delay is held (known): only the radar's
/// latency is tested.
///
/// Neither error alone is enough. The profile's curvature counts the samples of a run as
/// independent once the residuals' autocorrelation is allowed for, but the radar's noise moves
/// a whole run's delay at once: the runs' spread can be larger (the bundled scenes' latency,
/// 7.1 ms by the jackknife). On runs whose pressures change only when the brake is applied
/// (no wheel-slide protection), 12 runs' spread came out at about a quarter of the curvature's (the
/// tachometers' delay 1.3 against 4.7 ms), kept a delay 16 ms off the truth (Wald 22 by the
/// jackknife alone, 1.7 with the curvature) and made runs up to 1.033× worse.
fn drop_insignificant_delays(
    b: &Balance,
    at: &mut At,
    notes: &mut Vec<String>,
    tacho_fitted: bool,
) -> (f64, f64) {
    let free = |at: &At| b.gram(at, PadForm::Linear).rss_free();
    let mut dropped = false;
    // Delays that neither error could be computed for at the last test.
    let mut untested = (false, false);
    let se = loop {
        let fit = (at.radar_s != 0.0, tacho_fitted && at.tacho_s != 0.0);
        if fit == (false, false) {
            break (f64::NAN, f64::NAN);
        }
        let Some(j) = jackknife_delays(b, at, fit) else {
            break (f64::NAN, f64::NAN);
        };
        let se = (j.var_r.sqrt(), j.var_w.sqrt());
        // The test's errors: the larger of the jackknife's and the curvature's (marginal).
        let curv = j.curvature;
        let floor = curv.map_or((f64::NAN, f64::NAN), |c| (c[0].sqrt(), c[2].sqrt()));
        let tested = (se.0.max(floor.0), se.1.max(floor.1));
        // Both fitted: tested together, by the smaller of the two statistics (the bundled
        // scenes: latency 8.0 ± 7.1 ms and the tachometers' 3.2 ± 3.4 ms, correlated −0.96 —
        // the runs pin down their sum — neither beyond 1.96 standard errors alone, together
        // beyond χ²₂'s quantile; they take 14–16 % off the soap runs' μ error).
        // A fitted delay whose 95 % interval reaches the lower end of its searched range has
        // no minimum the runs place inside it, like one at the end itself: it goes first.
        let ends = (
            reaches_end(at.radar_s, tested.0, fit.0, LATENCY_RANGE_S),
            reaches_end(at.tacho_s, tested.1, fit.1, TACHO_DELAY_RANGE_S),
        );
        let t = (at.radar_s, at.tacho_s);
        let joint = [j.joint, curv.filter(|_| fit == (true, true))]
            .into_iter()
            .flatten()
            .filter_map(|v| wald(v, t))
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let (Some((w, corr)), (true, true), (false, false)) = (joint, fit, ends) {
            if w >= chi2_95(2) {
                break se;
            }
            notes.push(format!(
                "the {RADAR_DELAY} ({:.1} ± {:.1} ms) and the {TACHO_DELAY} ({:.1} ± {:.1} ms) came out, but together they are not told from 0 at 95 % (one standard error: the larger of the runs' scatter, each left out in turn, and the residual's curvature; correlation {corr:+.2}; Wald {w:.2}, the smaller of the two, against χ² {:.2}): both taken as 0",
                at.radar_s * 1e3,
                tested.0 * 1e3,
                at.tacho_s * 1e3,
                tested.1 * 1e3,
                chi2_95(2)
            ));
            at.radar_s = 0.0;
            at.tacho_s = 0.0;
            dropped = true;
            break (f64::NAN, f64::NAN);
        }
        // A delay without either standard error is not tested; one whose interval reaches
        // its range's end counts as 0 standard errors from 0.
        let z = |t: f64, se: f64, on: bool, end: bool| {
            if end {
                0.0
            } else if on && se.is_finite() {
                t.abs() / se
            } else {
                f64::INFINITY
            }
        };
        let (zr, zw) = (
            z(at.radar_s, tested.0, fit.0, ends.0),
            z(at.tacho_s, tested.1, fit.1, ends.1),
        );
        untested = (!tested.0.is_finite(), !tested.1.is_finite());
        let radar_first = !(zr >= zw);
        let (name, t, s, z, end, (lo, hi)) = if radar_first {
            let r = LATENCY_RANGE_S;
            (RADAR_DELAY, &mut at.radar_s, tested.0, zr, ends.0, r)
        } else {
            let r = TACHO_DELAY_RANGE_S;
            (TACHO_DELAY, &mut at.tacho_s, tested.1, zw, ends.1, r)
        };
        if z >= Z95 {
            break se;
        }
        notes.push(dropped_note(name, *t, s, end.then_some((lo, hi))));
        *t = 0.0;
        dropped = true;
        if let Some((s, _, _)) = b.radar_scale(at) {
            at.scale = s;
        }
        // The other delay again without this one, at the scale without it.
        let (other, range, t) = if radar_first {
            (TACHO_DELAY, TACHO_DELAY_RANGE_S, &mut at.tacho_s)
        } else {
            (RADAR_DELAY, LATENCY_RANGE_S, &mut at.radar_s)
        };
        if *t != 0.0 && (tacho_fitted || !radar_first) {
            let base = *at;
            let shifted = |x: f64| {
                if radar_first {
                    At { tacho_s: x, ..base }
                } else {
                    At { radar_s: x, ..base }
                }
            };
            let (t_new, d2) = profile_delay(range, |x| free(&shifted(x)));
            let t = if radar_first {
                &mut at.tacho_s
            } else {
                &mut at.radar_s
            };
            *t = t_new;
            if let Some(note) = unidentified(other, t_new, d2, range) {
                notes.push(note);
                *t = 0.0;
            }
        }
    };
    let tacho_kept = tacho_fitted && at.tacho_s != 0.0;
    for (kept, untested, name, t) in [
        (at.radar_s != 0.0, untested.0, RADAR_DELAY, at.radar_s),
        (tacho_kept, untested.1, TACHO_DELAY, at.tacho_s),
    ] {
        if kept && untested {
            notes.push(format!(
                "the {name} ({:.1} ms) is kept untested: neither the runs' scatter nor the residual's curvature gives it a standard error",
                t * 1e3
            ));
        }
    }
    if dropped {
        if let Some((s, _, _)) = b.radar_scale(at) {
            at.scale = s;
        }
    }
    se
}

/// Whether a fitted delay `t` (s, `on`) with standard error `se` has a 95 % interval that
/// reaches the lower end `lo` (s, negative) of its searched range. A sensor cannot read ahead
/// of the brake pressures, so a delay running off the negative end is the balance's model
/// error or a logger's time stamps, not a fit. The pair case's smooth dry runs: the radar's
/// latency alone at −43 ± 5.6 ms with the tachometers held at their window, where fitted
/// together both ran to the −50 ms end. The upper end is not tested: a long latency well
/// told from 0 (say 170 ± 20 ms) is kept, and one at the end itself is no fit already.
fn reaches_end(t: f64, se: f64, on: bool, (lo, _): (f64, f64)) -> bool {
    on && se.is_finite() && t - lo < Z95 * se
}

/// The note for a delay taken as 0 at `t` ± `se` (s): not told from 0, or (`range` given, s)
/// its interval reaching the range's lower end.
fn dropped_note(name: &str, t: f64, se: f64, range: Option<(f64, f64)>) -> String {
    match range {
        Some((lo, hi)) => format!(
            "the {name} came out at {:.1} ms ± {:.1} ms, its 95 % interval reaching the lower end of the searched range ({:.0}…{:.0} ms; no sensor reads ahead of the pressures): not identifiable from these runs, taken as 0 (check the logger's time stamps)",
            t * 1e3,
            se * 1e3,
            lo * 1e3,
            hi * 1e3
        ),
        None => format!(
            "the {name} came out at {:.1} ms ± {:.1} ms (one standard error: the larger of the runs' scatter, each left out in turn, and the residual's curvature): not told from 0 at 95 %, taken as 0",
            t * 1e3,
            se * 1e3
        ),
    }
}

/// The delays' covariance (s²) from the curvature of the balance's residual at `at`, as the
/// delays are profiled — the free fit (every axle's pressure and its pad term apart, the
/// speed terms, a constant per run): V = 2 σ² (n/n_eff) H⁻¹ with H the residual's Hessian in
/// the fitted delays (`fit`; central differences of 4 ms, the cross term where both are
/// fitted), σ² = RSS/(n − 10 − runs), n_eff the effective samples of the constant pad law's
/// residuals (as [`Balance::run_weights`] fits it). `all(i, j)` is the campaign's residual at
/// the stencil's point (i, j) × 4 ms (the jackknife's pass computes it), `(n, runs)` the rows
/// and the runs holding them. Returned as [var_r, cov, var_w] (NaN for a
/// delay not fitted); each delay's own curvature, uncorrelated, where H has no joint minimum;
/// None where a fitted delay's own curvature is not positive. What the samples' noise alone
/// allows: the runs' scatter ([`jackknife_delays`]) can come out smaller by chance on few
/// runs. Marginal, not conditional: with the two delays correlated (they shift the radar and
/// the wheels against the same pressures) each one's error is larger than its curvature alone
/// says.
fn curvature_cov(
    b: &Balance,
    at: &At,
    fit: (bool, bool),
    (n, runs): (usize, usize),
    all: &dyn Fn(i8, i8) -> f64,
) -> Option<[f64; 3]> {
    let n_rows = n as f64;
    let dof = n_rows - Y as f64 - runs as f64;
    let rss = all(0, 0);
    if !(dof > 0.0 && rss.is_finite()) || fit == (false, false) {
        return None;
    }
    let apart: Vec<Vec<usize>> = (0..AXLES).map(|a| vec![a]).collect();
    let cg = b.gram(at, PadForm::Constant);
    let n_eff = cg
        .rss_at(&apart, PadForm::Constant, 0.0)
        .or_else(|| cg.rss_at(&together(), PadForm::Constant, 0.0))
        .map(|f| b.n_eff(at, PadForm::Constant, &f))?;
    let scale = 2.0 * rss / dof * n_rows / n_eff;
    let (h, f) = (STENCIL_S, all);
    let d2 = |i: i8, j: i8| (f(i, j) - 2.0 * rss + f(-i, -j)) / (h * h);
    let (hr, hw) = (
        if fit.0 { d2(1, 0) } else { f64::NAN },
        if fit.1 { d2(0, 1) } else { f64::NAN },
    );
    match fit {
        (true, true) => {
            let hrw = (f(1, 1) - f(1, -1) - f(-1, 1) + f(-1, -1)) / (4.0 * h * h);
            let det = hr * hw - hrw * hrw;
            if hr > 0.0 && det > 0.0 && det.is_finite() {
                Some([scale * hw / det, -scale * hrw / det, scale * hr / det])
            } else {
                // No joint minimum (or no cross term): each delay's own curvature, which
                // understates the errors but still bounds the jackknife's.
                (hr > 0.0 && hw > 0.0).then(|| [scale / hr, 0.0, scale / hw])
            }
        }
        (true, false) => (hr > 0.0).then(|| [scale / hr, f64::NAN, f64::NAN]),
        _ => (hw > 0.0).then(|| [f64::NAN, f64::NAN, scale / hw]),
    }
}

/// The Wald statistic of both delays `t` = (radar, tachometers) against 0 with the joint
/// matrix `v` = [var_r, cov, var_w], tᵀ V⁻¹ t (χ² with 2 degrees of freedom under "both 0"),
/// and the two delays' correlation; None where V is not positive definite.
fn wald(v: [f64; 3], t: (f64, f64)) -> Option<(f64, f64)> {
    let [vr, c, vw] = v;
    let det = vr * vw - c * c;
    if !(vr > 0.0 && det > 0.0 && det.is_finite()) {
        return None;
    }
    let w = (vw * t.0 * t.0 - 2.0 * c * t.0 * t.1 + vr * t.1 * t.1) / det;
    Some((w, c / (vr * vw).sqrt()))
}

/// The delays' standard errors (s) by the jackknife over runs: each run left out in turn, the
/// fitted delays (`fit`: radar's, tachometers') moved by one Newton step on the other runs'
/// profiled residual (central differences of 4 ms about `at`; a step per delay where the two
/// together have no minimum), var = (R − 1)/R Σ (τ₋ᵣ − τ̄)² over the R runs that hold rows
/// and whose removal leaves a minimum (a NaN variance, no test, where fewer than 3 do); None
/// with fewer than 3 runs.
fn jackknife_delays(b: &Balance, at: &At, fit: (bool, bool)) -> Option<Jackknife> {
    let runs = b.runs.len();
    if runs < 3 || !b.per_run {
        return None;
    }
    let h = STENCIL_S;
    // The stencil's points (i, j) × h about `at`: the centre, ± each fitted delay, and the
    // diagonals for the cross term where both are fitted.
    let mut offsets: Vec<(i8, i8)> = vec![(0, 0)];
    if fit.0 {
        offsets.extend([(1, 0), (-1, 0)]);
    }
    if fit.1 {
        offsets.extend([(0, 1), (0, -1)]);
    }
    if fit == (true, true) {
        offsets.extend([(1, 1), (-1, -1), (1, -1), (-1, 1)]);
    }
    let points: Vec<((i8, i8), Point)> = offsets
        .into_iter()
        .map(|(i, j)| ((i, j), b.point(at, i, j)))
        .collect();
    let get = |i: i8, j: i8| points.iter().find(|(o, _)| *o == (i, j)).map(|(_, p)| p);
    let p0 = get(0, 0).expect("the centre is computed");
    let (f0, informative) = (&p0.without, &p0.held);
    // The whole campaign's residual at a point (NaN where not computed) gives the curvature.
    let all = |i: i8, j: i8| get(i, j).map_or(f64::NAN, |p| p.all);
    let held = informative.iter().filter(|x| **x).count();
    let curvature = curvature_cov(b, at, fit, (p0.n, held), &all);
    // Without each run, the jackknife's (the centre's where not computed).
    let without = |i: i8, j: i8| get(i, j).map_or(f0, |p| &p.without);
    let ((rp, rm), (wp, wm)) = (
        (without(1, 0), without(-1, 0)),
        (without(0, 1), without(0, -1)),
    );
    let cross = (fit == (true, true)).then(|| {
        (
            without(1, 1),
            without(-1, -1),
            without(1, -1),
            without(-1, 1),
        )
    });
    let steps: Vec<(f64, f64)> = (0..runs)
        .map(|r| {
            let newton1 = |fp: f64, fm: f64| {
                let d2 = (fp - 2.0 * f0[r] + fm) / (h * h);
                if d2 > 0.0 {
                    -(fp - fm) / (2.0 * h) / d2
                } else {
                    f64::NAN
                }
            };
            match (fit, &cross) {
                ((true, true), Some((pp, mm, pm, mp))) => {
                    let g = [(rp[r] - rm[r]) / (2.0 * h), (wp[r] - wm[r]) / (2.0 * h)];
                    let h11 = (rp[r] - 2.0 * f0[r] + rm[r]) / (h * h);
                    let h22 = (wp[r] - 2.0 * f0[r] + wm[r]) / (h * h);
                    let h12 = (pp[r] - pm[r] - mp[r] + mm[r]) / (4.0 * h * h);
                    let det = h11 * h22 - h12 * h12;
                    if h11 > 0.0 && det > 0.0 {
                        (
                            -(h22 * g[0] - h12 * g[1]) / det,
                            -(h11 * g[1] - h12 * g[0]) / det,
                        )
                    } else {
                        (newton1(rp[r], rm[r]), newton1(wp[r], wm[r]))
                    }
                }
                ((true, _), _) => (newton1(rp[r], rm[r]), 0.0),
                _ => (0.0, newton1(wp[r], wm[r])),
            }
        })
        .collect();
    let var = |x: fn(&(f64, f64)) -> f64| {
        let vals: Vec<f64> = steps
            .iter()
            .zip(informative)
            .filter(|(_, on)| **on)
            .map(|(s, _)| x(s))
            .filter(|v| v.is_finite())
            .collect();
        if vals.len() < 3 {
            return f64::NAN;
        }
        let n = vals.len() as f64;
        let m = vals.iter().sum::<f64>() / n;
        (n - 1.0) / n * vals.iter().map(|v| (v - m).powi(2)).sum::<f64>()
    };
    let joint = if fit == (true, true) {
        joint_matrix(&steps, informative)
    } else {
        None
    };
    Some(Jackknife {
        var_r: var(|s| s.0),
        var_w: var(|s| s.1),
        joint,
        curvature,
    })
}

/// The delays' finite-difference step (s): the profile's curvature, the jackknife's and the
/// test's stencil.
const STENCIL_S: f64 = 0.004;

/// The balance's profiled residual at one point of the delays' stencil.
struct Point {
    /// The whole campaign's residual sum of squares, and its rows.
    all: f64,
    n: usize,
    /// Without each run in turn.
    without: Vec<f64>,
    /// Whether each run holds rows of the balance.
    held: Vec<bool>,
}

/// The joint test's matrix [var_r, cov, var_w] (s²) of the jackknife's steps (radar's,
/// tachometers'), all three over the runs that hold rows and where both steps are numbers
/// (one set of runs: a covariance matrix by construction); None with fewer than 3 such runs.
fn joint_matrix(steps: &[(f64, f64)], informative: &[bool]) -> Option<[f64; 3]> {
    let both: Vec<(f64, f64)> = steps
        .iter()
        .zip(informative)
        .filter(|(s, on)| **on && s.0.is_finite() && s.1.is_finite())
        .map(|(s, _)| *s)
        .collect();
    if both.len() < 3 {
        return None;
    }
    let n = both.len() as f64;
    let (mr, mw) = (
        both.iter().map(|s| s.0).sum::<f64>() / n,
        both.iter().map(|s| s.1).sum::<f64>() / n,
    );
    let c = |f: &dyn Fn(&(f64, f64)) -> f64| (n - 1.0) / n * both.iter().map(f).sum::<f64>();
    Some([
        c(&|s| (s.0 - mr) * (s.0 - mr)),
        c(&|s| (s.0 - mr) * (s.1 - mw)),
        c(&|s| (s.1 - mw) * (s.1 - mw)),
    ])
}

/// The delays' jackknife variances over runs, s²: the radar's latency, the tachometers' delay
/// (each over the runs where its step is a number), and with both fitted the matrix
/// [var_r, cov, var_w] over the runs where both are (None otherwise).
struct Jackknife {
    var_r: f64,
    var_w: f64,
    joint: Option<[f64; 3]>,
    /// The curvature's covariance [var_r, cov, var_w] (s², [`curvature_cov`]).
    curvature: Option<[f64; 3]>,
}

/// The note for a group of axles fitted with one α.
fn shared_note(group: &[usize]) -> String {
    let names: Vec<String> = group.iter().map(|a| format!("{}", a + 1)).collect();
    let (last, rest) = names.split_last().expect("a shared group has two axles");
    format!(
        "the pressures of axles {} and {last} never differ enough to tell their brake coefficients apart: fitted with one α",
        rest.join(", ")
    )
}

const RADAR_DELAY: &str = "radar's latency";
const TACHO_DELAY: &str = "tachometers' delay";

/// The note for a delay `t` (s) that the runs do not determine — at the end of its searched
/// `range`, or where the profiled residual's curvature `d2` is not positive — else None.
fn unidentified(name: &str, t: f64, d2: f64, (lo, hi): (f64, f64)) -> Option<String> {
    if t <= lo + 1e-3 || t >= hi - 1e-3 {
        Some(format!(
            "the {name} came out at the end of the searched range ({:.0}…{:.0} ms), {:.0} ms: not identifiable from these runs, taken as 0 (check the logger's time stamps)",
            lo * 1e3,
            hi * 1e3,
            t * 1e3
        ))
    } else if !(d2 > 0.0) {
        Some(format!(
            "the {name} came out at {:.0} ms where the balance's residual has no minimum (the runs' pressures barely change, or every axle gets the same pressure): not identifiable from these runs, taken as 0",
            t * 1e3
        ))
    } else {
        None
    }
}

/// The candidate fits at `at` — each pad form with one resistance constant per run or one for
/// the campaign, the axles that separate — and the best by BIC (with a common n_eff: each
/// form's own would move the BIC by more than the fits differ), and whether it has one
/// constant per run.
fn select_model(
    b: &Balance,
    at: &At,
    runs_n: usize,
) -> (Option<(Fit, f64, bool)>, Vec<PadCandidate>) {
    // The pad forms at that latency and scale, with the axles that separate.
    let groups: Vec<Vec<usize>> = (0..AXLES).map(|a| vec![a]).collect();
    // The residuals' autocorrelation, from the constant form with every axle apart, scales
    // the standard errors that decide which axles separate.
    // The forms are compared with this n_eff too (each form's own would move the BIC by
    // more than the fits differ).
    let (inflate, n_eff_common) = {
        let g0 = b.gram(at, PadForm::Constant);
        g0.rss_at(&groups, PadForm::Constant, 0.0)
            .map_or((1.0, g0.n as f64), |f0| {
                let ne = b.n_eff(at, PadForm::Constant, &f0);
                (g0.n as f64 / ne, ne)
            })
    };
    // The running resistance's constant: one per run (a run's gradient), or one for the
    // campaign — chosen with the pad form by the same BIC (per-run constants cost a
    // parameter each, and take the brake force's level with them where a run's pressure
    // barely varies).
    let b_common = Balance {
        per_run: false,
        ..*b
    };
    let mut candidates = Vec::new();
    let mut best: Option<(Fit, f64, bool)> = None;
    for (bb, per_run) in [(b, true), (&b_common, false)] {
        for form in PadForm::ALL {
            // A form that could not be fitted, and why.
            let refused_candidate = |mix: f64, why: String| PadCandidate {
                form,
                mix,
                per_run_constants: per_run,
                gamma: f64::NAN,
                rss: f64::NAN,
                bic: f64::NAN,
                refused: Some(why),
            };
            let (mut mix, g, grams) = if form.mixes() {
                let Some((w, grams, searched)) = best_mix(bb, at, form, &groups) else {
                    candidates.push(refused_candidate(
                        0.0,
                        "no mixture weight gives a fit (the balance's normal matrix is singular)"
                            .into(),
                    ));
                    continue;
                };
                (w, grams.at(w), Some((grams, searched)))
            } else {
                (0.0, bb.gram(at, form), None)
            };
            let (mut fit, mut refused) = g.fit_form(&mut groups.clone(), form, inflate);
            // Where the fit settled on other axle groups than the weight was searched with
            // (axles merged where their α could not be told apart), the weight again with
            // those, and the fit (its groups and refusal) at it.
            if let (Some((grams, searched)), Some(f)) = (&grams, &fit) {
                if f.groups != *searched {
                    if let Some(w) = grams.best(&f.groups, form) {
                        let (again, why) =
                            grams.at(w).fit_form(&mut f.groups.clone(), form, inflate);
                        if again.as_ref().is_some_and(|a| a.rss <= f.rss) {
                            mix = w;
                            (fit, refused) = (again, why);
                        }
                    }
                }
            }
            if form.mixes() && refused.is_none() && mix.min(1.0 - mix) < 1e-3 {
                refused = Some(format!(
                    "w = {mix:.3} is at the end of its range (one of its two powers alone fits as well)"
                ));
            }
            let Some(mut fit) = fit else {
                candidates.push(refused_candidate(
                    mix,
                    refused.unwrap_or_else(|| "the fit failed".into()),
                ));
                continue;
            };
            fit.mix = mix;
            let constants = if per_run { runs_n } else { 1 };
            let k = fit.groups.len()
                + 2
                + usize::from(form != PadForm::Constant)
                + usize::from(form.mixes())
                + constants;
            let n = g.n as f64;
            let bic = n_eff_common * (fit.rss / n).ln() + k as f64 * n_eff_common.ln();
            candidates.push(PadCandidate {
                form,
                mix,
                per_run_constants: per_run,
                gamma: fit.gamma,
                rss: fit.rss,
                bic,
                refused: refused.clone(),
            });
            if refused.is_none() && best.as_ref().is_none_or(|(_, b0, _)| bic < *b0) {
                best = Some((fit, bic, per_run));
            }
        }
    }
    (best, candidates)
}

/// A mixed pad form's weight w (0 ≤ w ≤ 1, [`PadForm::phi`]) that leaves the least residual
/// with γ at its best ([`MixGrams::best`]), the balance's Gram matrices that give it, and the
/// axle groups it was searched with: every axle apart, or one group where that is singular at
/// every w (axles that share a pressure). None where no w gives a fit. [`select_model`]
/// searches again with the groups [`Gram::fit_form`] settles on. The φ columns are affine in w,
/// so every entry of the Gram matrix is a quadratic in w (the constants' elimination included:
/// the force balance's Σ w z zᵀ − (Σ w z)(Σ w z)ᵀ / Σ w, the integrated one's projections on
/// columns free of w; the rows and their weights do not depend on w): three passes over the
/// samples, at w = 0, ½ and 1, give it at every w ([`MixGrams`]).
fn best_mix(
    b: &Balance,
    at: &At,
    form: PadForm,
    groups: &[Vec<usize>],
) -> Option<(f64, MixGrams, Vec<Vec<usize>>)> {
    let grams = MixGrams::new(b, at, form);
    if let Some(w) = grams.best(groups, form) {
        return Some((w, grams, groups.to_vec()));
    }
    let one = together().to_vec();
    let w = grams.best(&one, form)?;
    Some((w, grams, one))
}

/// A balance's Gram matrices at the mixture weights 0, ½ and 1, and so at every w: each entry
/// is a quadratic in w ([`best_mix`]).
struct MixGrams {
    g0: Gram,
    half: Gram,
    g1: Gram,
}

impl MixGrams {
    fn new(b: &Balance, at: &At, form: PadForm) -> MixGrams {
        let pass = |w: f64| Balance { pad_mix: w, ..*b }.gram(at, form);
        MixGrams {
            g0: pass(0.0),
            half: pass(0.5),
            g1: pass(1.0),
        }
    }

    /// The Gram matrix at w: Lagrange's quadratic through (0, G₀), (½, G½), (1, G₁).
    fn at(&self, w: f64) -> Gram {
        let (l0, lh, l1) = (
            (1.0 - w) * (1.0 - 2.0 * w),
            4.0 * w * (1.0 - w),
            w * (2.0 * w - 1.0),
        );
        Gram {
            g: self
                .g0
                .g
                .iter()
                .zip(&self.half.g)
                .zip(&self.g1.g)
                .map(|((a, h), c)| l0 * a + lh * h + l1 * c)
                .collect(),
            n: self.g0.n,
        }
    }

    /// The least-residual w with `groups` and γ at its best: a grid of steps of 0.1, then a
    /// golden section about its best point (to 1e-3) — the residual is a smooth function of w,
    /// but not always unimodal over the whole range. None where no w of the grid gives a fit.
    fn best(&self, groups: &[Vec<usize>], form: PadForm) -> Option<f64> {
        let (w0, r0) = (0..=10)
            .map(|i| {
                let w = f64::from(i) / 10.0;
                (w, self.rss(w, groups, form))
            })
            .fold((0.0, f64::INFINITY), |m, x| if x.1 < m.1 { x } else { m });
        r0.is_finite().then(|| {
            golden(
                &|w| self.rss(w, groups, form),
                (w0 - 0.1).max(0.0),
                (w0 + 0.1).min(1.0),
                1e-3,
            )
        })
    }

    /// The residual at w with `groups` and γ at its best (∞ where the fit is singular).
    fn rss(&self, w: f64, groups: &[Vec<usize>], form: PadForm) -> f64 {
        self.at(w)
            .fit_over_gamma(groups, form)
            .map_or(f64::INFINITY, |f| f.rss)
    }
}

/// The runs with the vehicle's constants.
struct Balance<'a> {
    runs: &'a [RunSignals],
    r: f64,
    inv_r: f64,
    mass: f64,
    j_r: f64,
    v_ref: f64,
    /// One resistance constant per run (else one for the campaign).
    per_run: bool,
    /// The pipeline's α_i, N·m/bar: the balance fits each axle's ratio to it.
    alpha_pipeline: [f64; AXLES],
    /// Each run's weight in the least squares (1/its residual variance, relative), or empty
    /// for equal weights.
    weights: &'a [f64],
    /// The balance integrated over time ([`Balance::integrated_rows`]): momentum against the
    /// forces' impulses, each stretch of consecutive samples with its own constant of
    /// integration. Else the force balance row by row.
    integrated: bool,
    /// The pad friction's mixture weight w for the mixed forms ([`PadForm::phi`]; the other
    /// forms ignore it).
    pad_mix: f64,
}

/// Where the balance is evaluated: the radar's latency and the tachometers' delay (s), and the
/// radar's scale.
#[derive(Debug, Clone, Copy)]
struct At {
    radar_s: f64,
    tacho_s: f64,
    scale: f64,
}

/// Columns of the balance's Gram matrix: α_i,pipeline p_i/r (4), φ α_i,pipeline p_i/r (4), v,
/// v², y.
const Z: usize = 2 * AXLES + 3;
const Y: usize = Z - 1;

/// Series `x` at sample `k` shifted by `shift` samples (linear interpolation; exactly sample
/// k + shift when that is whole), None outside the series or where a sample it reads is not
/// `ok`. Shared by the calibration and the estimation it corrects.
#[inline]
pub(crate) fn shifted(x: &[f64], ok: &[bool], k: usize, shift: f64) -> Option<f64> {
    let pos = k as f64 + shift;
    // Outside the series (also what no index can hold): None, as past its end.
    if !(pos >= 0.0) || pos >= x.len() as f64 {
        return None;
    }
    // pos ≥ 0: truncation is the floor (and needs no libm call).
    let i = pos as usize;
    let f = pos - i as f64;
    if f == 0.0 {
        // On a sample: that sample alone (no neighbour needed).
        return (i < x.len() && ok[i]).then(|| x[i]);
    }
    if i + 1 >= x.len() || !ok[i] || !ok[i + 1] {
        return None;
    }
    Some(x[i] + f * (x[i + 1] - x[i]))
}

impl Balance<'_> {
    /// [`axle_alphas`] on the balance's fit at `at` (`keeps`: whether the pipeline's α stand,
    /// as decided elsewhere), their errors widened by the delays' and the radar scale's own
    /// errors (s, s, –), which the fit holds fixed ([`Balance::alpha_spread`]).
    fn axle_alphas_at(
        &self,
        g: &Gram,
        fit: &Fit,
        sigma2: f64,
        at: &At,
        (keeps, tau_se, tacho_se, scale_se): (Option<bool>, f64, f64, f64),
        notes: &mut Vec<String>,
    ) -> A {
        let a = axle_alphas(g, fit, sigma2, &self.alpha_pipeline, keeps);
        let (mut fitted, mut pooled) =
            self.alpha_spread(fit, at, [tau_se, tacho_se, scale_se], &a.shrink);
        // A moved fit that failed: those errors as the fit gives them, and a note.
        if fitted.iter().chain(&pooled).any(|x| !x.is_finite()) {
            notes.push("the brake coefficients' standard errors leave out the delays' and the radar scale's errors: the balance could not be fitted with them moved by one standard error".into());
            fitted = fitted.map(|x| if x.is_finite() { x } else { 0.0 });
            pooled = pooled.map(|x| if x.is_finite() { x } else { 0.0 });
        }
        a.widened((fitted, pooled), &self.alpha_pipeline)
    }

    /// How far each axle's ratio to the pipeline's α moves when the radar's latency, the
    /// tachometers' delay and the radar's scale each move by one standard error (`se`: s, s, –;
    /// NaN or 0 where not fitted), the model `fit` chose held (its form and axle groups; γ
    /// fitted again): half the central difference per parameter — the delta method. Returns
    /// the fitted ratios' spread and the pooled ones' (each axle's ratio moved by
    /// (1 − B) Δ its group + B Δ the common ratio, with `shrink` = B held). The radar's scale
    /// (from the coasts) is taken as independent of the delays and added in quadrature; the two
    /// delays, whose estimates are strongly correlated when both are fitted (−0.96 on the
    /// bundled scenes), are added with the same sign, an upper bound whatever their
    /// correlation. NaN where a moved fit fails (the caller leaves that share out, with a
    /// note).
    fn alpha_spread(
        &self,
        fit: &Fit,
        at: &At,
        se: [f64; 3],
        shrink: &[f64; AXLES],
    ) -> ([f64; AXLES], [f64; AXLES]) {
        // Each axle's ratio from its group's fit, and the common ratio, at `at`.
        let ratios = |at: &At| -> Option<([f64; AXLES], f64)> {
            let g = self.gram(at, fit.form);
            let f = g.fit_over_gamma(&fit.groups, fit.form)?;
            // The common ratio only where the pooling weighs it.
            let common = if shrink.iter().any(|b| *b > 0.0) {
                g.rss_at(&together(), fit.form, f.gamma)?.beta[0]
            } else {
                0.0
            };
            let mut r = [f64::NAN; AXLES];
            for (gi, grp) in fit.groups.iter().enumerate() {
                for &a in grp {
                    r[a] = f.beta[gi];
                }
            }
            Some((r, common))
        };
        // Per parameter, half the change of each fitted and pooled ratio (None: not fitted).
        let share = |p: usize| -> Option<[[f64; AXLES]; 2]> {
            let e = se[p];
            if !(e > 0.0 && e.is_finite()) {
                return None;
            }
            let moved = |sign: f64| {
                let mut a = *at;
                match p {
                    0 => a.radar_s += sign * e,
                    1 => a.tacho_s += sign * e,
                    _ => a.scale += sign * e,
                }
                ratios(&a)
            };
            let Some(((hi, chi), (lo, clo))) = moved(1.0).zip(moved(-1.0)) else {
                return Some([[f64::NAN; AXLES]; 2]);
            };
            let dc = 0.5 * (chi - clo);
            Some([
                std::array::from_fn(|a| 0.5 * (hi[a] - lo[a])),
                std::array::from_fn(|a| (1.0 - shrink[a]) * 0.5 * (hi[a] - lo[a]) + shrink[a] * dc),
            ])
        };
        let (radar, tacho, scale) = (share(0), share(1), share(2));
        let combine = |k: usize| -> [f64; AXLES] {
            std::array::from_fn(|a| {
                let delays = [radar, tacho]
                    .iter()
                    .flatten()
                    .map(|s| s[k][a].abs())
                    .sum::<f64>();
                delays.hypot(scale.map_or(0.0, |s| s[k][a]))
            })
        };
        (combine(0), combine(1))
    }

    /// One row's z (see [`Z`]) at `at`; None where a shifted signal is not available.
    fn z_row(
        &self,
        run: &RunSignals,
        row: &(usize, [f64; AXLES]),
        at: &At,
        form: PadForm,
    ) -> Option<[f64; Z]> {
        let (k, p) = *row;
        let shift = at.radar_s * run.fs;
        let v = shifted(&run.v_radar, &run.ok, k, shift)? / at.scale;
        let a = shifted(&run.a_radar, &run.ok, k, shift)? / at.scale;
        let wd = shifted(&run.wd_sum, &run.ok, k, at.tacho_s * run.fs)?;
        let phi = form.phi(v, self.v_ref, self.pad_mix);
        let mut z = [0.0; Z];
        for i in 0..AXLES {
            z[i] = self.alpha_pipeline[i] * p[i] * self.inv_r;
            z[AXLES + i] = phi * z[i];
        }
        z[2 * AXLES] = v;
        z[2 * AXLES + 1] = v * v;
        z[Y] = -(self.mass * a + self.j_r * wd);
        Some(z)
    }

    /// The Gram matrix of z with the constants eliminated (per run, or once).
    fn gram(&self, at: &At, form: PadForm) -> Gram {
        if self.integrated {
            return self.integrated_gram(at, form);
        }
        let mut g = vec![0.0; Z * Z];
        let mut n = 0;
        let mut gr = vec![0.0; Z * Z];
        let mut sr = [0.0; Z];
        let mut nr = 0usize;
        // The weights' sum over the rows (a run's rows share its weight).
        let mut wr = 0.0;
        let last = self.runs.len().saturating_sub(1);
        for (ri, run) in self.runs.iter().enumerate() {
            let w = self.weights.get(ri).copied().unwrap_or(1.0);
            nr += self.accumulate(run, w, at, form, (&mut gr, &mut sr, &mut wr));
            if (self.per_run || ri == last) && nr >= 2 {
                n += nr;
                for p in 0..Z {
                    for q in 0..=p {
                        g[p * Z + q] += gr[p * Z + q] - sr[p] * sr[q] / wr;
                    }
                }
            }
            if self.per_run || ri == last {
                gr.fill(0.0);
                sr = [0.0; Z];
                nr = 0;
                wr = 0.0;
            }
        }
        for p in 0..Z {
            for q in 0..p {
                g[q * Z + p] = g[p * Z + q];
            }
        }
        Gram { g, n }
    }

    /// Adds `run`'s rows at `at`, each with weight `w`, to the lower triangle of Σ w z zᵀ (`g`,
    /// Z × Z), to Σ w z (`s`) and to Σ w (`wsum`), row by row; returns the rows added.
    fn accumulate(
        &self,
        run: &RunSignals,
        w: f64,
        at: &At,
        form: PadForm,
        (g, s, wsum): (&mut [f64], &mut [f64; Z], &mut f64),
    ) -> usize {
        let mut n = 0usize;
        for row in &run.rows {
            let Some(z) = self.z_row(run, row, at, form) else {
                continue;
            };
            n += 1;
            *wsum += w;
            for p in 0..Z {
                // w z_p z_q as (w z_p) z_q: the same product, hoisted.
                let wp = w * z[p];
                s[p] += wp;
                for (gq, zq) in g[p * Z..=p * Z + p].iter_mut().zip(&z[..=p]) {
                    *gq += wp * zq;
                }
            }
        }
        n
    }

    /// The profiled residual at the delays' stencil point (i, j) × [`STENCIL_S`] about `at`:
    /// the whole campaign's and without each run in turn, from one pass over the samples
    /// (each run's Gram matrix; a campaign without one run is the sum less that run's).
    fn point(&self, at: &At, i: i8, j: i8) -> Point {
        let a = At {
            radar_s: at.radar_s + f64::from(i) * STENCIL_S,
            tacho_s: at.tacho_s + f64::from(j) * STENCIL_S,
            ..*at
        };
        let grams = self.run_grams(&a, PadForm::Linear);
        let mut total = Gram {
            g: vec![0.0; Z * Z],
            n: 0,
        };
        for g in &grams {
            total.n += g.n;
            total.g.iter_mut().zip(&g.g).for_each(|(t, x)| *t += x);
        }
        let without = grams
            .iter()
            .map(|g| {
                let loo = Gram {
                    g: total.g.iter().zip(&g.g).map(|(t, x)| t - x).collect(),
                    n: total.n - g.n,
                };
                loo.rss_free()
            })
            .collect();
        Point {
            all: total.rss_free(),
            n: total.n,
            without,
            held: grams.iter().map(|g| g.n > 0).collect(),
        }
    }

    /// Each run's Gram matrix of z with its own constant eliminated, G_r = Σ w z zᵀ −
    /// (Σ w z)(Σ w z)ᵀ / Σ w over its rows (a run with fewer than two rows: zero, n = 0); with
    /// one constant per run, [`Self::gram`] is their sum, so a
    /// campaign without one run is the sum less that run's (the delays' jackknife).
    fn run_grams(&self, at: &At, form: PadForm) -> Vec<Gram> {
        // Only the delays' profiles and jackknife use it, on the force balance.
        debug_assert!(!self.integrated, "run_grams is the force balance's");
        let mut grams = Vec::with_capacity(self.runs.len());
        for (ri, run) in self.runs.iter().enumerate() {
            let w = self.weights.get(ri).copied().unwrap_or(1.0);
            let mut g = vec![0.0; Z * Z];
            let mut s = [0.0; Z];
            let mut wr = 0.0;
            let n = self.accumulate(run, w, at, form, (&mut g, &mut s, &mut wr));
            if n < 2 {
                grams.push(Gram {
                    g: vec![0.0; Z * Z],
                    n: 0,
                });
                continue;
            }
            for p in 0..Z {
                for q in 0..=p {
                    g[p * Z + q] -= s[p] * s[q] / wr;
                }
            }
            for p in 0..Z {
                for q in 0..p {
                    g[q * Z + p] = g[p * Z + q];
                }
            }
            grams.push(Gram { g, n });
        }
        grams
    }

    /// The radar's scale from the coasts at latency τ, with its standard error (the larger of
    /// the samples' and the jackknife's over runs) and the runs it rests on; None without a
    /// coast.
    ///
    /// A coasting wheelset is slowed by the rail: the contact force that decelerates its
    /// inertia is a driving one, so it turns slightly faster than it rolls, r ω = v (1 + c d)
    /// with d = −r ω̇ the wheels' deceleration (running resistance; ~1e-4 of the speed at
    /// 200 km/h in the simulator). Pooled over runs whose coasts decelerate differently, the
    /// radar is fitted as v_radar(t + τ) = s r ω̄ − q r ω̄ d (q = s c); with every coast
    /// alike (or one run), as s r ω̄ alone, and the creep stays in s.
    fn radar_scale(&self, at: &At) -> Option<(f64, f64, usize)> {
        let mut used: Vec<Vec<(f64, f64, f64)>> = Vec::new();
        for run in self.runs {
            let rows: Vec<(f64, f64, f64)> = run
                .coast
                .iter()
                .filter_map(|&k| {
                    let v = shifted(&run.v_radar, &run.ok, k, at.radar_s * run.fs)?;
                    let tk = at.tacho_s * run.fs;
                    let w = shifted(&run.w_mean, &run.ok, k, tk)?;
                    let d = -self.r * shifted(&run.wd_sum, &run.ok, k, tk)? / AXLES as f64;
                    Some((w, w * d, v))
                })
                .collect();
            if rows.len() >= 100 / DECIMATE {
                used.push(rows);
            }
        }
        if used.is_empty() {
            return None;
        }
        // Normal equations of v = s x1 − q x2 (x1 = r ω̄, x2 = r ω̄ d).
        let (mut s11, mut s12, mut s22, mut s1y, mut s2y) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (x1, x2, y) in used.iter().flatten() {
            s11 += x1 * x1;
            s12 += x1 * x2;
            s22 += x2 * x2;
            s1y += x1 * y;
            s2y += x2 * y;
        }
        let det = s11 * s22 - s12 * s12;
        // The creep term is fitted when the coasts' decelerations differ: the two regressors
        // then correlate below 0.9999.
        let two = used.len() >= 3 && det > 0.0 && s12 * s12 / (s11 * s22) < 0.9999;
        let (s, q, var_unit) = if two {
            (
                (s22 * s1y - s12 * s2y) / det,
                (s11 * s2y - s12 * s1y) / det,
                s22 / det,
            )
        } else {
            (s1y / s11, 0.0, 1.0 / s11)
        };
        let (mut rss, mut n, mut n_eff) = (0.0, 0usize, 0.0);
        for rows in &used {
            let e: Vec<f64> = rows.iter().map(|(x1, x2, y)| y - s * x1 - q * x2).collect();
            rss += e.iter().map(|x| x * x).sum::<f64>();
            n += e.len();
            n_eff += effective_samples(&e);
        }
        let k = if two { 2.0 } else { 1.0 };
        let se = (rss / (n as f64 - k).max(1.0) * var_unit * n as f64 / n_eff).sqrt();
        // The jackknife over runs (each run's coast left out in turn, the same form): the
        // runs' own scatter, which the samples' count alone understates (a run's coast shares
        // its creep and the delays' errors).
        let runs = used.len();
        // Each fit without one run keeps the full fit's form, so it needs as many runs left
        // as the form has parameters and one more.
        let jack_se = if runs >= if two { 4 } else { 3 } {
            let solve = |t: [f64; 5]| {
                let [a11, a12, a22, a1y, a2y] = t;
                if two {
                    (a22 * a1y - a12 * a2y) / (a11 * a22 - a12 * a12)
                } else {
                    a1y / a11
                }
            };
            let total = [s11, s12, s22, s1y, s2y];
            let loo: Vec<f64> = used
                .iter()
                .map(|rows| {
                    let mut t = total;
                    for (x1, x2, y) in rows {
                        t[0] -= x1 * x1;
                        t[1] -= x1 * x2;
                        t[2] -= x2 * x2;
                        t[3] -= x1 * y;
                        t[4] -= x2 * y;
                    }
                    solve(t)
                })
                .collect();
            let loo: Vec<f64> = loo.into_iter().filter(|x| x.is_finite()).collect();
            let r = loo.len() as f64;
            let m = loo.iter().sum::<f64>() / r;
            if loo.len() >= 3 {
                ((r - 1.0) / r * loo.iter().map(|x| (x - m).powi(2)).sum::<f64>()).sqrt()
            } else {
                f64::NAN
            }
        } else {
            f64::NAN
        };
        Some((s, se.max(jack_se), runs))
    }

    /// Each run's residuals of the balance (unweighted) at a fit: on the force balance before
    /// the run's constant; integrated, after the stretches' and the run's constants.
    fn residuals(&self, at: &At, form: PadForm, fit: &Fit) -> Vec<Vec<f64>> {
        if self.integrated {
            return self.integrated_residuals(at, form, fit);
        }
        self.runs
            .iter()
            .map(|run| {
                run.rows
                    .iter()
                    .filter_map(|row| self.z_row(run, row, at, form))
                    .map(|z| z[Y] - fit.predict(&z))
                    .collect()
            })
            .collect()
    }

    /// Effective samples of the balance's residuals at a fit.
    fn n_eff(&self, at: &At, form: PadForm, fit: &Fit) -> f64 {
        let resid = self.residuals(at, form, fit);
        let mean_of = |e: &[f64]| e.iter().sum::<f64>() / e.len().max(1) as f64;
        let all: Vec<f64> = resid.iter().flatten().copied().collect();
        let global = mean_of(&all);
        let mut total = 0.0;
        for e in &resid {
            if e.len() < 2 {
                continue;
            }
            let c = if self.per_run { mean_of(e) } else { global };
            let e: Vec<f64> = e.iter().map(|x| x - c).collect();
            total += effective_samples(&e);
        }
        total.max(1.0)
    }

    /// Each run's weight for the least squares: the mean over the runs of the residual
    /// variance at `fit` (about the run's own mean) over the run's own, clamped to [0.1, 10].
    /// Runs logged differently (a radar at 100 Hz is four times as noisy after the filter as
    /// one at 417 Hz) would otherwise weigh as much as the rest, and their larger residuals
    /// would read as a scatter between the axles.
    /// The first fit is the constant pad law with every axle apart (one α for all where
    /// that is singular: two axles with one pressure); None when neither can be fitted.
    fn run_weights(&self, at: &At) -> Option<Vec<f64>> {
        let apart: Vec<Vec<usize>> = (0..AXLES).map(|a| vec![a]).collect();
        let form = PadForm::Constant;
        let g = self.gram(at, form);
        let fit = g
            .rss_at(&apart, form, 0.0)
            .or_else(|| g.rss_at(&together(), form, 0.0))?;
        let var: Vec<Option<f64>> = self
            .residuals(at, form, &fit)
            .into_iter()
            .map(|e| {
                (e.len() >= 2).then(|| {
                    let m = e.iter().sum::<f64>() / e.len() as f64;
                    e.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (e.len() - 1) as f64
                })
            })
            .collect();
        let known: Vec<f64> = var.iter().flatten().copied().filter(|v| *v > 0.0).collect();
        if known.is_empty() {
            return None;
        }
        let mean = known.iter().sum::<f64>() / known.len() as f64;
        Some(
            var.iter()
                .map(|v| match v {
                    Some(v) if *v > 0.0 => (mean / v).clamp(0.1, 10.0),
                    _ => 1.0,
                })
                .collect(),
        )
    }
}

/// The time column's index in an integrated row's augmented vector (after z).
const T: usize = Z;
/// Length of an integrated row's augmented vector: z and the time since its stretch began.
const U: usize = Z + 1;

/// Eliminates the time column from a (`U` × `U`) centred Gram matrix (its Schur complement,
/// the run's constant force partialled out) and returns the `Z` × `Z` matrix; a time column
/// without spread leaves the rest as it is.
fn eliminate_time(u: &mut [f64]) -> Vec<f64> {
    let tt = u[T * U + T];
    let mut g = vec![0.0; Z * Z];
    for p in 0..Z {
        for q in 0..Z {
            let cut = if tt > 0.0 {
                u[p * U + T] * u[T * U + q] / tt
            } else {
                0.0
            };
            g[p * Z + q] = u[p * U + q] - cut;
        }
    }
    g
}

/// One row of the integrated balance: its stretch (0, 1, … within the run), the time since
/// the stretch began (s) and the integrated z.
type IntegratedRow = (usize, f64, [f64; Z]);

/// The stretches of [`Balance::integrated_rows`]' rows that hold two or more (a stretch of one
/// row is all its own constant of integration: nothing is left of it for the fit).
fn stretches(rows: &[IntegratedRow]) -> impl Iterator<Item = &[IntegratedRow]> {
    rows.chunk_by(|a, b| a.0 == b.0)
        .filter(|part| part.len() >= 2)
}

impl Balance<'_> {
    /// The balance integrated over time, row by row: with z the force balance's row
    /// ([`Self::z_row`]: y = −(M v̇ + (J/r) Σ ω̇_i) = Σ x_j β_j + c_run), integrating from the
    /// first row of each stretch of consecutive rows t₀ to t gives
    ///
    /// −(M v(t) + (J/r) Σ_i ω_i(t)) = Σ_j β_j ∫_{t₀}^{t} x_j dt + c_run (t − t₀) + K   [N·s]
    ///
    /// with K the stretch's constant of integration (its initial momentum). The integrals are
    /// trapezoids over the rows (every `DECIMATE`-th sample of signals low-passed at the
    /// radar's cut-off). The radar's noise, which the force balance differentiates (its
    /// spectrum rising with frequency), enters here as it is: the slow content of the
    /// pressures — what tells the axles and the pad friction's speed law apart — is measured
    /// against the radar's noise at those frequencies rather than against its derivative's
    /// average over the whole band. A stretch ends where a row is missing (a locked wheel's
    /// settling, a dropout, the end of the data).
    fn integrated_rows(&self, run: &RunSignals, at: &At, form: PadForm) -> Vec<IntegratedRow> {
        let dt = DECIMATE as f64 / run.fs;
        let shift = at.radar_s * run.fs;
        let tacho = at.tacho_s * run.fs;
        let omega_sum = AXLES as f64 * self.inv_r;
        let mut out: Vec<IntegratedRow> = Vec::with_capacity(run.rows.len());
        // The previous row's sample index and force-balance z, and the running integrals.
        let mut prev: Option<(usize, [f64; Z])> = None;
        let mut acc = [0.0; Z];
        let (mut stretch, mut t0) = (0usize, 0usize);
        for row in &run.rows {
            let k = row.0;
            let momentum = shifted(&run.v_radar, &run.ok, k, shift).and_then(|v| {
                shifted(&run.w_mean, &run.ok, k, tacho)
                    .map(|w| -(self.mass * v / at.scale + self.j_r * omega_sum * w))
            });
            let (Some(z), Some(y)) = (self.z_row(run, row, at, form), momentum) else {
                prev = None;
                continue;
            };
            match prev {
                Some((kp, zp)) if k == kp + DECIMATE => {
                    for j in 0..Y {
                        acc[j] += 0.5 * (zp[j] + z[j]) * dt;
                    }
                }
                _ => {
                    if !out.is_empty() {
                        stretch += 1;
                    }
                    acc = [0.0; Z];
                    t0 = k;
                }
            }
            let mut zi = acc;
            zi[Y] = y;
            out.push((stretch, (k - t0) as f64 / run.fs, zi));
            prev = Some((k, z));
        }
        out
    }

    /// A run's integrated rows' Gram matrix of (z, t − t₀) with each stretch's constant of
    /// integration eliminated (each stretch centred), every row of weight `w`, (`U` × `U`), and
    /// the rows in it (stretches of one row give none).
    fn integrated_run_gram(
        &self,
        run: &RunSignals,
        w: f64,
        at: &At,
        form: PadForm,
    ) -> (Vec<f64>, usize) {
        let rows = self.integrated_rows(run, at, form);
        let mut g = vec![0.0; U * U];
        let mut n = 0usize;
        for part in stretches(&rows) {
            let mut gs = vec![0.0; U * U];
            let mut s = [0.0; U];
            for (_, t, z) in part {
                let mut u = [0.0; U];
                u[..Z].copy_from_slice(z);
                u[T] = *t;
                for p in 0..U {
                    let wp = w * u[p];
                    s[p] += wp;
                    for q in 0..=p {
                        gs[p * U + q] += wp * u[q];
                    }
                }
            }
            let ws = w * part.len() as f64;
            for p in 0..U {
                for q in 0..=p {
                    let c = gs[p * U + q] - s[p] * s[q] / ws;
                    g[p * U + q] += c;
                    if q != p {
                        g[q * U + p] += c;
                    }
                }
            }
            n += part.len();
        }
        (g, n)
    }

    /// [`Self::gram`] of the integrated balance: the stretches' constants eliminated, and the
    /// constant force's time column per run (or once for the campaign).
    fn integrated_gram(&self, at: &At, form: PadForm) -> Gram {
        let mut g = vec![0.0; Z * Z];
        let mut total = vec![0.0; U * U];
        let mut n = 0;
        for (ri, run) in self.runs.iter().enumerate() {
            let w = self.weights.get(ri).copied().unwrap_or(1.0);
            let (mut gr, nr) = self.integrated_run_gram(run, w, at, form);
            n += nr;
            if self.per_run {
                g.iter_mut()
                    .zip(eliminate_time(&mut gr))
                    .for_each(|(a, b)| *a += b);
            } else {
                total.iter_mut().zip(&gr).for_each(|(a, b)| *a += b);
            }
        }
        if !self.per_run {
            g = eliminate_time(&mut total);
        }
        Gram { g, n }
    }

    /// Per run, its integrated rows' e₀ = y − x·β and t − t₀ centred on their stretches, as
    /// (stretch-centred e₀, stretch-centred t) pairs.
    fn integrated_centred(&self, at: &At, form: PadForm, fit: &Fit) -> Vec<Vec<(f64, f64)>> {
        self.runs
            .iter()
            .map(|run| {
                let rows = self.integrated_rows(run, at, form);
                let mut out = Vec::with_capacity(rows.len());
                for part in stretches(&rows) {
                    let m = part.len() as f64;
                    let e0: Vec<f64> = part.iter().map(|(_, _, z)| z[Y] - fit.predict(z)).collect();
                    let (em, tm) = (
                        e0.iter().sum::<f64>() / m,
                        part.iter().map(|r| r.1).sum::<f64>() / m,
                    );
                    out.extend(e0.iter().zip(part).map(|(e, r)| (e - em, r.1 - tm)));
                }
                out
            })
            .collect()
    }

    /// Each run's integrated residuals at a fit: the stretches' constants and the run's
    /// constant force (or the campaign's one, `per_run` false) fitted at β and taken out.
    fn integrated_residuals(&self, at: &At, form: PadForm, fit: &Fit) -> Vec<Vec<f64>> {
        let centred = self.integrated_centred(at, form, fit);
        // Per run Σ e t and Σ t²; the slope of their ratio (0 without a spread in t).
        let sums: Vec<(f64, f64)> = centred
            .iter()
            .map(|rows| {
                rows.iter()
                    .fold((0.0, 0.0), |(a, b), (e, t)| (a + e * t, b + t * t))
            })
            .collect();
        let slope = |(et, tt): (f64, f64)| if tt > 0.0 { et / tt } else { 0.0 };
        // The campaign's one slope weighs each run's rows by its weight, as the Gram does.
        let common = (!self.per_run).then(|| {
            slope(
                sums.iter()
                    .enumerate()
                    .fold((0.0, 0.0), |(a, b), (ri, (et, tt))| {
                        let w = self.weights.get(ri).copied().unwrap_or(1.0);
                        (a + w * et, b + w * tt)
                    }),
            )
        });
        centred
            .iter()
            .zip(&sums)
            .map(|(rows, s)| {
                let c = common.unwrap_or_else(|| slope(*s));
                rows.iter().map(|(e, t)| e - c * t).collect()
            })
            .collect()
    }
}

/// The delay minimising `rss(τ)` over `(lo, hi)`: a grid of 5 ms, then golden section within
/// the best cell's neighbours; with the curvature RSS'' there.
fn profile_delay((lo, hi): (f64, f64), rss: impl Fn(f64) -> f64) -> (f64, f64) {
    let step = 0.005;
    let grid: Vec<f64> = (0..=((hi - lo) / step).round() as usize)
        .map(|i| lo + i as f64 * step)
        .collect();
    let vals: Vec<f64> = grid.iter().map(|&t| rss(t)).collect();
    let ib = vals
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map_or(0, |(i, _)| i);
    let a = grid[ib.saturating_sub(1)];
    let b = grid[(ib + 1).min(grid.len() - 1)];
    let t = golden(&rss, a, b, 1e-5);
    let h = STENCIL_S;
    let d2 = (rss(t + h) - 2.0 * rss(t) + rss(t - h)) / (h * h);
    (t, d2)
}

/// What the force balance, row by row, gives beside the delays themselves.
struct ForceBalance {
    /// The delays' standard errors, s (NaN where not fitted, or where no model could be fitted).
    tau_se: f64,
    tacho_se: f64,
    /// Whether the pipeline's α stand ([`axle_alphas`]'s test on this balance); None where
    /// no model could be fitted.
    keeps: Option<bool>,
    /// Its rows, their effective number and its residual's RMS (N) at its fit.
    samples: usize,
    n_eff: f64,
    rms_n: f64,
}

impl ForceBalance {
    /// The force balance `b` at the delays `at` (profiled as `d` says), with the pad form and
    /// constants its own BIC chooses. The delays' errors come from it because they were fitted
    /// on it; and whether the data call for a change from the pipeline's α at all is decided
    /// on it, whose errors are the larger: without pressure differences between the axles the
    /// integrated balance's errors come out too small (the clean mismatch scenes without the
    /// wheel-slide protection: the common α 0.1 % off the truth at 2 of its standard errors, γ
    /// at 3, and runs up to 20 % worse).
    fn at(b: &Balance, at: &At, d: &Delays, runs_n: usize) -> ForceBalance {
        match CampaignCalibrator::coefficients(b, at, runs_n, &mut Vec::new()) {
            Ok(c) => {
                let (tau_se, tacho_se) = parameter_errors(&c.balance(b), at, &c.fit, c.sigma2, d);
                let keeps = axle_alphas(&c.g, &c.fit, c.sigma2, &b.alpha_pipeline, None)
                    .kept
                    .is_some();
                ForceBalance {
                    tau_se,
                    tacho_se,
                    keeps: Some(keeps),
                    samples: c.g.n,
                    n_eff: c.n_eff,
                    rms_n: (c.fit.rss / (c.g.n as f64).max(1.0)).sqrt(),
                }
            }
            Err(_) => ForceBalance {
                tau_se: f64::NAN,
                tacho_se: f64::NAN,
                keeps: None,
                samples: 0,
                n_eff: f64::NAN,
                rms_n: f64::NAN,
            },
        }
    }
}

/// What [`CampaignCalibrator::coefficients`] fits on one form of the balance.
struct Coefficients {
    /// Each run's weight.
    weights: Vec<f64>,
    /// The chosen pad form's fit, with one constant per run (`per_run`) or one for the
    /// campaign.
    fit: Fit,
    per_run: bool,
    candidates: Vec<PadCandidate>,
    /// The chosen balance's Gram matrix, its residuals' effective samples and σ².
    g: Gram,
    n_eff: f64,
    sigma2: f64,
}

impl Coefficients {
    /// `b` as these coefficients were fitted on: weighted, with their constants.
    fn balance<'a>(&'a self, b: &Balance<'a>) -> Balance<'a> {
        Balance {
            weights: &self.weights,
            per_run: self.per_run,
            pad_mix: self.fit.mix,
            ..*b
        }
    }
}

/// One standard error of γ from the curvature of the residual sum of squares at the fit,
/// se² = 2 σ² / RSS'' (0 for the constant form).
fn gamma_error(g: &Gram, fit: &Fit, sigma2: f64) -> f64 {
    if fit.form == PadForm::Constant {
        return 0.0;
    }
    let rss = |gm: f64| {
        g.rss_at(&fit.groups, fit.form, gm)
            .map_or(f64::NAN, |x| x.rss)
    };
    curvature_se(rss, fit.gamma, fit.rss, sigma2)
}

/// se² = 2 σ² / RSS'' of the residual `rss` (NaN where it cannot be fitted) at γ, where it is
/// `centre`: a central difference of step 10⁻³.
fn curvature_se(rss: impl Fn(f64) -> f64, gamma: f64, centre: f64, sigma2: f64) -> f64 {
    let h = 1e-3;
    let d2 = (rss(gamma + h) - 2.0 * centre + rss(gamma - h)) / (h * h);
    (2.0 * sigma2 / d2).sqrt()
}

/// [`gamma_error`], for a mixture with its weight w profiled out: the curvature of
/// min over w of the residual at γ, so γ's error takes in what w trades off against it
/// (at a fixed w it would be too small). `b` is the balance `g` was built from.
fn gamma_error_over_mix(b: &Balance, at: &At, g: &Gram, fit: &Fit, sigma2: f64) -> f64 {
    if !fit.form.mixes() {
        return gamma_error(g, fit, sigma2);
    }
    let grams = MixGrams::new(b, at, fit.form);
    let (lo, hi) = ((fit.mix - 0.2).max(0.0), (fit.mix + 0.2).min(1.0));
    let profile = |gm: f64| {
        let rss = |w: f64| {
            grams
                .at(w)
                .rss_at(&fit.groups, fit.form, gm)
                .map_or(f64::INFINITY, |x| x.rss)
        };
        let r = rss(golden(&rss, lo, hi, 1e-5));
        if r.is_finite() {
            r
        } else {
            f64::NAN
        }
    };
    curvature_se(profile, fit.gamma, profile(fit.gamma), sigma2)
}

/// One standard error of each of the two delays, from the chosen model's residual sum of
/// squares: se² = 2 σ² / RSS'' at the fit (NaN for a delay taken as 0: not fitted), or the
/// jackknife's where that is larger.
fn parameter_errors(b: &Balance, at: &At, fit: &Fit, sigma2: f64, d: &Delays) -> (f64, f64) {
    // The delays' standard errors from the chosen model's residual sum of squares, its
    // curvature at each fitted delay (NaN for a delay taken as 0: not fitted).
    let curvature = |shifted: &dyn Fn(f64) -> At, fitted: bool| {
        if !fitted {
            return f64::NAN;
        }
        let h = STENCIL_S;
        let rss = |x: f64| {
            b.gram(&shifted(x), fit.form)
                .rss_at(&fit.groups, fit.form, fit.gamma)
                .map_or(f64::NAN, |f| f.rss)
        };
        (rss(h) - 2.0 * fit.rss + rss(-h)) / (h * h)
    };
    let radar_d2 = curvature(
        &|x| At {
            radar_s: at.radar_s + x,
            ..*at
        },
        d.radar_d2.is_finite(),
    );
    let tacho_d2 = curvature(
        &|x| At {
            tacho_s: at.tacho_s + x,
            ..*at
        },
        d.tacho_d2.is_finite(),
    );
    // The larger of the curvature's and the jackknife's (the runs' own scatter).
    let tau_se = (2.0 * sigma2 / radar_d2).sqrt().max(d.jack_se.0);
    let tacho_se = (2.0 * sigma2 / tacho_d2).sqrt().max(d.jack_se.1);
    (tau_se, tacho_se)
}

/// The axles' α from a fit: each group's ratio to the pipeline's α with its standard error
/// (σ² the residual variance, inflated), partially pooled ([`partial_pooling`]) when there
/// are several groups, times the pipeline's α_i.
struct A {
    alpha: [f64; AXLES],
    alpha_se: [f64; AXLES],
    fitted: [f64; AXLES],
    fitted_se: [f64; AXLES],
    /// Between-axle spread of the α (1σ, N·m/bar: the ratios' times the pipeline's mean α).
    between_sd: Option<f64>,
    /// The note when the ratios agreed with 1 and the pipeline's α were kept.
    kept: Option<String>,
    /// Each axle's weight on the common ratio in the partial pooling (0 without pooling).
    shrink: [f64; AXLES],
}

impl A {
    /// The standard errors with the shares of other parameters' errors added in quadrature
    /// (ratios to `alpha_pipeline`, [`Balance::alpha_spread`]): `fitted` to the fitted α's,
    /// `pooled` to the partially pooled ones.
    fn widened(
        self,
        (fitted, pooled): ([f64; AXLES], [f64; AXLES]),
        alpha_pipeline: &[f64; AXLES],
    ) -> A {
        let widen = |se: [f64; AXLES], by: [f64; AXLES]| -> [f64; AXLES] {
            std::array::from_fn(|a| se[a].hypot(by[a] * alpha_pipeline[a]))
        };
        A {
            alpha_se: widen(self.alpha_se, pooled),
            fitted_se: widen(self.fitted_se, fitted),
            ..self
        }
    }
}

/// `keep`: whether the pipeline's α stand, decided elsewhere (None: by this fit's own test,
/// below).
fn axle_alphas(
    g: &Gram,
    fit: &Fit,
    sigma2: f64,
    alpha_pipeline: &[f64; AXLES],
    keep: Option<bool>,
) -> A {
    let groups = &fit.groups;
    let mut ratio = [f64::NAN; AXLES];
    let mut ratio_se = [f64::NAN; AXLES];
    for (gi, grp) in groups.iter().enumerate() {
        for &a in grp {
            ratio[a] = fit.beta[gi];
            ratio_se[a] = (sigma2 * fit.var_unit(gi)).sqrt();
        }
    }
    let times = |r: &[f64; AXLES]| std::array::from_fn(|a| r[a] * alpha_pipeline[a]);
    let (fitted, fitted_se) = (times(&ratio), times(&ratio_se));
    let common = g.rss_at(&together(), fit.form, fit.gamma);
    let mut between_sd = None;
    let mut shrink = [0.0; AXLES];
    if groups.len() > 1 {
        if let Some(common) = &common {
            let common_se = (sigma2 * common.var_unit(0)).sqrt();
            // The groups differ when one common ratio fits significantly worse: the
            // likelihood ratio (RSS_common − RSS)/σ² against χ² with groups − 1 degrees of
            // freedom (it takes the ratios' correlations into account, which a sum of squared
            // z-scores would not: their sum is determined far better than their differences).
            let differ = (common.rss - fit.rss) / sigma2 > chi2_95(groups.len() - 1);
            let p = partial_pooling(groups, &ratio, &ratio_se, common.beta[0], common_se, differ);
            ratio = p.alpha;
            ratio_se = p.alpha_se;
            shrink = p.shrink;
            between_sd = Some(p.between_sd);
        }
    }
    // One ratio for all axles that, with the pad law's γ, does not differ from (1, 0) by
    // more than their errors: the pipeline's α stand, the pad friction constant (a change the
    // data do not call for only adds the fit's noise to every estimate). The likelihood ratio
    // of the common ratio's fit against ratio 1 and γ = 0 (the resistance free in both), with
    // one degree of freedom for the ratio, one for γ where the form has it and one for a
    // mixture's weight — for the constant form the same test as |ratio − 1| ≤ 1.96 standard
    // errors.
    let one_ratio = between_sd.is_none_or(|sd| sd == 0.0);
    let free = 1 + usize::from(fit.form != PadForm::Constant) + usize::from(fit.form.mixes());
    let at_pipeline = resistance_at_ratio_1(g, 1.0, 1.0).map(|r| r.rss);
    let kept = keep.unwrap_or_else(|| {
        one_ratio
            && common
                .as_ref()
                .zip(at_pipeline)
                .is_some_and(|(c, rss1)| (rss1 - c.rss) / sigma2 <= chi2_95(free))
    });
    if kept {
        ratio = [1.0; AXLES];
    }
    let mean_pipeline = alpha_pipeline.iter().sum::<f64>() / AXLES as f64;
    A {
        alpha: times(&ratio),
        alpha_se: times(&ratio_se),
        fitted,
        fitted_se,
        between_sd: between_sd.map(|sd| sd * mean_pipeline),
        shrink,
        kept: kept.then(|| {
            "the brake coefficients agree with the pipeline's within their errors (one ratio for all axles, not told from 1, and no speed term of the pad friction, at 95 %): the pipeline's α kept, the pad friction constant".to_string()
        }),
    }
}

/// The two-sided 95 % quantile of the standard normal distribution.
const Z95: f64 = 1.959_964;

/// Per-axle α after partial pooling.
struct Pooled {
    alpha: [f64; AXLES],
    alpha_se: [f64; AXLES],
    between_sd: f64,
    /// Each axle's weight on the common ratio, B = se²/(se² + τ²) (1: fully pooled).
    shrink: [f64; AXLES],
}

/// Partial pooling of the groups' α toward the common α (empirical Bayes, the normal–normal
/// model with the between-axle variance by the method of moments): τ² = max(0, s² − mean
/// se_g²) from the sample variance s² of the k groups' α̂_g about the common ᾱ; each α̂_g
/// moves toward ᾱ by B_g = se_g²/(se_g² + τ²), α_g = α̂_g − B_g (α̂_g − ᾱ).
/// Where the axles' α differ by no more than their errors (a brake rig as the pipeline says)
/// they end at the common α, which the balance determines far better than the differences; a
/// real scatter shifts them less.
///
/// The standard errors take the uncertainty of τ² itself into account ([`pooled_se`]): at a
/// known τ² an axle's error would be ((1 − B_g) se_g² + B_g² se_ᾱ²)^½, which with τ² = 0 is
/// the common α's alone — too small where four axles cannot tell a small scatter from none.
///
/// τ² is taken as 0 unless the groups `differ` significantly (the caller's test: the
/// balance's likelihood ratio of one common α against the groups', at 95 % — the role of
/// Cochran's heterogeneity test, *Biometrics* 10, 1954, with the estimates' correlations
/// taken into account). Without the test, the moments' τ² comes out positive for about half
/// of all brake rigs without any scatter (s² exceeds the mean se² by chance), and each axle
/// then keeps its α̂'s noise.
fn partial_pooling(
    groups: &[Vec<usize>],
    alpha: &[f64; AXLES],
    alpha_se: &[f64; AXLES],
    common: f64,
    common_se: f64,
    differ: bool,
) -> Pooled {
    let k = groups.len() as f64;
    let (mut s2, mut se2) = (0.0, 0.0);
    for grp in groups {
        let a = grp[0];
        s2 += (alpha[a] - common).powi(2);
        se2 += alpha_se[a].powi(2);
    }
    let tau2 = if differ {
        (s2 / (k - 1.0) - se2 / k).max(0.0)
    } else {
        0.0
    };
    let mut out = Pooled {
        alpha: *alpha,
        alpha_se: *alpha_se,
        between_sd: tau2.sqrt(),
        shrink: [0.0; AXLES],
    };
    let fitted: Vec<(f64, f64)> = groups
        .iter()
        .map(|grp| (alpha[grp[0]], alpha_se[grp[0]]))
        .collect();
    for (grp, &(a_hat, se_g)) in groups.iter().zip(&fitted) {
        let v = se_g * se_g;
        let b = if v + tau2 > 0.0 { v / (v + tau2) } else { 1.0 };
        let pooled = a_hat - b * (a_hat - common);
        let se = pooled_se(&fitted, (a_hat, se_g), pooled, (common, common_se), tau2);
        for &i in grp {
            out.alpha[i] = pooled;
            out.alpha_se[i] = se;
            out.shrink[i] = b;
        }
    }
    out
}

/// Points of [`pooled_se`]'s quadrature over τ.
const TAU_POINTS: usize = 4000;

/// The scale of [`pooled_se`]'s half-Cauchy prior on the between-axle spread τ of the ratios
/// to the pipeline's α (dimensionless: 5 %). Weakly informative: flat within a few per cent
/// (railgrip's choice; a rig whose axles' brakes differ by more than that is assumed unusual,
/// not excluded).
const TAU_PRIOR_SCALE: f64 = 0.05;

/// One standard error of a pooled group's ratio to the pipeline's α that includes the
/// between-axle variance's own uncertainty: the root of the posterior mean squared error of the
/// `reported` value, E_τ[V(τ) + (E(τ) − reported)²], with E(τ) = α̂ − B(τ)(α̂ − common) and
/// V(τ) = (1 − B(τ)) se² + B(τ)² common_se² the group's posterior mean and variance at a
/// known τ (B(τ) = se²/(se² + τ²)), and τ's posterior from the `fitted` groups' (α̂_g, se_g)
/// under α̂_g ~ N(common, se_g² + τ²) — the hierarchical normal model's marginal likelihood
/// (Gelman et al., *Bayesian Data Analysis*, 3rd ed. 2013, eq. 5.21, with the common ratio
/// taken as known, since the balance fits it far better than the groups, and the groups'
/// estimates as independent) — times a half-Cauchy prior of scale [`TAU_PRIOR_SCALE`], the
/// family Gelman recommends when the groups are few (*Bayesian Analysis* 1, 2006, 515–533).
/// Quadrature: the midpoint rule in u = τ/(s + τ) ∈ [0, 1), s the groups' root mean square
/// se_g, [`TAU_POINTS`] points. Where a group's error is not a positive number (the posterior
/// would not be integrable at τ = 0), the error at the moments' `tau2` instead.
fn pooled_se(
    fitted: &[(f64, f64)],
    (a_hat, se): (f64, f64),
    reported: f64,
    (common, common_se): (f64, f64),
    tau2: f64,
) -> f64 {
    let v = se * se;
    let at = |tau2: f64| {
        let b = if v + tau2 > 0.0 { v / (v + tau2) } else { 1.0 };
        let mean = a_hat - b * (a_hat - common);
        (1.0 - b) * v + b * b * common_se * common_se + (mean - reported).powi(2)
    };
    if !fitted
        .iter()
        .all(|(a, e)| *e > 0.0 && e.is_finite() && a.is_finite())
    {
        return at(tau2).sqrt();
    }
    let s = (fitted.iter().map(|(_, e)| e * e).sum::<f64>() / fitted.len() as f64).sqrt();
    let log_post = |tau: f64| {
        let lik: f64 = fitted
            .iter()
            .map(|(a, e)| {
                let w = e * e + tau * tau;
                -0.5 * w.ln() - (a - common).powi(2) / (2.0 * w)
            })
            .sum();
        lik - (1.0 + (tau / TAU_PRIOR_SCALE).powi(2)).ln()
    };
    let nodes: Vec<(f64, f64)> = (0..TAU_POINTS)
        .map(|j| {
            let u = (j as f64 + 0.5) / TAU_POINTS as f64;
            let tau = s * u / (1.0 - u);
            // ln of the posterior density times dτ/du = s/(1 − u)².
            (tau, log_post(tau) + (s / ((1.0 - u) * (1.0 - u))).ln())
        })
        .collect();
    let top = nodes
        .iter()
        .map(|(_, l)| *l)
        .fold(f64::NEG_INFINITY, f64::max);
    let (mut wsum, mut msum) = (0.0, 0.0);
    for (tau, l) in nodes {
        let w = (l - top).exp();
        wsum += w;
        msum += w * at(tau * tau);
    }
    (msum / wsum).sqrt()
}

/// The 95 % quantile of χ² with `dof` degrees of freedom (1 ≤ dof ≤ AXLES − 1; standard
/// tables, e.g. Abramowitz & Stegun 1964, table 26.8).
fn chi2_95(dof: usize) -> f64 {
    const Q: [f64; 3] = [3.841_459, 5.991_465, 7.814_728];
    Q[dof.clamp(1, Q.len()) - 1]
}

/// Golden-section minimum of `f` on [a, b].
fn golden(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64, tol: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    while (b - a).abs() > tol {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    (a + b) / 2.0
}

/// Within-run Gram matrix of the z columns and its sample count.
struct Gram {
    g: Vec<f64>,
    n: usize,
}

/// A fit of the balance: coefficients (one ratio to the pipeline's α per group, c1, c2), γ,
/// the weighted RSS and the unscaled variances (diagonal of (XᵀWX)⁻¹).
#[derive(Debug, Clone)]
struct Fit {
    form: PadForm,
    /// A mixture's weight w (the balance's [`Balance::pad_mix`] it was fitted on; 0 for the
    /// other forms): set where the form is chosen ([`select_model`]).
    mix: f64,
    groups: Vec<Vec<usize>>,
    gamma: f64,
    beta: Vec<f64>,
    /// (XᵀWX)⁻¹ of the fit's columns (groups' α, c1, c2), row-major: σ² times it is β's
    /// covariance — after [`Fit::over_gamma`], the block of β in the joint inverse with γ.
    cov: Vec<f64>,
    /// After [`Fit::over_gamma`]: the joint inverse of the fit's columns and ∂x·β/∂γ (last),
    /// row-major.
    joint: Option<Vec<f64>>,
    /// Correlations between the groups' α estimates (groups × groups).
    corr: Vec<f64>,
    rss: f64,
}

impl Fit {
    /// The fit's columns x at a z row (each group's Σ (z_a + γ φ z_a), v, v²) and how many
    /// there are (groups + 2).
    fn columns(&self, z: &[f64; Z]) -> ([f64; AXLES + 2], usize) {
        let mut x = [0.0; AXLES + 2];
        let k = self.groups.len();
        for (xg, grp) in x.iter_mut().zip(&self.groups) {
            *xg = grp.iter().map(|&a| z[a] + self.gamma * z[AXLES + a]).sum();
        }
        x[k] = z[2 * AXLES];
        x[k + 1] = z[2 * AXLES + 1];
        (x, k + 2)
    }

    /// x·β for a z row (the run constant excluded), summed in column order.
    fn predict(&self, z: &[f64; Z]) -> f64 {
        let (x, n) = self.columns(z);
        x[..n]
            .iter()
            .zip(&self.beta)
            .fold(0.0, |s, (x, b)| s + b * x)
    }

    /// The unscaled variance of coefficient `i`: the diagonal of (XᵀWX)⁻¹.
    fn var_unit(&self, i: usize) -> f64 {
        self.cov[i * self.beta.len() + i]
    }

    /// ∂(x·β)/∂γ at a z row: Σ_g β_g Σ_{a∈g} φ z_a.
    fn gamma_column(&self, z: &[f64; Z]) -> f64 {
        self.groups
            .iter()
            .zip(&self.beta)
            .map(|(grp, b)| b * grp.iter().map(|&a| z[AXLES + a]).sum::<f64>())
            .sum()
    }

    /// The unscaled variance of a linear combination x̄·β + x̄_γ γ of the fitted coefficients
    /// (a run constant's share of the coefficients' errors): over γ where the fit has the joint
    /// inverse ([`Fit::over_gamma`]), else at the fitted γ.
    fn combination_var(&self, xbar: &[f64], xg: f64) -> f64 {
        let k = self.beta.len();
        match &self.joint {
            Some(j) => {
                let x = |p: usize| if p < k { xbar[p] } else { xg };
                (0..=k)
                    .flat_map(|p| (0..=k).map(move |q| (p, q)))
                    .map(|(p, q)| x(p) * j[p * (k + 1) + q] * x(q))
                    .sum()
            }
            None => (0..k)
                .flat_map(|p| (0..k).map(move |q| (p, q)))
                .map(|(p, q)| xbar[p] * self.cov[p * k + q] * xbar[q])
                .sum(),
        }
    }

    /// The fit with its coefficients' covariance taken over γ too (the fit's columns and
    /// ∂x·β/∂γ = Σ_g β_g Σ_{a∈g} φ z_a solved together on `g`, the block of the coefficients
    /// kept): at a fixed γ the errors of c1 and c2, which the pad law's speed term trades off
    /// against, are too small. As it is for the constant form or where the joint matrix is
    /// singular.
    fn over_gamma(self, g: &Gram) -> Fit {
        if self.form == PadForm::Constant {
            return self;
        }
        let mut cols: Vec<Vec<(usize, f64)>> = self
            .groups
            .iter()
            .map(|grp| {
                grp.iter()
                    .flat_map(|&a| [(a, 1.0), (AXLES + a, self.gamma)])
                    .collect()
            })
            .collect();
        cols.push(vec![(2 * AXLES, 1.0)]);
        cols.push(vec![(2 * AXLES + 1, 1.0)]);
        cols.push(
            self.groups
                .iter()
                .zip(&self.beta)
                .flat_map(|(grp, b)| grp.iter().map(move |&a| (AXLES + a, *b)))
                .collect(),
        );
        let Some((_, inv, _)) = g.solve(&cols) else {
            return self;
        };
        let (k, kj) = (self.beta.len(), cols.len());
        debug_assert_eq!(kj, k + 1);
        let cov: Vec<f64> = (0..k * k).map(|i| inv[(i / k) * kj + i % k]).collect();
        let ng = self.groups.len();
        let mut corr = vec![0.0; ng * ng];
        for p in 0..ng {
            for q in 0..ng {
                corr[p * ng + q] = cov[p * k + q] / (cov[p * k + p] * cov[q * k + q]).sqrt();
            }
        }
        Fit {
            cov,
            corr,
            joint: Some(inv),
            ..self
        }
    }
}

impl Gram {
    /// Least squares with every z column free (α_i and α_i γ_i separately): the latency's
    /// profile, which does not depend on the pad form.
    fn rss_free(&self) -> f64 {
        let k = Y;
        let cols: Vec<Vec<(usize, f64)>> = (0..k).map(|c| vec![(c, 1.0)]).collect();
        self.solve(&cols).map_or(f64::NAN, |(_, _, rss)| rss)
    }

    /// Solves for columns x_c = Σ w z_j (`cols`); returns β, (XᵀX)⁻¹ and the RSS. None when
    /// XᵀX is not positive definite.
    fn solve(&self, cols: &[Vec<(usize, f64)>]) -> Option<(Vec<f64>, Vec<f64>, f64)> {
        let k = cols.len();
        let gz = |p: usize, q: usize| self.g[p * Z + q];
        let mut a = vec![0.0; k * k];
        let mut rhs = vec![0.0; k];
        for (c, cc) in cols.iter().enumerate() {
            for (&(p, wp), _) in cc.iter().zip(0..) {
                rhs[c] += wp * gz(p, Y);
            }
            for (d, cd) in cols.iter().enumerate() {
                let mut s = 0.0;
                for &(p, wp) in cc {
                    for &(q, wq) in cd {
                        s += wp * wq * gz(p, q);
                    }
                }
                a[c * k + d] = s;
            }
        }
        // Standardise so the pivots measure conditioning, not units.
        let sc: Vec<f64> = (0..k)
            .map(|c| a[c * k + c].sqrt().max(f64::MIN_POSITIVE))
            .collect();
        let mut an = a.clone();
        for p in 0..k {
            for q in 0..k {
                an[p * k + q] /= sc[p] * sc[q];
            }
        }
        let l = cholesky(&an, k)?;
        let (dmin, dmax) = (0..k)
            .map(|p| l[p * k + p])
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), d| {
                (lo.min(d), hi.max(d))
            });
        if !((dmax / dmin).powi(2) < 1e12) {
            return None;
        }
        let rn: Vec<f64> = (0..k).map(|c| rhs[c] / sc[c]).collect();
        let bn = cho_solve(&l, k, &rn);
        let beta: Vec<f64> = (0..k).map(|c| bn[c] / sc[c]).collect();
        let rss = gz(Y, Y) - beta.iter().zip(&rhs).map(|(b, r)| b * r).sum::<f64>();
        let mut inv = vec![0.0; k * k];
        for c in 0..k {
            let mut e = vec![0.0; k];
            e[c] = 1.0;
            let col = cho_solve(&l, k, &e);
            for d in 0..k {
                inv[d * k + c] = col[d] / (sc[d] * sc[c]);
            }
        }
        Some((beta, inv, rss.max(0.0)))
    }

    /// The fit at a given γ.
    fn rss_at(&self, groups: &[Vec<usize>], form: PadForm, gamma: f64) -> Option<Fit> {
        let mut cols: Vec<Vec<(usize, f64)>> = groups
            .iter()
            .map(|grp| {
                grp.iter()
                    .flat_map(|&a| [(a, 1.0), (AXLES + a, gamma)])
                    .collect()
            })
            .collect();
        cols.push(vec![(2 * AXLES, 1.0)]);
        cols.push(vec![(2 * AXLES + 1, 1.0)]);
        let (beta, inv, rss) = self.solve(&cols)?;
        let k = cols.len();
        let ng = groups.len();
        let mut corr = vec![0.0; ng * ng];
        for p in 0..ng {
            for q in 0..ng {
                corr[p * ng + q] = inv[p * k + q] / (inv[p * k + p] * inv[q * k + q]).sqrt();
            }
        }
        Some(Fit {
            form,
            mix: 0.0,
            groups: groups.to_vec(),
            gamma,
            cov: inv,
            joint: None,
            beta,
            corr,
            rss,
        })
    }

    /// The fit with `groups` at the best γ for `form` (golden section over [`GAMMA_RANGE`];
    /// 0 for the constant form).
    fn fit_over_gamma(&self, groups: &[Vec<usize>], form: PadForm) -> Option<Fit> {
        if form == PadForm::Constant {
            return self.rss_at(groups, form, 0.0);
        }
        let rss = |g: f64| {
            self.rss_at(groups, form, g)
                .map_or(f64::INFINITY, |x| x.rss)
        };
        let gamma = golden(&rss, GAMMA_RANGE.0, GAMMA_RANGE.1, 1e-6);
        self.rss_at(groups, form, gamma)
    }

    /// The best γ for `form` (0 for the constant form), merging axles whose α cannot be told
    /// apart ([`MAX_ALPHA_REL_SE`]); the second value says why the form is refused, if it is.
    fn fit_form(
        &self,
        groups: &mut Vec<Vec<usize>>,
        form: PadForm,
        inflate: f64,
    ) -> (Option<Fit>, Option<String>) {
        loop {
            let Some(fit) = self.fit_over_gamma(groups, form) else {
                if groups.len() > 1 {
                    merge_first(groups, None);
                    continue;
                }
                return (None, Some("the balance's normal matrix is singular".into()));
            };
            // Relative standard error of each group's α.
            let sigma2 = fit.rss / (self.n as f64).max(1.0) * inflate;
            let worst = (0..groups.len())
                .map(|gi| ((sigma2 * fit.var_unit(gi)).sqrt() / fit.beta[gi].abs(), gi))
                .fold((0.0f64, 0usize), |m, x| {
                    if x.0 > m.0 || x.0.is_nan() {
                        x
                    } else {
                        m
                    }
                });
            if groups.len() > 1 && (worst.0 > MAX_ALPHA_REL_SE || worst.0.is_nan()) {
                merge_first(groups, Some((worst.1, fit.corr_partner(worst.1))));
                continue;
            }
            let refused = (form != PadForm::Constant
                && (fit.gamma - GAMMA_RANGE.0)
                    .abs()
                    .min((fit.gamma - GAMMA_RANGE.1).abs())
                    < 1e-3)
                .then(|| format!("γ = {:.3} is at the end of the searched range", fit.gamma));
            return (Some(fit), refused);
        }
    }
}

impl Fit {
    fn corr_partner(&self, gi: usize) -> usize {
        let ng = self.groups.len();
        (0..ng)
            .filter(|&q| q != gi)
            .min_by(|&p, &q| self.corr[gi * ng + p].total_cmp(&self.corr[gi * ng + q]))
            .unwrap_or(0)
    }
}

/// Every axle in one group (one common ratio).
fn together() -> [Vec<usize>; 1] {
    [(0..AXLES).collect()]
}

/// Merges two groups (the given pair, or the first two).
fn merge_first(groups: &mut Vec<Vec<usize>>, pair: Option<(usize, usize)>) {
    let (a, b) = pair.unwrap_or((0, 1));
    let (lo, hi) = (a.min(b), a.max(b));
    let moved = groups.remove(hi);
    groups[lo].extend(moved);
    groups[lo].sort_unstable();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn groups() -> Vec<Vec<usize>> {
        (0..AXLES).map(|a| vec![a]).collect()
    }

    /// At no delays and scale 1.
    const AT_0: At = At {
        radar_s: 0.0,
        tacho_s: 0.0,
        scale: 1.0,
    };

    /// The tests' vehicle: wheel radius (m) and mass (kg).
    const R_M: f64 = 0.46;
    const MASS_KG: f64 = 40_000.0;

    /// The tests' balance: [`R_M`], [`MASS_KG`], no axle inertia, top speed 55 m/s.
    fn test_balance<'a>(
        runs: &'a [RunSignals],
        weights: &'a [f64],
        alpha: [f64; AXLES],
        per_run: bool,
        integrated: bool,
    ) -> Balance<'a> {
        Balance {
            runs,
            r: R_M,
            inv_r: 1.0 / R_M,
            mass: MASS_KG,
            j_r: 0.0,
            v_ref: 55.0,
            per_run,
            alpha_pipeline: alpha,
            weights,
            integrated,
            pad_mix: 0.0,
        }
    }

    /// Run `ri` of `n` samples at 100 Hz, every sample valid, the wheels' terms zero; no radar
    /// samples, rows, coast or troughs yet.
    fn test_run(ri: usize, n: usize) -> RunSignals {
        RunSignals {
            name: format!("run{ri}"),
            fs: 100.0,
            v_radar: Vec::new(),
            a_radar: Vec::new(),
            ok: vec![true; n],
            w_mean: vec![0.0; n],
            wd_sum: vec![0.0; n],
            rows: Vec::new(),
            coast: Vec::new(),
            troughs: vec![None; AXLES],
            radar_noise: Err(noise::Unknown::TooFew),
        }
    }

    /// Runs of `sizes` rows for a synthetic balance: speeds and the four pressures from a fixed
    /// pseudo-random sequence, y = Σ ratio_i α_i p_i/r + c_run + c1 v + c2 v² + noise (N),
    /// carried by the radar's deceleration (the wheels' ω̇ zero).
    fn synthetic_runs(sizes: &[usize], r: f64, mass: f64, alpha: [f64; AXLES]) -> Vec<RunSignals> {
        let mut rng = crate::rng::Rng::new(7);
        let mut uniform = move || rng.uniform();
        let ratio = [1.01, 0.99, 1.02, 0.98];
        sizes
            .iter()
            .enumerate()
            .map(|(ri, &n)| {
                let c_run = 900.0 + 400.0 * ri as f64;
                let mut run = test_run(ri, n);
                for k in 0..n {
                    let v = 5.0 + 50.0 * uniform();
                    let p: [f64; AXLES] = std::array::from_fn(|_| 1.0 + 3.0 * uniform());
                    let brake: f64 = (0..AXLES).map(|i| ratio[i] * alpha[i] * p[i] / r).sum();
                    let y = brake + c_run + 30.0 * v + 6.0 * v * v + 500.0 * (uniform() - 0.5);
                    run.v_radar.push(v);
                    run.a_radar.push(-y / mass);
                    run.rows.push((k, p));
                }
                run
            })
            .collect()
    }

    /// The α errors' spread (the delta method): nothing where no parameter was fitted; where
    /// the radar's latency was, every fitted ratio moves, and each pooled ratio moves as its
    /// pooling weight says: as its own group's with B = 0, as the common ratio — the same for
    /// every axle — with B = 1.
    #[test]
    fn the_alpha_errors_spread_follows_the_fit_and_the_pooling() {
        let alpha = [1600.0, 1650.0, 1580.0, 1620.0];
        let runs = synthetic_runs(&[200, 150], R_M, MASS_KG, alpha);
        let b = test_balance(&runs, &[], alpha, true, false);
        let form = PadForm::Constant;
        let fit = b.gram(&AT_0, form).rss_at(&groups(), form, 0.0).unwrap();
        let none = b.alpha_spread(&fit, &AT_0, [f64::NAN, 0.0, f64::NAN], &[0.0; AXLES]);
        assert_eq!(none, ([0.0; AXLES], [0.0; AXLES]));
        let se = [0.004, f64::NAN, f64::NAN];
        let (fitted, apart) = b.alpha_spread(&fit, &AT_0, se, &[0.0; AXLES]);
        assert!(
            fitted.iter().all(|x| *x > 0.0 && x.is_finite()),
            "{fitted:?}"
        );
        assert_eq!(apart, fitted);
        let (again, pooled) = b.alpha_spread(&fit, &AT_0, se, &[1.0; AXLES]);
        assert_eq!(again, fitted);
        assert!(
            pooled.iter().all(|x| *x == pooled[0]) && pooled[0] > 0.0,
            "{pooled:?}"
        );
    }

    /// The inverse of the symmetric positive definite matrix `m` by Gauss–Jordan elimination
    /// with partial pivoting (a reference independent of the balance's own solver).
    fn gauss_jordan(mut m: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let n = m.len();
        for (i, row) in m.iter_mut().enumerate() {
            row.extend((0..n).map(|j| f64::from(u8::from(i == j))));
        }
        for c in 0..n {
            let piv = (c..n)
                .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
                .unwrap();
            m.swap(c, piv);
            let d = m[c][c];
            m[c].iter_mut().for_each(|x| *x /= d);
            for r in 0..n {
                if r != c {
                    let f = m[r][c];
                    let pivot_row = m[c].clone();
                    m[r].iter_mut()
                        .zip(&pivot_row)
                        .for_each(|(x, p)| *x -= f * p);
                }
            }
        }
        m.into_iter().map(|row| row[n..].to_vec()).collect()
    }

    /// Each run's constant and its standard error against weighted least squares with an
    /// explicit column per run's constant (or one for the campaign): unequal run weights and a
    /// run of one row, σ² = 1 so the error is the inverse normal matrix's.
    #[test]
    fn run_constants_are_those_of_least_squares_with_a_column_per_constant() {
        let (r, mass, alpha) = (R_M, MASS_KG, [1600.0, 1650.0, 1580.0, 1620.0]);
        let runs = synthetic_runs(&[40, 25, 1, 30], r, mass, alpha);
        let weights = [1.0, 2.5, 0.7, 1.3];
        let at = AT_0;
        let form = PadForm::Constant;
        for per_run in [true, false] {
            let b = test_balance(&runs, &weights, alpha, per_run, false);
            let fit = b.gram(&at, form).rss_at(&groups(), form, 0.0).unwrap();
            let res = Resistance {
                c: [fit.beta[AXLES], fit.beta[AXLES + 1]],
                se: [0.0; 2],
                rss: fit.rss,
                fit,
                sigma2: 1.0,
            };
            let got = b.run_constants(&at, form, &res);
            // The reference: columns α_i p_i/r, v, v², then the constants' indicators.
            let nc = if per_run { runs.len() } else { 1 };
            let k = AXLES + 2 + nc;
            let mut m = vec![vec![0.0; k]; k];
            let mut rhs = vec![0.0; k];
            for (ri, run) in runs.iter().enumerate() {
                for row in &run.rows {
                    let z = b.z_row(run, row, &at, form).unwrap();
                    let mut x = vec![0.0; k];
                    x[..AXLES].copy_from_slice(&z[..AXLES]);
                    x[AXLES] = z[2 * AXLES];
                    x[AXLES + 1] = z[2 * AXLES + 1];
                    x[AXLES + 2 + if per_run { ri } else { 0 }] = 1.0;
                    for p in 0..k {
                        rhs[p] += weights[ri] * x[p] * z[Y];
                        for q in 0..k {
                            m[p][q] += weights[ri] * x[p] * x[q];
                        }
                    }
                }
            }
            let inv = gauss_jordan(m);
            let beta: Vec<f64> = (0..k)
                .map(|p| (0..k).map(|q| inv[p][q] * rhs[q]).sum())
                .collect();
            for (ri, c) in got.iter().enumerate() {
                let d = AXLES + 2 + if per_run { ri } else { 0 };
                assert_eq!(c.run, format!("run{ri}"));
                assert!(
                    (c.constant_n - beta[d]).abs() < 1e-6 * beta[d].abs(),
                    "per run {per_run}, run {ri}: {} against {}",
                    c.constant_n,
                    beta[d]
                );
                assert!(
                    (c.se_n / inv[d][d].sqrt() - 1.0).abs() < 1e-6,
                    "per run {per_run}, run {ri}: se {} against {}",
                    c.se_n,
                    inv[d][d].sqrt()
                );
            }
        }
    }

    /// Weighted least squares of the integrated balance `b` solved directly: the α_i columns, v,
    /// v², a time column per run (one with `per_run` false), then a constant per stretch. Returns
    /// β, the inverse normal matrix and the RSS.
    fn direct_least_squares(
        b: &Balance,
        at: &At,
        weights: &[f64],
    ) -> (Vec<f64>, Vec<Vec<f64>>, f64) {
        let form = PadForm::Constant;
        let rows: Vec<Vec<IntegratedRow>> = b
            .runs
            .iter()
            .map(|run| b.integrated_rows(run, at, form))
            .collect();
        let per_run = b.per_run;
        let nt = if per_run { b.runs.len() } else { 1 };
        let stretches: Vec<usize> = rows.iter().map(|r| r.last().unwrap().0 + 1).collect();
        let k = AXLES + 2 + nt + stretches.iter().sum::<usize>();
        let mut m = vec![vec![0.0; k]; k];
        let mut rhs = vec![0.0; k];
        let mut yy = 0.0;
        let mut first = 0;
        for (ri, run_rows) in rows.iter().enumerate() {
            for (stretch, t, z) in run_rows {
                let mut x = vec![0.0; k];
                x[..AXLES].copy_from_slice(&z[..AXLES]);
                x[AXLES] = z[2 * AXLES];
                x[AXLES + 1] = z[2 * AXLES + 1];
                x[AXLES + 2 + if per_run { ri } else { 0 }] = *t;
                x[AXLES + 2 + nt + first + stretch] = 1.0;
                yy += weights[ri] * z[Y] * z[Y];
                for p in 0..k {
                    rhs[p] += weights[ri] * x[p] * z[Y];
                    for q in 0..k {
                        m[p][q] += weights[ri] * x[p] * x[q];
                    }
                }
            }
            first += stretches[ri];
        }
        let inv = gauss_jordan(m);
        let beta: Vec<f64> = (0..k)
            .map(|p| (0..k).map(|q| inv[p][q] * rhs[q]).sum())
            .collect();
        let rss = yy - beta.iter().zip(&rhs).map(|(b, r)| b * r).sum::<f64>();
        (beta, inv, rss)
    }

    /// Three runs of 40, 25 and 30 rows every `DECIMATE` samples (random speeds, rates and
    /// pressures); run 0 misses its 18th row, so it has two stretches.
    fn stretched_runs() -> Vec<RunSignals> {
        let mut rng = crate::rng::Rng::new(11);
        let mut uniform = move || rng.uniform();
        [40usize, 25, 30]
            .iter()
            .enumerate()
            .map(|(ri, &rows)| {
                let n = rows * DECIMATE;
                let mut run = test_run(ri, n);
                run.v_radar = vec![0.0; n];
                run.a_radar = vec![0.0; n];
                for j in 0..rows {
                    let k = j * DECIMATE;
                    run.v_radar[k] = 5.0 + 50.0 * uniform();
                    run.a_radar[k] = -1.0 + 0.5 * uniform();
                    // Run 0 misses a row: two stretches.
                    if !(ri == 0 && j == 17) {
                        run.rows
                            .push((k, std::array::from_fn(|_| 1.0 + 3.0 * uniform())));
                    }
                }
                run
            })
            .collect()
    }

    /// A mixture's Gram matrix at any weight from the three at 0, ½ and 1 ([`MixGrams`]) is
    /// the one built at that weight, on the force balance and the integrated one, with a
    /// constant per run and one for the campaign, weighted runs; and the weight the search
    /// finds is the least-residual one (a direct scan over w agrees within its step).
    #[test]
    fn a_mixtures_gram_is_quadratic_in_its_weight() {
        let runs = stretched_runs();
        let weights = [1.0, 2.5, 0.7];
        let alpha = [1600.0, 1650.0, 1580.0, 1620.0];
        for form in [PadForm::LinearQuadratic, PadForm::QuadraticCubic] {
            for (per_run, integrated) in
                [(true, false), (false, false), (true, true), (false, true)]
            {
                let b = test_balance(&runs, &weights, alpha, per_run, integrated);
                let grams = MixGrams::new(&b, &AT_0, form);
                for w in [0.13, 0.3, 0.77] {
                    let direct = Balance { pad_mix: w, ..b }.gram(&AT_0, form);
                    let got = grams.at(w);
                    assert_eq!(got.n, direct.n);
                    let scale = direct.g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                    for (i, (a, d)) in got.g.iter().zip(&direct.g).enumerate() {
                        assert!(
                            (a - d).abs() <= 1e-9 * scale,
                            "{form:?} per_run {per_run} integrated {integrated} w {w} entry {i}: {a} against {d}"
                        );
                    }
                }
                let (w, _, searched) = best_mix(&b, &AT_0, form, &groups()).unwrap();
                assert_eq!(searched, groups());
                let rss = |w: f64| grams.rss(w, &groups(), form);
                let scan = (0..=200)
                    .map(|i| f64::from(i) / 200.0)
                    .min_by(|p, q| rss(*p).total_cmp(&rss(*q)))
                    .unwrap();
                assert!(
                    rss(w) <= rss(scan) * (1.0 + 1e-6),
                    "{form:?}: w {w} against {scan}"
                );
            }
        }
        // Two axles on one pressure: every axle apart is singular at every w, and the search
        // holds them in one group instead of returning a weight it never fitted.
        let mut shared = stretched_runs();
        for run in &mut shared {
            for row in &mut run.rows {
                row.1[1] = row.1[0];
            }
        }
        let b = test_balance(&shared, &weights, alpha, true, false);
        let form = PadForm::QuadraticCubic;
        assert!(b
            .gram(&AT_0, form)
            .fit_over_gamma(&groups(), form)
            .is_none());
        let (w, grams, searched) = best_mix(&b, &AT_0, form, &groups()).unwrap();
        assert_eq!(searched, together().to_vec());
        let g = grams.at(w);
        let rss = |w: f64| grams.rss(w, &together(), form);
        assert!(g.fit_over_gamma(&together(), form).is_some());
        assert!((0..=20).all(|i| rss(w) <= rss(f64::from(i) / 20.0) * (1.0 + 1e-6)));
    }

    /// A mixture's weight searched again with the axle groups its fit settled on: axles 1 and 2
    /// on one pressure (singular apart at every w, so the first search holds all four in one
    /// group), axle 4's pressure rising towards standstill as (1 − v/v_top)³ and its α 6 % below
    /// the others', so that one common ratio leaks into the pad law's shape. The first search's
    /// weight is then far from the truth; the second, with the groups the fit settles on (axles
    /// 1 and 2 merged, since they cannot be told apart), finds it, and the candidate carries it.
    #[test]
    fn a_mixtures_weight_is_searched_again_with_the_groups_its_fit_settles_on() {
        let (w_true, gamma_true) = (0.4, 0.06);
        let ratio = [1.0, 1.0, 1.0, 0.94];
        let alpha = [1600.0; AXLES];
        let form = PadForm::LinearQuadratic;
        let mut rng = crate::rng::Rng::new(3);
        let runs: Vec<RunSignals> = [300usize, 250, 280, 260]
            .iter()
            .enumerate()
            .map(|(ri, &n)| {
                let mut run = test_run(ri, n);
                for k in 0..n {
                    let v = 55.0 * rng.uniform();
                    let u = 1.0 - v / 55.0;
                    let shared = 1.0 + 3.0 * rng.uniform();
                    let p = [
                        shared,
                        shared,
                        1.0 + 3.0 * rng.uniform(),
                        0.5 + 3.5 * u * u * u + 0.3 * rng.uniform(),
                    ];
                    let pad = 1.0 + gamma_true * form.phi(v, 55.0, w_true);
                    let brake: f64 = (0..AXLES)
                        .map(|i| ratio[i] * alpha[i] * pad * p[i] / R_M)
                        .sum();
                    let y = brake + 1000.0 + 30.0 * v + 6.0 * v * v + 20.0 * rng.normal();
                    run.v_radar.push(v);
                    run.a_radar.push(-y / MASS_KG);
                    run.rows.push((k, p));
                }
                run
            })
            .collect();
        let b = test_balance(&runs, &[], alpha, true, false);
        let (first, _, searched) = best_mix(&b, &AT_0, form, &groups()).unwrap();
        assert_eq!(searched, together().to_vec());
        assert!((first - w_true).abs() > 0.15, "first search: w = {first}");
        let (_, candidates) = select_model(&b, &AT_0, runs.len());
        let c = candidates
            .iter()
            .find(|c| c.form == form && c.per_run_constants)
            .unwrap();
        assert!(c.refused.is_none(), "{:?}", c.refused);
        assert!(
            (c.mix - w_true).abs() < 0.02 && (c.gamma - gamma_true).abs() < 0.002,
            "w = {}, γ = {} (first search: w = {first})",
            c.mix,
            c.gamma
        );
    }

    /// The integrated balance's Gram (each stretch's constant of integration and each run's
    /// time column eliminated) gives the coefficients, the residual sum of squares and the run
    /// constants with their errors of weighted least squares with a column per stretch and a
    /// time column per run (or one), solved directly; and its rows integrate by trapezoids,
    /// a stretch ending at a missing row.
    #[test]
    fn the_integrated_balance_is_least_squares_with_a_constant_per_stretch() {
        let (r, alpha) = (R_M, [1600.0, 1650.0, 1580.0, 1620.0]);
        let runs = stretched_runs();
        let weights = [1.0, 2.5, 0.7];
        let at = AT_0;
        let form = PadForm::Constant;
        for per_run in [true, false] {
            let b = test_balance(&runs, &weights, alpha, per_run, true);
            // The trapezoids: the first axle's column against its own sum, from 0 at each
            // stretch's first row.
            let rows0 = b.integrated_rows(&runs[0], &at, form);
            assert_eq!(rows0.len(), runs[0].rows.len());
            assert_eq!(rows0.iter().filter(|r| r.0 == 1).count(), 40 - 18);
            let dt = DECIMATE as f64 / runs[0].fs;
            let f = |i: usize| alpha[0] * runs[0].rows[i].1[0] / r;
            let mut acc = 0.0;
            for i in 0..rows0.len() {
                if i == 0 || rows0[i].0 != rows0[i - 1].0 {
                    acc = 0.0;
                } else {
                    acc += 0.5 * (f(i - 1) + f(i)) * dt;
                }
                assert!(
                    (rows0[i].2[0] - acc).abs() <= 1e-9 * acc.max(1.0),
                    "row {i}: {} against {acc}",
                    rows0[i].2[0]
                );
            }
            let fit = b.gram(&at, form).rss_at(&groups(), form, 0.0).unwrap();
            let res = Resistance {
                c: [fit.beta[AXLES], fit.beta[AXLES + 1]],
                se: [0.0; 2],
                rss: fit.rss,
                fit: fit.clone(),
                sigma2: 1.0,
            };
            let got = b.run_constants(&at, form, &res);
            let (beta, inv, rss) = direct_least_squares(&b, &at, &weights);
            for (p, (got, want)) in fit.beta.iter().zip(&beta[..AXLES + 2]).enumerate() {
                assert!(
                    (got / want - 1.0).abs() < 1e-6,
                    "per run {per_run}, coefficient {p}: {got} against {want}"
                );
            }
            assert!(
                (fit.rss / rss - 1.0).abs() < 1e-6,
                "{} against {rss}",
                fit.rss
            );
            for (ri, c) in got.iter().enumerate() {
                let d = AXLES + 2 + if per_run { ri } else { 0 };
                assert!(
                    (c.constant_n - beta[d]).abs() < 1e-6 * beta[d].abs(),
                    "per run {per_run}, run {ri}: {} against {}",
                    c.constant_n,
                    beta[d]
                );
                assert!(
                    (c.se_n / inv[d][d].sqrt() - 1.0).abs() < 1e-6,
                    "per run {per_run}, run {ri}: se {} against {}",
                    c.se_n,
                    inv[d][d].sqrt()
                );
            }
        }
    }

    #[test]
    fn ratios_that_differ_by_no_more_than_their_errors_pool_to_the_common_one() {
        // Groups that do not differ significantly: no scatter between the axles.
        let r = [1.005, 0.995, 1.01, 0.99];
        let p = partial_pooling(&groups(), &r, &[0.01; AXLES], 1.0, 0.005, false);
        assert_eq!(p.between_sd, 0.0);
        assert_eq!(p.alpha, [1.0; AXLES]);
        // Not the common ratio's 0.005 alone: the scatter between the axles might be small
        // rather than none (tests/data/pooling/reference.py).
        let reference = [
            0.007_062_205_3,
            0.007_062_205_3,
            0.007_946_136_9,
            0.007_946_136_9,
        ];
        for (se, r) in p.alpha_se.iter().zip(reference) {
            assert!((se / r - 1.0).abs() < 1e-4, "{se} against {r}");
        }
    }

    /// The pooled standard errors against an independent quadrature of the same posterior
    /// (tests/data/pooling/reference.py: the trapezoid rule directly in τ, 2 000 001 points;
    /// it checks the quadrature, not the model, which both take from the same formulas).
    #[test]
    fn pooled_standard_errors_match_the_reference_quadrature() {
        // (fitted ratios, their errors, common, its error, differ, (reported, se) per axle)
        type Case = (
            [f64; AXLES],
            [f64; AXLES],
            f64,
            f64,
            bool,
            [(f64, f64); AXLES],
        );
        let cases: [Case; 2] = [
            (
                [1.03, 0.97, 1.01, 0.99],
                [0.01; AXLES],
                1.0,
                0.005,
                true,
                [
                    (1.025_5, 0.010_075_681_7),
                    (0.974_5, 0.010_075_681_7),
                    (1.008_5, 0.009_195_788_7),
                    (0.991_5, 0.009_195_788_7),
                ],
            ),
            (
                [1.012, 0.991, 1.004, 0.985],
                [0.006, 0.009, 0.007, 0.008],
                0.999,
                0.0035,
                true,
                [
                    (1.008_395_378_691, 0.006_177_329_4),
                    (0.994_706_387_035, 0.007_109_721_6),
                    (1.002_284_714_119, 0.005_869_762_9),
                    (0.990_676_874_340, 0.007_309_454_5),
                ],
            ),
        ];
        for (r, se, common, common_se, differ, want) in cases {
            let p = partial_pooling(&groups(), &r, &se, common, common_se, differ);
            for (a, (alpha, alpha_se)) in want.iter().enumerate() {
                assert!((p.alpha[a] - alpha).abs() < 1e-11, "{a}: {}", p.alpha[a]);
                assert!(
                    (p.alpha_se[a] / alpha_se - 1.0).abs() < 1e-4,
                    "{a}: {} against {alpha_se}",
                    p.alpha_se[a]
                );
            }
        }
    }

    /// Equal errors, groups that do not differ significantly: every axle's error is at least
    /// the common ratio's (here 0.005 against the groups' 0.01) and grows with the groups'
    /// scatter about it; a group with no error at all takes the error at the moments' τ².
    #[test]
    fn pooled_standard_errors_grow_with_the_scatter() {
        let se_of = |spread: f64| {
            let r = [
                1.0 + spread,
                1.0 - spread,
                1.0 + spread / 2.0,
                1.0 - spread / 2.0,
            ];
            partial_pooling(&groups(), &r, &[0.01; AXLES], 1.0, 0.005, false).alpha_se[0]
        };
        let mut last = 0.0;
        for spread in [0.0, 0.005, 0.01, 0.02, 0.04] {
            let se = se_of(spread);
            assert!(se >= 0.005 && se > last, "spread {spread}: {se}");
            last = se;
        }
        // An error of 0 is no posterior to integrate: the error at τ² = 0.
        let mut e = [0.01; AXLES];
        e[2] = 0.0;
        let p = partial_pooling(&groups(), &[1.0; AXLES], &e, 1.0, 0.005, false);
        assert!(
            p.alpha_se.iter().all(|se| (se - 0.005).abs() < 1e-15),
            "{:?}",
            p.alpha_se
        );
    }

    #[test]
    fn ratios_that_scatter_beyond_their_errors_keep_most_of_it() {
        // Groups that differ: τ² = (20e-4/3 − 1e-4) = 5.67e-4, B = 0.15.
        let r = [1.03, 0.97, 1.01, 0.99];
        let p = partial_pooling(&groups(), &r, &[0.01; AXLES], 1.0, 0.005, true);
        let tau2: f64 = 20e-4 / 3.0 - 1e-4;
        assert!((p.between_sd - tau2.sqrt()).abs() < 1e-12);
        let b = 1e-4 / (1e-4 + tau2);
        for ((pooled, se), fitted) in p.alpha.iter().zip(&p.alpha_se).zip(&r) {
            assert!((pooled - (fitted - b * (fitted - 1.0))).abs() < 1e-12);
            // About the axle's own error: the pooling gains little where the scatter is
            // large, and τ²'s uncertainty costs a little (the reference values above).
            assert!(*se > 0.009 && *se < 0.0101, "{se}");
        }
    }

    #[test]
    fn the_chi_squared_quantiles_are_the_tables() {
        // χ²(0.95) with 1, 2, 3 degrees of freedom; 2 has the closed form −2 ln 0.05.
        assert!((chi2_95(2) + 2.0 * 0.05f64.ln()).abs() < 1e-6);
        assert!((chi2_95(1) - Z95 * Z95).abs() < 1e-5);
        assert!(chi2_95(3) > chi2_95(2));
    }
}
