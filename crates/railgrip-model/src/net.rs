//! The network evaluator of kind `mlp` (see [`super`] for the evaluation rule): allocation-free
//! single calls with four neurons per AVX2 register, and a batch path vectorised across
//! samples (AVX-512F, AVX2 or plain f64), every path performing the same IEEE operations lane
//! by lane — bit-identical results whatever the CPU (tested below).

use super::file::{ModelFile, Scaling, MAX_HIDDEN, MAX_INPUTS};
use super::polach::PolachEval;
use super::support::SupportEval;
use railgrip_contact::saturation::she_ratio;
use railgrip_simd::{self as simd, Isa, Lanes, Portable};
#[cfg(target_arch = "x86_64")]
use railgrip_simd::{Avx2, Avx512, F64x4, F64x8};

/// Samples per block of [`super::Model::mu_batch`].
pub const LANES: usize = 16;

/// Neurons per chunk of the single-call path (one AVX2 register of f64).
const CHUNK: usize = 4;
/// Activation buffer length of the deep path when every padded layer fits (see `Net::narrow`).
const NARROW: usize = 64;

/// The network evaluator (kind mlp).
#[derive(Debug, Clone)]
pub(super) struct Net {
    k: usize,
    lo: [f64; MAX_INPUTS],
    hi: [f64; MAX_INPUTS],
    gx: [f64; MAX_INPUTS],
    ox: [f64; MAX_INPUTS],
    /// Hidden neurons, and that number rounded up to a multiple of [`CHUNK`].
    nh: usize,
    pad: usize,
    /// Hidden-layer weights, column-major with stride `pad`: w1c[c · pad + h] = W1[h][c];
    /// `b1` and `w2` likewise padded. The padding neurons have zero weights and are never
    /// summed: they only let the single-call path run in fixed-width chunks.
    w1c: Vec<f64>,
    b1: Vec<f64>,
    w2: Vec<f64>,
    /// The same weights in blocks of [`CHUNK`] neurons for the single-call path.
    blocks: Vec<Block>,
    /// The instruction set of this CPU, detected once.
    isa: Isa,
    /// Output bias (−0.0 stored as +0.0 so that adding the padding neurons' exact +0.0 terms
    /// never changes the sum: see [`Net::net_chunks`]).
    b2: f64,
    gy: f64,
    oy: f64,
    blend: f64,
    /// C / Q: μ per unit creepage.
    creep_per_creepage: f64,
    v_ref: f64,
    /// Ambient temperature for calls without one, °C (4-input networks; else unused).
    t_ref: f64,
    /// The data-support blend (version-2 files with a support grid).
    support: Option<Box<SupportEval>>,
    /// Hidden layers after the first (version-3 files; empty for one hidden layer), and then
    /// the output weights of the last hidden layer (`w2` serves one-hidden-layer networks).
    deep: Vec<DeepLayer>,
    wo: Vec<f64>,
    /// Every layer at most 64 neurons wide (padded): the deep path's activation buffers are
    /// then 64 long, not [`MAX_HIDDEN`] (zeroing 4 KB per call cost ~12 % at 3-32-32-1).
    narrow: bool,
    /// A residual network's Polach law, added after the support blend (`None`: a plain network).
    base: Option<Box<PolachEval>>,
}

/// A hidden layer after the first: `n` neurons fed by the previous layer's activations.
/// Weights column-major with stride `pad` (`n` rounded up to [`CHUNK`]) and doubled like the
/// first layer's: wc[h · pad + g] = 2 W[g][h]; the padding neurons have zero weights and bias.
#[derive(Debug, Clone)]
struct DeepLayer {
    n: usize,
    pad: usize,
    wc: Vec<f64>,
    b: Vec<f64>,
}

/// One block of [`LANES`] samples of a batch: slip, slip rate, speed and temperature (NaN:
/// the reference values).
struct BlockIn {
    dv: [f64; LANES],
    ddv: [f64; LANES],
    v: [f64; LANES],
    t: [f64; LANES],
}

