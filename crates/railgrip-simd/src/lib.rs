//! The f64 vectors the model evaluators and the simulator's step run on: one trait, [`Lanes`],
//! with the plain `f64` (the portable path, one lane) and, on x86_64, [`F64x4`] (AVX2 + FMA,
//! four lanes) and [`F64x8`] (AVX-512F, eight lanes) implementations, so that tanh, the hidden
//! layer ([`tanh_of_doubled`]), exp ([`exp_lanes`]), atan ([`atan_parts`]) and the cube
//! root ([`cbrt4`], correctly rounded) are written once and every path performs the same
//! IEEE operations lane by lane — the results are bit-identical whatever the CPU (tested in
//! `model::net::tests` and `sim::tests`). [`Select`] adds comparisons and blends (f64 and
//! AVX2) for the simulator's branch-free axle step.
//! Multiply-adds are fused everywhere (`f64::mul_add`, `vfmadd`): FMA is correctly rounded, so
//! hardware and software agree to the bit; on a CPU without FMA the portable path computes it
//! in software.
//!
//! Safety by construction: CPU features are detected once, in [`Isa::detect`], which alone
//! creates the tokens [`Avx2`] and [`Avx512`]. A vector of [`F64x4`] or [`F64x8`] can only be
//! made from its token (or from another vector), so holding one proves the CPU has its
//! instructions, and every lane operation is a safe method. `unsafe` remains inside this
//! module's intrinsic wrappers and at the few dispatch points that enter a function compiled
//! with `#[target_feature]` (each with a SAFETY comment naming the token that proves it).
//!
//! Writing the SIMD paths with intrinsics rather than leaving lane loops to the auto-vectoriser
//! keeps their speed from depending on the compiler's cost model (a change of the polynomial
//! once made the auto-vectorised batch path 2× slower). Every method is `#[inline(always)]`
//! so that it is compiled with the target features of the function it is used in.

/// The instruction sets railgrip's vector code uses, detected on this CPU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    /// AVX-512F and VL, with AVX2 and FMA.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx512(Avx512),
    /// AVX2 and FMA.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx2(Avx2),
    /// Plain f64.
    Portable,
}

impl Isa {
    /// The widest set this CPU has (the one place railgrip asks the CPU).
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx2") && has!("fma") {
                if has!("avx512f") && has!("avx512vl") {
                    return Isa::Avx512(Avx512(()));
                }
                return Isa::Avx2(Avx2(()));
            }
        }
        Isa::Portable
    }

    /// This set and every narrower one, the widest last (for tests and benchmarks that compare
    /// the paths).
    pub fn all_available() -> Vec<Isa> {
        match Isa::detect() {
            Isa::Avx512(t) => vec![Isa::Portable, Isa::Avx2(t.avx2()), Isa::Avx512(t)],
            Isa::Avx2(t) => vec![Isa::Portable, Isa::Avx2(t)],
            Isa::Portable => vec![Isa::Portable],
        }
    }
}

/// Proof that the CPU has AVX2 and FMA; made only by [`Isa::detect`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Avx2(());

/// Proof that the CPU has AVX-512F, AVX-512VL, AVX2 and FMA; made only by [`Isa::detect`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Avx512(());

impl Avx512 {
    /// A CPU with AVX-512 as detected here also has AVX2 and FMA.
    pub fn avx2(self) -> Avx2 {
        Avx2(())
    }
}

/// The portable path's token: plain f64 needs no CPU feature.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Portable;

/// f64 lanes with the operations the evaluators use. A vector exists only where its
/// instructions do (see the module documentation), so every operation is safe.
pub trait Lanes: Copy {
    /// Lanes per vector.
    const N: usize;
    /// The token that proves this CPU runs these lanes.
    type Isa: Copy;
    /// The token of an existing vector (which proves it).
    fn isa(self) -> Self::Isa;
    fn splat(isa: Self::Isa, x: f64) -> Self;
    /// Loads `N` values from the front of `p` (panics when it holds fewer).
    fn load(isa: Self::Isa, p: &[f64]) -> Self;
    /// Stores `N` values to the front of `p` (panics when it holds fewer).
    fn store(self, p: &mut [f64]);
    fn add(self, b: Self) -> Self;
    fn sub(self, b: Self) -> Self;
    fn mul(self, b: Self) -> Self;
    fn div(self, b: Self) -> Self;
    /// self · b + c, one rounding.
    fn fma(self, b: Self, c: Self) -> Self;
    /// −(self · b) + c, one rounding.
    fn fnma(self, b: Self, c: Self) -> Self;
    /// x86 `minpd`: self < b ? self : b.
    fn min(self, b: Self) -> Self;
    /// x86 `maxpd`: self > b ? self : b.
    fn max(self, b: Self) -> Self;
    /// 2ⁿ from t = n + 1.5·2⁵² (n in the low mantissa bits, two's complement, |n| < 1023):
    /// the bits (t + 1023) shifted into the exponent field.
    fn pow2_of_magic(self) -> Self;
    /// A vector like `self` with every lane `x`.
    #[inline(always)]
    fn like(self, x: f64) -> Self {
        Self::splat(self.isa(), x)
    }
}

