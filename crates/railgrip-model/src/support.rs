//! The data-support blend of networks with a support grid (format version 2; step 3 of the
//! evaluation rule in [`super`]): a multilinear interpolation, over the grid's cell centres,
//! of the support indicator and of the fallback (|μ|; a residual network's residual). The C
//! header does the same operations in the same order (no fused multiply-adds), so the results
//! agree to the bit.

use super::file::{SupportSpec, MAX_INPUTS};

/// A support grid ready to evaluate.
#[derive(Debug, Clone)]
pub(super) struct SupportEval {
    k: usize,
    /// Cells per input (unused inputs 1).
    n: [usize; MAX_INPUTS],
    /// Flat-index stride per input.
    stride: [usize; MAX_INPUTS],
    /// n_c / 2: the cell coordinate is u = (x_n + 1) · n_c/2 − 1/2 (cell centres at integers).
    half: [f64; MAX_INPUTS],
    /// 1 for a supported cell, 0 otherwise.
    s: Vec<f64>,
    /// Fallback |μ| per cell.
    f: Vec<f64>,
    /// Ensemble spread per cell (empty without).
    spread: Vec<f64>,
}

impl SupportEval {
    pub(super) fn new(spec: &SupportSpec) -> SupportEval {
        let k = spec.cells.len();
        let mut n = [1; MAX_INPUTS];
        n[..k].copy_from_slice(&spec.cells);
        let mut stride = [1; MAX_INPUTS];
        for c in (0..k.saturating_sub(1)).rev() {
            stride[c] = stride[c + 1] * n[c + 1];
        }
        SupportEval {
            k,
            n,
            stride,
            half: n.map(|v| v as f64 / 2.0),
            s: (0..spec.len())
                .map(|j| if spec.supported(j) { 1.0 } else { 0.0 })
                .collect(),
            f: spec.fallback_mu.clone(),
            spread: spec.spread.clone(),
        }
    }

    /// The lower corner's flat index, the fractions along each input, and the fade beyond the
    /// grid for normalised, unclamped inputs `xn`: u_c = (x_n,c + 1) · n_c/2 − 1/2 (cell centres
    /// at integers), clamped to [0, n_c − 1] for the interpolation; i_c = min(⌊u_c⌋, n_c − 2);
    /// f_c = u_c − i_c. Beyond the grid's edge (x_n = ±1, u_c = −1/2 or n_c − 1/2) the support
    /// fades to 0 over one cell, as if a row of unsupported cells lay outside the grid:
    /// fade = Π_c (1 − min(1, d_c)) with d_c = max(0, −1/2 − u_c, u_c − (n_c − 1) − 1/2) of the
    /// unclamped u_c. (Inside the edge nothing fades: a run at the coldest ambient temperature
    /// of a campaign lies on the edge of a four-input grid and is fully supported.)
    #[inline(always)]
    fn corner<const K: usize>(&self, xn: &[f64; MAX_INPUTS]) -> (usize, [f64; MAX_INPUTS], f64) {
        let mut base = 0;
        let mut f = [0.0; MAX_INPUTS];
        let mut fade = 1.0;
        for c in 0..K {
            let top = (self.n[c] - 1) as f64;
            let raw = (xn[c] + 1.0) * self.half[c] - 0.5;
            let beyond = (-0.5 - raw).max(raw - top - 0.5).clamp(0.0, 1.0);
            fade *= 1.0 - beyond;
            let u = raw.clamp(0.0, top);
            let i = u.floor().min(top - 1.0);
            f[c] = u - i;
            base += i as usize * self.stride[c];
        }
        (base, f, fade)
    }

    /// Multilinear interpolation of `a` and `b` at `xn`: Σ over the 2ᵏ corners, in the order
    /// of their bit patterns (input 0 the highest bit), of Π_c (f_c or 1 − f_c) · value, the
    /// product built from 1.0 input by input; and the fade beyond the grid. Compiled for two,
    /// three and four inputs (loops unrolled).
    #[inline(always)]
    fn interpolate2(&self, xn: &[f64; MAX_INPUTS], a: &[f64], b: &[f64]) -> (f64, f64, f64) {
        match self.k {
            2 => self.interpolate_k::<2>(xn, a, b),
            3 => self.interpolate_k::<3>(xn, a, b),
            _ => self.interpolate_k::<4>(xn, a, b),
        }
    }

    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn interpolate_k<const K: usize>(
        &self,
        xn: &[f64; MAX_INPUTS],
        a: &[f64],
        b: &[f64],
    ) -> (f64, f64, f64) {
        let (base, f, fade) = self.corner::<K>(xn);
        let (mut sa, mut sb) = (0.0, 0.0);
        for corner in 0..(1usize << K) {
            let mut w = 1.0;
            let mut j = base;
            for c in 0..K {
                if corner >> (K - 1 - c) & 1 == 1 {
                    w *= f[c];
                    j += self.stride[c];
                } else {
                    w *= 1.0 - f[c];
                }
            }
            sa += w * a[j];
            sb += w * b[j];
        }
        (sa, sb, fade)
    }

    /// Step 3 of the evaluation rule: with w the interpolated support (times the fade beyond
    /// the grid) and F the interpolated fallback at the normalised, unclamped inputs `xn`,
    /// m where w = 1, F where w = 0, else w m + (1 − w) F.
    #[inline(always)]
    pub(super) fn apply(&self, xn: &[f64; MAX_INPUTS], m: f64) -> f64 {
        let (w, fb, fade) = self.interpolate2(xn, &self.s, &self.f);
        let w = w * fade;
        if w == 1.0 {
            m
        } else if w == 0.0 {
            fb
        } else {
            w * m + (1.0 - w) * fb
        }
    }

    /// The interpolated support w ∈ [0, 1] at `xn` (with the fade beyond the grid).
    pub(super) fn weight(&self, xn: &[f64; MAX_INPUTS]) -> f64 {
        let (w, _, fade) = self.interpolate2(xn, &self.s, &self.s);
        w * fade
    }

    /// The interpolated ensemble spread at `xn` (`None` without).
    pub(super) fn spread(&self, xn: &[f64; MAX_INPUTS]) -> Option<f64> {
        (!self.spread.is_empty()).then(|| self.interpolate2(xn, &self.spread, &self.spread).0)
    }
}