/// [`CHUNK`] hidden neurons' weights, contiguous (padding neurons all zero).
#[derive(Debug, Clone, Default)]
struct Block {
    b1: [f64; CHUNK],
    w1: [[f64; CHUNK]; MAX_INPUTS],
    w2: [f64; CHUNK],
}

/// tanh for the evaluators, branch-free and inlinable (glibc's `tanh` is a ~10 ns call; ten of
/// them would be most of an evaluation). With x = 2z clamped to [−40, 40] (beyond, tanh rounds
/// to ±1): x = n ln 2 + r with n = round(x / ln 2) (by the 1.5·2⁵² rounding trick) and
/// |r| ≤ ln 2 / 2 (Cody–Waite split of ln 2, fdlibm's constants); e^r − 1 = r P(r) with
/// `simd::EXPM1_P` (Estrin's scheme); e^x − 1 = 2ⁿ (e^r − 1) + (2ⁿ − 1), exact but for one rounding
/// (a fused multiply-add), in (−1, ∞); tanh z = (e^x − 1)/(e^x − 1 + 2), whose denominator
/// never cancels. Every multiply-add is fused (`f64::mul_add`: correctly rounded, so the AVX2
/// `vfmadd`, a software `fma` and C99 `fma()` give the same bits). Within 4 ulp of the C
/// library's tanh (tested); tanh_fast(−0.0) is +0.0. The C header computes the same operations.
#[inline(always)]
pub fn tanh_fast(z: f64) -> f64 {
    simd::tanh_of_doubled(2.0 * z)
}

impl Net {
    pub(super) fn new(file: &ModelFile) -> Net {
        let k = file.inputs.len();
        let creep = file
            .creep
            .as_ref()
            .expect("checked: kind mlp has a creep section");
        let Scaling {
            lo,
            hi,
            gx,
            ox,
            gy,
            oy,
            w1c,
        } = file.scaling();
        let h = &file.layers[0];
        let o = file.layers.last().expect("checked: an output layer");
        let nh = h.biases.len();
        let pad = nh.div_ceil(CHUNK) * CHUNK;
        let padded = |v: &[f64]| {
            let mut p = v.to_vec();
            p.resize(pad, 0.0);
            p
        };
        // Doubled (exact): the evaluators compute 2z, the argument tanh needs as e^(2z).
        let w1c: Vec<f64> = w1c.chunks(nh).flat_map(padded).map(|w| 2.0 * w).collect();
        let b1: Vec<f64> = padded(&h.biases).iter().map(|b| 2.0 * b).collect();
        let w2 = if file.layers.len() == 2 {
            padded(&o.weights[0])
        } else {
            vec![0.0; pad]
        };
        let hidden = &file.layers[..file.layers.len() - 1];
        let deep: Vec<DeepLayer> = hidden
            .windows(2)
            .map(|pair| {
                let (prev, l) = (&pair[0], &pair[1]);
                let n = l.biases.len();
                let lpad = n.div_ceil(CHUNK) * CHUNK;
                let mut wc = vec![0.0; prev.biases.len() * lpad];
                for (g, row) in l.weights.iter().enumerate() {
                    for (h, w) in row.iter().enumerate() {
                        wc[h * lpad + g] = 2.0 * w;
                    }
                }
                let mut b: Vec<f64> = l.biases.iter().map(|b| 2.0 * b).collect();
                b.resize(lpad, 0.0);
                DeepLayer {
                    n,
                    pad: lpad,
                    wc,
                    b,
                }
            })
            .collect();
        let blocks = (0..pad / CHUNK)
            .map(|j| {
                let at = |v: &[f64], c: usize| -> [f64; CHUNK] {
                    v[c * pad + j * CHUNK..c * pad + (j + 1) * CHUNK]
                        .try_into()
                        .expect("chunk")
                };
                let mut b = Block {
                    b1: at(&b1, 0),
                    w2: at(&w2, 0),
                    ..Block::default()
                };
                for c in 0..k {
                    b.w1[c] = at(&w1c, c);
                }
                b
            })
            .collect();
        Net {
            k,
            lo,
            hi,
            gx,
            ox,
            nh,
            pad,
            w1c,
            b1,
            w2,
            blocks,
            isa: Isa::detect(),
            b2: o.biases[0] + 0.0,
            gy,
            oy,
            blend: creep.blend_mps,
            creep_per_creepage: creep.creep_stiffness_n / creep.wheel_load_n,
            v_ref: creep.reference_speed_mps,
            t_ref: creep.reference_temperature_c.unwrap_or(f64::NAN),
            support: file.support.as_ref().map(|s| Box::new(SupportEval::new(s))),
            narrow: pad <= NARROW && deep.iter().all(|l| l.pad <= NARROW),
            deep,
            wo: o.weights[0].clone(),
            base: file.base.as_ref().map(|b| Box::new(PolachEval::of_law(b))),
        }
    }

