//! The network's least-squares problem ([`MlpProblem`]) on blocks of [`mlp::BLOCK`] samples, the
//! data stored by input column so that SIMD lanes run across samples ([`mlp::block`], AVX-512,
//! AVX2 or plain f64, chosen at run time and bit-identical). Per block the Jacobian J (P × B)
//! and the residuals r are built with the residuals as one more row, A = [J; rᵀ]; then the
//! lower triangle of A Aᵀ (a symmetric rank-k update, faer's triangular matrix product) holds
//! JᵀJ and Jᵀr at once.
//! Blocks are grouped into fixed chunks of [`CHUNK`] samples, chunks run in parallel and are
//! summed in order, so the result does not depend on the number of threads; memory is
//! O(chunk × P) per thread, never O(N × P).
//! The forward pass of LM's accepted trial step is the next epoch's, so a training pass keeps
//! its hidden activations and residuals (O(N × hidden), up to [`MAX_CACHED_VALUES`] per
//! problem) and the normal equations at the same θ build only the Jacobian from them — the same
//! values, so the same bits. (Rejected trial steps, the first epoch, and starts that share one
//! problem and overwrite each other's pass still compute it.)

use faer::linalg::matmul::triangular::{matmul, BlockStructure};
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::lm::{same_theta, LeastSquares, NormalEquations};
use super::mlp::{self, Pass, Scratch, Shape, BLOCK};
use crate::model::MAX_INPUTS;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx2, Avx512, F64x4, F64x8};
use crate::simd::{Isa, Portable};

/// Samples per chunk: fixed, so the sums (chunk results added in order) do not depend on the
/// number of threads.
pub const CHUNK: usize = 8 * BLOCK;

/// The waves a trial step's SSE runs in at most ([`LeastSquares::sse_unless`]): after each,
/// the sum so far may already reject the step. More waves stop a rejected trial sooner but
/// wait for the slowest chunk more often; over the bundled archive's networks a rejected
/// trial's sum already rejects about halfway through, so 8 waves stop it after ~4. Fewer on
/// small training sets (see [`MlpProblem::sse_of`]).
const SSE_WAVES: usize = 8;

