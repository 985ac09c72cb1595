//! Polach's law over a block of samples on the vector lanes of this CPU: the fits spend most
//! of their time evaluating the law and its gradient (one exp and one atan per sample and
//! iteration), so the problem evaluates [`BLOCK`] samples at a time here and accumulates the
//! normal equations from the block in sample order, as before.

use super::law::{law_lanes, Sample};
use crate::simd::{Isa, Portable, Select};

/// Samples per block.
pub(super) const BLOCK: usize = 64;

/// One block's inputs and the law's values: fill `mu0` (μ0 × g(v) per sample), `dv` and
/// `cs` for the first `n` samples, then [`LawBlock::eval`].
pub(super) struct LawBlock {
    pub(super) n: usize,
    pub(super) mu0: [f64; BLOCK],
    pub(super) dv: [f64; BLOCK],
    pub(super) cs: [f64; BLOCK],
    /// μ per sample.
    pub(super) f: [f64; BLOCK],
    /// ∂μ/∂(μ0, A, B, k_A, ρ) per sample (μ0 the sample's μ0 × g(v)); zero when evaluated
    /// without the gradient.
    pub(super) grad: [[f64; BLOCK]; 5],
}

impl LawBlock {
    pub(super) fn new() -> Box<LawBlock> {
        Box::new(LawBlock {
            n: 0,
            mu0: [0.0; BLOCK],
            dv: [0.0; BLOCK],
            cs: [0.0; BLOCK],
            f: [0.0; BLOCK],
            grad: [[0.0; BLOCK]; 5],
        })
    }

    /// Loads `samples` (at most [`BLOCK`]) with μ0 × g(v) from `mu0_of`.
    #[inline]
    pub(super) fn load(&mut self, samples: &[Sample], mut mu0_of: impl FnMut(&Sample) -> f64) {
        self.n = samples.len();
        for (i, s) in samples.iter().enumerate() {
            self.mu0[i] = mu0_of(s);
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

/// JᵀJ and Jᵀr of a least-squares problem with `k` coordinates, accumulated a panel of
/// [`PANEL`] samples at a time: each sample's Jacobian row and residual become one column of
/// A = [J; rᵀ] ((k + 1) × panel), and the lower triangle of A Aᵀ is added to the Gram
/// matrix by faer's triangular matrix product (sequential: the sum's order, and so its bits,
/// do not depend on the threads). The network's problem accumulates its normal equations
/// the same way.
pub(super) struct Gram {
    k: usize,
    filled: usize,
    panel: Vec<f64>,
    gram: Vec<f64>,
}

impl Gram {
    pub(super) fn new(k: usize) -> Gram {
        Gram {
            k,
            filled: 0,
            panel: vec![0.0; (k + 1) * PANEL],
            gram: vec![0.0; (k + 1) * (k + 1)],
        }
    }

    /// Adds one sample's Jacobian row (`k` values) and residual.
    #[inline]
    pub(super) fn push(&mut self, row: &[f64], r: f64) {
        let j = self.filled;
        for (c, x) in row[..self.k].iter().enumerate() {
            self.panel[c * PANEL + j] = *x;
        }
        self.panel[self.k * PANEL + j] = r;
        self.filled += 1;
        if self.filled == PANEL {
            self.flush();
        }
    }

    fn flush(&mut self) {
        use faer::linalg::matmul::triangular::{matmul, BlockStructure};
        use faer::{Accum, MatMut, MatRef, Par};
        let (q, n) = (self.k + 1, self.filled);
        if n == 0 {
            return;
        }
        let a = MatRef::from_row_major_slice_with_stride(&self.panel, q, n, PANEL);
        matmul(
            MatMut::from_row_major_slice_mut(&mut self.gram, q, q),
            BlockStructure::TriangularLower,
            Accum::Add,
            a,
            BlockStructure::Rectangular,
            a.transpose(),
            BlockStructure::Rectangular,
            1.0,
            Par::Seq,
        );
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
