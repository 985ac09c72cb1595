//! The network's least-squares problem ([`MlpProblem`]) on blocks of [`mlp::BLOCK`] samples, the
//! data stored by input column so that SIMD lanes run across samples ([`mlp::block`], AVX-512,
//! AVX2 or plain f64, chosen at run time and bit-identical). Per block the Jacobian J (P × B)
//! and the residuals r are built with the residuals as one more row, A = [J; rᵀ]; then the
//! lower triangle of A Aᵀ (a symmetric rank-k update, faer's triangular matrix product) holds
//! JᵀJ and Jᵀr at once.
//! Blocks are grouped into fixed chunks of [`CHUNK`] samples, chunks run in parallel and are
//! summed in order, so the result does not depend on the number of threads; memory is
//! O(chunk × P) per thread, never O(N × P).

use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::lm::{LeastSquares, NormalEquations};
use super::mlp::{self, Scratch, Shape, BLOCK};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx2, Avx512, F64x4, F64x8};
use crate::simd::{Isa, Portable};

/// Samples per chunk: fixed, so the sums (chunk results added in order) do not depend on the
/// number of threads.
pub const CHUNK: usize = 8 * BLOCK;

/// [`mlp::block`] on the widest lanes of this CPU (same bits on every path).
#[allow(clippy::too_many_arguments)]
pub(super) fn block_dispatch(
    isa: Isa,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<(&mut [f64], usize)>,
    scratch: &mut Scratch,
) {
    match isa {
        // SAFETY: the token proves AVX-512F on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { block_avx512(t, shape, theta, x, y, n, r, jac, scratch) },
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { block_avx2(t, shape, theta, x, y, n, r, jac, scratch) },
        _ => mlp::block::<f64>(Portable, shape, theta, x, y, n, r, jac, scratch),
    }
}

/// [`mlp::block`] on AVX-512 registers (eight samples per vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[allow(clippy::too_many_arguments)]
fn block_avx512(
    isa: Avx512,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<(&mut [f64], usize)>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x8>(isa, shape, theta, x, y, n, r, jac, scratch)
}

/// [`mlp::block`] on AVX2 registers (four samples per vector).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
fn block_avx2(
    isa: Avx2,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    jac: Option<(&mut [f64], usize)>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x4>(isa, shape, theta, x, y, n, r, jac, scratch)
}

/// Samples stored by input column, padded to whole blocks (padding: inputs and target 0,
/// masked out of every sum).
#[derive(Clone)]
struct Columns {
    x: Vec<Vec<f64>>,
    y: Vec<f64>,
    /// Real samples.
    n: usize,
}

impl Columns {
    /// From row-major inputs (`k` per sample) and targets.
    fn new(x: &[f64], y: &[f64], k: usize) -> Columns {
        let n = y.len();
        let padded = n.div_ceil(BLOCK) * BLOCK;
        let mut cols = vec![vec![0.0; padded]; k];
        for (s, row) in x.chunks_exact(k).enumerate() {
            for (c, v) in row.iter().enumerate() {
                cols[c][s] = *v;
            }
        }
        let mut yy = y.to_vec();
        yy.resize(padded, 0.0);
        Columns { x: cols, y: yy, n }
    }

    /// Index ranges of the chunks.
    fn chunks(&self) -> Vec<std::ops::Range<usize>> {
        (0..self.n)
            .step_by(CHUNK)
            .map(|a| a..(a + CHUNK).min(self.n))
            .collect()
    }
}

/// The MLP's least-squares problem on normalised data.
pub struct MlpProblem {
    pub shape: Shape,
    train: Columns,
    val: Columns,
    /// (max − min)² / 4 of the target: normalised MSE → μ² units.
    scale: f64,
    isa: Isa,
}

impl MlpProblem {
    /// From normalised row-major inputs and targets.
    pub fn new(
        shape: Shape,
        x: Vec<f64>,
        y: Vec<f64>,
        vx: Vec<f64>,
        vy: Vec<f64>,
        scale: f64,
    ) -> Self {
        let k = shape.inputs;
        MlpProblem {
            shape,
            train: Columns::new(&x, &y, k),
            val: Columns::new(&vx, &vy, k),
            scale,
            isa: Isa::detect(),
        }
    }

    /// The same data for a network of another shape (same inputs).
    pub fn with_shape(&self, shape: Shape) -> MlpProblem {
        assert_eq!(shape.inputs, self.shape.inputs);
        MlpProblem {
            shape,
            train: self.train.clone(),
            val: self.val.clone(),
            scale: self.scale,
            isa: self.isa,
        }
    }

