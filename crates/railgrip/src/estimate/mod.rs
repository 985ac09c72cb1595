//! Adhesion estimation per axle and sample (seed 002 002_8d8769283f5e9cb6.txt, "Data from
//! test runs" and "Simplified dynamic model").
//!
//! From the conditioned signals (filtered v, ω_i, p_i and their derivatives):
//! - slip velocity Δv_i = v − r ω_i in braking (eq. 2) or r ω_i − v in traction (eq. 3), m/s,
//!   and its rate dΔv_i/dt = v̇ − r ω̇_i (braking) or r ω̇_i − v̇ (traction), m/s²;
//! - slip ratio Δv_i / v in braking (eq. 4) or Δv_i / (r ω_i) in traction (eq. 5), undefined
//!   (NaN) where the denominator is not positive;
//! - vehicle deceleration d = −v̇, m/s², and the normal loads N_i(d) of eq. 12–13
//!   ([`crate::vehicle::axle_loads`]), N;
//! - tangential force T_i = (J ω̇_i + α_i p_i) / r from the torque balance T_i r = J ω̇_i +
//!   C_f,i (eq. 9) with C_f,i = α_i p_i (eq. 10), N — eq. 11 in the paper prints the J ω̇ term
//!   with the wrong sign; eq. 9 and eq. 14 are the consistent pair. The contract logs no motor
//!   torque, so traction mode changes the slip definitions only;
//! - adhesion coefficient μ_i = T_i / N_i (eq. 14).
//!
//! Each sample gets a validity flag per axle; the first failing reason is counted
//! ([`MaskCounts`]): no data (unbridged gap), segment too short to filter, within one period
//! of the lowest cut-off of a segment's ends (filter start-up transients), vehicle speed below
//! `estimate.min_speed_mps` (towards standstill the slip ratio and the torque balance lose
//! meaning), cylinder pressure below `estimate.min_pressure_bar` (brake not applied), wheel
//! locked (r ω below `estimate.locked_wheel_speed_mps`: the brake torque is then static
//! friction, not α p), and any non-finite result.

// `!(x >= lo)` is deliberate: a NaN fails the check instead of passing it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod calibrate;
pub mod counting;
pub mod noise;
pub mod radar;
pub mod selfcal;

use std::path::{Path, PathBuf};

use crate::config::{EstimateConfig, FilterMode, Phase, Pipeline};
use crate::format::{RunMetadata, AXLES};
use crate::ingest::RunLog;
use crate::signal::{self, Conditioned, FilterError, GroupDelays};
use crate::vehicle::axle_loads;

/// Column names of the estimates table, in order (docs/input-logs.md#estimates-table).
pub const ESTIMATE_COLUMNS: [&str; 13] = [
    "time_s",
    "axle",
    "v_mps",
    "omega_radps",
    "p_bar",
    "dv_mps",
    "ddv_mps2",
    "slip_ratio",
    "decel_mps2",
    "normal_N",
    "tangential_N",
    "mu",
    "valid",
];

/// Parquet key-value metadata key under which the run's metadata travels with the estimates
/// table (JSON object of string pairs, the keys of the data contract's metadata).
pub const PARQUET_METADATA_KEY: &str = "railgrip.run_metadata";

/// Why estimation or writing failed.
#[derive(Debug, thiserror::Error)]
pub enum EstimateError {
    #[error("{file}: {source}. Hint: check [filters] in the pipeline file")]
    Filter {
        file: PathBuf,
        #[source]
        source: FilterError,
    },
    #[error(transparent)]
    Write(#[from] crate::table::TableError),
    #[error("{path}: cannot create the folder: {source}")]
    Folder {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: {what}. Hint: {hint}")]
    Calibration {
        file: PathBuf,
        what: String,
        hint: String,
    },
}

/// Samples masked per reason (each invalid sample counted once, under its first reason).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MaskCounts {
    pub no_data: usize,
    pub short_segment: usize,
    pub settling: usize,
    /// In a bridged logger gap or within the filters' support of one.
    pub bridged_gap: usize,
    pub low_speed: usize,
    pub brake_released: usize,
    pub wheel_locked: usize,
    pub not_finite: usize,
}

impl MaskCounts {
    pub fn total(&self) -> usize {
        self.no_data
            + self.short_segment
            + self.settling
            + self.bridged_gap
            + self.low_speed
            + self.brake_released
            + self.wheel_locked
            + self.not_finite
    }