impl Lanes for f64 {
    const N: usize = 1;
    type Isa = Portable;
    #[inline(always)]
    fn isa(self) -> Portable {
        Portable
    }
    #[inline(always)]
    fn splat(_: Portable, x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn load(_: Portable, p: &[f64]) -> f64 {
        p[0]
    }
    #[inline(always)]
    fn store(self, p: &mut [f64]) {
        p[0] = self;
    }
    #[inline(always)]
    fn add(self, b: f64) -> f64 {
        self + b
    }
    #[inline(always)]
    fn sub(self, b: f64) -> f64 {
        self - b
    }
    #[inline(always)]
    fn mul(self, b: f64) -> f64 {
        self * b
    }
    #[inline(always)]
    fn div(self, b: f64) -> f64 {
        self / b
    }
    #[inline(always)]
    fn fma(self, b: f64, c: f64) -> f64 {
        self.mul_add(b, c)
    }
    #[inline(always)]
    fn fnma(self, b: f64, c: f64) -> f64 {
        (-self).mul_add(b, c)
    }
    #[inline(always)]
    fn min(self, b: f64) -> f64 {
        if self < b {
            self
        } else {
            b
        }
    }
    #[inline(always)]
    fn max(self, b: f64) -> f64 {
        if self > b {
            self
        } else {
            b
        }
    }
    #[inline(always)]
    fn pow2_of_magic(self) -> f64 {
        f64::from_bits(self.to_bits().wrapping_add(1023) << 52)
    }
}

#[cfg(target_arch = "x86_64")]
pub use x86::{F64x4, F64x8};

/// The x86 vectors. Every intrinsic call below is sound because a value of the vector type
/// (or its token) exists only after [`Isa::detect`] found the instructions on this CPU.
#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Avx2, Avx512, Lanes, Select};
    use std::arch::x86_64::*;

    /// Four f64 in an AVX2 register; exists only on a CPU with AVX2 and FMA.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct F64x4(__m256d);

    /// Eight f64 in an AVX-512 register; exists only on a CPU with AVX-512F.
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct F64x8(__m512d);

    /// Per-lane truth values of [`F64x4`] (all ones or all zeros per lane).
    #[derive(Clone, Copy)]
    #[repr(transparent)]
    pub struct Mask4(__m256d);

    /// [`Lanes`] for an x86 vector type from its intrinsics (AVX2 + FMA for `F64x4`,
    /// AVX-512F for `F64x8`; the two sets name them alike).
    macro_rules! x86_lanes {
        ($t:ident, $isa:ident, $n:literal, $set1:ident, $load:ident, $store:ident, $add:ident,
         $sub:ident, $mul:ident, $div:ident, $fmadd:ident, $fnmadd:ident, $min:ident,
         $max:ident, $to_int:ident, $to_pd:ident, $slli:ident, $add64:ident,
         $set1_64:ident) => {
            impl Lanes for $t {
                const N: usize = $n;
                type Isa = $isa;
                #[inline(always)]
                fn isa(self) -> $isa {
                    // A vector of this type was made from its token.
                    $isa(())
                }
                #[inline(always)]
                fn splat(_: $isa, x: f64) -> Self {
                    // SAFETY: the token proves the CPU has the instructions.
                    $t(unsafe { $set1(x) })
                }
                #[inline(always)]
                fn load(_: $isa, p: &[f64]) -> Self {
                    let p = &p[..$n];
                    // SAFETY: the token proves the instructions; `p` holds N values.
                    $t(unsafe { $load(p.as_ptr()) })
                }
                #[inline(always)]
                fn store(self, p: &mut [f64]) {
                    let p = &mut p[..$n];
                    // SAFETY: `self` proves the instructions; `p` holds N values.
                    unsafe { $store(p.as_mut_ptr(), self.0) }
                }
                #[inline(always)]
                fn add(self, b: Self) -> Self {
                    // SAFETY (here and below): `self` proves the instructions.
                    $t(unsafe { $add(self.0, b.0) })
                }
                #[inline(always)]
                fn sub(self, b: Self) -> Self {
                    $t(unsafe { $sub(self.0, b.0) })
                }
                #[inline(always)]
                fn mul(self, b: Self) -> Self {
                    $t(unsafe { $mul(self.0, b.0) })
                }
                #[inline(always)]
                fn div(self, b: Self) -> Self {
                    $t(unsafe { $div(self.0, b.0) })
                }
                #[inline(always)]
                fn fma(self, b: Self, c: Self) -> Self {
                    $t(unsafe { $fmadd(self.0, b.0, c.0) })
                }
                #[inline(always)]
                fn fnma(self, b: Self, c: Self) -> Self {
                    $t(unsafe { $fnmadd(self.0, b.0, c.0) })
                }
                #[inline(always)]
                fn min(self, b: Self) -> Self {
                    $t(unsafe { $min(self.0, b.0) })
                }
                #[inline(always)]
                fn max(self, b: Self) -> Self {
                    $t(unsafe { $max(self.0, b.0) })
                }
                #[inline(always)]
                fn pow2_of_magic(self) -> Self {
                    $t(unsafe { $to_pd($slli::<52>($add64($to_int(self.0), $set1_64(1023)))) })
                }
            }
        };
    }

