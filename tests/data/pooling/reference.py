"""Reference values for the partial pooling's standard errors with the between-axle variance's
uncertainty (railgrip's `pooled_se`, crates/railgrip/src/estimate/selfcal.rs).

An independent computation: the posterior of tau (the groups' fitted ratios
a_g ~ N(common, se_g^2 + tau^2), a half-Cauchy prior of scale 0.05 on tau), integrated with the
trapezoid rule directly in tau on a dense grid of 2 000 001 points over [0, 400 s] (s the groups'
root mean square se); the tail beyond it is left out (the likelihood falls as tau^-4 with 4
groups and the prior as tau^-2: its mass there is below 1e-9 of the total). numpy >= 1.20. Prints one line per case: the reported value and its standard error for each
group, which the Rust test compares with.

    python3 tests/data/pooling/reference.py
"""
import numpy as np

PRIOR_SCALE = 0.05
# np.trapezoid since numpy 2.0, np.trapz before.
trapezoid = getattr(np, "trapezoid", None) or np.trapz

CASES = [
    # fitted (ratio, se) per group, common, common_se, differ
    ([(1.005, 0.01), (0.995, 0.01), (1.01, 0.01), (0.99, 0.01)], 1.0, 0.005, False),
    ([(1.03, 0.01), (0.97, 0.01), (1.01, 0.01), (0.99, 0.01)], 1.0, 0.005, True),
    ([(1.012, 0.006), (0.991, 0.009), (1.004, 0.007), (0.985, 0.008)], 0.999, 0.0035, True),
]


def moments_tau2(fitted, common, differ):
    if not differ:
        return 0.0
    k = len(fitted)
    s2 = sum((a - common) ** 2 for a, _ in fitted)
    se2 = sum(e * e for _, e in fitted)
    return max(0.0, s2 / (k - 1) - se2 / k)


def main():
    for fitted, common, common_se, differ in CASES:
        a = np.array([f[0] for f in fitted])
        e = np.array([f[1] for f in fitted])
        s = np.sqrt(np.mean(e * e))
        tau = np.linspace(0.0, 400.0 * s, 2_000_001)
        w = e[None, :] ** 2 + tau[:, None] ** 2
        loglik = np.sum(-0.5 * np.log(w) - (a[None, :] - common) ** 2 / (2 * w), axis=1)
        logpost = loglik - np.log1p((tau / PRIOR_SCALE) ** 2)
        lik = np.exp(logpost - logpost.max())
        tau2 = moments_tau2(fitted, common, differ)
        out = []
        for ag, eg in fitted:
            v = eg * eg
            b_rep = v / (v + tau2) if v + tau2 > 0 else 1.0
            reported = ag - b_rep * (ag - common)
            b = v / (v + tau ** 2)
            mean = ag - b * (ag - common)
            var = (1 - b) * v + b * b * common_se ** 2
            mse = var + (mean - reported) ** 2
            num = trapezoid(lik * mse, tau)
            den = trapezoid(lik, tau)
            out.append((reported, np.sqrt(num / den)))
        print(" ".join(f"{r:.12f}:{se:.10f}" for r, se in out))


if __name__ == "__main__":
    main()