    /// (reason, count) pairs for messages.
    pub fn pairs(&self) -> [(&'static str, usize); 8] {
        [
            ("no data (gap)", self.no_data),
            ("segment too short", self.short_segment),
            ("filter settling", self.settling),
            ("bridged gap", self.bridged_gap),
            ("speed below minimum", self.low_speed),
            ("brake not applied", self.brake_released),
            ("wheel locked", self.wheel_locked),
            ("not finite", self.not_finite),
        ]
    }
}

/// Estimates of one axle, one value per sample of the run.
#[derive(Debug, Clone, Default)]
pub struct AxleEstimates {
    /// Filtered axle angular speed ω_i, rad/s.
    pub omega_radps: Vec<f64>,
    /// Filtered brake-cylinder pressure p_i, bar.
    pub p_bar: Vec<f64>,
    /// Slip velocity Δv_i, m/s.
    pub dv_mps: Vec<f64>,
    /// Slip rate dΔv_i/dt, m/s².
    pub ddv_mps2: Vec<f64>,
    /// Normal load N_i, N.
    pub normal_n: Vec<f64>,
    /// Tangential force T_i, N.
    pub tangential_n: Vec<f64>,
    /// Adhesion coefficient μ_i = T_i / N_i.
    pub mu: Vec<f64>,
    pub valid: Vec<bool>,
    pub masked: MaskCounts,
}

/// Per-sample estimates of a run.
#[derive(Debug, Clone)]
pub struct Estimates {
    pub source: PathBuf,
    pub sample_rate_hz: f64,
    /// s, the RunLog's time base.
    pub time_s: Vec<f64>,
    /// Filtered vehicle speed v, m/s.
    pub v_mps: Vec<f64>,
    /// Vehicle deceleration d = −dv/dt, m/s² (positive when braking).
    pub decel_mps2: Vec<f64>,
    pub axles: [AxleEstimates; AXLES],
    pub phase: Phase,
    pub mode: FilterMode,
    pub group_delay_s: GroupDelays,
    /// Radar samples replaced by the despiking filter.
    pub despiked: usize,
    pub metadata: RunMetadata,
    /// Slip velocity above which an axle counts as sliding in [`Estimates::summary`], m/s.
    pub sliding_threshold_mps: f64,
    /// Wheel radius r used for the slip, m.
    pub wheel_radius_m: f64,
}

#[inline]
fn slip_ratio(braking: bool, dv: f64, v: f64, rw: f64) -> f64 {
    let denom = if braking { v } else { rw };
    if denom > 0.0 {
        dv / denom
    } else {
        f64::NAN
    }
}

/// Conditions and estimates a run with a pipeline's settings (and its calibration, when it
/// carries one: [`estimate_corrected`]).
pub fn estimate(log: &RunLog, pipeline: &Pipeline) -> Result<Estimates, EstimateError> {
    if let Some(cal) = &pipeline.calibrated {
        return estimate_corrected(log, pipeline, &cal.corrections);
    }
    let cond =
        signal::condition(log, &pipeline.filters).map_err(|source| EstimateError::Filter {
            file: log.source.clone(),
            source,
        })?;
    Ok(estimate_conditioned(log, cond, pipeline))
}

/// Conditions and estimates a run with a campaign's self-calibration applied
/// ([`selfcal::Corrections`]): the radar's reading divided by its scale and moved back by its
/// latency, v(t) = v_radar(t + τ)/s, the tachometers moved back by their delay, ω(t) =
/// ω_tacho(t + τ_w) (linear interpolation between samples; a sample whose shifted reading
/// falls outside the log or into a gap has no data), each axle's brake coefficient α_i, and
/// the pad friction's factor 1 + γ φ(v) on it.
pub fn estimate_corrected(
    log: &RunLog,
    pipeline: &Pipeline,
    corr: &selfcal::Corrections,
) -> Result<Estimates, EstimateError> {
    let shifted = corrected_log(log, corr);
    let mut p = pipeline.clone();
    p.vehicle.brake_torque_nm_per_bar = corr.alpha_nm_per_bar;
    p.calibrated = None;
    let cond = signal::condition(&shifted, &p.filters).map_err(|source| EstimateError::Filter {
        file: log.source.clone(),
        source,
    })?;
    Ok(estimate_with(&shifted, cond, &p, Some(&corr.pad)))
}

/// `log` with its radar corrected by scale and latency and its tachometers by their delay
/// (see [`estimate_corrected`]).
fn corrected_log(log: &RunLog, corr: &selfcal::Corrections) -> RunLog {
    let mut out = log.clone();
    let n = log.len();
    // The reading at k + shift (linear between samples), None outside the log or in a gap.
    let at = |x: &[f64], k: usize, shift: f64| selfcal::shifted(x, &log.valid, k, shift);
    let radar_shift = corr.radar_latency_s * log.sample_rate_hz;
    let tacho_shift = corr.tacho_delay_s * log.sample_rate_hz;
    let inv_s = 1.0 / corr.radar_scale;
    for k in 0..n {
        let v = at(&log.v_radar_mps, k, radar_shift);
        let w: [Option<f64>; AXLES] =
            std::array::from_fn(|a| at(&log.omega_radps[a], k, tacho_shift));
        match (v, w.iter().all(Option::is_some)) {
            (Some(v), true) => {
                out.v_radar_mps[k] = v * inv_s;
                for (o, x) in out.omega_radps.iter_mut().zip(w) {
                    o[k] = x.unwrap_or(f64::NAN);
                }
            }
            _ => out.valid[k] = false,
        }
    }
    out
}

/// The estimation step on already conditioned signals (consumed: the filtered ω and p move
/// into the result).
pub fn estimate_conditioned(log: &RunLog, c: Conditioned, pipeline: &Pipeline) -> Estimates {
    estimate_with(log, c, pipeline, None)
}

/// [`estimate_conditioned`] with the pad friction's speed law on α, when given.
fn estimate_with(
    log: &RunLog,
    c: Conditioned,
    pipeline: &Pipeline,
    pad: Option<&selfcal::PadLaw>,
) -> Estimates {
    let veh = &pipeline.vehicle;
    let cfg = &pipeline.estimate;
    let r = veh.wheel_radius_m;
    let Conditioned {
        v_mps,
        accel_mps2,
        omega_radps,
        omega_dot_radps2,
        p_bar,
        has_data,
        usable,
        settled,
        near_bridge,
        mode,
        group_delay_s,
        despiked,
        ..
    } = c;
    // The loads of eq. 12–13 are affine in the deceleration: N_i = N0_i + dN_i · d.
    let n0 = axle_loads(veh, 0.0);
    let dn: [f64; AXLES] = {
        let one = axle_loads(veh, 1.0);
        std::array::from_fn(|a| one[a] - n0[a])
    };
    let mut decel_mps2 = accel_mps2;
    let run = Run {
        n: log.len(),
        v_mps: &v_mps,
        accel_mps2: &decel_mps2, // still dv/dt here
        has_data: &has_data,
        usable: &usable,
        settled: &settled,
        near_bridge: &near_bridge,
        braking: cfg.phase == Phase::Braking,
        r,
        inv_r: 1.0 / r,
        j: veh.axle_inertia_kgm2,
        cfg,
        pad,
    };
    let mut omega_radps = omega_radps.into_iter();
    let mut p_bar = p_bar.into_iter();
    let mut omega_dot = omega_dot_radps2.into_iter();
    let axles: [AxleEstimates; AXLES] = std::array::from_fn(|a| {
        run.axle(
            omega_radps.next().expect("4 axles"),
            p_bar.next().expect("4 axles"),
            omega_dot.next().expect("4 axles"),
            veh.brake_torque_nm_per_bar[a],
            (n0[a], dn[a]),
        )
    });
    for x in decel_mps2.iter_mut() {
        *x = -*x;
    }
    Estimates {
        source: log.source.clone(),
        sample_rate_hz: log.sample_rate_hz,
        time_s: log.time_s.clone(),
        v_mps,
        decel_mps2,
        axles,
        phase: cfg.phase,
        mode,
        group_delay_s,
        despiked,
        metadata: log.metadata.clone(),
        sliding_threshold_mps: cfg.sliding_threshold_mps,
        wheel_radius_m: r,
    }
}

/// What every axle's estimation reads: the run's conditioned vehicle speed and its rate,
/// the masks, and the settings.
struct Run<'a> {
    /// Samples of the run.
    n: usize,
    v_mps: &'a [f64],
    /// dv/dt, m/s².
    accel_mps2: &'a [f64],
    has_data: &'a [bool],
    usable: &'a [bool],
    settled: &'a [bool],
    near_bridge: &'a [bool],
    braking: bool,
    /// Wheel radius r (m), 1 / r, and the axle's inertia J (kg m²).
    r: f64,
    inv_r: f64,
    j: f64,
    cfg: &'a EstimateConfig,
    /// The pad friction's speed law on α (campaign self-calibration), if any.
    pad: Option<&'a selfcal::PadLaw>,
}

impl Run<'_> {
    /// The estimates of one axle from its filtered ω, p and ω̇ (which becomes the slip rate),
    /// its brake coefficient α (N m/bar) and its load N = N0 − dN · v̇ (`loads` = (N0, dN)).
    /// Column by column: each loop is a plain map over slices, which the compiler vectorises.
    fn axle(
        &self,
        omega: Vec<f64>,
        p: Vec<f64>,
        mut wd: Vec<f64>,
        alpha: f64,
        (n0, dn): (f64, f64),
    ) -> AxleEstimates {
        let (r, inv_r, j) = (self.r, self.inv_r, self.j);
        let v_mps = self.v_mps;
        let acc = self.accel_mps2;
        let dv_mps: Vec<f64> = if self.braking {
            v_mps.iter().zip(&omega).map(|(v, w)| v - r * w).collect()
        } else {
            v_mps.iter().zip(&omega).map(|(v, w)| r * w - v).collect()
        };
        let normal_n: Vec<f64> = acc.iter().map(|x| n0 - dn * x).collect();
        let tangential_n: Vec<f64> = match self.pad {
            None => wd
                .iter()
                .zip(&p)
                .map(|(w, p)| (j * w + alpha * p) * inv_r)
                .collect(),
            Some(law) => wd
                .iter()
                .zip(&p)
                .zip(v_mps)
                .map(|((w, p), v)| (j * w + alpha * law.factor(*v) * p) * inv_r)
                .collect(),
        };
        // dΔv/dt = v̇ − r ω̇ (braking), written over ω̇, which is not needed after T.
        let sign = if self.braking { 1.0 } else { -1.0 };
        for (w, a) in wd.iter_mut().zip(acc) {
            *w = sign * (a - r * *w);
        }
        let ddv_mps2 = wd;
        let mu: Vec<f64> = tangential_n
            .iter()
            .zip(&normal_n)
            .map(|(t, nn)| if *nn > 0.0 { t / nn } else { f64::NAN })
            .collect();
        let (valid, masked) = self.validity(&omega, &p, &dv_mps, &ddv_mps2, &tangential_n, &mu);
        AxleEstimates {
            omega_radps: omega,
            p_bar: p,
            dv_mps,
            ddv_mps2,
            normal_n,
            tangential_n,
            mu,
            valid,
            masked,
        }
    }

