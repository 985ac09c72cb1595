//! The network of seed 002 (002_8d8769283f5e9cb6.txt, "Neural network"): inputs → one hidden
//! layer of tanh neurons → one linear output, on inputs and target scaled by mapminmax.
//!
//! ŷ = b2 + Σ_h w2_h tanh(z_h),  z_h = b1_h + Σ_i W1_hi x_i            (x, ŷ in [−1, 1] units)
//!
//! Parameters are one flat vector θ = [W1 (row-major, hidden × inputs), b1, w2, b2] — MATLAB's
//! order IW, b1, LW, b2 — so the Levenberg–Marquardt solver sees a plain vector. The Jacobian
//! row of a sample is analytic:
//! ∂ŷ/∂W1_hi = w2_h (1 − t_h²) x_i, ∂ŷ/∂b1_h = w2_h (1 − t_h²), ∂ŷ/∂w2_h = t_h, ∂ŷ/∂b2 = 1,
//! with t_h = tanh(z_h) (checked against finite differences in a test).

use crate::rng::Rng;

/// Shape of a network: inputs and hidden neurons.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    pub inputs: usize,
    pub hidden: usize,
}

impl Shape {
    /// Length of θ: hidden × (inputs + 2) + 1.
    pub fn n_params(self) -> usize {
        self.hidden * (self.inputs + 2) + 1
    }
    fn b1(self) -> usize {
        self.hidden * self.inputs
    }
    fn w2(self) -> usize {
        self.b1() + self.hidden
    }
    fn b2(self) -> usize {
        self.w2() + self.hidden
    }
}

/// Network output for normalised inputs `x` (length `shape.inputs`).
#[inline]
pub fn forward(shape: Shape, theta: &[f64], x: &[f64]) -> f64 {
    let (ni, nh) = (shape.inputs, shape.hidden);
    let mut y = theta[shape.b2()];
    for h in 0..nh {
        let mut z = theta[shape.b1() + h];
        for i in 0..ni {
            z += theta[h * ni + i] * x[i];
        }
        y += theta[shape.w2() + h] * z.tanh();
    }
    y
}

/// Output and its gradient with respect to θ (`grad.len() == n_params`).
#[inline]
pub fn forward_grad(shape: Shape, theta: &[f64], x: &[f64], grad: &mut [f64]) -> f64 {
    let (ni, nh) = (shape.inputs, shape.hidden);
    let mut y = theta[shape.b2()];
    for h in 0..nh {
        let mut z = theta[shape.b1() + h];
        for i in 0..ni {
            z += theta[h * ni + i] * x[i];
        }
        let t = z.tanh();
        let w2 = theta[shape.w2() + h];
        y += w2 * t;
        let d = w2 * (1.0 - t * t);
        for i in 0..ni {
            grad[h * ni + i] = d * x[i];
        }
        grad[shape.b1() + h] = d;
        grad[shape.w2() + h] = t;
    }
    grad[shape.b2()] = 1.0;
    y
}

/// Nguyen–Widrow initialisation for inputs scaled to [−1, 1] (as MATLAB's `initnw` for a
/// tansig layer): each hidden neuron's weight row is a random direction of length
/// β = 0.7 · hidden^(1/inputs), and the biases are spread over [−β, β] (with the sign of
/// the row's first weight) so the neurons' active regions tile the input range. The linear
/// output layer gets uniform weights and bias in [−1, 1] (MATLAB's `rands`). Same seed →
/// same θ.
pub fn nguyen_widrow(shape: Shape, seed: u64) -> Vec<f64> {
    let (ni, nh) = (shape.inputs, shape.hidden);
    let mut rng = Rng::new(seed);
    let mut theta = vec![0.0; shape.n_params()];
    let beta = 0.7 * (nh as f64).powf(1.0 / ni as f64);
    for h in 0..nh {
        let row: Vec<f64> = loop {
            let r: Vec<f64> = (0..ni).map(|_| 2.0 * rng.uniform() - 1.0).collect();
            let norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 1e-3 {
                break r.iter().map(|v| v / norm).collect();
            }
        };
        for i in 0..ni {
            theta[h * ni + i] = beta * row[i];
        }
        let spread = if nh > 1 {
            -1.0 + 2.0 * h as f64 / (nh - 1) as f64
        } else {
            0.0
        };
        theta[shape.b1() + h] = beta * spread * row[0].signum();
    }
    for h in 0..nh {
        theta[shape.w2() + h] = 2.0 * rng.uniform() - 1.0;
    }
    theta[shape.b2()] = 2.0 * rng.uniform() - 1.0;
    theta
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn analytic_gradient_matches_central_differences() {
        let shape = Shape {
            inputs: 3,
            hidden: 10,
        };
        let theta = nguyen_widrow(shape, 42);
        let mut g = vec![0.0; shape.n_params()];
        for x in [[0.3, -0.7, 0.1], [-1.0, 1.0, 0.0], [0.9, 0.9, -0.9]] {
            forward_grad(shape, &theta, &x, &mut g);
            for p in 0..shape.n_params() {
                let h = 1e-6;
                let mut tp = theta.clone();
                tp[p] += h;
                let mut tm = theta.clone();
                tm[p] -= h;
                let fd = (forward(shape, &tp, &x) - forward(shape, &tm, &x)) / (2.0 * h);
                assert!((fd - g[p]).abs() < 1e-8, "param {p}: {fd} vs {}", g[p]);
            }
        }
    }

    #[test]
    fn initialisation_is_seeded_and_tiles_the_input_range() {
        let shape = Shape {
            inputs: 2,
            hidden: 10,
        };
        assert_eq!(nguyen_widrow(shape, 1), nguyen_widrow(shape, 1));
        assert_ne!(nguyen_widrow(shape, 1), nguyen_widrow(shape, 2));
        let t = nguyen_widrow(shape, 1);
        let beta = 0.7 * 10f64.sqrt();
        for h in 0..10 {
            let norm = (t[2 * h].powi(2) + t[2 * h + 1].powi(2)).sqrt();
            assert!((norm - beta).abs() < 1e-12);
            assert!(t[20 + h].abs() <= beta + 1e-12);
        }
    }
}
