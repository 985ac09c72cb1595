"""Reference for railgrip's flash-temperature strip model (crates/railgrip-contact/src/flash.rs).

Jaeger's surface temperature of a semi-infinite body under a heat flux q(t) switched on at
t = 0 (Carslaw & Jaeger 1959, Duhamel's integral of the constant-flux solution):

    dT(t) = 1/sqrt(pi*lam*rho*c) * integral_0^min(t, tc) q(tau) / sqrt(t - tau) dtau

for the semi-elliptic source a point sees crossing a Hertz contact in the time tc,
q(tau) = q0 * sqrt(1 - (1 - 2 tau/tc)^2). Written normalised: theta(t/tc) =
dT * sqrt(pi*lam*rho*c) / (q0 * sqrt(tc)). scipy.integrate.quad with the algebraic
end-point weights, relative tolerance 1e-12.

    python3 tests/data/flash/make_reference.py > tests/data/flash/jaeger_elliptic.csv
"""
import numpy as np
from scipy.integrate import quad


def theta(t):
    """Normalised rise at t (units of tc)."""
    q = lambda u: np.sqrt(max(0.0, 1.0 - (1.0 - 2.0 * u) ** 2))
    if t <= 1.0:
        # q(u)/sqrt(t-u) on [0, t]: weight (t-u)^-1/2 at the upper end.
        v, _ = quad(q, 0.0, t, weight="alg", wvar=(0.0, -0.5), epsabs=0, epsrel=1e-12, limit=500)
        return v
    f = lambda u: q(u) / np.sqrt(t - u)
    v, _ = quad(f, 0.0, 1.0, epsabs=0, epsrel=1e-12, limit=500)
    return v


print("t_over_tc,theta")
for t in [0.1, 0.25, 0.5, 0.75, 0.9, 1.0, 1.25, 1.5, 2.0, 3.0, 5.0]:
    print(f"{t},{theta(t):.12e}")
