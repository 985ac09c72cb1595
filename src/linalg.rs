//! Small dense linear algebra for the least-squares solvers (a handful of parameters, so no
//! BLAS/LAPACK): Cholesky factorisation of a symmetric positive definite matrix and solves.

/// Lower-triangular Cholesky factor L (row-major, k×k) of the symmetric matrix `a` with
/// A = L Lᵀ, or `None` when A is not (numerically) positive definite — a pivot that is not
/// strictly positive and finite.
pub fn cholesky(a: &[f64], k: usize) -> Option<Vec<f64>> {
    debug_assert_eq!(a.len(), k * k);
    let mut l = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..=i {
            let mut s = a[i * k + j];
            for p in 0..j {
                s -= l[i * k + p] * l[j * k + p];
            }
            if i == j {
                if !(s > 0.0 && s.is_finite()) {
                    return None;
                }
                l[i * k + i] = s.sqrt();
            } else {
                l[i * k + j] = s / l[j * k + j];
            }
        }
    }
    Some(l)
}

/// Solves L Lᵀ x = b for the factor of [`cholesky`].
pub fn cho_solve(l: &[f64], k: usize, b: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; k];
    for i in 0..k {
        let mut s = b[i];
        for p in 0..i {
            s -= l[i * k + p] * y[p];
        }
        y[i] = s / l[i * k + i];
    }
    let mut x = vec![0.0; k];
    for i in (0..k).rev() {
        let mut s = y[i];
        for p in i + 1..k {
            s -= l[p * k + i] * x[p];
        }
        x[i] = s / l[i * k + i];
    }
    x
}

/// Diagonal of A⁻¹ from the Cholesky factor (k solves; fine for small k).
pub fn inverse_diagonal(l: &[f64], k: usize) -> Vec<f64> {
    (0..k)
        .map(|p| {
            let mut e = vec![0.0; k];
            e[p] = 1.0;
            cho_solve(l, k, &e)[p]
        })
        .collect()
}

/// Effective number of independent samples of a residual series, n / (1 + 2 Σ_k ρ_k), with
/// the autocorrelations ρ_k summed up to the first lag where they are no longer positive
/// (Geyer's initial positive sequence, simplified). Filtered signals at 417 Hz are correlated
/// over hundreds of samples; treating them as independent would shrink standard errors by an
/// order of magnitude.
pub fn effective_samples(e: &[f64]) -> f64 {
    let n = e.len();
    let c0: f64 = e.iter().map(|x| x * x).sum();
    if n < 2 || c0 <= 0.0 {
        return n as f64;
    }
    let mut tau = 1.0;
    for k in 1..n / 2 {
        let ck: f64 = e[..n - k].iter().zip(&e[k..]).map(|(a, b)| a * b).sum();
        let rho = ck / c0;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    (n as f64 / tau).clamp(1.0, n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_a_small_system() {
        let a = [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let l = cholesky(&a, 3).unwrap();
        let x = cho_solve(&l, 3, &[1.0, 2.0, 3.0]);
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a[i * 3 + j] * x[j]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-12);
        }
        let d = inverse_diagonal(&l, 3);
        assert!(d.iter().all(|v| *v > 0.0));
        assert!(cholesky(&[1.0, 1.0, 1.0, 1.0], 2).is_none());
        assert!(cholesky(&[f64::NAN], 1).is_none());
    }

    #[test]
    fn white_noise_is_independent_and_a_smooth_series_is_not() {
        let mut rng = crate::rng::Rng::new(3);
        let white: Vec<f64> = (0..5000).map(|_| rng.normal()).collect();
        assert!(effective_samples(&white) > 3000.0);
        let smooth: Vec<f64> = (0..5000).map(|i| (i as f64 * 0.01).sin()).collect();
        assert!(effective_samples(&smooth) < 100.0);
    }
}