    /// The validity flag of each sample of one axle, and the invalid samples counted under
    /// their first failing reason (in the order of [`MaskCounts::pairs`]).
    fn validity(
        &self,
        omega: &[f64],
        p: &[f64],
        dv_mps: &[f64],
        ddv_mps2: &[f64],
        tangential_n: &[f64],
        mu: &[f64],
    ) -> (Vec<bool>, MaskCounts) {
        let (cfg, r, braking, v_mps) = (self.cfg, self.r, self.braking, self.v_mps);
        let mut masked = MaskCounts::default();
        let valid: Vec<bool> = (0..self.n)
            .map(|i| {
                let m = &mut masked;
                if !self.usable[i] {
                    if self.has_data[i] {
                        m.short_segment += 1;
                    } else {
                        m.no_data += 1;
                    }
                } else if self.near_bridge[i] {
                    m.bridged_gap += 1;
                } else if !self.settled[i] {
                    m.settling += 1;
                } else if !(v_mps[i] >= cfg.min_speed_mps) {
                    m.low_speed += 1;
                } else if !(p[i] >= cfg.min_pressure_bar) {
                    m.brake_released += 1;
                } else if !(r * omega[i] >= cfg.locked_wheel_speed_mps) {
                    m.wheel_locked += 1;
                } else if !(dv_mps[i].is_finite()
                    && ddv_mps2[i].is_finite()
                    && tangential_n[i].is_finite()
                    && mu[i].is_finite()
                    && slip_ratio(braking, dv_mps[i], v_mps[i], r * omega[i]).is_finite())
                {
                    m.not_finite += 1;
                } else {
                    return true;
                }
                false
            })
            .collect();
        (valid, masked)
    }
}

