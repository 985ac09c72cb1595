//! Polach's law over a block of samples on the vector lanes of this CPU: the fits spend most
//! of their time evaluating the law and its gradient (one exp and one atan per sample and
//! iteration), so the problem evaluates [`BLOCK`] samples at a time here, and accumulates its
//! normal equations by panels of samples ([`Gram`]).

use super::law::{law_lanes, Sample};
use crate::simd::{Isa, Portable, Select};

/// Samples per block.
pub(super) const BLOCK: usize = 64;

/// One block's inputs and the law's values: [`LawBlock::load`] the samples, then
/// [`LawBlock::eval`].
pub(super) struct LawBlock {
    pub(super) n: usize,
    /// The speed factor g(v) per sample (1 without a speed law), its basis φ(v) and whether g
    /// sits at its floor ([`super::problem`]'s speed law).
    pub(super) gv: [f64; BLOCK],
    pub(super) phi: [[f64; 3]; BLOCK],
    pub(super) held: [bool; BLOCK],
    /// μ0 × g(v) per sample.
    pub(super) mu0: [f64; BLOCK],
    /// Slip Δv per sample, m/s.
    pub(super) dv: [f64; BLOCK],
    /// The patch term c (w/v)/Q per sample (the gradient ε times μ_w), dimensionless.
    pub(super) cs: [f64; BLOCK],
    /// μ per sample.
    pub(super) f: [f64; BLOCK],
    /// ∂μ/∂(μ0, A, B, k_A, ρ) per sample (μ0 the sample's μ0 × g(v)); only after an
    /// evaluation with the gradient.
    pub(super) grad: [[f64; BLOCK]; 5],
}

impl LawBlock {
    pub(super) fn new() -> Box<LawBlock> {
        Box::new(LawBlock {
            n: 0,
            gv: [0.0; BLOCK],
            phi: [[0.0; 3]; BLOCK],
            held: [false; BLOCK],
            mu0: [0.0; BLOCK],
            dv: [0.0; BLOCK],
            cs: [0.0; BLOCK],
            f: [0.0; BLOCK],
            grad: [[0.0; BLOCK]; 5],
        })
    }

    /// Loads `samples` (at most [`BLOCK`]) with μ0 = `mu0` and the speed factor, its basis and
    /// floor flag from `speed`.
    #[inline]
    pub(super) fn load(
        &mut self,
        samples: &[Sample],
        mu0: f64,
        mut speed: impl FnMut(&Sample) -> (f64, [f64; 3], bool),
    ) {
        self.n = samples.len();
        for (i, s) in samples.iter().enumerate() {
            (self.gv[i], self.phi[i], self.held[i]) = speed(s);
            self.mu0[i] = mu0 * self.gv[i];
            self.dv[i] = s.dv;
            self.cs[i] = s.cs;
        }
    }

    /// The law at every loaded sample with (A, B, k_A, ρ) = `law`, with its gradient when
    /// `grad`, on the widest lanes of `isa` (the same bits on every path: [`law_lanes`]).
    pub(super) fn eval(&mut self, isa: Isa, law: [f64; 4], grad: bool) {
        match (isa, grad) {
            // SAFETY: the token proves AVX2 and FMA on this CPU (AVX-512 CPUs have them too;
            // four lanes are what the law's selects are written for).
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512(t), true) => unsafe { eval_avx2::<true>(t.avx2(), self, law) },
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx512(t), false) => unsafe { eval_avx2::<false>(t.avx2(), self, law) },
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2(t), true) => unsafe { eval_avx2::<true>(t, self, law) },
            #[cfg(target_arch = "x86_64")]
            (Isa::Avx2(t), false) => unsafe { eval_avx2::<false>(t, self, law) },
            (_, true) => eval_lanes::<f64, true>(Portable, self, law),
            (_, false) => eval_lanes::<f64, false>(Portable, self, law),
        }
    }
}

