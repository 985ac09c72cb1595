"""Coefficients of P(r) ≈ (e^r − 1)/r on |r| ≤ ln 2 / 2 (+ margin) for railgrip's tanh.

railgrip::model evaluates e^r − 1 = r · P(r) with P of degree 10 (Estrin's scheme) after the
Cody–Waite reduction x = n ln 2 + r. This script fits P by Chebyshev least squares in 60-digit
arithmetic (mpmath.chebyfit: within a few per cent of the minimax error), rounds the
coefficients to IEEE doubles, and reports the worst relative error of the rounded polynomial
against (e^r − 1)/r on 20 001 points. Run: python3 tests/data/tanh/make_coefficients.py
"""
import mpmath as mp

mp.mp.dps = 60
H = mp.log(2) / 2 * mp.mpf("1.0001")  # |r| bound with room for the rounding of n
DEGREE = 10


def g(r):
    return mp.expm1(r) / r if r != 0 else mp.mpf(1)


coeffs, err = mp.chebyfit(g, [-H, H], DEGREE + 1, error=True)
coeffs = coeffs[::-1]  # chebyfit returns the highest power first
doubles = [float(c) for c in coeffs]
worst = mp.mpf(0)
for i in range(20001):
    r = -H + 2 * H * i / 20000
    p = mp.mpf(0)
    for c in reversed(doubles):
        p = p * r + mp.mpf(c)
    worst = max(worst, abs(p / g(r) - 1))
print(f"// chebyfit error bound {mp.nstr(err, 3)}, rounded coefficients: max relative error {mp.nstr(worst, 3)}")
print("const EXPM1_P: [f64; 11] = [")
for c in doubles:
    print(f"    {c!r},")
print("];")