    /// Σ r² over `cols` (blocks in order, samples in order within a block).
    fn sse_of(&self, theta: &[f64], cols: &Columns) -> f64 {
        let parts: Vec<f64> = cols
            .chunks()
            .into_par_iter()
            .map(|range| {
                let mut scratch = Scratch::new(self.shape);
                let mut r = vec![0.0; BLOCK];
                let mut sse = 0.0;
                for a in range.clone().step_by(BLOCK) {
                    let n = BLOCK.min(range.end - a);
                    let xs: Vec<&[f64]> = cols.x.iter().map(|c| &c[a..a + BLOCK]).collect();
                    block_dispatch(
                        self.isa,
                        self.shape,
                        theta,
                        &xs,
                        &cols.y[a..a + BLOCK],
                        BLOCK,
                        &mut r,
                        None,
                        &mut scratch,
                    );
                    sse += r[..n].iter().map(|e| e * e).sum::<f64>();
                }
                sse
            })
            .collect();
        parts.iter().sum()
    }

    /// A Aᵀ, A = [J; rᵀ] ((P + 1) × (P + 1), row-major) over the samples of `range` (one
    /// chunk), and Σ r² summed in sample order (as [`MlpProblem::sse_of`] sums it, so that the
    /// current and a trial error compare like for like). A holds the whole chunk, so one matrix
    /// product serves it; the blocks write their Jacobian rows straight into it, and `buf` is
    /// reused from chunk to chunk of a rayon job.
    fn gram_of_chunk(
        &self,
        theta: &[f64],
        range: std::ops::Range<usize>,
        buf: &mut ChunkBuffers,
    ) -> (Vec<f64>, f64) {
        let p = self.shape.n_params();
        let cols = &self.train;
        let width = range.len().div_ceil(BLOCK) * BLOCK;
        let a_mat = &mut buf.a_mat[..(p + 1) * width];
        let r = &mut buf.r;
        let mut sse = 0.0;
        for (b, a) in range.clone().step_by(BLOCK).enumerate() {
            let n = BLOCK.min(range.end - a);
            let xs: Vec<&[f64]> = cols.x.iter().map(|c| &c[a..a + BLOCK]).collect();
            let at = b * BLOCK;
            block_dispatch(
                self.isa,
                self.shape,
                theta,
                &xs,
                &cols.y[a..a + BLOCK],
                BLOCK,
                r,
                Some((&mut a_mat[at..], width)),
                &mut buf.scratch,
            );
            sse += r[..n].iter().map(|e| e * e).sum::<f64>();
            a_mat[p * width + at..p * width + at + n].copy_from_slice(&r[..n]);
            // Padding samples are zero in A: they contribute nothing.
            for q in 0..=p {
                a_mat[q * width + at + n..q * width + at + BLOCK].fill(0.0);
            }
        }
        // The lower triangle of A Aᵀ: a symmetric rank-k update (faer, sequential).
        let mut gram = vec![0.0; (p + 1) * (p + 1)];
        let am = MatRef::from_row_major_slice(a_mat, p + 1, width);
        matmul(
            MatMut::from_row_major_slice_mut(&mut gram, p + 1, p + 1),
            BlockStructure::TriangularLower,
            Accum::Replace,
            am,
            BlockStructure::Rectangular,
            am.transpose(),
            BlockStructure::Rectangular,
            1.0,
            Par::Seq,
        );
        (gram, sse)
    }
}

/// What [`MlpProblem::gram_of_chunk`] works in, allocated once per rayon job of an epoch's
/// normal equations (each job takes several chunks) rather than once per chunk: A for a whole
/// chunk, the block's residuals and its hidden activations.
struct ChunkBuffers {
    a_mat: Vec<f64>,
    r: Vec<f64>,
    scratch: Scratch,
}

impl ChunkBuffers {
    fn new(shape: Shape) -> ChunkBuffers {
        ChunkBuffers {
            a_mat: vec![0.0; (shape.n_params() + 1) * CHUNK],
            r: vec![0.0; BLOCK],
            scratch: Scratch::new(shape),
        }
    }
}

impl LeastSquares for MlpProblem {
    fn n_params(&self) -> usize {
        self.shape.n_params()
    }
    fn n_train(&self) -> usize {
        self.train.n
    }
    fn sse(&self, theta: &[f64]) -> f64 {
        self.sse_of(theta, &self.train)
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let p = self.shape.n_params();
        let grams: Vec<(Vec<f64>, f64)> = self
            .train
            .chunks()
            .into_par_iter()
            .map_init(
                || ChunkBuffers::new(self.shape),
                |buf, range| self.gram_of_chunk(theta, range, buf),
            )
            .collect();
        let mut total = vec![0.0; (p + 1) * (p + 1)];
        let mut sse = 0.0;
        for (g, s) in &grams {
            for (t, v) in total.iter_mut().zip(g) {
                *t += v;
            }
            sse += s;
        }
        // JᵀJ from the lower triangle (mirrored), Jᵀr from the last row.
        let q = p + 1;
        let jtj = (0..p * p)
            .map(|i| {
                let (a, b) = (i / p, i % p);
                total[a.max(b) * q + a.min(b)]
            })
            .collect();
        NormalEquations {
            jtj,
            jtr: (0..p).map(|a| total[p * q + a]).collect(),
            sse,
        }
    }
    fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
        if self.val.n == 0 {
            return None;
        }
        Some(self.sse_of(theta, &self.val) / self.val.n as f64 * self.scale)
    }
    fn mse_scale(&self) -> f64 {
        self.scale
    }
}