/// Per-axle figures of a run (printed by `railgrip estimate`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxleSummary {
    pub axle: usize,
    pub valid_samples: usize,
    /// Highest μ over valid samples (NaN when none).
    pub peak_mu: f64,
    /// Largest slip velocity over valid samples, m/s (NaN when none).
    pub max_dv_mps: f64,
    /// Time with Δv above the sliding threshold (valid samples), s.
    pub sliding_s: f64,
    /// Adhesion utilisation: mean μ over the valid samples ÷ peak μ — the share of the best
    /// adhesion this axle found that it used on average while braking (NaN when none).
    pub utilisation: f64,
}

impl Estimates {
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Slip ratio of axle `a` (0-based) at sample `i`: Δv / v in braking (seed 002 eq. 4),
    /// Δv / (r ω) in traction (eq. 5); NaN where the denominator is not positive. Derived on
    /// demand (it is Δv over a stored speed), not stored.
    pub fn slip_ratio(&self, a: usize, i: usize) -> f64 {
        let ax = &self.axles[a];
        slip_ratio(
            self.phase == Phase::Braking,
            ax.dv_mps[i],
            self.v_mps[i],
            self.wheel_radius_m * ax.omega_radps[i],
        )
    }

    /// Per-axle figures.
    pub fn summary(&self) -> [AxleSummary; AXLES] {
        let dt = 1.0 / self.sample_rate_hz;
        std::array::from_fn(|a| {
            let ax = &self.axles[a];
            let (mut k, mut peak, mut max_dv, mut sliding, mut sum) =
                (0usize, f64::NEG_INFINITY, f64::NEG_INFINITY, 0usize, 0.0);
            for i in (0..self.len()).filter(|&i| ax.valid[i]) {
                k += 1;
                peak = peak.max(ax.mu[i]);
                max_dv = max_dv.max(ax.dv_mps[i]);
                sum += ax.mu[i];
                if ax.dv_mps[i] > self.sliding_threshold_mps {
                    sliding += 1;
                }
            }
            let none = k == 0;
            AxleSummary {
                axle: a + 1,
                valid_samples: k,
                peak_mu: if none { f64::NAN } else { peak },
                max_dv_mps: if none { f64::NAN } else { max_dv },
                sliding_s: sliding as f64 * dt,
                utilisation: if none || peak <= 0.0 {
                    f64::NAN
                } else {
                    sum / k as f64 / peak
                },
            }
        })
    }