/// Values between the end of one row of a chunk's matrix A and the start of the next (one
/// 64-byte cache line), so that rows are not a power of two apart.
const ROW_PAD: usize = 8;

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
    pass: Pass<'_>,
    scratch: &mut Scratch,
) {
    match isa {
        // SAFETY: the token proves AVX-512F on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512(t) => unsafe { block_avx512(t, shape, theta, x, y, n, r, pass, scratch) },
        // SAFETY: the token proves AVX2 and FMA on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2(t) => unsafe { block_avx2(t, shape, theta, x, y, n, r, pass, scratch) },
        _ => mlp::block::<f64>(Portable, shape, theta, x, y, n, r, pass, scratch),
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
    pass: Pass<'_>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x8>(isa, shape, theta, x, y, n, r, pass, scratch)
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
    pass: Pass<'_>,
    scratch: &mut Scratch,
) {
    mlp::block::<F64x4>(isa, shape, theta, x, y, n, r, pass, scratch)
}

/// The last forward pass over the training samples: its θ and, per block, the hidden
/// activations ([`Scratch::save`]) and the residuals. LM's accepted trial step is the next
/// epoch's θ, so the normal equations there take the activations and residuals from here
/// instead of computing them again — the same values, so the same bits.
struct ForwardCache {
    /// The shape `data` is laid out for (a problem whose public `shape` was changed since does
    /// not use it).
    shape: Shape,
    /// θ of `data`; empty while `data` is being written or holds nothing.
    theta: Vec<f64>,
    /// Per block: [`Scratch::activations`] values, then the block's [`BLOCK`] residuals.
    data: Vec<f64>,
}

/// Training sets whose forward pass would take more than this many values (8 MiB) to keep,
/// compute it again for the normal equations instead: kept, it is written and read back from
/// memory, and once it no longer stays in the caches that costs more than the forward pass.
/// Measured with `cargo bench --bench lm` on a 2-core AMD EPYC VM (1 MiB L2 per core, 32 MiB
/// L3), kept against computed again: 2-10-1 at 15 000 and 60 000 samples (1.3 and 5.1 MiB
/// kept) 2.5–3 % faster, 3-40-1 at 15 000 (4.7 MiB) 3–5 % faster; 2-10-1 at 250 000
/// (21 MiB) 4 % slower and at 1 000 000 (84 MiB) 18 % slower. Per problem: every network
/// being fitted (folds and candidates run side by side, two at a time on two cores) holds its
/// own.
const MAX_CACHED_VALUES: usize = 1 << 20;

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
    /// The [`BLOCK`] samples from `a` of every input column, on the stack (no allocation per
    /// block), and how many columns there are.
    #[inline]
    fn block(&self, a: usize) -> ([&[f64]; MAX_INPUTS], usize) {
        let mut xs: [&[f64]; MAX_INPUTS] = [&[]; MAX_INPUTS];
        for (x, c) in xs.iter_mut().zip(&self.x) {
            *x = &c[a..a + BLOCK];
        }
        (xs, self.x.len())
    }

    /// From row-major inputs (`k` per sample) and targets.
    fn new(x: &[f64], y: &[f64], k: usize) -> Columns {
        // Configurations name at most MAX_INPUTS inputs (`train.inputs`), as model files hold.
        assert!(
            k <= MAX_INPUTS,
            "a network takes at most {MAX_INPUTS} inputs, not {k}"
        );
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
    /// The training set's last forward pass; None where it would be too large to keep. Taken
    /// with `try_lock`, never `lock`: a rayon worker that holds it can pick up another start's
    /// work on the same problem on the same thread, which would then wait for itself; a start
    /// that finds it taken computes without it.
    cache: Option<std::sync::Mutex<ForwardCache>>,
}

impl MlpProblem {
    /// The [`BLOCK`] samples of `cols` from `a` through [`block_dispatch`]: residuals into `r`,
    /// and whatever else `pass` asks for.
    fn run_block(
        &self,
        theta: &[f64],
        cols: &Columns,
        a: usize,
        r: &mut [f64],
        pass: Pass<'_>,
        scratch: &mut Scratch,
    ) {
        let (xs, k) = cols.block(a);
        let y = &cols.y[a..a + BLOCK];
        block_dispatch(
            self.isa,
            self.shape,
            theta,
            &xs[..k],
            y,
            BLOCK,
            r,
            pass,
            scratch,
        );
    }

    /// From normalised row-major inputs and targets.
    ///
    /// # Panics
    /// With more than `MAX_INPUTS` (4) inputs per sample: no configuration names more.
    pub fn new(
        shape: Shape,
        x: Vec<f64>,
        y: Vec<f64>,
        vx: Vec<f64>,
        vy: Vec<f64>,
        scale: f64,
    ) -> Self {
        let k = shape.inputs;
        let train = Columns::new(&x, &y, k);
        MlpProblem {
            shape,
            cache: ForwardCache::for_set(shape, &train),
            train,
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
            // Its one caller evaluates the averaged network once: nothing to keep.
            cache: None,
            train: self.train.clone(),
            val: self.val.clone(),
            scale: self.scale,
            isa: self.isa,
        }
    }

    /// Σ r² over `cols` (blocks in order, samples in order within a block, the chunks' sums
    /// added in chunk order); with `cache`, the pass's activations and residuals are kept in it
    /// for [`MlpProblem::normal_equations`]. With `reject`, the chunks run in at most
    /// [`SSE_WAVES`] waves, and once the sum of the chunks so far makes `reject` true that
    /// partial sum is returned (and nothing kept): every later chunk only adds a square, so the
    /// whole sum would reject too ([`LeastSquares::sse_unless`]).
    fn sse_of(
        &self,
        theta: &[f64],
        cols: &Columns,
        mut cache: Option<&mut ForwardCache>,
        reject: Option<&(dyn Fn(f64) -> bool + Sync)>,
    ) -> f64 {
        let per_block = Scratch::activations(self.shape) + BLOCK;
        let per_chunk = CHUNK / BLOCK * per_block;
        let pass = |range: std::ops::Range<usize>, mut keep: Option<&mut [f64]>| {
            let mut scratch = Scratch::new(self.shape);
            let mut r = vec![0.0; BLOCK];
            let mut sse = 0.0;
            for (b, a) in range.clone().step_by(BLOCK).enumerate() {
                let n = BLOCK.min(range.end - a);
                self.run_block(theta, cols, a, &mut r, Pass::Forward, &mut scratch);
                sse += r[..n].iter().map(|e| e * e).sum::<f64>();
                if let Some(keep) = keep.as_deref_mut() {
                    let (act, res) =
                        keep[b * per_block..(b + 1) * per_block].split_at_mut(per_block - BLOCK);
                    scratch.save(act);
                    res.copy_from_slice(&r);
                }
            }
            sse
        };
        let chunks = cols.chunks();
        // A wave is at least four chunks per thread: each wave ends in a wait for the slowest
        // chunk and wakes the pool's other threads again, which cost one network trained alone
        // on 15 000 samples (8 chunks, waves of 2) 14 % per epoch (`cargo bench --bench lm`).
        let wave = match reject {
            Some(_) => chunks
                .len()
                .div_ceil(SSE_WAVES)
                .max(4 * rayon::current_num_threads())
                .max(1),
            None => chunks.len().max(1),
        };
        if let Some(c) = cache.as_deref_mut() {
            c.theta.clear();
        }
        let mut parts: Vec<f64> = Vec::with_capacity(chunks.len());
        for (w, ranges) in chunks.chunks(wave).enumerate() {
            let done: Vec<f64> = match cache.as_deref_mut() {
                Some(c) => {
                    // The last chunk may hold fewer blocks: its part is the rest.
                    let at = w * wave * per_chunk;
                    let end = (at + ranges.len() * per_chunk).min(c.data.len());
                    let data = &mut c.data[at..end];
                    ranges
                        .par_iter()
                        .cloned()
                        .zip_eq(data.par_chunks_mut(per_chunk))
                        .map(|(range, keep)| pass(range, Some(keep)))
                        .collect()
                }
                None => ranges
                    .par_iter()
                    .cloned()
                    .map(|range| pass(range, None))
                    .collect(),
            };
            parts.extend(done);
            if let Some(reject) = reject {
                let so_far: f64 = parts.iter().sum();
                if parts.len() < chunks.len() && reject(so_far) {
                    return so_far;
                }
            }
        }
        if let Some(c) = cache {
            c.theta.extend_from_slice(theta);
        }
        parts.iter().sum()
    }

    /// A Aᵀ, A = [J; rᵀ] ((P + 1) × (P + 1), row-major) over the samples of `range` (one
    /// chunk), and Σ r² summed in sample order (as [`MlpProblem::sse_of`] sums it, so that the
    /// current and a trial error compare like for like). A holds the whole chunk, so one matrix
    /// product serves it; the blocks write their Jacobian rows straight into it, and `buf` is
    /// reused from chunk to chunk of a rayon job. `kept`: the chunk's part of a forward pass at
    /// this θ ([`ForwardCache`]), whose activations and residuals are used instead of a forward
    /// pass of its own.
    fn gram_of_chunk(
        &self,
        theta: &[f64],
        range: std::ops::Range<usize>,
        buf: &mut ChunkBuffers,
        kept: Option<&[f64]>,
    ) -> (Vec<f64>, f64) {
        let p = self.shape.n_params();
        let cols = &self.train;
        let width = range.len().div_ceil(BLOCK) * BLOCK;
        // Rows `ld` apart, not `width`: a power-of-two distance would put every row's samples
        // in the same L1 cache set, and the Jacobian's P row streams would evict each other.
        let ld = width + ROW_PAD;
        let a_mat = &mut buf.a_mat[..(p + 1) * ld];
        let r = &mut buf.r;
        let per_block = Scratch::activations(self.shape) + BLOCK;
        let mut sse = 0.0;
        for (b, a) in range.clone().step_by(BLOCK).enumerate() {
            let n = BLOCK.min(range.end - a);
            let at = b * BLOCK;
            let jac = &mut a_mat[at..];
            let pass = if let Some(kept) = kept {
                // The forward pass at this θ was the last one: its activations and residuals.
                let (act, res) =
                    kept[b * per_block..(b + 1) * per_block].split_at(per_block - BLOCK);
                buf.scratch.restore(act);
                r.copy_from_slice(res);
                Pass::Jacobian(jac, ld)
            } else {
                Pass::Both(jac, ld)
            };
            self.run_block(theta, cols, a, r, pass, &mut buf.scratch);
            sse += r[..n].iter().map(|e| e * e).sum::<f64>();
            a_mat[p * ld + at..p * ld + at + n].copy_from_slice(&r[..n]);
            // Padding samples are zero in A: they contribute nothing.
            for q in 0..=p {
                a_mat[q * ld + at + n..q * ld + at + BLOCK].fill(0.0);
            }
        }
        // The lower triangle of A Aᵀ: a symmetric rank-k update (faer, sequential).
        let mut gram = vec![0.0; (p + 1) * (p + 1)];
        let am = MatRef::from_row_major_slice_with_stride(a_mat, p + 1, width, ld);
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

impl ForwardCache {
    /// An empty cache for the training set `train`, or None where it would hold more than
    /// [`MAX_CACHED_VALUES`].
    fn for_set(shape: Shape, train: &Columns) -> Option<std::sync::Mutex<ForwardCache>> {
        let values = train.y.len() / BLOCK * (Scratch::activations(shape) + BLOCK);
        (values <= MAX_CACHED_VALUES).then(|| {
            std::sync::Mutex::new(ForwardCache {
                shape,
                theta: Vec::new(),
                data: vec![0.0; values],
            })
        })
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
            a_mat: vec![0.0; (shape.n_params() + 1) * (CHUNK + ROW_PAD)],
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
        let mut guard = self.cache.as_ref().and_then(|c| c.try_lock().ok());
        let cache = guard.as_deref_mut().filter(|c| c.shape == self.shape);
        self.sse_of(theta, &self.train, cache, None)
    }
    fn sse_unless(&self, theta: &[f64], reject: &(dyn Fn(f64) -> bool + Sync)) -> f64 {
        let mut guard = self.cache.as_ref().and_then(|c| c.try_lock().ok());
        let cache = guard.as_deref_mut().filter(|c| c.shape == self.shape);
        self.sse_of(theta, &self.train, cache, Some(reject))
    }
    fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
        let p = self.shape.n_params();
        let mut guard = self.cache.as_ref().and_then(|c| c.try_lock().ok());
        let holds = |c: &ForwardCache| c.shape == self.shape && same_theta(&c.theta, theta);
        // Released at once when it holds another θ: a start beside this one may fill it.
        if !guard.as_deref().is_some_and(holds) {
            guard = None;
        }
        let kept = guard.as_deref();
        let chunks = self.train.chunks();
        let grams: Vec<(Vec<f64>, f64)> = match kept {
            Some(kept) => {
                let per_chunk = CHUNK / BLOCK * (Scratch::activations(self.shape) + BLOCK);
                chunks
                    .into_par_iter()
                    .zip_eq(kept.data.par_chunks(per_chunk))
                    .map_init(
                        || ChunkBuffers::new(self.shape),
                        |buf, (range, kept)| self.gram_of_chunk(theta, range, buf, Some(kept)),
                    )
                    .collect()
            }
            None => chunks
                .into_par_iter()
                .map_init(
                    || ChunkBuffers::new(self.shape),
                    |buf, range| self.gram_of_chunk(theta, range, buf, None),
                )
                .collect(),
        };
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
        Some(self.sse_of(theta, &self.val, None, None) / self.val.n as f64 * self.scale)
    }
    fn mse_scale(&self) -> f64 {
        self.scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normal equations are the same bits whether the last forward pass was at their θ
    /// (the activations reused), at another θ, or absent, for one and two hidden layers and a
    /// training set that ends in a partial block.
    #[test]
    fn normal_equations_reuse_the_forward_pass_bit_for_bit() {
        let two = Shape {
            inputs: 2,
            hidden: 6,
            hidden2: 5,
        };
        for shape in [Shape::one(3, 10), two] {
            let problem = problem_of(shape, 2 * CHUNK + 3 * BLOCK + 17);
            assert!(problem.cache.is_some());
            let theta = mlp::nguyen_widrow(shape, 5);
            let other: Vec<f64> = theta.iter().map(|t| t * 0.9).collect();
            let fresh = problem.normal_equations(&theta);
            // LM's order: the trial's SSE, the validation error, the next normal equations.
            let sse = problem.sse(&theta);
            problem.validation_mse(&theta);
            assert_eq!(kept_theta(&problem), theta, "the training pass is kept");
            let reused = problem.normal_equations(&theta);
            problem.sse(&other);
            let after_other = problem.normal_equations(&theta);
            assert_eq!(fresh.bits(), reused.bits(), "{shape:?}");
            assert_eq!(fresh.bits(), after_other.bits(), "{shape:?}");
            assert_eq!(sse.to_bits(), fresh.sse.to_bits());
        }
    }

    /// The θ whose training forward pass `problem` keeps (empty: none kept).
    fn kept_theta(problem: &MlpProblem) -> Vec<f64> {
        let cache = problem
            .cache
            .as_ref()
            .expect("a problem that keeps its pass");
        cache.lock().unwrap().theta.clone()
    }

    /// A problem of `shape` on `n` deterministic samples (the same for training and validation).
    fn problem_of(shape: Shape, n: usize) -> MlpProblem {
        let k = shape.inputs;
        let x: Vec<f64> = (0..n * k)
            .map(|i| ((i * 7919) % 1000) as f64 / 500.0 - 1.0)
            .collect();
        let y: Vec<f64> = (0..n)
            .map(|i| ((i * 104_729) % 997) as f64 / 498.5 - 1.0)
            .collect();
        MlpProblem::new(shape, x.clone(), y.clone(), x, y, 1.0)
    }

    /// A trial's SSE stops early only where the whole sum rejects too: for limits below,
    /// at and above the SSE it rejects exactly when the whole sum does, returns the whole sum's
    /// bits when it does not, stops before the end well below, and leaves no forward pass
    /// kept when it stopped (the normal equations after it are the fresh ones).
    #[test]
    fn a_trial_sse_stops_only_where_the_whole_sum_rejects() {
        // On two threads whatever the machine: the waves' size follows the pool's threads.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(a_trial_sse_stops_only_where_the_whole_sum_rejects_on_this_pool);
    }

    fn a_trial_sse_stops_only_where_the_whole_sum_rejects_on_this_pool() {
        let shape = Shape::one(2, 10);
        let problem = problem_of(shape, 20 * CHUNK + 3 * BLOCK + 17);
        let theta = mlp::nguyen_widrow(shape, 7);
        let full = problem.sse(&theta);
        let fresh = problem.normal_equations(&theta);
        for q in [0.0, 0.05, 0.3, 0.7, 0.999, 1.0, 1.001, 2.0] {
            let f0 = full * q;
            let reject = |e: f64| !(e.is_finite() && e < f0);
            let e = problem.sse_unless(&theta, &reject);
            assert_eq!(reject(e), reject(full), "limit {q} × SSE");
            if !reject(full) {
                assert_eq!(e.to_bits(), full.to_bits(), "limit {q} × SSE");
            } else {
                assert!(e <= full, "limit {q} × SSE: {e} > {full}");
                if q < 0.5 {
                    assert!(e < full, "limit {q} × SSE: no early stop");
                    assert!(
                        kept_theta(&problem).is_empty(),
                        "a stopped pass is not kept"
                    );
                }
                let ne = problem.normal_equations(&theta);
                assert_eq!(ne.bits(), fresh.bits(), "limit {q} × SSE");
            }
        }
    }

    /// The same problem without the early stop (every trial's SSE summed whole).
    struct Whole<'a>(&'a MlpProblem);
    impl LeastSquares for Whole<'_> {
        fn n_params(&self) -> usize {
            self.0.n_params()
        }
        fn n_train(&self) -> usize {
            self.0.n_train()
        }
        fn sse(&self, theta: &[f64]) -> f64 {
            self.0.sse(theta)
        }
        fn normal_equations(&self, theta: &[f64]) -> NormalEquations {
            self.0.normal_equations(theta)
        }
        fn validation_mse(&self, theta: &[f64]) -> Option<f64> {
            self.0.validation_mse(theta)
        }
        fn mse_scale(&self) -> f64 {
            self.0.mse_scale()
        }
    }

    /// Trained with trial errors that stop early, and with every trial summed whole: the same
    /// parameters and the same history, bit for bit (trainlm and trainbr).
    #[test]
    fn training_is_the_same_bits_with_and_without_the_early_stop() {
        use crate::identify::lm::{run, LevenbergMarquardt, LmSettings};
        let shape = Shape::one(2, 10);
        for settings in [
            LmSettings {
                epochs: 40,
                ..LmSettings::default()
            },
            LmSettings {
                epochs: 40,
                ..LmSettings::trainbr()
            },
        ] {
            let problem = problem_of(shape, 12 * CHUNK + 5 * BLOCK + 9);
            let theta0 = mlp::nguyen_widrow(shape, 3);
            let (a, _) = run(&problem, LevenbergMarquardt::new(settings), theta0.clone()).unwrap();
            let (b, _) = run(Whole(&problem), LevenbergMarquardt::new(settings), theta0).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(a.best().unwrap()), bits(b.best().unwrap()));
            let hist = |s: &LevenbergMarquardt| {
                s.history()
                    .iter()
                    .map(|e| [e.train_mse, e.val_mse, e.mu, e.grad_norm].map(f64::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(hist(&a), hist(&b));
            assert!(a.history().len() > 5, "too few epochs to show anything");
        }
    }
}
