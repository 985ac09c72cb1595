//! Signal conditioning: a [`RunLog`] in, [`Conditioned`] signals out.
//!
//! Per seed 002 (002_8d8769283f5e9cb6.txt, "Data from test runs"): the radar speed is
//! despiked ([`despike`], Hampel) and low-passed at 1.5 Hz, the tachometers at 4 Hz, the
//! brake-cylinder pressures at 4 Hz (configurable), all with a 4th-order Butterworth
//! ([`filter`]), zero-phase by default or causal as in the paper. Derivatives
//! ([`derivative`]) of the filtered vehicle speed and axle speeds follow.
//!
//! The filters never run across a hole: samples the RunLog marks invalid (unbridged gaps) or
//! that are not finite split the run into segments, each conditioned on its own. Segments
//! shorter than [`filter::MIN_LEN`] samples stay NaN and are counted.

pub mod derivative;
pub mod despike;
pub mod filter;

use crate::config::{FilterConfig, FilterMode};
use crate::format::AXLES;
use crate::ingest::RunLog;
pub use filter::{FilterError, LowPass4};

/// Filtered signals and derivatives on the RunLog's time base; NaN outside usable segments.
#[derive(Debug, Clone)]
pub struct Conditioned {
    pub sample_rate_hz: f64,
    pub mode: FilterMode,
    /// Filtered radar speed, m/s.
    pub v_mps: Vec<f64>,
    /// dv/dt of the filtered radar speed, m/s² (negative when braking).
    pub accel_mps2: Vec<f64>,
    /// Filtered axle angular speeds, rad/s.
    pub omega_radps: [Vec<f64>; AXLES],
    /// dω/dt of the filtered axle speeds, rad/s².
    pub omega_dot_radps2: [Vec<f64>; AXLES],
    /// Filtered brake-cylinder pressures, bar.
    pub p_bar: [Vec<f64>; AXLES],
    /// True where every channel has a finite, valid sample (no unbridged gap).
    pub has_data: Vec<bool>,
    /// True where the sample lies in a segment that was conditioned.
    pub usable: Vec<bool>,
    /// True where the sample is usable and at least [`Conditioned::settle_s`] from both ends
    /// of its segment, where the filters' start-up transients have died out.
    pub settled: Vec<bool>,
    /// Settling margin at segment ends: one period of the lowest cut-off, s.
    pub settle_s: f64,
    /// True where a sample lies in a bridged gap (`ingest.bridge_gap_ms`) or within
    /// [`Conditioned::bridge_support_s`] of one; such samples are not `settled`.
    pub near_bridge: Vec<bool>,
    /// Margin around a bridged gap, s.
    pub bridge_support_s: f64,
    /// Radar samples replaced by the Hampel filter.
    pub despiked: usize,
    /// Group delay at DC of the radar, tachometer and pressure filters, s (0 in zero-phase
    /// mode). In causal mode the radar lags the tachometers by the difference, which shifts
    /// the slip Δv = v − rω against the pressure.
    pub group_delay_s: GroupDelays,
}

/// Group delays at DC of the three filters, s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupDelays {
    pub radar_s: f64,
    pub tacho_s: f64,
    pub pressure_s: f64,
}

/// The three low-pass filters of a pipeline.
#[derive(Debug, Clone, Copy)]
pub struct Filters {
    pub radar: LowPass4,
    pub tacho: LowPass4,
    pub pressure: LowPass4,
}

impl Filters {
    /// Designs the filters for `sample_rate_hz` (the pipeline checks 0 < fc < fs/2 already;
    /// this repeats it for callers that build configs by hand).
    pub fn design(cfg: &FilterConfig, sample_rate_hz: f64) -> Result<Filters, FilterError> {
        Ok(Filters {
            radar: LowPass4::butterworth(cfg.radar_cutoff_hz, sample_rate_hz)?,
            tacho: LowPass4::butterworth(cfg.tacho_cutoff_hz, sample_rate_hz)?,
            pressure: LowPass4::butterworth(cfg.pressure_cutoff_hz, sample_rate_hz)?,
        })
    }
}

/// Contiguous ranges `[start, end)` of samples that are valid and finite in every channel.
pub fn segments(log: &RunLog) -> Vec<(usize, usize)> {
    let n = log.len();
    let ok = |i: usize| {
        log.valid[i]
            && log.v_radar_mps[i].is_finite()
            && log.omega_radps.iter().all(|w| w[i].is_finite())
            && log.p_bar.iter().all(|p| p[i].is_finite())
    };
    let mut out = Vec::new();
    let mut start = None;
    for i in 0..n {
        match (ok(i), start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push((s, i));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, n));
    }
    out
}