/// [`eval_lanes`] on AVX2 registers (four samples per vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn eval_avx2<const GRAD: bool>(isa: crate::simd::Avx2, b: &mut LawBlock, law: [f64; 4]) {
    eval_lanes::<crate::simd::F64x4, GRAD>(isa, b, law);
}

/// The law on lanes of `V` over the block, the samples past the last whole vector one at a
/// time on f64 (the same operations).
#[inline(always)]
fn eval_lanes<V: Select, const GRAD: bool>(isa: V::Isa, b: &mut LawBlock, law: [f64; 4]) {
    let mut i = 0;
    while i + V::N <= b.n {
        let (f, g) = law_lanes::<V, GRAD>(
            V::load(isa, &b.mu0[i..]),
            law,
            V::load(isa, &b.dv[i..]),
            V::load(isa, &b.cs[i..]),
        );
        f.store(&mut b.f[i..]);
        if GRAD {
            for (out, gk) in b.grad.iter_mut().zip(g) {
                gk.store(&mut out[i..]);
            }
        }
        i += V::N;
    }
    for j in i..b.n {
        let (f, g) = law_lanes::<f64, GRAD>(b.mu0[j], law, b.dv[j], b.cs[j]);
        b.f[j] = f;
        if GRAD {
            for (out, gk) in b.grad.iter_mut().zip(g) {
                out[j] = gk;
            }
        }
    }
}

/// Samples per panel of [`Gram`].
const PANEL: usize = 1024;

/// JᵀJ and Jᵀr of a least-squares problem with `k` coordinates, accumulated a panel of up to
/// [`PANEL`] samples at a time: each sample's Jacobian row and residual become one column of
/// A = [J; rᵀ] ((k + 1) × panel, a row per coordinate), and every entry of the lower triangle
/// of A Aᵀ is one dot product of two rows ([`dot_rows`]), added to the Gram matrix panel by
/// panel in order. The dot products run in four interleaved partial sums with fused
/// multiply-adds on every path (AVX2 or plain f64), so the fit is the same bits on every CPU.
pub(super) struct Gram {
    k: usize,
    isa: Isa,
    /// Columns per panel: [`PANEL`], or fewer for a problem with fewer samples.
    width: usize,
    filled: usize,
    panel: Vec<f64>,
    gram: Vec<f64>,
}

impl Gram {
    /// For `k` coordinates and (at most) `samples` samples.
    pub(super) fn new(k: usize, samples: usize, isa: Isa) -> Gram {
        let width = samples.clamp(4, PANEL).next_multiple_of(4);
        Gram {
            k,
            isa,
            width,
            filled: 0,
            panel: vec![0.0; (k + 1) * width],
            gram: vec![0.0; (k + 1) * (k + 1)],
        }
    }

    /// Adds one sample's Jacobian row (`k` values) and residual (the tests' way in; the
    /// problem writes whole columns through [`Gram::slots`]).
    #[cfg(test)]
    pub(super) fn push(&mut self, row: &[f64], r: f64) {
        for (c, x) in row[..self.k].iter().enumerate() {
            self.slots(c, 1)[0] = *x;
        }
        self.slots(self.k, 1)[0] = r;
        self.advance(1);
    }

    /// Samples the current panel has room for.
    #[inline]
    pub(super) fn room(&self) -> usize {
        self.width - self.filled
    }

    /// Row `c` of the panel (a coordinate's Jacobian values; `c = k`: the residuals) for the
    /// next `n ≤ room()` samples, to be written before [`Gram::advance`].
    #[inline]
    pub(super) fn slots(&mut self, c: usize, n: usize) -> &mut [f64] {
        let at = c * self.width + self.filled;
        &mut self.panel[at..at + n]
    }

