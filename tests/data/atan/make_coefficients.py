"""Coefficients of the [6/6] Padé approximant atan(t)/t ≈ P(u)/Q(u), u = t², for railgrip's
simulator (railgrip::simd::ATAN_P / ATAN_Q).

The simulator's Polach law needs atan(|b|/d) with one division. The argument is reduced to
|t| ≤ tan(π/8) by the regimes t, (t − 1)/(t + 1) (+ π/4) and −1/t (+ π/2), each a ratio n/m of
the inputs, and P, Q are evaluated homogeneously, n·m¹²·P(n²/m²) / (m·m¹²·Q(n²/m²)), so no
division happens before the last. This script builds the Padé approximant of the Maclaurin
series Σ (−1)^k u^k / (2k + 1) in 60-digit arithmetic (mpmath.pade), normalises Q(0) = 1,
rounds to IEEE doubles, and reports the worst relative error of t·P/Q (rounded coefficients)
against atan(t) on 40 001 points of (0, tan(π/8)].
Run: python3 tests/data/atan/make_coefficients.py
"""
import mpmath as mp

mp.mp.dps = 60
M = 6
series = [mp.mpf((-1) ** k) / (2 * k + 1) for k in range(2 * M + 2)]
p, q = mp.pade(series, M, M)
p = [c / q[0] for c in p]
q = [c / q[0] for c in q]
pd = [float(c) for c in p]
qd = [float(c) for c in q]
T = mp.tan(mp.pi / 8)
worst = mp.mpf(0)
for i in range(1, 40002):
    t = T * i / 40001
    u = t * t
    num = sum(mp.mpf(c) * u**k for k, c in enumerate(pd))
    den = sum(mp.mpf(c) * u**k for k, c in enumerate(qd))
    worst = max(worst, abs(t * num / den / mp.atan(t) - 1))
print(f"// [6/6] Padé, rounded coefficients: max relative error {mp.nstr(worst, 3)} on (0, tan(pi/8)]")
print("pub(crate) const ATAN_P: [f64; 7] = [" + ", ".join(repr(c) for c in pd) + "];")
print("pub(crate) const ATAN_Q: [f64; 7] = [" + ", ".join(repr(c) for c in qd) + "];")
