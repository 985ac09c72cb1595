//! Dense linear algebra for the least-squares solvers: Cholesky factorisation of a symmetric
//! positive definite matrix and solves. Up to [`BLOCKED_FROM`] parameters the textbook
//! (Cholesky–Banachiewicz) loop — the Polach fits, calibration and the seed 002 network; from
//! there faer's blocked factorisation, for the hundreds to thousands of parameters of larger
//! networks.

/// Order from which [`cholesky`] uses faer's blocked factorisation.
pub const BLOCKED_FROM: usize = 192;

/// Lower-triangular Cholesky factor L (row-major, k×k) of the symmetric matrix `a` with
/// A = L Lᵀ, or `None` when A is not (numerically) positive definite — a pivot that is not
/// strictly positive and finite. Reads only the lower triangle of `a`.
pub fn cholesky(a: &[f64], k: usize) -> Option<Vec<f64>> {
    debug_assert_eq!(a.len(), k * k);
    if k >= BLOCKED_FROM {
        return cholesky_blocked(a, k);
    }
    cholesky_unblocked(a, k)
}

/// Large systems by faer's blocked LLᵀ factorisation (sequential, so the result does not
/// depend on the thread count).
fn cholesky_blocked(a: &[f64], k: usize) -> Option<Vec<f64>> {
    let m = faer::MatRef::from_row_major_slice(a, k, k);
    let llt = m.llt(faer::Side::Lower).ok()?;
    let l = llt.L();
    let mut out = vec![0.0; k * k];
    for i in 0..k {
        for j in 0..=i {
            let v = l[(i, j)];
            if !v.is_finite() || (i == j && v <= 0.0) {
                return None;
            }
            out[i * k + j] = v;
        }
    }
    Some(out)
}

fn cholesky_unblocked(a: &[f64], k: usize) -> Option<Vec<f64>> {
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

/// Diagonal of A⁻¹ from the Cholesky factor (k solves): the reference [`inverse_trace`] is
/// tested against.
#[cfg(test)]
fn inverse_diagonal(l: &[f64], k: usize) -> Vec<f64> {
    (0..k)
        .map(|p| {
            let mut e = vec![0.0; k];
            e[p] = 1.0;
            cho_solve(l, k, &e)[p]
        })
        .collect()
}

/// tr(A⁻¹) from the Cholesky factor L of A: tr(A⁻¹) = tr(L⁻ᵀ L⁻¹) = ‖L⁻¹‖²_F, with L⁻¹ by
/// forward substitution column by column (k³/6 multiply-adds).
pub fn inverse_trace(l: &[f64], k: usize) -> f64 {
    let mut total = 0.0;
    let mut col = vec![0.0; k];
    for j in 0..k {
        // Column j of L⁻¹: zero above the diagonal.
        for i in j..k {
            let mut s = if i == j { 1.0 } else { 0.0 };
            for p in j..i {
                s -= l[i * k + p] * col[p];
            }
            col[i] = s / l[i * k + i];
            total += col[i] * col[i];
        }
    }
    total
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
        let tr = inverse_trace(&l, 3);
        assert!((tr - d.iter().sum::<f64>()).abs() < 1e-14, "{tr} vs {d:?}");
        assert!(cholesky(&[1.0, 1.0, 1.0, 1.0], 2).is_none());
        assert!(cholesky(&[f64::NAN], 1).is_none());
    }

    #[test]
    fn blocked_and_unblocked_factors_agree() {
        let mut rng = crate::rng::Rng::new(9);
        for k in [BLOCKED_FROM, 300] {
            // A = B Bᵀ + k I: symmetric positive definite.
            let b: Vec<f64> = (0..k * k).map(|_| rng.normal()).collect();
            let mut a = vec![0.0; k * k];
            for i in 0..k {
                for j in 0..k {
                    a[i * k + j] = (0..k).map(|p| b[i * k + p] * b[j * k + p]).sum::<f64>();
                }
                a[i * k + i] += k as f64;
            }
            let l1 = cholesky_unblocked(&a, k).unwrap();
            let l2 = cholesky(&a, k).unwrap();
            let worst = l1
                .iter()
                .zip(&l2)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-11, "k = {k}: {worst:e}");
            // Not positive definite: a negative pivot late in the matrix.
            a[(k - 1) * k + k - 1] = -1.0;
            assert!(cholesky(&a, k).is_none());
        }
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
