//! 4th-order Butterworth low-pass as two cascaded biquads (seed 002
//! 002_8d8769283f5e9cb6.txt, "Data from test runs": 1.5 Hz for the radar, 4 Hz for the
//! tachometers).
//!
//! Design: the biquad crate's bilinear-transform low-pass sections (pre-warped at the
//! cut-off, like scipy's `butter`) with the Butterworth pole quality factors
//! Q_k = 1 / (2 cos((2k − 1)π/8)), k = 1, 2 → 0.541196, 1.306563. The product of the two
//! sections is the transfer function of `scipy.signal.butter(4, fc, fs=fs, output='sos')`.
//!
//! Running: Direct Form II transposed (the crate's `DirectForm2Transposed`, as scipy's
//! `sosfilt`). Two modes:
//! - [`LowPass4::causal`]: one forward pass starting in the steady state of the first sample
//!   (scipy `sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])`). A zero initial state — MATLAB's
//!   `filter` default — would add a start-up transient of the full signal level.
//! - [`LowPass4::zero_phase`]: forward–backward with scipy `sosfiltfilt`'s edge handling: odd
//!   extension by 3 × (2 × sections + 1) = 15 samples at both ends, each pass starting in the
//!   steady state of its first sample.
//!
//! Both agree with scipy to ≤ 1e-9 relative on committed reference signals
//! (tests/data/signal/, made by tests/data/signal/make_reference.py).

use biquad::{Biquad, Coefficients, DirectForm2Transposed, ToHertz, Type};

/// Samples of odd extension at each end in zero-phase mode (scipy's default padlen for two
/// second-order sections: 3 × 5).
pub const PAD: usize = 15;

/// Shortest signal the zero-phase filter accepts (scipy: longer than padlen).
pub const MIN_LEN: usize = PAD + 1;

/// Errors of the filter design and application.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("low-pass cut-off {cutoff_hz} Hz at {sample_rate_hz} Hz sampling: must be > 0 and < half the sampling rate")]
    Cutoff { cutoff_hz: f64, sample_rate_hz: f64 },
    #[error("{len} samples: the zero-phase filter needs at least {MIN_LEN}")]
    TooShort { len: usize },
}

/// A 4th-order Butterworth low-pass, two second-order sections.
#[derive(Debug, Clone, Copy)]
pub struct LowPass4 {
    sections: [Coefficients<f64>; 2],
    /// Cut-off (−3 dB of one pass), Hz.
    pub cutoff_hz: f64,
    /// Sampling rate, Hz.
    pub sample_rate_hz: f64,
}

impl LowPass4 {
    /// Designs the filter. Valid domain: 0 < `cutoff_hz` < `sample_rate_hz` / 2.
    pub fn butterworth(cutoff_hz: f64, sample_rate_hz: f64) -> Result<Self, FilterError> {
        let err = FilterError::Cutoff {
            cutoff_hz,
            sample_rate_hz,
        };
        if !(sample_rate_hz.is_finite()
            && cutoff_hz.is_finite()
            && cutoff_hz > 0.0
            && cutoff_hz < sample_rate_hz / 2.0)
        {
            return Err(err);
        }
        let q = |k: f64| 1.0 / (2.0 * ((2.0 * k - 1.0) * std::f64::consts::PI / 8.0).cos());
        let section = |qk: f64| {
            Coefficients::<f64>::from_params(Type::LowPass, sample_rate_hz.hz(), cutoff_hz.hz(), qk)
                .map_err(|_| err.clone())
        };
        Ok(LowPass4 {
            sections: [section(q(1.0))?, section(q(2.0))?],
            cutoff_hz,
            sample_rate_hz,
        })
    }

    /// The two sections' coefficients (b0, b1, b2, a1, a2; a0 = 1).
    pub fn sections(&self) -> [[f64; 5]; 2] {
        self.sections.map(|c| [c.b0, c.b1, c.b2, c.a1, c.a2])
    }

    /// Group delay at DC of one forward pass, s: Σ over sections of
    /// Σ n b_n / Σ b_n − Σ n a_n / Σ a_n samples (the derivative of the phase at ω = 0).
    /// The zero-phase mode has none.
    pub fn dc_group_delay_s(&self) -> f64 {
        let samples: f64 = self
            .sections
            .iter()
            .map(|c| {
                let b = c.b0 + c.b1 + c.b2;
                let a = 1.0 + c.a1 + c.a2;
                (c.b1 + 2.0 * c.b2) / b - (c.a1 + 2.0 * c.a2) / a
            })
            .sum();
        samples / self.sample_rate_hz
    }