    /// The network alone at physical inputs (clamped to the domain). The hidden layer runs in
    /// fixed-width chunks of [`CHUNK`] neurons (zero-padded) so the compiler turns each into
    /// SIMD, with the chunk count a compile-time constant for up to 16 neurons; the output sum
    /// runs over the real neurons in order — the same operations as the batch path and the C
    /// header, same results.
    #[inline(always)]
    fn net<V: Lanes>(&self, isa: V::Isa, x: [f64; MAX_INPUTS]) -> f64 {
        if !self.deep.is_empty() {
            return if self.narrow {
                self.net_deep::<V, NARROW>(isa, x)
            } else {
                self.net_deep::<V, MAX_HIDDEN>(isa, x)
            };
        }
        // The usual sizes with the chunk count known at compile time (fully unrolled).
        match self.pad / CHUNK {
            1 => self.net_chunks::<V, 1>(isa, x),
            2 => self.net_chunks::<V, 2>(isa, x),
            3 => self.net_chunks::<V, 3>(isa, x),
            4 => self.net_chunks::<V, 4>(isa, x),
            _ => self.net_any::<V>(isa, x),
        }
    }

    /// One block of the hidden layer, w2_h tanh(b1_h + Σ_c W1_hc x_n,c) for its neurons
    /// (weights doubled: the sum is 2z), on lanes `V`.
    #[inline(always)]
    fn chunk<V: Lanes>(&self, isa: V::Isa, b: &Block, xn: &[f64; MAX_INPUTS]) -> [f64; CHUNK] {
        let mut o = [0.0; CHUNK];
        for i in (0..CHUNK).step_by(V::N) {
            let mut z2 = V::load(isa, &b.b1[i..]);
            for (c, &xc) in xn.iter().enumerate().take(self.k) {
                z2 = V::load(isa, &b.w1[c][i..]).fma(V::splat(isa, xc), z2);
            }
            simd::tanh_of_doubled(z2)
                .mul(V::load(isa, &b.w2[i..]))
                .store(&mut o[i..]);
        }
        o
    }

    #[inline(always)]
    fn inputs(&self, x: [f64; MAX_INPUTS]) -> [f64; MAX_INPUTS] {
        let mut xn = [0.0; MAX_INPUTS];
        for c in 0..self.k {
            xn[c] = self.gx[c].mul_add(x[c].clamp(self.lo[c], self.hi[c]), self.ox[c]);
        }
        xn
    }

    /// The network with `C` blocks: the output sum runs over all `C` · [`CHUNK`] terms in
    /// order; the padding neurons' terms are exactly +0.0 (zero weights, tanh(+0) = +0), and
    /// y + 0.0 = y for every y but −0.0, which the sum can never hold (it starts at b2 ≠ −0.0,
    /// and a rounded sum is −0.0 only when both terms are) — so the result is that of summing
    /// the real neurons only, as the batch path and the C header do.
    #[inline(always)]
    fn net_chunks<V: Lanes, const C: usize>(&self, isa: V::Isa, x: [f64; MAX_INPUTS]) -> f64 {
        let xn = self.inputs(x);
        let blocks: &[Block; C] = self.blocks[..C].try_into().expect("C blocks");
        let mut y = self.b2;
        for b in blocks {
            for t in self.chunk::<V>(isa, b, &xn) {
                y += t;
            }
        }
        (y - self.oy) / self.gy
    }

