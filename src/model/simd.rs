//! The f64 vectors the network evaluators run on: one trait, [`Lanes`], with the plain `f64`
//! (the portable path, one lane) and, on x86_64, AVX2 (`__m256d`, four lanes) and AVX-512F
//! (`__m512d`, eight lanes) implementations, so that tanh and the hidden layer are written once
//! ([`tanh_of_doubled`]) and every path performs the same IEEE operations lane by lane — the
//! results are bit-identical whatever the CPU (tested in `model::tests`). Multiply-adds are
//! fused everywhere (`f64::mul_add`, `vfmadd`): FMA is correctly rounded, so hardware and
//! software agree to the bit; on a CPU without FMA the portable path computes it in software.
//!
//! Writing the SIMD paths with intrinsics rather than leaving lane loops to the auto-vectoriser
//! keeps their speed from depending on the compiler's cost model (a change of the polynomial
//! once made the auto-vectorised batch path 2× slower).

/// f64 lanes with the operations the evaluators use.
///
/// # Safety
/// The x86 implementations may only be used inside functions compiled for (and run on a CPU
/// with) their target features: AVX2 + FMA for `__m256d`, AVX-512F for `__m512d`. Every method
/// is `#[inline(always)]` so that it is compiled with the caller's features.
pub(crate) unsafe trait Lanes: Copy {
    /// Lanes per vector.
    const N: usize;
    unsafe fn splat(x: f64) -> Self;
    /// Loads `N` values from the front of `p` (which must hold at least `N`).
    unsafe fn load(p: &[f64]) -> Self;
    /// Stores `N` values to the front of `p` (which must hold at least `N`).
    unsafe fn store(self, p: &mut [f64]);
    unsafe fn add(self, b: Self) -> Self;
    unsafe fn sub(self, b: Self) -> Self;
    unsafe fn mul(self, b: Self) -> Self;
    unsafe fn div(self, b: Self) -> Self;
    /// self · b + c, one rounding.
    unsafe fn fma(self, b: Self, c: Self) -> Self;
    /// −(self · b) + c, one rounding.
    unsafe fn fnma(self, b: Self, c: Self) -> Self;
    /// x86 `minpd`: self < b ? self : b.
    unsafe fn min(self, b: Self) -> Self;
    /// x86 `maxpd`: self > b ? self : b.
    unsafe fn max(self, b: Self) -> Self;
    /// 2ⁿ from t = n + 1.5·2⁵² (n in the low mantissa bits, two's complement, |n| < 1023):
    /// the bits (t + 1023) shifted into the exponent field.
    unsafe fn pow2_of_magic(self) -> Self;
}