/// The margin masked on each side of a bridged gap, s: the time in which the slowest pole
/// pair of the lowest-cut-off 4th-order Butterworth decays to BRIDGE_DECAY of its start
/// (poles at ω_c e^{±j 5π/8}: decay rate ω_c cos(3π/8) = 0.383 ω_c).
pub fn bridge_support_s(cfg: &FilterConfig) -> f64 {
    let lowest = cfg
        .radar_cutoff_hz
        .min(cfg.tacho_cutoff_hz)
        .min(cfg.pressure_cutoff_hz);
    let rate = std::f64::consts::TAU * lowest * (3.0 * std::f64::consts::PI / 8.0).cos();
    BRIDGE_SUPPORT_TAUS / rate
}

/// Time constants of the slowest pole pair masked around a bridged gap.
pub const BRIDGE_SUPPORT_TAUS: f64 = 1.0;

/// Channels in the order they are filtered together: radar, ω1..ω4, p1..p4.
const LANES: usize = 1 + 2 * AXLES;

/// Conditions a run: despiking, low-pass, derivatives. The nine channels are filtered in
/// lockstep ([`filter::zero_phase_lanes`]), segment by segment.
pub fn condition(log: &RunLog, cfg: &FilterConfig) -> Result<Conditioned, FilterError> {
    let fs = log.sample_rate_hz;
    let f = Filters::design(cfg, fs)?;
    let all_segs = segments(log);
    let segs: Vec<(usize, usize)> = all_segs
        .iter()
        .copied()
        .filter(|(a, b)| b - a >= filter::MIN_LEN)
        .collect();
    let (outs, despiked) = filter_segments(log, cfg, &f, &segs)?;
    let dt = 1.0 / fs;
    let [v_mps, o1, o2, o3, o4, p1, p2, p3, p4] = outs;
    let omega_radps = [o1, o2, o3, o4];
    let accel_mps2 = derivative_of(&v_mps, &segs, dt);
    let omega_dot_radps2: [Vec<f64>; AXLES] =
        std::array::from_fn(|a| derivative_of(&omega_radps[a], &segs, dt));
    let p_bar = [p1, p2, p3, p4];
    let mode = cfg.mode;
    let m = Masks::new(log, cfg, &all_segs, &segs);
    let delay = |lp: &LowPass4| match mode {
        FilterMode::ZeroPhase => 0.0,
        FilterMode::Causal => lp.dc_group_delay_s(),
    };
    Ok(Conditioned {
        sample_rate_hz: fs,
        mode,
        v_mps,
        accel_mps2,
        omega_radps,
        omega_dot_radps2,
        p_bar,
        has_data: m.has_data,
        usable: m.usable,
        settled: m.settled,
        settle_s: m.settle_s,
        near_bridge: m.near_bridge,
        bridge_support_s: m.bridge_support_s,
        despiked,
        group_delay_s: GroupDelays {
            radar_s: delay(&f.radar),
            tacho_s: delay(&f.tacho),
            pressure_s: delay(&f.pressure),
        },
    })
}

/// Sets the samples of `v` outside the segments `segs` to NaN (the rest is left as is).
fn nan_outside(v: &mut [f64], segs: &[(usize, usize)]) {
    let mut at = 0;
    for &(a, b) in segs {
        v[at..a].fill(f64::NAN);
        at = b;
    }
    v[at..].fill(f64::NAN);
}