    /// Both sections set to the steady state of a constant input `x0` (scipy `sosfilt_zi`:
    /// each section's state for its DC input, section gain Σb / Σa).
    fn steady(&self, x0: f64) -> [DirectForm2Transposed<f64>; 2] {
        let mut level = x0;
        self.sections.map(|c| {
            let gain = (c.b0 + c.b1 + c.b2) / (1.0 + c.a1 + c.a2);
            let y = gain * level;
            let mut f = DirectForm2Transposed::<f64>::new(c);
            f.s2 = c.b2 * level - c.a2 * y;
            f.s1 = c.b1 * level - c.a1 * y + f.s2;
            level = y;
            f
        })
    }

    /// One forward pass over `x`, starting in the steady state of `x[0]` (scipy
    /// `sosfilt(sos, x, zi=sosfilt_zi(sos) * x[0])`). Empty input gives empty output.
    pub fn causal(&self, x: &[f64]) -> Vec<f64> {
        let mut buf: Vec<[f64; 1]> = x.iter().map(|&v| [v]).collect();
        causal_lanes(&[*self], &mut buf);
        buf.into_iter().map(|[v]| v).collect()
    }

    /// Forward–backward filtering of `x` with scipy `sosfiltfilt`'s odd padding and initial
    /// conditions. Needs at least [`MIN_LEN`] samples.
    pub fn zero_phase(&self, x: &[f64]) -> Result<Vec<f64>, FilterError> {
        let mut buf = vec![[0.0]; x.len() + 2 * PAD];
        for (b, &v) in buf[PAD..].iter_mut().zip(x) {
            *b = [v];
        }
        zero_phase_lanes(&[*self], &mut buf)?;
        Ok(buf[PAD..PAD + x.len()].iter().map(|[v]| *v).collect())
    }
}

/// Runs `L` filters in lockstep over interleaved samples, in place: `buf[j][l]` is sample j
/// of channel l, filtered by `filters[l]`. The L recursions are independent, so the CPU
/// overlaps them — one pass over 9 channels costs little more than one channel's latency
/// chain. One forward pass from the steady state of each channel's first sample.
pub fn causal_lanes<const L: usize>(filters: &[LowPass4; L], buf: &mut [[f64; L]]) {
    let Some(first) = buf.first() else { return };
    let mut st: [[DirectForm2Transposed<f64>; 2]; L] =
        std::array::from_fn(|l| filters[l].steady(first[l]));
    run_lanes(&mut st, buf.iter_mut());
}

/// Zero-phase forward–backward filtering of `L` interleaved channels in place (see
/// [`causal_lanes`]). `buf` holds [`PAD`] free rows, the n ≥ [`MIN_LEN`] samples, and [`PAD`]
/// free rows; the free rows receive scipy's odd extension and the samples the result.
pub fn zero_phase_lanes<const L: usize>(
    filters: &[LowPass4; L],
    buf: &mut [[f64; L]],
) -> Result<(), FilterError> {
    let n = buf.len().saturating_sub(2 * PAD);
    if n < MIN_LEN {
        return Err(FilterError::TooShort { len: n });
    }
    let (first, last) = (buf[PAD], buf[PAD + n - 1]);
    for k in 1..=PAD {
        let (ahead, behind) = (buf[PAD + k], buf[PAD + n - 1 - k]);
        for l in 0..L {
            buf[PAD - k][l] = 2.0 * first[l] - ahead[l];
            buf[PAD + n - 1 + k][l] = 2.0 * last[l] - behind[l];
        }
    }
    let start = buf[0];
    let mut st: [[DirectForm2Transposed<f64>; 2]; L] =
        std::array::from_fn(|l| filters[l].steady(start[l]));
    run_lanes(&mut st, buf.iter_mut());
    let end = buf[buf.len() - 1];
    let mut st: [[DirectForm2Transposed<f64>; 2]; L] =
        std::array::from_fn(|l| filters[l].steady(end[l]));
    run_lanes(&mut st, buf.iter_mut().rev());
    Ok(())
}

