//! The data-support blend of networks with a support grid (format version 2; step 4 of the
//! evaluation rule in [`super`]): a multilinear interpolation, over the grid's cell centres,
//! of the support indicator and of the fallback |μ|. The C header does the same operations in
//! the same order (no fused multiply-adds), so the results agree to the bit.

use super::file::SupportSpec;

/// A support grid ready to evaluate.
#[derive(Debug, Clone)]
pub(super) struct SupportEval {
    k: usize,
    /// Cells per input (unused inputs 1).
    n: [usize; 3],
    /// Flat-index stride per input.
    stride: [usize; 3],
    /// n_c / 2: the cell coordinate is u = (x_n + 1) · n_c/2 − 1/2 (cell centres at integers).
    half: [f64; 3],
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
        let mut n = [1; 3];
        n[..k].copy_from_slice(&spec.cells);
        let mut stride = [1; 3];
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

    /// The lower corner's flat index and the fractions along each input for normalised
    /// inputs `xn` (already clamped to [−1, 1] by the domain clamp): u_c = (x_n,c + 1) · n_c/2 − 1/2
    /// clamped to [0, n_c − 1]; i_c = min(⌊u_c⌋, n_c − 2); f_c = u_c − i_c.
    #[inline(always)]
    fn corner(&self, xn: &[f64; 3]) -> (usize, [f64; 3]) {
        let mut base = 0;
        let mut f = [0.0; 3];
        for c in 0..self.k {
            let top = (self.n[c] - 1) as f64;
            let u = ((xn[c] + 1.0) * self.half[c] - 0.5).clamp(0.0, top);
            let i = u.floor().min(top - 1.0);
            f[c] = u - i;
            base += i as usize * self.stride[c];
        }
        (base, f)
    }

    /// Multilinear interpolation of `values` at `xn`: Σ over the 2ᵏ corners, in the order of
    /// their bit patterns (input 0 the highest bit), of Π_c (f_c or 1 − f_c) · value, the
    /// product built from 1.0 input by input.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn interpolate2(&self, xn: &[f64; 3], a: &[f64], b: &[f64]) -> (f64, f64) {
        let (base, f) = self.corner(xn);
        let (mut sa, mut sb) = (0.0, 0.0);
        for corner in 0..(1usize << self.k) {
            let mut w = 1.0;
            let mut j = base;
            for c in 0..self.k {
                if corner >> (self.k - 1 - c) & 1 == 1 {
                    w *= f[c];
                    j += self.stride[c];
                } else {
                    w *= 1.0 - f[c];
                }
            }
            sa += w * a[j];
            sb += w * b[j];
        }
        (sa, sb)
    }

    /// Step 4 of the evaluation rule: with w the interpolated support and F the interpolated
    /// fallback at `xn`, |μ| = m where w = 1, F where w = 0, else w m + (1 − w) F.
    #[inline(always)]
    pub(super) fn apply(&self, xn: &[f64; 3], m: f64) -> f64 {
        let (w, fb) = self.interpolate2(xn, &self.s, &self.f);
        if w == 1.0 {
            m
        } else if w == 0.0 {
            fb
        } else {
            w * m + (1.0 - w) * fb
        }
    }

    /// The interpolated support w ∈ [0, 1] at `xn`.
    pub(super) fn weight(&self, xn: &[f64; 3]) -> f64 {
        self.interpolate2(xn, &self.s, &self.s).0
    }

    /// The interpolated ensemble spread at `xn` (`None` without).
    pub(super) fn spread(&self, xn: &[f64; 3]) -> Option<f64> {
        (!self.spread.is_empty()).then(|| self.interpolate2(xn, &self.spread, &self.spread).0)
    }
}