    /// A network of two or more hidden layers: the first layer as in [`Net::chunk`] but keeping
    /// the activations t1 (no output product), each further layer
    /// 2z_g = fma(2W_gh, t_h, ·) over h in order from 2b_g, t_g = tanh, and the output
    /// y = b_o + Σ_g w_o,g t_g over the last layer's neurons in order (product, then sum: the
    /// rule of one hidden layer) — the operations of the C header's loop, lane by lane.
    #[inline(always)]
    fn net_deep<V: Lanes, const W: usize>(&self, isa: V::Isa, x: [f64; MAX_INPUTS]) -> f64 {
        let xn = self.inputs(x);
        let mut a = [0.0; W];
        let mut b = [0.0; W];
        for (j, blk) in self.blocks.iter().enumerate() {
            for i in (0..CHUNK).step_by(V::N) {
                let mut z2 = V::load(isa, &blk.b1[i..]);
                for (c, &xc) in xn.iter().enumerate().take(self.k) {
                    z2 = V::load(isa, &blk.w1[c][i..]).fma(V::splat(isa, xc), z2);
                }
                simd::tanh_of_doubled(z2).store(&mut a[j * CHUNK + i..]);
            }
        }
        let (mut cur, mut next) = (&mut a, &mut b);
        let mut n_prev = self.nh;
        for layer in &self.deep {
            // Eight, then two, then one register of neurons at a time: each neuron's sum is
            // one chain of fma in h order whatever the blocking (same bits), but R chains side
            // by side keep the FMA units busy instead of waiting out each one's latency.
            let mut i = 0;
            while i + 8 * V::N <= layer.pad {
                Self::deep_block::<V, 8>(isa, layer, &cur[..n_prev], i, next);
                i += 8 * V::N;
            }
            while i + 2 * V::N <= layer.pad {
                Self::deep_block::<V, 2>(isa, layer, &cur[..n_prev], i, next);
                i += 2 * V::N;
            }
            while i < layer.pad {
                Self::deep_block::<V, 1>(isa, layer, &cur[..n_prev], i, next);
                i += V::N;
            }
            std::mem::swap(&mut cur, &mut next);
            n_prev = layer.n;
        }
        let mut y = self.b2;
        for (w, t) in self.wo.iter().zip(cur.iter()) {
            y += w * t;
        }
        (y - self.oy) / self.gy
    }

    /// Neurons `i..i + R·N` of a further hidden layer: 2z_g = fma(2W_gh, t_h, ·) over the
    /// previous layer's activations `t` in order from 2b_g, then tanh, into `out`.
    #[inline(always)]
    fn deep_block<V: Lanes, const R: usize>(
        isa: V::Isa,
        layer: &DeepLayer,
        t: &[f64],
        i: usize,
        out: &mut [f64],
    ) {
        let mut z2: [V; R] = std::array::from_fn(|r| V::load(isa, &layer.b[i + r * V::N..]));
        // Rows of `pad` weights, one per input neuron h; this block's R·N of each (one bounds
        // check per row).
        for (row, &th) in layer.wc.chunks_exact(layer.pad).zip(t) {
            let th = V::splat(isa, th);
            let row = &row[i..i + R * V::N];
            for (r, z) in z2.iter_mut().enumerate() {
                *z = V::load(isa, &row[r * V::N..]).fma(th, *z);
            }
        }
        for (r, z) in z2.into_iter().enumerate() {
            simd::tanh_of_doubled(z).store(&mut out[i + r * V::N..]);
        }
    }

    #[inline(always)]
    fn net_any<V: Lanes>(&self, isa: V::Isa, x: [f64; MAX_INPUTS]) -> f64 {
        let xn = self.inputs(x);
        let mut y = self.b2;
        for b in &self.blocks {
            for t in self.chunk::<V>(isa, b, &xn) {
                y += t;
            }
        }
        (y - self.oy) / self.gy
    }