    /// Counts `n` samples written through [`Gram::slots`]; a full panel is summed.
    #[inline]
    pub(super) fn advance(&mut self, n: usize) {
        self.filled += n;
        if self.filled == self.width {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let (q, n, w) = (self.k + 1, self.filled, self.width);
        if n == 0 {
            return;
        }
        // Zeros after the last sample up to a whole vector: they add nothing.
        let n4 = n.next_multiple_of(4);
        for c in 0..q {
            self.panel[c * w + n..c * w + n4].fill(0.0);
        }
        let row = |c: usize| &self.panel[c * w..c * w + n4];
        for a in 0..q {
            // Four rows b at a time share the loads of row a (each sum keeps its own order).
            let mut b = 0;
            while b + 4 <= a + 1 {
                let d = dot_rows4(
                    self.isa,
                    row(a),
                    [row(b), row(b + 1), row(b + 2), row(b + 3)],
                );
                for (i, x) in d.into_iter().enumerate() {
                    self.gram[a * q + b + i] += x;
                }
                b += 4;
            }
            for b in b..=a {
                self.gram[a * q + b] += dot_rows(self.isa, row(a), row(b));
            }
        }
        self.filled = 0;
    }

    /// JᵀJ (k × k, row-major, both triangles) and Jᵀr.
    pub(super) fn finish(mut self) -> (Vec<f64>, Vec<f64>) {
        self.flush();
        let (k, q) = (self.k, self.k + 1);
        let mut jtj = vec![0.0; k * k];
        for a in 0..k {
            for b in 0..=a {
                let x = self.gram[a * q + b];
                jtj[a * k + b] = x;
                jtj[b * k + a] = x;
            }
        }
        let jtr = self.gram[k * q..k * q + k].to_vec();
        (jtj, jtr)
    }
}

/// Σ a_i b_i over two rows whose length is a multiple of four: partial sums
/// s_j = Σ_m a_(4m+j) b_(4m+j) (a fused multiply-add each, m ascending), then
/// (s0 + s2) + (s1 + s3) — on AVX2 lanes or on f64, the same operations and bits.
pub(super) fn dot_rows(isa: Isa, a: &[f64], b: &[f64]) -> f64 {
    debug_assert!(a.len() == b.len() && a.len().is_multiple_of(4));
    match isa {
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { dot_rows_avx2(t.avx2(), a, b) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { dot_rows_avx2(t, a, b) },
        _ => {
            let mut s = [0.0f64; 4];
            for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
                for j in 0..4 {
                    s[j] = x[j].mul_add(y[j], s[j]);
                }
            }
            (s[0] + s[2]) + (s[1] + s[3])
        }
    }
}

/// [`dot_rows`] of `a` with four rows at once (the same sums, loading `a` once).
pub(super) fn dot_rows4(isa: Isa, a: &[f64], b: [&[f64]; 4]) -> [f64; 4] {
    match isa {
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { dot_rows4_avx2(t.avx2(), a, b) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { dot_rows4_avx2(t, a, b) },
        _ => b.map(|r| dot_rows(isa, a, r)),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn dot_rows4_avx2(isa: crate::simd::Avx2, a: &[f64], b: [&[f64]; 4]) -> [f64; 4] {
    use crate::simd::{F64x4, Lanes};
    let n = a.len();
    let b = b.map(|r| &r[..n]);
    let mut acc = [F64x4::splat(isa, 0.0); 4];
    let mut i = 0;
    while i + 4 <= n {
        let x = F64x4::load(isa, &a[i..]);
        for (s, r) in acc.iter_mut().zip(&b) {
            *s = x.fma(F64x4::load(isa, &r[i..]), *s);
        }
        i += 4;
    }
    acc.map(|s| F64x4::total4(s, &[0.0; 4]))
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn dot_rows_avx2(isa: crate::simd::Avx2, a: &[f64], b: &[f64]) -> f64 {
    use crate::simd::{F64x4, Lanes};
    let mut acc = F64x4::splat(isa, 0.0);
    for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        acc = F64x4::load(isa, x).fma(F64x4::load(isa, y), acc);
    }
    F64x4::total4(acc, &[0.0; 4])
}