/// Despikes the radar and low-passes the nine channels (radar, ω1..ω4, p1..p4) of each
/// segment in `segs` in lockstep, zero-phase or causal; NaN outside the segments. Returns
/// the filtered channels and the number of radar samples the Hampel filter replaced.
fn filter_segments(
    log: &RunLog,
    cfg: &FilterConfig,
    f: &Filters,
    segs: &[(usize, usize)],
) -> Result<([Vec<f64>; LANES], usize), FilterError> {
    let fs = log.sample_rate_hz;
    let n = log.len();
    let bank: [LowPass4; LANES] = std::array::from_fn(|l| match l {
        0 => f.radar,
        l if l <= AXLES => f.tacho,
        _ => f.pressure,
    });
    let inputs: [&[f64]; LANES] = std::array::from_fn(|l| match l {
        0 => &log.v_radar_mps[..],
        l if l <= AXLES => &log.omega_radps[l - 1][..],
        l => &log.p_bar[l - 1 - AXLES][..],
    });
    // Zeroed allocations come from the OS already zero (no fill pass); only the samples
    // outside the conditioned segments are set to NaN.
    let mut outs: [Vec<f64>; LANES] = std::array::from_fn(|_| {
        let mut v = vec![0.0; n];
        nan_outside(&mut v, segs);
        v
    });
    let mut radar = Vec::new();
    let mut buf: Vec<[f64; LANES]> = Vec::new();
    let mut despiked = 0;
    for &(a, b) in segs {
        radar.clear();
        radar.extend_from_slice(&log.v_radar_mps[a..b]);
        if let Some(d) = cfg.despike {
            despiked += despike::despike(&mut radar, &d, fs);
        }
        let x: [&[f64]; LANES] = std::array::from_fn(|l| match l {
            0 => &radar[..],
            l => &inputs[l][a..b],
        });
        match cfg.mode {
            FilterMode::ZeroPhase => {
                let mut it = outs.iter_mut();
                let y: [&mut [f64]; LANES] =
                    std::array::from_fn(|_| &mut it.next().expect("LANES outputs")[a..b]);
                filter::zero_phase_many(&bank, x, y)?;
            }
            FilterMode::Causal => {
                buf.clear();
                buf.extend((0..b - a).map(|j| std::array::from_fn(|l| x[l][j])));
                filter::causal_lanes(&bank, &mut buf);
                for (l, out) in outs.iter_mut().enumerate() {
                    for (o, row) in out[a..b].iter_mut().zip(&buf) {
                        *o = row[l];
                    }
                }
            }
        }
    }
    Ok((outs, despiked))
}

/// The time derivative of `y` (sample step `dt`, s) segment by segment; NaN outside `segs`.
fn derivative_of(y: &[f64], segs: &[(usize, usize)], dt: f64) -> Vec<f64> {
    let mut d = vec![0.0; y.len()];
    nan_outside(&mut d, segs);
    for &(a, b) in segs {
        derivative::derivative(&y[a..b], dt, &mut d[a..b]);
    }
    d
}

/// The per-sample masks of a conditioned run and the margins they use.
struct Masks {
    has_data: Vec<bool>,
    usable: Vec<bool>,
    settled: Vec<bool>,
    settle_s: f64,
    near_bridge: Vec<bool>,
    bridge_support_s: f64,
}

impl Masks {
    /// `has_data` over every segment (`all_segs`); `usable` over the conditioned ones
    /// (`segs`), `settled` one period of the lowest cut-off inside their ends; the bridged
    /// gaps and the filters' support around them are `near_bridge` and never settled.
    fn new(
        log: &RunLog,
        cfg: &FilterConfig,
        all_segs: &[(usize, usize)],
        segs: &[(usize, usize)],
    ) -> Masks {
        let fs = log.sample_rate_hz;
        let n = log.len();
        let mut usable = vec![false; n];
        let mut settled = vec![false; n];
        let lowest = cfg
            .radar_cutoff_hz
            .min(cfg.tacho_cutoff_hz)
            .min(cfg.pressure_cutoff_hz);
        let settle_s = 1.0 / lowest;
        let guard = (settle_s * fs).ceil() as usize;
        for &(a, b) in segs {
            usable[a..b].fill(true);
            if b - a > 2 * guard {
                settled[a + guard..b - guard].fill(true);
            }
        }
        // Bridged gaps: the interpolated samples and the filters' support around them.
        let support = bridge_support_s(cfg);
        let mut near_bridge = vec![false; n];
        if let (Some(&t0), true) = (log.time_s.first(), log.gaps.iter().any(|g| g.bridged)) {
            for g in log.gaps.iter().filter(|g| g.bridged) {
                let a = (((g.from_s - support - t0) * fs).floor().max(0.0) as usize).min(n);
                let b = (((g.to_s + support - t0) * fs).ceil().max(0.0) as usize + 1).min(n);
                near_bridge[a..b].fill(true);
                settled[a..b].fill(false);
            }
        }
        let mut has_data = vec![false; n];
        for &(a, b) in all_segs {
            has_data[a..b].fill(true);
        }
        Masks {
            has_data,
            usable,
            settled,
            settle_s,
            near_bridge,
            bridge_support_s: support,
        }
    }
}