    /// [`Model::mu_vt`] of the network: four neurons per AVX2 register when the CPU has AVX2
    /// and FMA (compiled with AVX-512VL's 32 registers when it has those), else the portable
    /// path (plain f64; `mul_add` is a libm call on CPUs without FMA). Same bits on every path.
    #[inline]
    pub(super) fn mu_vt(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> f64 {
        match self.isa {
            // SAFETY: the token proves AVX-512F/VL, AVX2 and FMA on this CPU.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => unsafe { self.mu_vt_avx512vl(t, dv_mps, ddv_mps2, v_mps, t_c) },
            // SAFETY: the token proves AVX2 and FMA on this CPU.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(t) => unsafe { self.mu_vt_avx2(t, dv_mps, ddv_mps2, v_mps, t_c) },
            _ => self.mu_vt_impl::<f64>(Portable, dv_mps, ddv_mps2, v_mps, t_c),
        }
    }

    /// [`Net::mu_vt`] on AVX2 registers, compiled with AVX-512VL (its 32 vector registers keep
    /// tanh's constants in registers; about 5 % faster in development measurements). Rust never
    /// contracts a multiply and an add on its own, so only the written `fma`s are fused.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
    fn mu_vt_avx512vl(&self, isa: Avx512, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> f64 {
        self.mu_vt_impl::<F64x4>(isa.avx2(), dv_mps, ddv_mps2, v_mps, t_c)
    }

    /// [`Net::mu_vt`] on AVX2 registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn mu_vt_avx2(&self, isa: Avx2, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> f64 {
        self.mu_vt_impl::<F64x4>(isa, dv_mps, ddv_mps2, v_mps, t_c)
    }

    /// The physical inputs of step 1 for one call: mirrored slip and slip rate, the speed
    /// (NaN → the reference speed) and the temperature (NaN → the reference temperature).
    #[inline(always)]
    fn mirrored(
        &self,
        dv_mps: f64,
        ddv_mps2: f64,
        v_mps: f64,
        t_c: f64,
    ) -> (f64, [f64; MAX_INPUTS]) {
        let (s, dv, ddv) = if dv_mps < 0.0 {
            (-1.0, -dv_mps, -ddv_mps2)
        } else {
            (1.0, dv_mps, ddv_mps2)
        };
        let v = if v_mps.is_finite() { v_mps } else { self.v_ref };
        let t = if t_c.is_finite() { t_c } else { self.t_ref };
        (s, [dv, ddv, v, t])
    }

    #[inline(always)]
    fn mu_vt_impl<V: Lanes>(
        &self,
        isa: V::Isa,
        dv_mps: f64,
        ddv_mps2: f64,
        v_mps: f64,
        t_c: f64,
    ) -> f64 {
        if !(dv_mps.is_finite() && ddv_mps2.is_finite()) {
            return f64::NAN;
        }
        let (s, x) = self.mirrored(dv_mps, ddv_mps2, v_mps, t_c);
        let [dv, ddv, v, t] = x;
        let net = self.net_supported::<V>(isa, x);
        if dv >= self.blend {
            return s * net;
        }
        let sat = self.net_supported::<V>(isa, [self.blend, ddv, v, t]).abs();
        let v_creep = if self.k >= 3 { v.max(1.0) } else { self.v_ref };
        let slope = self.creep_per_creepage / v_creep;
        let lin = if sat > 0.0 {
            sat * she_ratio(slope * dv / sat)
        } else {
            0.0
        };
        let w = dv / self.blend;
        let w = w * w * (3.0 - 2.0 * w);
        s * (w * net + (1.0 - w) * lin)
    }

    /// Steps 2 and 3 of the evaluation rule: the network, blended towards the fallback
    /// outside the data support (version-2 files with a grid), plus a residual network's law.
    #[inline(always)]
    fn net_supported<V: Lanes>(&self, isa: V::Isa, x: [f64; MAX_INPUTS]) -> f64 {
        let n = self.net::<V>(isa, x);
        let n = match &self.support {
            None => n,
            Some(sup) => sup.apply(&self.raw_inputs(x), n),
        };
        self.plus_base(x, n)
    }

    /// `n` plus a residual network's law at the mirrored inputs `x` (Δv ≥ 0, v, T; dΔv/dt is
    /// not an input of the law); `n` for a plain network.
    #[inline(always)]
    fn plus_base(&self, x: [f64; MAX_INPUTS], n: f64) -> f64 {
        match &self.base {
            None => n,
            Some(b) => n + b.mu_vt(x[0], 0.0, x[2], x[3]),
        }
    }

    /// The inputs normalised but not clamped (the support grid fades beyond the domain).
    #[inline(always)]
    fn raw_inputs(&self, x: [f64; MAX_INPUTS]) -> [f64; MAX_INPUTS] {
        let mut xn = [0.0; MAX_INPUTS];
        for c in 0..self.k {
            xn[c] = self.gx[c].mul_add(x[c], self.ox[c]);
        }
        xn
    }

    /// The mirrored inputs of step 1, normalised but not clamped (for the support grid).
    fn mirrored_inputs(
        &self,
        dv_mps: f64,
        ddv_mps2: f64,
        v_mps: f64,
        t_c: f64,
    ) -> [f64; MAX_INPUTS] {
        self.raw_inputs(self.mirrored(dv_mps, ddv_mps2, v_mps, t_c).1)
    }

    /// The interpolated support w ∈ [0, 1] (1 inside the data; `None` without a grid).
    pub(super) fn support_weight(
        &self,
        dv_mps: f64,
        ddv_mps2: f64,
        v_mps: f64,
        t_c: f64,
    ) -> Option<f64> {
        let sup = self.support.as_ref()?;
        Some(sup.weight(&self.mirrored_inputs(dv_mps, ddv_mps2, v_mps, t_c)))
    }

    /// The interpolated ensemble spread of μ (`None` without).
    pub(super) fn spread(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> Option<f64> {
        let sup = self.support.as_ref()?;
        sup.spread(&self.mirrored_inputs(dv_mps, ddv_mps2, v_mps, t_c))
    }

    /// [`Model::mu_batch_t`] of the network (`v_mps`, `t_c` empty: the reference values).
    pub(super) fn mu_batch(
        &self,
        dv_mps: &[f64],
        ddv_mps2: &[f64],
        v_mps: &[f64],
        t_c: &[f64],
        out: &mut [f64],
    ) {
        let n = out.len();
        let full = n - n % LANES;
        let isa = self.isa;
        let lanes = |x: &[f64], b: usize| -> [f64; LANES] {
            if x.is_empty() {
                [f64::NAN; LANES]
            } else {
                x[b..b + LANES].try_into().expect("block")
            }
        };
        // Deeper networks: sample by sample on the single-call path (same bits by construction).
        let full = if self.deep.is_empty() { full } else { 0 };
        for b in (0..full).step_by(LANES) {
            let block = BlockIn {
                dv: lanes(dv_mps, b),
                ddv: lanes(ddv_mps2, b),
                v: lanes(v_mps, b),
                t: lanes(t_c, b),
            };
            let o: &mut [f64; LANES] = (&mut out[b..b + LANES]).try_into().expect("block");
            self.block_dispatch(isa, &block, o);
        }
        let at = |x: &[f64], i: usize| x.get(i).copied().unwrap_or(f64::NAN);
        for i in full..n {
            out[i] = self.mu_vt(dv_mps[i], ddv_mps2[i], at(v_mps, i), at(t_c, i));
        }
    }

    fn block_dispatch(&self, isa: Isa, input: &BlockIn, out: &mut [f64; LANES]) {
        match isa {
            // SAFETY: the token proves AVX-512F on this CPU.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => unsafe { self.block_avx512(t, input, out) },
            // SAFETY: the token proves AVX2 and FMA on this CPU.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(t) => unsafe { self.block_avx2(t, input, out) },
            _ => self.block::<f64>(Portable, input, out),
        }
    }

    /// [`Net::block`] on AVX-512 registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn block_avx512(&self, isa: Avx512, input: &BlockIn, out: &mut [f64; LANES]) {
        self.block::<F64x8>(isa, input, out)
    }

    /// [`Net::block`] on AVX2 registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn block_avx2(&self, isa: Avx2, input: &BlockIn, out: &mut [f64; LANES]) {
        self.block::<F64x4>(isa, input, out)
    }