/// Zero-phase filtering of `L` separate channels in lockstep, `x[l]` into `y[l]` (all the
/// same length n ≥ [`MIN_LEN`]): the same arithmetic as [`zero_phase_lanes`] without an
/// interleaved copy of the signals (only the 2 × [`PAD`] extension rows are stored apart).
pub fn zero_phase_many<const L: usize>(
    filters: &[LowPass4; L],
    x: [&[f64]; L],
    y: [&mut [f64]; L],
) -> Result<(), FilterError> {
    let n = x[0].len();
    assert!(
        x.iter().all(|c| c.len() == n) && y.iter().all(|c| c.len() == n),
        "zero_phase_many: channel lengths"
    );
    if n < MIN_LEN {
        return Err(FilterError::TooShort { len: n });
    }
    // Odd extensions, in time order.
    let left: [[f64; L]; PAD] =
        std::array::from_fn(|j| std::array::from_fn(|l| 2.0 * x[l][0] - x[l][PAD - j]));
    let mut right: [[f64; L]; PAD] =
        std::array::from_fn(|j| std::array::from_fn(|l| 2.0 * x[l][n - 1] - x[l][n - 2 - j]));
    // Forward: left extension (outputs not needed), the signal into y, the right extension.
    let mut st: [[DirectForm2Transposed<f64>; 2]; L] =
        std::array::from_fn(|l| filters[l].steady(left[0][l]));
    for row in &left {
        for (v, [s1, s2]) in row.iter().zip(st.iter_mut()) {
            s2.run(s1.run(*v));
        }
    }
    for j in 0..n {
        for l in 0..L {
            let [s1, s2] = &mut st[l];
            y[l][j] = s2.run(s1.run(x[l][j]));
        }
    }
    run_lanes(&mut st, right.iter_mut());
    // Backward: from the steady state of the last forward output, through the right
    // extension (discarded) and the signal in place.
    let end = right[PAD - 1];
    let mut st: [[DirectForm2Transposed<f64>; 2]; L] =
        std::array::from_fn(|l| filters[l].steady(end[l]));
    run_lanes(&mut st, right.iter_mut().rev());
    for j in (0..n).rev() {
        for l in 0..L {
            let [s1, s2] = &mut st[l];
            y[l][j] = s2.run(s1.run(y[l][j]));
        }
    }
    Ok(())
}

#[inline]
fn run_lanes<'a, const L: usize>(
    st: &mut [[DirectForm2Transposed<f64>; 2]; L],
    rows: impl Iterator<Item = &'a mut [f64; L]>,
) {
    for row in rows {
        for (v, [s1, s2]) in row.iter_mut().zip(st.iter_mut()) {
            *v = s2.run(s1.run(*v));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cutoff_outside_zero_to_nyquist_is_an_error() {
        for fc in [0.0, -1.0, 208.5, 300.0, f64::NAN, f64::INFINITY] {
            assert!(LowPass4::butterworth(fc, 417.0).is_err(), "{fc}");
        }
        assert!(LowPass4::butterworth(208.0, 417.0).is_ok());
    }

    #[test]
    fn unity_dc_gain_and_constant_passes_unchanged() {
        let f = LowPass4::butterworth(1.5, 417.0).unwrap();
        let x = vec![33.3; 500];
        let y = f.causal(&x);
        assert!(y.iter().all(|v| (v - 33.3).abs() < 1e-10), "{:?}", &y[..3]);
        let y = f.zero_phase(&x).unwrap();
        assert!(y.iter().all(|v| (v - 33.3).abs() < 1e-10));
    }

    #[test]
    fn group_delay_matches_the_analog_prototype() {
        // Analog 4th-order Butterworth: τ(0) = (1/Q1 + 1/Q2) / (2π fc) = 2.6131 / (2π fc).
        for fc in [1.5, 4.0] {
            let f = LowPass4::butterworth(fc, 417.0).unwrap();
            let analog = 2.0
                * ((std::f64::consts::PI / 8.0).cos() + (3.0 * std::f64::consts::PI / 8.0).cos())
                / (2.0 * std::f64::consts::PI * fc);
            let d = f.dc_group_delay_s();
            assert!((d - analog).abs() / analog < 2e-3, "{fc}: {d} vs {analog}");
        }
    }

    #[test]
    fn short_input_is_an_error_not_a_panic() {
        let f = LowPass4::butterworth(4.0, 417.0).unwrap();
        assert_eq!(
            f.zero_phase(&[1.0; 15]),
            Err(FilterError::TooShort { len: 15 })
        );
        assert!(f.causal(&[]).is_empty());
    }
}