    x86_lanes!(
        F64x4,
        Avx2,
        4,
        _mm256_set1_pd,
        _mm256_loadu_pd,
        _mm256_storeu_pd,
        _mm256_add_pd,
        _mm256_sub_pd,
        _mm256_mul_pd,
        _mm256_div_pd,
        _mm256_fmadd_pd,
        _mm256_fnmadd_pd,
        _mm256_min_pd,
        _mm256_max_pd,
        _mm256_castpd_si256,
        _mm256_castsi256_pd,
        _mm256_slli_epi64,
        _mm256_add_epi64,
        _mm256_set1_epi64x
    );
    x86_lanes!(
        F64x8,
        Avx512,
        8,
        _mm512_set1_pd,
        _mm512_loadu_pd,
        _mm512_storeu_pd,
        _mm512_add_pd,
        _mm512_sub_pd,
        _mm512_mul_pd,
        _mm512_div_pd,
        _mm512_fmadd_pd,
        _mm512_fnmadd_pd,
        _mm512_min_pd,
        _mm512_max_pd,
        _mm512_castpd_si512,
        _mm512_castsi512_pd,
        _mm512_slli_epi64,
        _mm512_add_epi64,
        _mm512_set1_epi64
    );

    // SAFETY (every block in this impl): a `F64x4` or `Mask4` exists only on a CPU with
    // AVX2 (see the module documentation); these are AVX/SSE2 intrinsics, subsets of it.
    impl Select for F64x4 {
        type Mask = Mask4;
        #[inline(always)]
        fn le(self, b: Self) -> Mask4 {
            Mask4(unsafe { _mm256_cmp_pd::<_CMP_LE_OQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn lt(self, b: Self) -> Mask4 {
            Mask4(unsafe { _mm256_cmp_pd::<_CMP_LT_OQ>(self.0, b.0) })
        }
        #[inline(always)]
        fn select(m: Mask4, a: Self, b: Self) -> Self {
            F64x4(unsafe { _mm256_blendv_pd(b.0, a.0, m.0) })
        }
        #[inline(always)]
        fn and(m: Mask4, n: Mask4) -> Mask4 {
            Mask4(unsafe { _mm256_and_pd(m.0, n.0) })
        }
        #[inline(always)]
        fn or(m: Mask4, n: Mask4) -> Mask4 {
            Mask4(unsafe { _mm256_or_pd(m.0, n.0) })
        }
        #[inline(always)]
        fn and_not(m: Mask4, n: Mask4) -> Mask4 {
            Mask4(unsafe { _mm256_andnot_pd(m.0, n.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            F64x4(unsafe { _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0) })
        }
        #[inline(always)]
        fn neg(self) -> Self {
            F64x4(unsafe { _mm256_xor_pd(_mm256_set1_pd(-0.0), self.0) })
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            F64x4(unsafe { _mm256_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            F64x4(unsafe {
                let m = _mm256_set1_pd(-0.0);
                _mm256_or_pd(_mm256_andnot_pd(m, self.0), _mm256_and_pd(m, sign.0))
            })
        }
        #[inline(always)]
        fn load_scalars(_: Avx2, p: &[f64]) -> Self {
            F64x4(unsafe { _mm256_set_pd(p[3], p[2], p[1], p[0]) })
        }
        #[inline(always)]
        fn total4(last: Self, _: &[f64; 4]) -> f64 {
            unsafe {
                let s = _mm_add_pd(
                    _mm256_castpd256_pd128(last.0),
                    _mm256_extractf128_pd::<1>(last.0),
                );
                _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)))
            }
        }
    }
}

/// Lanes with comparisons and blends, for branch-free code (the simulator's axle step).
pub trait Select: Lanes {
    /// Per-lane truth values.
    type Mask: Copy;
    /// self ≤ b (false where either is NaN).
    fn le(self, b: Self) -> Self::Mask;
    /// self < b (false where either is NaN).
    fn lt(self, b: Self) -> Self::Mask;
    /// m ? a : b, lane by lane.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    fn and(m: Self::Mask, n: Self::Mask) -> Self::Mask;
    fn or(m: Self::Mask, n: Self::Mask) -> Self::Mask;
    /// !m & n.
    fn and_not(m: Self::Mask, n: Self::Mask) -> Self::Mask;
    /// |self| (clears the sign bit).
    fn abs(self) -> Self;
    /// −self (flips the sign bit).
    fn neg(self) -> Self;
    /// Correctly rounded square root.
    fn sqrt(self) -> Self;
    /// |self| with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    /// [`Lanes::load`] of values that scalar code has just stored: lane by lane, because a
    /// vector load cannot be forwarded from several narrower stores still in the store buffer
    /// and would wait for them to reach the cache.
    fn load_scalars(isa: Self::Isa, p: &[f64]) -> Self;
    /// (t0 + t2) + (t1 + t3) of four values: the lanes of `last` (four lanes) or, one lane
    /// at a time, the array the lanes were stored to.
    fn total4(last: Self, stored: &[f64; 4]) -> f64;
}

impl Select for f64 {
    type Mask = bool;
    #[inline(always)]
    fn le(self, b: f64) -> bool {
        self <= b
    }
    #[inline(always)]
    fn lt(self, b: f64) -> bool {
        self < b
    }
    #[inline(always)]
    fn select(m: bool, a: f64, b: f64) -> f64 {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn and(m: bool, n: bool) -> bool {
        m & n
    }
    #[inline(always)]
    fn or(m: bool, n: bool) -> bool {
        m | n
    }
    #[inline(always)]
    fn and_not(m: bool, n: bool) -> bool {
        !m & n
    }
    #[inline(always)]
    fn abs(self) -> f64 {
        f64::abs(self)
    }
    #[inline(always)]
    fn neg(self) -> f64 {
        -self
    }
    #[inline(always)]
    fn sqrt(self) -> f64 {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn copysign(self, sign: f64) -> f64 {
        f64::copysign(self, sign)
    }
    #[inline(always)]
    fn load_scalars(_: Portable, p: &[f64]) -> f64 {
        p[0]
    }
    #[inline(always)]
    fn total4(_: f64, t: &[f64; 4]) -> f64 {
        (t[0] + t[2]) + (t[1] + t[3])
    }
}

/// Coefficients of P(r) ≈ (e^r − 1)/r on |r| ≤ ln 2 / 2, degree 10, fitted by Chebyshev least
/// squares in 60-digit arithmetic and rounded to doubles by
/// `tests/data/tanh/make_coefficients.py` (max relative error 2.4e-17 ≈ 0.2 ulp; the degree-13
/// Taylor series it replaced was as accurate with two more terms).
pub const EXPM1_P: [f64; 11] = [
    1.0,
    0.5000000000000006,
    0.1666666666666667,
    0.041666666666573066,
    0.008333333333326136,
    0.001388888893251478,
    0.00019841269874820627,
    2.480150431378554e-05,
    2.7557255400206422e-06,
    2.7626371065696354e-07,
    2.5105217004720745e-08,
];

const MAGIC: f64 = 6_755_399_441_055_744.0; // 1.5 · 2^52
const LOG2E: f64 = std::f64::consts::LOG2_E;
// fdlibm's Cody–Waite split of ln 2 (LN2_HI has trailing zero bits: n · LN2_HI is exact).
const LN2_HI: f64 = 6.931_471_803_691_238e-1;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;

/// e^x = scale · (1 + p) on every lane, for x in [−708, 709] (the caller clamps): Cody–Waite
/// reduction x = n ln 2 + r (|r| ≤ ln 2 / 2), e^r − 1 = r P(r) with [`EXPM1_P`] (Estrin's scheme),
/// scale = 2ⁿ. Returns (scale, p) so that e^x − 1 = scale · p + (scale − 1) stays exact but
/// for one rounding.
#[inline(always)]
fn exp_parts<V: Lanes>(x: V) -> (V, V) {
    let isa = x.isa();
    let magic = V::splat(isa, MAGIC);
    let t = x.fma(V::splat(isa, LOG2E), magic);
    let n = t.sub(magic);
    let r = n.fnma(V::splat(isa, LN2_LO), n.fnma(V::splat(isa, LN2_HI), x));
    let r2 = r.mul(r);
    let r4 = r2.mul(r2);
    let r8 = r4.mul(r4);
    let q0 = V::splat(isa, EXPM1_P[1]).fma(r, V::splat(isa, EXPM1_P[0]));
    let q1 = V::splat(isa, EXPM1_P[3]).fma(r, V::splat(isa, EXPM1_P[2]));
    let q2 = V::splat(isa, EXPM1_P[5]).fma(r, V::splat(isa, EXPM1_P[4]));
    let q3 = V::splat(isa, EXPM1_P[7]).fma(r, V::splat(isa, EXPM1_P[6]));
    let q4 = V::splat(isa, EXPM1_P[9]).fma(r, V::splat(isa, EXPM1_P[8]));
    let s0 = q1.fma(r2, q0);
    let s1 = q3.fma(r2, q2);
    let s2 = V::splat(isa, EXPM1_P[10]).fma(r2, q4);
    let u0 = s1.fma(r4, s0);
    let p = s2.fma(r8, u0).mul(r);
    (t.pow2_of_magic(), p)
}

/// e^x on every lane, x clamped to [−700, 700] (e^−700 ≈ 1e−304 is still a normal double):
/// [`exp_parts`], within 1 ulp of the C library (tested).
#[inline(always)]
pub fn exp_lanes<V: Lanes>(x: V) -> V {
    let isa = x.isa();
    let x = x.min(V::splat(isa, 700.0)).max(V::splat(isa, -700.0));
    let (scale, p) = exp_parts(x);
    scale.fma(p, scale)
}

/// tanh(z) on every lane given z2 = 2z — see `railgrip_model::tanh_fast` for the method and
/// accuracy. With x = z2 clamped to [−40, 40]: e^x − 1 = 2ⁿ P r + (2ⁿ − 1) in one fused step
/// ([`exp_parts`]), tanh = (e^x − 1)/(e^x − 1 + 2).
#[inline(always)]
pub fn tanh_of_doubled<V: Lanes>(z2: V) -> V {
    let isa = z2.isa();
    let x = z2.min(V::splat(isa, 40.0)).max(V::splat(isa, -40.0));
    let (scale, p) = exp_parts(x);
    let em1 = scale.fma(p, scale.sub(V::splat(isa, 1.0)));
    em1.div(em1.add(V::splat(isa, 2.0)))
}

/// Coefficients of the [6/6] Padé approximant atan(t)/t ≈ P(t²)/Q(t²), from
/// `tests/data/atan/make_coefficients.py` (mpmath; max relative error of the rounded
/// coefficients 1.2e-17 for |t| ≤ tan(π/8)).
pub const ATAN_P: [f64; 7] = [
    1.0,
    2.7866666666666666,
    2.8904347826086956,
    1.3693416149068323,
    0.28994079401402056,
    0.02213105421074192,
    0.0002685815488923002,
];
pub const ATAN_Q: [f64; 7] = [
    1.0,
    3.12,
    3.7304347826086954,
    2.1316770186335403,
    0.5890160183066362,
    0.0692960021537219,
    0.0023098667384573966,
];

/// atan(b/d) for d > 0 (b, d finite) as off + num/den with den > 0, without dividing: the
/// caller divides once, usually after folding den into a common denominator.
///
/// The argument is reduced to |t| ≤ tan(π/8) as a ratio n/m of the inputs (σ = sign of b):
/// |b| ≤ tan(π/8)·d: t = b/d; |b| > tan(3π/8)·d: σπ/2 + (−σd)/|b|; otherwise
/// σπ/4 + (b − σd)/(|b| + d). Then atan(n/m) = (n/m)·P(u)/Q(u), u = n²/m² ([`ATAN_P`],
/// [`ATAN_Q`]), evaluated homogeneously with S = n², L = m²:
///   Σ c_k S^k L^(6−k) = (c0 L + c1 S) L⁵ + (c2 L + c3 S) S² L³ + ((c4 L + c5 S) S⁴ L + c6 S⁶),
/// six multiply levels; num = n Σ p_k…, den = m Σ q_k…. den has the magnitude of
/// max(|b|, d)¹³ — the caller keeps b and d within about 10^±20.
#[inline(always)]
pub fn atan_parts<V: Select>(b: V, d: V) -> (V, V, V) {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
    let isa = b.isa();
    let ab = b.abs();
    let sd = d.copysign(b);
    let low = ab.le(d.mul(V::splat(isa, 0.414_213_562_373_095_1)));
    let high = d.mul(V::splat(isa, 2.414_213_562_373_095)).lt(ab);
    let n = V::select(low, b, V::select(high, sd.neg(), b.sub(sd)));
    let m = V::select(low, d, V::select(high, ab, ab.add(d)));
    let off = V::select(
        low,
        V::splat(isa, 0.0),
        V::select(high, V::splat(isa, FRAC_PI_2), V::splat(isa, FRAC_PI_4)).copysign(b),
    );
    let s = n.mul(n);
    let l = m.mul(m);
    let s2 = s.mul(s);
    let l2 = l.mul(l);
    let s4 = s2.mul(s2);
    let l3 = l2.mul(l);
    let l4 = l2.mul(l2);
    let mono = [l4.mul(l), s2.mul(l3), s4.mul(l), s4.mul(s2)];
    (
        off,
        n.mul(homogeneous6(&ATAN_P, s, l, &mono)),
        m.mul(homogeneous6(&ATAN_Q, s, l, &mono)),
    )
}

/// Σ c_k S^k L^(6−k) from the monomials [L⁵, S²L³, S⁴L, S⁶] (see [`atan_parts`]). (A
/// function, not a closure: closures do not inherit the caller's target features, and the
/// intrinsics would not inline into them.)
#[inline(always)]
fn homogeneous6<V: Lanes>(c: &[f64; 7], s: V, l: V, mono: &[V; 4]) -> V {
    let isa = s.isa();
    let p01 = V::splat(isa, c[1]).fma(s, V::splat(isa, c[0]).mul(l));
    let p23 = V::splat(isa, c[3]).fma(s, V::splat(isa, c[2]).mul(l));
    let p45 = V::splat(isa, c[5]).fma(s, V::splat(isa, c[4]).mul(l));
    let t0 = p01.fma(mono[0], p23.mul(mono[1]));
    let t1 = p45.fma(mono[2], V::splat(isa, c[6]).mul(mono[3]));
    t0.add(t1)
}

/// The bit trick's start for x^(−1/3) (the integer form of −log₂(x)/3, as in the well-known
/// inverse square root trick): x's bits divided by 3 subtracted from this constant give r₀
/// with |1 − x r₀³| ≤ 0.1021 for every positive normal x. The constant was searched for the
/// smallest such bound over [1, 8) and 10^±300 (a development script; [`cbrt`] needs only
/// some bound below about 0.15 for its two steps).
const CBRT_MAGIC: u64 = 0x553e_e960_0000_0000;

/// One step r ← r (1 − e)^(−1/3), e = 1 − x r³, by the binomial series
/// 1 + e/3 + 2e²/9 + 14e³/81 (+ 35e⁴/243 + …, left out): from |e| ≤ 0.1021 the next e is at
/// most 5.2e-5, and from there the step leaves only rounding (~2⁻⁵²).
#[inline(always)]
fn inverse_cbrt_step<V: Lanes>(x: V, r: V) -> V {
    let e = x.fnma(r.mul(r).mul(r), x.like(1.0));
    let q = e
        .fma(x.like(14.0 / 81.0), x.like(2.0 / 9.0))
        .fma(e, x.like(1.0 / 3.0))
        .mul(e);
    r.fma(q, r)
}

/// [`cbrt`]'s fast path on lanes, from the start r₀ ≈ x^(−1/3): returns y (x r², a few ulp
/// off), the correction t, the rounded root z = fl(y + t) and its exact tail y + t − z, for
/// [`cbrt_fast`].
#[inline(always)]
fn cbrt_lanes<V: Lanes>(x: V, r0: V) -> [V; 4] {
    let r = inverse_cbrt_step(x, inverse_cbrt_step(x, r0));
    let y = x.mul(r).mul(r);
    let s = y.mul(y);
    let s_lo = y.fma(y, s.mul(x.like(-1.0)));
    let c = y.mul(s);
    let c_lo = y.fma(s, c.mul(x.like(-1.0)));
    let rho = x.sub(c).sub(c_lo).sub(y.mul(s_lo));
    let t = rho.mul(r.mul(r).mul(x.like(1.0 / 3.0)));
    let z = y.add(t);
    let tail = t.sub(z.sub(y));
    [y, t, z, tail]
}

/// The start r₀ ≈ x^(−1/3) from x's bits ([`CBRT_MAGIC`]).
#[inline(always)]
fn cbrt_start(x: f64) -> f64 {
    f64::from_bits(CBRT_MAGIC.wrapping_sub(x.to_bits() / 3))
}

/// z if it is certainly the correctly rounded cube root of x (see [`cbrt`]), else None.
#[inline(always)]
fn cbrt_fast(x: f64, [y, t, z, tail]: [f64; 4]) -> Option<f64> {
    const MANTISSA: u64 = (1 << 52) - 1;
    // False for a NaN t too.
    let small = t.abs() < y * TWO_POW_M50;
    if !(1e-290..=1e290).contains(&x) || !small {
        return None;
    }
    let bits = z.to_bits();
    // Half the spacing of the doubles on the tail's side of z: 2^(exponent − 53) (z ≥ 1e-97:
    // the exponent field is above 53), half that below a power of two.
    let mut half_spacing = f64::from_bits((bits & !MANTISSA) - (53 << 52));
    if bits & MANTISSA == 0 && tail < 0.0 {
        half_spacing *= 0.5;
    }
    (half_spacing - tail.abs() > z * TWO_POW_M96).then_some(z)
}

/// The cube root of x, **correctly rounded**: the bits of `f64::cbrt` where that is correctly
/// rounded — on Linux it is (compiler-builtins' port of CORE-MATH's cbrt, Sibidanov and
/// Zimmermann; not glibc's, which is not). Where it is compiled with FMA (the AVX2 and AVX-512
/// paths) the fast path has no call and no division, and [`cbrt4`] takes four roots at once on
/// vector lanes (the simulator's patch refresh, one per axle and logger record under load
/// transfer); without FMA each of its ten fused multiply-adds is a call to the software one.
///
/// Fast path, for positive x in [1e-290, 1e290] (every intermediate stays a normal double,
/// the exact product tails included):
/// 1. r ≈ x^(−1/3): the bit trick ([`CBRT_MAGIC`]), then two steps of
///    [`inverse_cbrt_step`]: relative error ~2⁻⁵² (rounding);
/// 2. y = x r² = cbrt(x)(1 + ε), |ε| a few 2⁻⁵³, and one Newton correction in double-double
///    arithmetic: ρ = x − y³ with y² = s + s_lo and y s = c + c_lo exact (FMA), x − c exact
///    (Sterbenz's lemma: c is within a factor 2 of x), error of ρ ≲ 2⁻¹⁰⁰ x; t = ρ r²/3
///    ≈ ρ/(3y²). y + t is within E ≈ 2ε² y + 2⁻¹⁰⁰ y of the true root (the Newton step's
///    own error ε² y and the ε of r² in t's factor); the check requires |t| < 2⁻⁵⁰ y, which
///    bounds |ε| by about 2⁻⁵⁰ and E below 2⁻⁹⁸ y (measured: ε ≤ 2⁻⁵¹·¹, E ≤ 2⁻¹⁰⁰·⁸ y);
/// 3. z = fl(y + t) with its exact tail y + t − z (Dekker's Fast2Sum, |y| ≥ |t|). z is the
///    correctly rounded root when |tail| + E is below half the spacing of the doubles on the
///    tail's side of z (half that below a power of two): the interval around y + t cannot
///    reach a rounding boundary. Checked with 2⁻⁹⁶ z (4× the bound on E) for E.
///
/// Everything else — zero, negative, subnormal, huge, infinite and NaN arguments, and the
/// near-boundary cases the check rejects (about one argument in 2⁴³; CORE-MATH's hard cases
/// among them, where z is an ulp off) — goes to `f64::cbrt`. Tested bit for bit against
/// `f64::cbrt` over millions of arguments on the portable and AVX2 paths, with the hard cases
/// rejected and every other argument taking the fast path (`cbrt_is_the_correctly_rounded_one`).
#[inline(always)]
pub fn cbrt(x: f64) -> f64 {
    cbrt_fast(x, cbrt_lanes(x, cbrt_start(x))).unwrap_or_else(|| x.cbrt())
}

/// [`cbrt`] of four values, the fast path on `V`'s lanes (the same bits on every path; `V` of
/// one, two or four lanes — four is all there is to fill).
#[inline(always)]
pub fn cbrt4<V: Lanes>(isa: V::Isa, x: [f64; 4]) -> [f64; 4] {
    const { assert!(V::N <= 4 && 4 % V::N == 0, "cbrt4 takes lanes of at most 4") };
    let r0 = x.map(cbrt_start);
    let mut parts = [[0.0; 4]; 4];
    let mut i = 0;
    while i < 4 {
        let lanes = cbrt_lanes(V::load(isa, &x[i..]), V::load(isa, &r0[i..]));
        for (part, lane) in parts.iter_mut().zip(lanes) {
            lane.store(&mut part[i..]);
        }
        i += V::N;
    }
    std::array::from_fn(|k| {
        cbrt_fast(x[k], [parts[0][k], parts[1][k], parts[2][k], parts[3][k]])
            .unwrap_or_else(|| x[k].cbrt())
    })
}

const TWO_POW_M96: f64 = 1.0 / (1u128 << 96) as f64;
const TWO_POW_M50: f64 = 1.0 / (1u64 << 50) as f64;

#[cfg(test)]
mod tests {
    use super::*;

    /// [`cbrt`] and [`cbrt4`] (portable and AVX2 lanes) give `f64::cbrt`'s bits (correctly
    /// rounded on Linux, where this runs): random arguments over the whole range, every 2⁻²⁰
    /// step of [0.5, 2) (the simulator's load ratios), perfect cubes and their neighbours (where
    /// the root is exact or next to a double), CORE-MATH's two round-to-nearest hard cases
    /// scaled by 8^k (the fast path's z is an ulp off there: the check must reject it), and the
    /// special values. Every other argument of the fast path's domain must take it.
    #[cfg(target_os = "linux")]
    #[test]
    fn cbrt_is_the_correctly_rounded_one() {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2,fma")]
        fn avx2(isa: Avx2, x: [f64; 4]) -> [f64; 4] {
            cbrt4::<F64x4>(isa, x)
        }
        let avx2_isa = match Isa::detect() {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(t) => Some(t.avx2()),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(t) => Some(t),
            _ => None,
        };
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let mut batch = Vec::with_capacity(4);
        let (checked, slow) = (std::cell::Cell::new(0u64), std::cell::Cell::new(0u64));
        let mut check = |x: f64| {
            let b = x.cbrt();
            assert!(same(cbrt(x), b), "cbrt({x:e}) = {:e}, libm {b:e}", cbrt(x));
            checked.set(checked.get() + 1);
            if (1e-290..=1e290).contains(&x) && cbrt_fast(x, cbrt_lanes(x, cbrt_start(x))).is_none()
            {
                slow.set(slow.get() + 1);
            }
            batch.push(x);
            if batch.len() == 4 {
                let x4 = [batch[0], batch[1], batch[2], batch[3]];
                batch.clear();
                let mut paths = vec![("portable", cbrt4::<f64>(Portable, x4))];
                #[cfg(target_arch = "x86_64")]
                if let Some(isa) = avx2_isa {
                    // SAFETY: `isa` proves AVX2 and FMA.
                    paths.push(("avx2", unsafe { avx2(isa, x4) }));
                }
                for (name, got) in paths {
                    for k in 0..4 {
                        let b = x4[k].cbrt();
                        assert!(
                            same(got[k], b),
                            "{name} cbrt4: cbrt({:e}) = {:e}, libm {b:e}",
                            x4[k],
                            got[k]
                        );
                    }
                }
            }
        };
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..4_000_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            check(f64::from_bits(state));
        }
        let mut x = 0.5;
        while x < 2.0 {
            check(x);
            x += 1.0 / (1u64 << 20) as f64;
        }
        for k in 1..200_000u64 {
            let c = (k * k) as f64 * k as f64;
            for d in -3i64..=3 {
                check(f64::from_bits(c.to_bits().wrapping_add_signed(d)));
                check(f64::from_bits(
                    (c / 4096.0).to_bits().wrapping_add_signed(d),
                ));
            }
        }
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            8.0,
            0.125,
            1e-290,
            1e290,
            1e-300,
            1e300,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            check(x);
        }
        let (slow, checked) = (slow.get(), checked.get());
        assert_eq!(slow, 0, "{slow} of {checked} arguments left the fast path");
        // The hard cases (0x1.a202bfc89ddffp+2, 0x1.9b78223aa307cp+1): rejected, and right.
        for hard in [
            f64::from_bits(0x401a_202b_fc89_ddff),
            f64::from_bits(0x4009_b782_23aa_307c),
        ] {
            for k in [-90, -7, 0, 7, 90] {
                let x = hard * 8f64.powi(k);
                assert!(
                    cbrt_fast(x, cbrt_lanes(x, cbrt_start(x))).is_none(),
                    "hard case {x:e} passed the check"
                );
                check(x);
            }
        }
    }

    fn atan_f64(b: f64, d: f64) -> f64 {
        let (off, num, den) = atan_parts(b, d);
        off + num / den
    }

    #[test]
    fn atan_parts_matches_the_c_library() {
        let mut worst: f64 = 0.0;
        for i in -4000..=4000 {
            let t = 10f64.powf(i as f64 / 400.0);
            for s in [1.0, -1.0] {
                for d in [1e-9, 0.37, 1.0, 2e4] {
                    let b = s * t * d;
                    let got = atan_f64(b, d);
                    let want = (b / d).atan();
                    worst = worst.max(((got - want) / want).abs());
                }
            }
        }
        assert!(worst < 1e-15, "worst relative error {worst:e}");
        assert_eq!(atan_f64(0.0, 3.0), 0.0);
        let (_, _, den) = atan_parts(-1e6, 1e-3);
        assert!(den > 0.0);
    }

    #[test]
    fn exp_lanes_matches_the_c_library() {
        let mut worst: f64 = 0.0;
        for i in 0..=200_000 {
            let x = -700.0 + 1400.0 * i as f64 / 200_000.0;
            let got = exp_lanes(x);
            worst = worst.max(((got - x.exp()) / x.exp()).abs());
        }
        assert!(worst < 4.5e-16, "worst relative error {worst:e}");
        assert!(exp_lanes(-1e6) > 0.0 && exp_lanes(1e6).is_finite());
        // Exactly 1 at ±0: the simulator's thermal stage skips the call there (same bits).
        assert_eq!(exp_lanes(0.0).to_bits(), 1.0f64.to_bits());
        assert_eq!(exp_lanes(-0.0).to_bits(), 1.0f64.to_bits());
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_atan_and_exp_give_the_portable_bits() {
        let isa = match Isa::detect() {
            Isa::Avx512(t) => t.avx2(),
            Isa::Avx2(t) => t,
            Isa::Portable => return,
        };
        #[target_feature(enable = "avx2,fma")]
        fn four(isa: Avx2, b: &[f64; 4], d: &[f64; 4]) -> ([f64; 4], [f64; 4]) {
            let (off, num, den) = atan_parts(F64x4::load(isa, b), F64x4::load(isa, d));
            let (mut a, mut e) = ([0.0; 4], [0.0; 4]);
            off.add(num.div(den)).store(&mut a);
            exp_lanes(F64x4::load(isa, b)).store(&mut e);
            (a, e)
        }
        for i in 0..2000 {
            let x = (i as f64 - 1000.0) * 0.037;
            let b = [x, -x * 3.1, x * 1e-3, x * 40.0];
            let d = [0.5, 1.7, 1e-4, 3.0];
            // SAFETY: `isa` proves AVX2 and FMA.
            let (a, e) = unsafe { four(isa, &b, &d) };
            for k in 0..4 {
                assert_eq!(
                    a[k].to_bits(),
                    atan_f64(b[k], d[k]).to_bits(),
                    "{} {}",
                    b[k],
                    d[k]
                );
                assert_eq!(e[k].to_bits(), exp_lanes(b[k]).to_bits());
            }
        }
    }
}