    /// The long table (one row per sample and axle, time-major) as a polars DataFrame with
    /// [`ESTIMATE_COLUMNS`].
    pub fn to_dataframe(&self) -> polars::prelude::PolarsResult<polars::prelude::DataFrame> {
        use polars::prelude::*;
        let n = self.len();
        let long = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            let mut out = Vec::with_capacity(n * AXLES);
            for i in 0..n {
                for a in 0..AXLES {
                    out.push(f(i, a));
                }
            }
            out
        };
        let ax = &self.axles;
        let f64col =
            |name: &str, v: Vec<f64>| Float64Chunked::from_vec(name.into(), v).into_column();
        let c = ESTIMATE_COLUMNS;
        let axle: Vec<i32> = (0..n).flat_map(|_| 1..=AXLES as i32).collect();
        let valid: Vec<bool> = (0..n)
            .flat_map(|i| (0..AXLES).map(move |a| ax[a].valid[i]))
            .collect();
        DataFrame::new(
            n * AXLES,
            vec![
                f64col(c[0], long(&|i, _| self.time_s[i])),
                Int32Chunked::from_vec(c[1].into(), axle).into_column(),
                f64col(c[2], long(&|i, _| self.v_mps[i])),
                f64col(c[3], long(&|i, a| ax[a].omega_radps[i])),
                f64col(c[4], long(&|i, a| ax[a].p_bar[i])),
                f64col(c[5], long(&|i, a| ax[a].dv_mps[i])),
                f64col(c[6], long(&|i, a| ax[a].ddv_mps2[i])),
                f64col(c[7], long(&|i, a| self.slip_ratio(a, i))),
                f64col(c[8], long(&|i, _| self.decel_mps2[i])),
                f64col(c[9], long(&|i, a| ax[a].normal_n[i])),
                f64col(c[10], long(&|i, a| ax[a].tangential_n[i])),
                f64col(c[11], long(&|i, a| ax[a].mu[i])),
                BooleanChunked::from_slice(c[12].into(), &valid).into_column(),
            ],
        )
    }

    /// Writes `<dir>/<stem>.estimates.parquet` (zstd) and, with `csv`, the same table as
    /// `<dir>/<stem>.estimates.csv`, each atomically. Returns the paths written.
    pub fn write(&self, dir: &Path, stem: &str, csv: bool) -> Result<Vec<PathBuf>, EstimateError> {
        self.write_named(dir, &format!("{stem}.estimates"), csv)
    }

    /// As [`Estimates::write`] with the file name `<name>.parquet` (and `<name>.csv`).
    pub fn write_named(
        &self,
        dir: &Path,
        name: &str,
        csv: bool,
    ) -> Result<Vec<PathBuf>, EstimateError> {
        std::fs::create_dir_all(dir).map_err(|source| EstimateError::Folder {
            path: dir.to_path_buf(),
            source,
        })?;
        let pq = dir.join(format!("{name}.parquet"));
        let mut df = self.to_dataframe().map_err(|e| crate::table::TableError {
            path: pq.clone(),
            source: std::io::Error::other(e),
        })?;
        let meta = serde_json::to_string(&self.metadata.to_pairs()).unwrap_or_default();
        crate::table::write_parquet(&mut df, &pq, Some((PARQUET_METADATA_KEY, meta)))?;
        let mut written = vec![pq];
        if csv {
            let path = dir.join(format!("{name}.csv"));
            crate::table::write_csv(&mut df, &path)?;
            written.push(path);
        }
        Ok(written)
    }
}
