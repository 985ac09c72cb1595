//! The logger: the sensor models and the truth table, sampled at their logger instants k/rate
//! (µs resolution), from the state of the first step at or after each instant (the counting
//! tachometers' wheel angles excepted: those are taken back to the instant itself). Each sensor
//! effect (radar noise and spikes, tachometer pulse counting, pressure noise) runs only when
//! the scene lists it and is counted where its work is done.

use super::scene::{Effect, Scene};
use super::state::SimState;
use super::{EffectCounters, Series, Truth};
use crate::format::AXLES;
use crate::rng::Rng;

/// Normal deviates for the sensor noise, both of each Box–Muller pair (one log, one sqrt and
/// one sin_cos per two deviates).
#[derive(Default)]
struct Normals {
    spare: Option<f64>,
}

impl Normals {
    fn next(&mut self, rng: &mut Rng) -> f64 {
        match self.spare.take() {
            Some(x) => x,
            None => {
                let (x, y) = rng.normal_pair();
                self.spare = Some(y);
                x
            }
        }
    }
}

/// The sample groups, each on its own schedule: radar, tachometers, pressures, truth.
const RADAR: usize = 0;
const TACHO: usize = 1;
const PRESSURE: usize = 2;
const TRUTH: usize = 3;

/// The logger of one run.
pub(super) struct Logger<'a> {
    sc: &'a Scene,
    rates: [f64; 4],
    /// Index and logger time (k / rate) of the next sample of each group, and the earliest.
    next_k: [u64; 4],
    next_t: [f64; 4],
    next_due: f64,
    rng: Rng,
    normals: Normals,
    /// Radar spike probability per sample.
    spike_prob: f64,
    /// Angle per tachometer pulse (rad), counting window (samples) and the wheel angles of the
    /// last `window + 1` tachometer samples.
    pulse_angle: f64,
    window: usize,
    theta_hist: Vec<[f64; AXLES]>,
    /// `radar_error`: the true speed at the last radar instants (a ring as long as the
    /// latency), empty without it.
    radar_hist: Vec<f64>,
    /// Measured channels in [`crate::format::Signal::ALL`] order.
    pub channels: Vec<Series>,
    pub truth: Truth,
}

/// Rounds to a resolution of 1/inv (a logger's resolution; keeps files small and exact).
#[inline(always)]
fn round_to(x: f64, inv: f64) -> f64 {
    (x * inv).round() / inv
}

#[inline(always)]
fn push(s: &mut Series, t: f64, v: f64) {
    s.time_s.push(t);
    s.values.push(v);
}