    /// [`Model::mu_vt`] for a block of samples on lanes `V`, lane by lane the same operations
    /// as the single call: inputs, then per neuron in order 2z = fma(2W1, x_n, ·) from 2b1,
    /// y += w2 · tanh, then (y − o_y)/g_y; the creep region (rare in a batch) by the scalar rule.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn block<V: Lanes>(&self, isa: V::Isa, input: &BlockIn, out: &mut [f64; LANES]) {
        let mut sgn = [1.0; LANES];
        let mut x = [[0.0; LANES]; MAX_INPUTS];
        for l in 0..LANES {
            let (s, xl) = self.mirrored(input.dv[l], input.ddv[l], input.v[l], input.t[l]);
            sgn[l] = s;
            for c in 0..MAX_INPUTS {
                x[c][l] = xl[c];
            }
        }
        let mut xn = [[0.0; LANES]; MAX_INPUTS];
        for c in 0..self.k {
            let (lo, hi, g, o) = (self.lo[c], self.hi[c], self.gx[c], self.ox[c]);
            for l in 0..LANES {
                xn[c][l] = g.mul_add(x[c][l].clamp(lo, hi), o);
            }
        }
        let mut net = [0.0; LANES];
        let mut y = [V::splat(isa, self.b2); LANES];
        let vectors = LANES / V::N;
        for h in 0..self.nh {
            let b1 = V::splat(isa, self.b1[h]);
            let w2 = V::splat(isa, self.w2[h]);
            for j in 0..vectors {
                let mut z2 = b1;
                for c in 0..self.k {
                    let w = V::splat(isa, self.w1c[c * self.pad + h]);
                    z2 = w.fma(V::load(isa, &xn[c][j * V::N..]), z2);
                }
                y[j] = y[j].add(w2.mul(simd::tanh_of_doubled(z2)));
            }
        }
        let (oy, gy) = (V::splat(isa, self.oy), V::splat(isa, self.gy));
        for j in 0..vectors {
            y[j].sub(oy).div(gy).store(&mut net[j * V::N..]);
        }
        for l in 0..LANES {
            let (dv, ddv) = (input.dv[l], input.ddv[l]);
            out[l] = if !(dv.is_finite() && ddv.is_finite()) {
                f64::NAN
            } else if x[0][l] >= self.blend {
                let xl = [x[0][l], x[1][l], x[2][l], x[3][l]];
                let n = match &self.support {
                    None => net[l],
                    Some(sup) => sup.apply(&self.raw_inputs(xl), net[l]),
                };
                sgn[l] * self.plus_base(xl, n)
            } else {
                self.mu_vt(dv, ddv, input.v[l], input.t[l])
            };
        }
    }

    pub(super) fn in_domain(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> bool {
        let x = [
            dv_mps.abs(),
            if dv_mps < 0.0 { -ddv_mps2 } else { ddv_mps2 },
            v_mps,
            t_c,
        ];
        (0..self.k).all(|c| x[c] >= self.lo[c] && x[c] <= self.hi[c])
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Law, Model};
    use super::*;

    #[test]
    fn every_compiled_path_gives_the_portable_bits() {
        // The two-input golden network over (Δv, dΔv/dt), and the four-input one over speeds
        // and temperatures too (inside, between, beyond its runs' and NaN: the references).
        let two = include_str!("../../../models/golden/synthetic_mlp.json");
        let four = include_str!("../../../models/golden/synthetic_mlp_4inputs.json");
        for (text, vs, ts) in [
            (two, &[f64::NAN][..], &[f64::NAN][..]),
            (
                four,
                &[f64::NAN, 10.0, 25.0, 40.0][..],
                &[f64::NAN, -30.0, -10.0, 3.0, 20.0, 35.0][..],
            ),
        ] {
            let m = Model::new(ModelFile::from_json(text, "golden").unwrap()).unwrap();
            let Law::Mlp(net) = &m.law else {
                panic!("the golden model is a network")
            };
            let mut points = Vec::new();
            for i in 0..400 {
                let dv = -4.5 + 0.0225 * i as f64;
                for ddv in [-3.5, -1.0, -0.01, 0.0, 0.3, 2.9, 7.0] {
                    for &v in vs {
                        for &t in ts {
                            points.push([dv, ddv, v, t]);
                        }
                    }
                }
            }
            points.push([f64::NAN, 0.0, f64::NAN, f64::NAN]);
            points.push([0.5, f64::INFINITY, f64::NAN, f64::NAN]);
            same_on_every_path(&m, net, &points);
        }
    }

    /// Single calls and batch blocks on every instruction set this CPU has give the portable
    /// path's bits at `points` (Δv, dΔv/dt, v, T).
    fn same_on_every_path(m: &Model, net: &Net, points: &[[f64; 4]]) {
        let portable: Vec<u64> = points
            .iter()
            .map(|p| {
                net.mu_vt_impl::<f64>(Portable, p[0], p[1], p[2], p[3])
                    .to_bits()
            })
            .collect();
        let same = |name: &str, got: &[f64]| {
            for (k, (g, p)) in got.iter().zip(&portable).enumerate() {
                let p = f64::from_bits(*p);
                assert!(
                    g.to_bits() == p.to_bits() || (g.is_nan() && p.is_nan()),
                    "{name} at {:?}: {g} vs {p}",
                    points[k]
                );
            }
        };
        let single: Vec<f64> = points
            .iter()
            .map(|p| m.mu_vt(p[0], p[1], p[2], p[3]))
            .collect();
        same("dispatched single call", &single);
        let n = points.len() - points.len() % LANES;
        // Every instruction set this CPU has, the widest last.
        let sets = Isa::all_available();
        for s in &sets {
            let got: Vec<f64> = points
                .iter()
                .map(|p| match *s {
                    // SAFETY: the token proves the instructions.
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx2(t) => unsafe { net.mu_vt_avx2(t, p[0], p[1], p[2], p[3]) },
                    // SAFETY: the token proves the instructions.
                    #[cfg(target_arch = "x86_64")]
                    Isa::Avx512(t) => unsafe { net.mu_vt_avx512vl(t, p[0], p[1], p[2], p[3]) },
                    _ => net.mu_vt_impl::<f64>(Portable, p[0], p[1], p[2], p[3]),
                })
                .collect();
            same(&format!("{s:?} single call"), &got);
        }
        let col =
            |c: usize, b: usize| -> [f64; LANES] { std::array::from_fn(|l| points[b + l][c]) };
        for s in sets {
            let mut out = vec![0.0; n];
            for b in (0..n).step_by(LANES) {
                let o: &mut [f64; LANES] = (&mut out[b..b + LANES]).try_into().unwrap();
                let block = BlockIn {
                    dv: col(0, b),
                    ddv: col(1, b),
                    v: col(2, b),
                    t: col(3, b),
                };
                net.block_dispatch(s, &block, o);
            }
            same(&format!("{s:?} batch block"), &out);
        }
    }

    #[test]
    fn tanh_fast_matches_the_c_library() {
        let mut worst: f64 = 0.0;
        let mut z = -25.0;
        while z <= 25.0 {
            let (a, b) = (tanh_fast(z), z.tanh());
            let rel = if b == 0.0 {
                a.abs()
            } else {
                ((a - b) / b).abs()
            };
            worst = worst.max(rel);
            z += 0.000_731;
        }
        for z in [
            0.0, -0.0, 1e-300, -1e-300, 1e-9, 0.1733, 0.3466, 0.5, 19.0, 20.0, 40.0, 1e6, -1e6,
        ] {
            let (a, b) = (tanh_fast(z), z.tanh());
            assert!(
                (a - b).abs() <= 4.0 * f64::EPSILON * b.abs().max(f64::MIN_POSITIVE),
                "{z}: {a} vs {b}"
            );
            if b != 0.0 {
                assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{z}");
            }
        }
        assert!(worst < 4.0 * f64::EPSILON, "{worst:e}");
    }
}