// SAFETY: plain f64 arithmetic, no target features needed.
unsafe impl Lanes for f64 {
    const N: usize = 1;
    #[inline(always)]
    unsafe fn splat(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    unsafe fn load(p: &[f64]) -> f64 {
        p[0]
    }
    #[inline(always)]
    unsafe fn store(self, p: &mut [f64]) {
        p[0] = self;
    }
    #[inline(always)]
    unsafe fn add(self, b: f64) -> f64 {
        self + b
    }
    #[inline(always)]
    unsafe fn sub(self, b: f64) -> f64 {
        self - b
    }
    #[inline(always)]
    unsafe fn mul(self, b: f64) -> f64 {
        self * b
    }
    #[inline(always)]
    unsafe fn div(self, b: f64) -> f64 {
        self / b
    }
    #[inline(always)]
    unsafe fn fma(self, b: f64, c: f64) -> f64 {
        self.mul_add(b, c)
    }
    #[inline(always)]
    unsafe fn fnma(self, b: f64, c: f64) -> f64 {
        (-self).mul_add(b, c)
    }
    #[inline(always)]
    unsafe fn min(self, b: f64) -> f64 {
        if self < b {
            self
        } else {
            b
        }
    }
    #[inline(always)]
    unsafe fn max(self, b: f64) -> f64 {
        if self > b {
            self
        } else {
            b
        }
    }
    #[inline(always)]
    unsafe fn pow2_of_magic(self) -> f64 {
        f64::from_bits(self.to_bits().wrapping_add(1023) << 52)
    }
}

/// [`Lanes`] for an x86 register type from its intrinsics (AVX2 + FMA for `__m256d`, AVX-512F
/// for `__m512d`; the two sets name them alike).
#[cfg(target_arch = "x86_64")]
macro_rules! x86_lanes {
    ($t:ty, $n:literal, $set1:ident, $load:ident, $store:ident, $add:ident,
     $sub:ident, $mul:ident, $div:ident, $fmadd:ident, $fnmadd:ident, $min:ident, $max:ident,
     $to_int:ident, $to_pd:ident, $slli:ident, $add64:ident, $set1_64:ident) => {
        // SAFETY: used only inside functions compiled for the register's target features
        // (see the trait's contract); loads and stores check the slice length first.
        unsafe impl Lanes for $t {
            const N: usize = $n;
            #[inline(always)]
            unsafe fn splat(x: f64) -> Self {
                unsafe { $set1(x) }
            }
            #[inline(always)]
            unsafe fn load(p: &[f64]) -> Self {
                assert!(p.len() >= $n);
                unsafe { $load(p.as_ptr()) }
            }
            #[inline(always)]
            unsafe fn store(self, p: &mut [f64]) {
                assert!(p.len() >= $n);
                unsafe { $store(p.as_mut_ptr(), self) }
            }
            #[inline(always)]
            unsafe fn add(self, b: Self) -> Self {
                unsafe { $add(self, b) }
            }
            #[inline(always)]
            unsafe fn sub(self, b: Self) -> Self {
                unsafe { $sub(self, b) }
            }
            #[inline(always)]
            unsafe fn mul(self, b: Self) -> Self {
                unsafe { $mul(self, b) }
            }
            #[inline(always)]
            unsafe fn div(self, b: Self) -> Self {
                unsafe { $div(self, b) }
            }
            #[inline(always)]
            unsafe fn fma(self, b: Self, c: Self) -> Self {
                unsafe { $fmadd(self, b, c) }
            }
            #[inline(always)]
            unsafe fn fnma(self, b: Self, c: Self) -> Self {
                unsafe { $fnmadd(self, b, c) }
            }
            #[inline(always)]
            unsafe fn min(self, b: Self) -> Self {
                unsafe { $min(self, b) }
            }
            #[inline(always)]
            unsafe fn max(self, b: Self) -> Self {
                unsafe { $max(self, b) }
            }
            #[inline(always)]
            unsafe fn pow2_of_magic(self) -> Self {
                unsafe { $to_pd($slli::<52>($add64($to_int(self), $set1_64(1023)))) }
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::Lanes;
    use std::arch::x86_64::*;

    x86_lanes!(
        __m256d,
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
        __m512d,
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
}

/// Coefficients of P(r) ≈ (e^r − 1)/r on |r| ≤ ln 2 / 2, degree 10, fitted by Chebyshev least
/// squares in 60-digit arithmetic and rounded to doubles by
/// `tests/data/tanh/make_coefficients.py` (max relative error 2.4e-17 ≈ 0.2 ulp; the degree-13
/// Taylor series it replaced was as accurate with two more terms).
pub(crate) const EXPM1_P: [f64; 11] = [
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

/// tanh(z) on every lane given z2 = 2z — see [`crate::model::tanh_fast`] for the method and
/// accuracy. With x = z2 clamped to [−40, 40]: x = n ln 2 + r, e^r − 1 = r P(r) (Estrin),
/// e^x − 1 = 2ⁿ P r + (2ⁿ − 1) in one fused step, tanh = (e^x − 1)/(e^x − 1 + 2).
///
/// # Safety
/// As [`Lanes`]: only with `V`'s target features enabled in the caller.
#[inline(always)]
pub(crate) unsafe fn tanh_of_doubled<V: Lanes>(z2: V) -> V {
    unsafe {
        let c = |k: usize| V::splat(EXPM1_P[k]);
        let x = z2.min(V::splat(40.0)).max(V::splat(-40.0));
        let magic = V::splat(MAGIC);
        let t = x.fma(V::splat(LOG2E), magic);
        let n = t.sub(magic);
        let r = n.fnma(V::splat(LN2_LO), n.fnma(V::splat(LN2_HI), x));
        let r2 = r.mul(r);
        let r4 = r2.mul(r2);
        let r8 = r4.mul(r4);
        let q0 = c(1).fma(r, c(0));
        let q1 = c(3).fma(r, c(2));
        let q2 = c(5).fma(r, c(4));
        let q3 = c(7).fma(r, c(6));
        let q4 = c(9).fma(r, c(8));
        let s0 = q1.fma(r2, q0);
        let s1 = q3.fma(r2, q2);
        let s2 = c(10).fma(r2, q4);
        let u0 = s1.fma(r4, s0);
        let p = s2.fma(r8, u0).mul(r);
        let scale = t.pow2_of_magic();
        let em1 = scale.fma(p, scale.sub(V::splat(1.0)));
        em1.div(em1.add(V::splat(2.0)))
    }
}