impl<'a> Logger<'a> {
    /// An empty log with room for the whole run (at most ten minutes' worth up front: no
    /// reallocation and copy while the step loop runs).
    #[inline(always)]
    pub(super) fn new(sc: &'a Scene, seed: u64) -> Logger<'a> {
        let s = &sc.sensors;
        let rates = [
            s.radar_rate_hz,
            s.tacho_rate_hz,
            s.pressure_rate_hz,
            sc.run.output_rate_hz,
        ];
        let room = |rate: f64| ((sc.run.max_duration_s.min(600.0) * rate).ceil() as usize) + 2;
        let series = |rate: f64| Series {
            time_s: Vec::with_capacity(room(rate)),
            values: Vec::with_capacity(room(rate)),
        };
        let channels: Vec<Series> = (0..9)
            .map(|i| {
                series(
                    rates[match i {
                        0 => RADAR,
                        1..=4 => TACHO,
                        _ => PRESSURE,
                    }],
                )
            })
            .collect();
        let column = || Vec::with_capacity(room(sc.run.output_rate_hz));
        let columns = || std::array::from_fn(|_| column());
        let window = ((s.tacho_window_s * s.tacho_rate_hz).round() as usize).max(1);
        let spike_prob = s.radar_spike_rate_hz / s.radar_rate_hz;
        Logger {
            sc,
            rates,
            next_k: [0; 4],
            next_t: [0.0; 4],
            next_due: 0.0,
            rng: Rng::new(seed),
            normals: Normals::default(),
            spike_prob: if spike_prob.is_finite() {
                spike_prob
            } else {
                0.0
            },
            pulse_angle: std::f64::consts::TAU / s.tacho_pulses_per_rev,
            window,
            theta_hist: vec![[0.0; AXLES]; window + 1],
            radar_hist: if sc.effects.has(Effect::RadarError) {
                vec![0.0; (s.radar_latency_s * s.radar_rate_hz).floor() as usize + 2]
            } else {
                Vec::new()
            },
            channels,
            truth: Truth {
                time_s: column(),
                v_mps: column(),
                omega_radps: columns(),
                p_bar: columns(),
                normal_n: columns(),
                tangential_n: columns(),
                mu: columns(),
                dv_mps: columns(),
                ddv_mps2: columns(),
                contact_temperature_c: if sc.effects.has(Effect::Thermal) {
                    columns()
                } else {
                    Default::default()
                },
            },
        }
    }

    /// True when a sample of some group is due at step time `t` (s).
    #[inline(always)]
    pub(super) fn due(&self, t: f64) -> bool {
        t + 1e-12 >= self.next_due
    }

    /// Takes every sample due at step time `t` from the state `st`; true when a truth sample
    /// was among them. (Inlined into the step loop like the sensor models below: compiled
    /// there with the loop's target features, `f64::round` is a few instructions instead of a
    /// libm call — 8 % of a full scene's time when it was not.)
    #[inline(always)]
    pub(super) fn record(&mut self, t: f64, st: &SimState, counters: &mut EffectCounters) -> bool {
        let mut truth = false;
        for g in 0..4 {
            while self.next_t[g] <= t + 1e-12 {
                // Logger clock at µs resolution.
                let ts = round_to(self.next_k[g] as f64 / self.rates[g], 1e6);
                match g {
                    RADAR => self.radar(ts, st, counters),
                    TACHO => self.tachometers(ts, t - self.next_t[g], st, counters),
                    PRESSURE => self.pressures(ts, st, counters),
                    TRUTH => {
                        self.truth_sample(ts, st);
                        truth = true;
                    }
                    _ => unreachable!("four groups"),
                }
                self.next_k[g] += 1;
                self.next_t[g] = self.next_k[g] as f64 / self.rates[g];
            }
        }
        self.next_due = self.next_t.iter().copied().fold(f64::INFINITY, f64::min);
        truth
    }

    #[inline(always)]
    fn radar(&mut self, ts: f64, st: &SimState, counters: &mut EffectCounters) {
        let (fx, s) = (self.sc.effects, &self.sc.sensors);
        let mut m = st.v;
        if fx.has(Effect::RadarError) {
            // The true speed at the radar's instants, kept as long as the latency; the reading
            // is the speed `radar_latency_s` ago (linear between two instants), scaled. Before
            // the first instant it is the first one's (the run starts at constant speed).
            counters.hit(Effect::RadarError);
            let k = self.next_k[RADAR] as usize;
            let len = self.radar_hist.len();
            self.radar_hist[k % len] = st.v;
            let lag = s.radar_latency_s * self.rates[RADAR];
            let n = lag.floor() as usize;
            let frac = lag - n as f64;
            let at = |j: usize| self.radar_hist[k.saturating_sub(j) % len];
            m = s.radar_scale * ((1.0 - frac) * at(n) + frac * at(n + 1));
        }
        if fx.has(Effect::RadarNoise) {
            counters.hit(Effect::RadarNoise);
            m += s.radar_noise_mps * self.normals.next(&mut self.rng);
        }
        if fx.has(Effect::RadarSpikes) {
            counters.hit(Effect::RadarSpikes);
            if self.rng.uniform() < self.spike_prob {
                m += if self.rng.uniform() < 0.5 { -1.0 } else { 1.0 }
                    * s.radar_spike_mps
                    * (0.5 + self.rng.uniform());
            }
        }
        push(&mut self.channels[0], ts, round_to(m.max(0.0), 1e3));
    }

    /// The tachometers' sample k at logger time `ts`, taken at the step `lag_s` (0 ≤ lag_s <
    /// one step, s) after its instant. Without `tacho_quantization` the reading is the wheel's
    /// ω (rad/s). With it, a pulse counter over the last W samples (W = window × rate,
    /// rounded): ω̂_k = (⌊θ_k/Δθ⌋ − ⌊θ_(k−W)/Δθ⌋) Δθ f / W, θ the wheel's angle (rad) at each
    /// sample's instant, Δθ = 2π / pulses per revolution, f the tachometers' rate (Hz): the mean
    /// ω over the window, W/(2f) late, within one count (Δθ f / W) of it.
    #[inline(always)]
    fn tachometers(&mut self, ts: f64, lag_s: f64, st: &SimState, counters: &mut EffectCounters) {
        let quantized = self.sc.effects.has(Effect::TachoQuantization);
        let k = self.next_k[TACHO] as usize;
        let window = self.window;
        // The wheel angles at the sample's instant: the angle advanced with the present ω over
        // the last step, so θ(instant) = θ_step − ω lag_s exactly. (Latched at the step, a
        // reading was off by ω times the difference of two samples' lags over the window's
        // duration, up to 0.44 % of ω, repeating with the 8 Hz beat of the 10 kHz steps
        // against a 417 Hz logger.)
        let mut theta = st.theta;
        for (th, om) in theta.iter_mut().zip(st.ax.omega) {
            *th -= om * lag_s;
        }
        self.theta_hist[k % (window + 1)] = theta;
        for (a, (&th, &omega)) in theta.iter().zip(&st.ax.omega).enumerate() {
            let m = if quantized {
                counters.hit(Effect::TachoQuantization);
                // Pulses counted over the last `window` samples.
                let span = k.min(window);
                if span == 0 {
                    omega
                } else {
                    let old = self.theta_hist[(k - span) % (window + 1)][a];
                    let count = (th / self.pulse_angle).floor() - (old / self.pulse_angle).floor();
                    count * self.pulse_angle * self.rates[TACHO] / span as f64
                }
            } else {
                omega
            };
            push(&mut self.channels[1 + a], ts, round_to(m, 1e4));
        }
    }

    #[inline(always)]
    fn pressures(&mut self, ts: f64, st: &SimState, counters: &mut EffectCounters) {
        let noisy = self.sc.effects.has(Effect::PressureNoise);
        for a in 0..AXLES {
            let mut m = st.p[a];
            if noisy {
                counters.hit(Effect::PressureNoise);
                m += self.sc.sensors.pressure_noise_bar * self.normals.next(&mut self.rng);
            }
            push(&mut self.channels[5 + a], ts, round_to(m, 1e3));
        }
    }

    #[inline(always)]
    fn truth_sample(&mut self, ts: f64, st: &SimState) {
        let r = self.sc.vehicle.wheel_radius_m;
        let tr = &mut self.truth;
        tr.time_s.push(ts);
        tr.v_mps.push(st.v);
        for a in 0..AXLES {
            let omega = st.ax.omega[a];
            tr.omega_radps[a].push(omega);
            tr.p_bar[a].push(st.p[a]);
            tr.normal_n[a].push(st.normal[a]);
            tr.tangential_n[a].push(st.ax.t_star[a]);
            tr.mu[a].push(st.ax.t_star[a] / st.normal[a]);
            tr.dv_mps[a].push(st.v - r * omega);
            tr.ddv_mps2[a].push(st.ddv[a]);
        }
        if self.sc.effects.has(super::scene::Effect::Thermal) {
            for a in 0..AXLES {
                tr.contact_temperature_c[a].push(st.contact_c[a]);
            }
        }
    }
}
