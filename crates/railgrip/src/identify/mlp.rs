//! The network of seed 002 (002_8d8769283f5e9cb6.txt, "Neural network") and its deeper
//! variants: inputs → one or two hidden layers of tanh neurons → one linear output, on inputs
//! and target scaled by mapminmax.
//!
//! One hidden layer (seed 002):  ŷ = b_o + Σ_h w_o,h t_h,  t_h = tanh(b1_h + Σ_i W1_hi x_i);
//! two: t2_g = tanh(b2_g + Σ_h W2_gh t_h) feeds the output instead.
//!
//! Parameters are one flat vector θ in MATLAB's order — IW (row-major, hidden × inputs), b1,
//! [LW2 (row-major, hidden2 × hidden), b2,] LW_out, b_out — so the Levenberg–Marquardt solver
//! sees a plain vector. The Jacobian row of a sample is analytic (back-propagation):
//! ∂ŷ/∂w_o,g = t_g (last layer), ∂ŷ/∂b_o = 1, δ_g = w_o,g (1 − t_g²);
//! two layers: ∂ŷ/∂W2_gh = δ2_g t_h, ∂ŷ/∂b2_g = δ2_g, δ1_h = (1 − t_h²) Σ_g W2_gh δ2_g;
//! ∂ŷ/∂W1_hi = δ1_h x_i, ∂ŷ/∂b1_h = δ1_h (checked against finite differences in tests).
//!
//! tanh is the evaluators' ([`crate::model::tanh_fast`]: branch-free, within 4 ulp of the C
//! library's), so a trained network is evaluated with the function it was trained with.
//! [`forward`] and [`forward_grad`] compute one sample; [`block`] a block of samples across SIMD
//! lanes ([`crate::simd::Lanes`]): residuals and, when asked, the Jacobian columns.

use crate::rng::Rng;
use crate::simd::{tanh_of_doubled, Lanes};

/// Shape of a network: inputs, hidden neurons, and neurons of a second hidden layer (0: none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shape {
    pub inputs: usize,
    pub hidden: usize,
    pub hidden2: usize,
}

impl Shape {
    /// One hidden layer (seed 002).
    pub fn one(inputs: usize, hidden: usize) -> Shape {
        Shape {
            inputs,
            hidden,
            hidden2: 0,
        }
    }
    /// Length of θ.
    pub fn n_params(self) -> usize {
        self.wo() + self.last() + 1
    }
    /// Neurons of the last hidden layer.
    pub fn last(self) -> usize {
        if self.hidden2 > 0 {
            self.hidden2
        } else {
            self.hidden
        }
    }
    fn b1(self) -> usize {
        self.hidden * self.inputs
    }
    fn w2(self) -> usize {
        self.b1() + self.hidden
    }
    fn b2(self) -> usize {
        self.w2() + self.hidden2 * self.hidden
    }
    /// Offset of the output weights.
    fn wo(self) -> usize {
        if self.hidden2 > 0 {
            self.b2() + self.hidden2
        } else {
            self.w2()
        }
    }
    fn bo(self) -> usize {
        self.wo() + self.last()
    }
}

/// A network of any depth: inputs, then the neurons of each hidden layer in order (the
/// output is one linear neuron). θ runs layer by layer — W (row-major, out × in), then b —
/// and ends with the output weights and bias: for one or two hidden layers exactly [`Shape`]'s
/// order, so LM and burn networks share [`forward_layers`], [`nguyen_widrow_layers`] and the
/// model file's layers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Arch {
    pub inputs: usize,
    pub hidden: Vec<usize>,
}

impl Arch {
    /// Widths from the inputs to the output, `[inputs, h1, …, hL, 1]`.
    pub fn sizes(&self) -> Vec<usize> {
        std::iter::once(self.inputs)
            .chain(self.hidden.iter().copied())
            .chain([1])
            .collect()
    }
    /// Length of θ.
    pub fn n_params(&self) -> usize {
        self.sizes().windows(2).map(|p| p[1] * (p[0] + 1)).sum()
    }
    /// The LM trainer's [`Shape`] (one or two hidden layers), else `None`.
    pub fn lm_shape(&self) -> Option<Shape> {
        match self.hidden[..] {
            [h] => Some(Shape::one(self.inputs, h)),
            [h, h2] => Some(Shape {
                inputs: self.inputs,
                hidden: h,
                hidden2: h2,
            }),
            _ => None,
        }
    }
}

impl From<Shape> for Arch {
    fn from(s: Shape) -> Arch {
        Arch {
            inputs: s.inputs,
            hidden: if s.hidden2 > 0 {
                vec![s.hidden, s.hidden2]
            } else {
                vec![s.hidden]
            },
        }
    }
}

impl std::fmt::Display for Arch {
    /// `3-32-32-1`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let s: Vec<String> = self.sizes().iter().map(|n| n.to_string()).collect();
        f.write_str(&s.join("-"))
    }
}

/// Output of a network of any depth for normalised inputs `x` (θ in [`Arch`]'s order): the
/// same operations as [`forward`] (fused multiply-adds in order), for one or two hidden
/// layers the same bits.
pub fn forward_layers(arch: &Arch, theta: &[f64], x: &[f64]) -> f64 {
    let mut at = 0;
    let mut t: Vec<f64> = x[..arch.inputs].to_vec();
    for &n in &arch.hidden {
        let n_in = t.len();
        let next: Vec<f64> = (0..n)
            .map(|g| {
                let row = &theta[at + g * n_in..at + (g + 1) * n_in];
                let z = row
                    .iter()
                    .zip(&t)
                    .fold(theta[at + n * n_in + g], |z, (w, v)| w.mul_add(*v, z));
                tanh(z)
            })
            .collect();
        at += n * (n_in + 1);
        t = next;
    }
    t.iter().enumerate().fold(theta[at + t.len()], |y, (g, v)| {
        theta[at + g].mul_add(*v, y)
    })
}

/// [`nguyen_widrow`] for any depth: each hidden layer by [`nw_layer`] on its inputs, the output
/// layer uniform in [−1, 1]. For one or two hidden layers the same θ as [`nguyen_widrow`].
pub fn nguyen_widrow_layers(arch: &Arch, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let mut theta = vec![0.0; arch.n_params()];
    let mut at = 0;
    let mut n_in = arch.inputs;
    for &n in &arch.hidden {
        nw_layer(&mut rng, n_in, n, &mut theta, at, at + n * n_in);
        at += n * (n_in + 1);
        n_in = n;
    }
    for w in &mut theta[at..] {
        *w = 2.0 * rng.uniform() - 1.0;
    }
    theta
}

fn tanh(z: f64) -> f64 {
    tanh_of_doubled(2.0 * z)
}

/// Network output for normalised inputs `x` (length `shape.inputs`).
pub fn forward(shape: Shape, theta: &[f64], x: &[f64]) -> f64 {
    forward_impl(shape, theta, x, None)
}

/// Output and its gradient with respect to θ (`grad.len() == n_params`).
pub fn forward_grad(shape: Shape, theta: &[f64], x: &[f64], grad: &mut [f64]) -> f64 {
    forward_impl(shape, theta, x, Some(grad))
}

fn forward_impl(shape: Shape, theta: &[f64], x: &[f64], grad: Option<&mut [f64]>) -> f64 {
    let (ni, nh, nh2) = (shape.inputs, shape.hidden, shape.hidden2);
    let t1: Vec<f64> = (0..nh)
        .map(|h| {
            let z = (0..ni).fold(theta[shape.b1() + h], |z, i| {
                theta[h * ni + i].mul_add(x[i], z)
            });
            tanh(z)
        })
        .collect();
    let t2: Vec<f64> = (0..nh2)
        .map(|g| {
            let z = (0..nh).fold(theta[shape.b2() + g], |z, h| {
                theta[shape.w2() + g * nh + h].mul_add(t1[h], z)
            });
            tanh(z)
        })
        .collect();
    let last = if nh2 > 0 { &t2 } else { &t1 };
    let y = last
        .iter()
        .enumerate()
        .fold(theta[shape.bo()], |y, (g, t)| {
            theta[shape.wo() + g].mul_add(*t, y)
        });
    let Some(grad) = grad else {
        return y;
    };
    grad[shape.bo()] = 1.0;
    let mut delta1 = vec![0.0; nh];
    for (g, t) in last.iter().enumerate() {
        grad[shape.wo() + g] = *t;
    }
    if nh2 > 0 {
        for g in 0..nh2 {
            let d2 = theta[shape.wo() + g] * (-t2[g]).mul_add(t2[g], 1.0);
            grad[shape.b2() + g] = d2;
            for h in 0..nh {
                grad[shape.w2() + g * nh + h] = d2 * t1[h];
                delta1[h] = theta[shape.w2() + g * nh + h].mul_add(d2, delta1[h]);
            }
        }
        for h in 0..nh {
            delta1[h] *= (-t1[h]).mul_add(t1[h], 1.0);
        }
    } else {
        for h in 0..nh {
            delta1[h] = theta[shape.wo() + h] * (-t1[h]).mul_add(t1[h], 1.0);
        }
    }
    for h in 0..nh {
        grad[shape.b1() + h] = delta1[h];
        for i in 0..ni {
            grad[h * ni + i] = delta1[h] * x[i];
        }
    }
    y
}

/// Samples per [`block`].
pub const BLOCK: usize = 256;

/// Scratch space of [`block`] for one shape (the hidden activations of a block).
pub struct Scratch {
    t1: Vec<f64>,
    t2: Vec<f64>,
    d2: Vec<f64>,
}

impl Scratch {
    pub fn new(shape: Shape) -> Scratch {
        Scratch {
            t1: vec![0.0; shape.hidden * BLOCK],
            t2: vec![0.0; shape.hidden2 * BLOCK],
            d2: vec![0.0; shape.hidden2 * BLOCK],
        }
    }

    /// Values per block of [`Scratch::save`]: the hidden activations of both layers.
    pub fn activations(shape: Shape) -> usize {
        (shape.hidden + shape.hidden2) * BLOCK
    }

    /// Copies the hidden activations [`block`]'s forward pass left here into `out`
    /// ([`Scratch::activations`] values).
    pub fn save(&self, out: &mut [f64]) {
        let (a, b) = out.split_at_mut(self.t1.len());
        a.copy_from_slice(&self.t1);
        b.copy_from_slice(&self.t2);
    }

    /// Puts activations saved by [`Scratch::save`] back, for [`Pass::Jacobian`].
    pub fn restore(&mut self, saved: &[f64]) {
        let (a, b) = saved.split_at(self.t1.len());
        self.t1.copy_from_slice(a);
        self.t2.copy_from_slice(b);
    }
}

/// What [`block`] computes.
pub(crate) enum Pass<'a> {
    /// The residuals (the hidden activations left in the scratch).
    Forward,
    /// The residuals and the Jacobian rows `out[p · stride + s]` (see [`block`]).
    Both(&'a mut [f64], usize),
    /// The Jacobian rows alone, from hidden activations already in the scratch — left there
    /// by a forward pass, or put back ([`Scratch::restore`]): the same values give the same
    /// bits. `y` and `r` are not touched.
    Jacobian(&'a mut [f64], usize),
}

/// One block of `n ≤ BLOCK` samples on lanes `V` (`n` a multiple of `V::N`; the caller pads):
/// inputs `x[c][s]` (normalised input c of sample s), targets `y[s]`. Writes the residuals
/// `r[s] = ŷ_s − y_s` and, as `pass` asks, the Jacobian rows
/// `out[p · stride + s] = ∂ŷ_s/∂θ_p` (`stride ≥ n`: [`BLOCK`] for a block of its own, or the
/// row stride of a larger matrix the block is a column range of).
/// Every lane performs the operations of [`forward_grad`] in the same order (fused
/// multiply-adds, the same tanh), so the results are those of one sample at a time.
/// The forward pass leaves the hidden activations in `scratch` ([`Scratch::activations`]);
/// the Jacobian is built from them there.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn block<V: Lanes>(
    isa: V::Isa,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    y: &[f64],
    n: usize,
    r: &mut [f64],
    pass: Pass<'_>,
    scratch: &mut Scratch,
) {
    let (forward, jac) = match pass {
        Pass::Forward => (true, None),
        Pass::Both(out, stride) => (true, Some((out, stride))),
        Pass::Jacobian(out, stride) => (false, Some((out, stride))),
    };
    let (ni, nh, nh2) = (shape.inputs, shape.hidden, shape.hidden2);
    let two = V::splat(isa, 2.0);
    let mut s = 0;
    while forward && s < n {
        // Hidden layer 1.
        for h in 0..nh {
            let mut z = V::splat(isa, theta[shape.b1() + h]);
            for (i, xi) in x.iter().enumerate().take(ni) {
                z = V::splat(isa, theta[h * ni + i]).fma(V::load(isa, &xi[s..]), z);
            }
            tanh_of_doubled(two.mul(z)).store(&mut scratch.t1[h * BLOCK + s..]);
        }
        // Hidden layer 2.
        for g in 0..nh2 {
            let mut z = V::splat(isa, theta[shape.b2() + g]);
            for h in 0..nh {
                let w = V::splat(isa, theta[shape.w2() + g * nh + h]);
                z = w.fma(V::load(isa, &scratch.t1[h * BLOCK + s..]), z);
            }
            tanh_of_doubled(two.mul(z)).store(&mut scratch.t2[g * BLOCK + s..]);
        }
        // Output and residual.
        let (last, n_last) = if nh2 > 0 {
            (&scratch.t2, nh2)
        } else {
            (&scratch.t1, nh)
        };
        let mut out = V::splat(isa, theta[shape.bo()]);
        for g in 0..n_last {
            let w = V::splat(isa, theta[shape.wo() + g]);
            out = w.fma(V::load(isa, &last[g * BLOCK + s..]), out);
        }
        out.sub(V::load(isa, &y[s..])).store(&mut r[s..]);
        s += V::N;
    }
    if let Some((jac, stride)) = jac {
        jacobian_block::<V>(isa, shape, theta, x, n, (jac, stride), scratch);
    }
}

/// The Jacobian rows of [`block`] from the hidden activations in `scratch`.
#[inline(always)]
fn jacobian_block<V: Lanes>(
    isa: V::Isa,
    shape: Shape,
    theta: &[f64],
    x: &[&[f64]],
    n: usize,
    (jac, stride): (&mut [f64], usize),
    scratch: &mut Scratch,
) {
    let (ni, nh, nh2) = (shape.inputs, shape.hidden, shape.hidden2);
    let one = V::splat(isa, 1.0);
    let mut s = 0;
    while s < n {
        let (last, n_last) = if nh2 > 0 {
            (&scratch.t2, nh2)
        } else {
            (&scratch.t1, nh)
        };
        one.store(&mut jac[shape.bo() * stride + s..]);
        for g in 0..n_last {
            V::load(isa, &last[g * BLOCK + s..]).store(&mut jac[(shape.wo() + g) * stride + s..]);
        }
        // δ of the first layer, through the second when there is one.
        if nh2 > 0 {
            for g in 0..nh2 {
                let t = V::load(isa, &scratch.t2[g * BLOCK + s..]);
                let d2 = V::splat(isa, theta[shape.wo() + g]).mul(t.fnma(t, one));
                d2.store(&mut scratch.d2[g * BLOCK + s..]);
                d2.store(&mut jac[(shape.b2() + g) * stride + s..]);
                for h in 0..nh {
                    d2.mul(V::load(isa, &scratch.t1[h * BLOCK + s..]))
                        .store(&mut jac[(shape.w2() + g * nh + h) * stride + s..]);
                }
            }
        }
        for h in 0..nh {
            let t = V::load(isa, &scratch.t1[h * BLOCK + s..]);
            let d1 = if nh2 > 0 {
                let mut acc = V::splat(isa, 0.0);
                for g in 0..nh2 {
                    let w = V::splat(isa, theta[shape.w2() + g * nh + h]);
                    acc = w.fma(V::load(isa, &scratch.d2[g * BLOCK + s..]), acc);
                }
                acc.mul(t.fnma(t, one))
            } else {
                V::splat(isa, theta[shape.wo() + h]).mul(t.fnma(t, one))
            };
            d1.store(&mut jac[(shape.b1() + h) * stride + s..]);
            for (i, xi) in x.iter().enumerate().take(ni) {
                d1.mul(V::load(isa, &xi[s..]))
                    .store(&mut jac[(h * ni + i) * stride + s..]);
            }
        }
        s += V::N;
    }
}

/// Nguyen–Widrow initialisation for inputs scaled to [−1, 1] (as MATLAB's `initnw` for a
/// tansig layer): each first-layer neuron's weight row is a random direction of length
/// β = 0.7 · hidden^(1/inputs), and the biases are spread over [−β, β] (with the sign of
/// the row's first weight) so the neurons' active regions tile the input range. A second
/// hidden layer is initialised the same way on its inputs (the first layer's outputs, in
/// [−1, 1]). The linear output layer gets uniform weights and bias in [−1, 1] (MATLAB's
/// `rands`). Same seed → same θ; a one-layer network gets the same θ as before deeper
/// networks existed.
pub fn nguyen_widrow(shape: Shape, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let mut theta = vec![0.0; shape.n_params()];
    nw_layer(
        &mut rng,
        shape.inputs,
        shape.hidden,
        &mut theta,
        0,
        shape.b1(),
    );
    if shape.hidden2 > 0 {
        nw_layer(
            &mut rng,
            shape.hidden,
            shape.hidden2,
            &mut theta,
            shape.w2(),
            shape.b2(),
        );
    }
    for g in 0..shape.last() {
        theta[shape.wo() + g] = 2.0 * rng.uniform() - 1.0;
    }
    theta[shape.bo()] = 2.0 * rng.uniform() - 1.0;
    theta
}

/// The mean of networks of one hidden layer and one shape, as one network: the hidden layers
/// side by side, the output weights divided by their number and the output bias their mean
/// (ŷ = Σ_m ŷ_m / M exactly, up to rounding). Returns the wide shape and its θ.
pub fn average(shape: Shape, members: &[&[f64]]) -> (Shape, Vec<f64>) {
    assert!(shape.hidden2 == 0 && !members.is_empty());
    let m = members.len();
    let wide = Shape::one(shape.inputs, shape.hidden * m);
    let mut theta = Vec::with_capacity(wide.n_params());
    for t in members {
        theta.extend_from_slice(&t[..shape.b1()]);
    }
    for t in members {
        theta.extend_from_slice(&t[shape.b1()..shape.w2()]);
    }
    for t in members {
        theta.extend(t[shape.wo()..shape.bo()].iter().map(|w| w / m as f64));
    }
    theta.push(members.iter().map(|t| t[shape.bo()]).sum::<f64>() / m as f64);
    debug_assert_eq!(theta.len(), wide.n_params());
    (wide, theta)
}

/// Nguyen–Widrow weights (row-major `n_out × n_in` at `w`) and biases (at `b`) of one layer.
fn nw_layer(rng: &mut Rng, n_in: usize, n_out: usize, theta: &mut [f64], w: usize, b: usize) {
    let beta = 0.7 * (n_out as f64).powf(1.0 / n_in as f64);
    for h in 0..n_out {
        let row: Vec<f64> = loop {
            let r: Vec<f64> = (0..n_in).map(|_| 2.0 * rng.uniform() - 1.0).collect();
            let norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
            if norm > 1e-3 {
                break r.iter().map(|v| v / norm).collect();
            }
        };
        for i in 0..n_in {
            theta[w + h * n_in + i] = beta * row[i];
        }
        let spread = if n_out > 1 {
            -1.0 + 2.0 * h as f64 / (n_out - 1) as f64
        } else {
            0.0
        };
        theta[b + h] = beta * spread * row[0].signum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use proptest::prelude::{prop_assert_eq, proptest, ProptestConfig};

    /// The any-depth helpers are the one- and two-layer functions, bit for bit.
    #[test]
    fn any_depth_helpers_match_the_lm_shapes() {
        let mut rng = Rng::new(3);
        for shape in [
            Shape::one(3, 10),
            Shape {
                inputs: 2,
                hidden: 6,
                hidden2: 4,
            },
        ] {
            let arch = Arch::from(shape);
            assert_eq!(arch.n_params(), shape.n_params());
            assert_eq!(arch.lm_shape(), Some(shape));
            let theta = nguyen_widrow(shape, 7);
            assert_eq!(nguyen_widrow_layers(&arch, 7), theta);
            for _ in 0..50 {
                let x: Vec<f64> = (0..3).map(|_| 2.0 * rng.uniform() - 1.0).collect();
                assert_eq!(
                    forward_layers(&arch, &theta, &x).to_bits(),
                    forward(shape, &theta, &x).to_bits()
                );
            }
        }
        let deep = Arch {
            inputs: 3,
            hidden: vec![5, 4, 3],
        };
        assert_eq!(deep.to_string(), "3-5-4-3-1");
        assert_eq!(deep.n_params(), 5 * 4 + 4 * 6 + 3 * 5 + 4);
        assert_eq!(deep.lm_shape(), None);
    }

    fn check_gradient(shape: Shape, seed: u64, x: &[f64]) {
        let theta = nguyen_widrow(shape, seed);
        let mut g = vec![0.0; shape.n_params()];
        forward_grad(shape, &theta, x, &mut g);
        for p in 0..shape.n_params() {
            let h = 1e-6;
            let mut tp = theta.clone();
            tp[p] += h;
            let mut tm = theta.clone();
            tm[p] -= h;
            let fd = (forward(shape, &tp, x) - forward(shape, &tm, x)) / (2.0 * h);
            assert!(
                (fd - g[p]).abs() < 1e-7 * (1.0 + g[p].abs()),
                "{shape:?} param {p}: {fd} vs {}",
                g[p]
            );
        }
    }

    #[test]
    fn analytic_gradient_matches_central_differences() {
        for shape in [
            Shape::one(3, 10),
            Shape {
                inputs: 3,
                hidden: 6,
                hidden2: 5,
            },
        ] {
            for x in [[0.3, -0.7, 0.1], [-1.0, 1.0, 0.0], [0.9, 0.9, -0.9]] {
                check_gradient(shape, 42, &x);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn block_equals_one_sample_at_a_time(
            inputs in 1usize..=4, hidden in 1usize..=12, hidden2 in 0usize..=6,
            seed in 0u64..1000, n_vec in 1usize..=8,
        ) {
            let shape = Shape { inputs, hidden, hidden2 };
            let theta = nguyen_widrow(shape, seed);
            let n = 4 * n_vec;
            let mut rng = Rng::new(seed ^ 7);
            let x: Vec<Vec<f64>> = (0..inputs).map(|_| (0..BLOCK).map(|_| 2.0 * rng.uniform() - 1.0).collect()).collect();
            let y: Vec<f64> = (0..BLOCK).map(|_| rng.uniform()).collect();
            let xs: Vec<&[f64]> = x.iter().map(|c| c.as_slice()).collect();
            let p = shape.n_params();
            let (mut r, mut jac) = (vec![0.0; BLOCK], vec![0.0; p * BLOCK]);
            let mut scratch = Scratch::new(shape);
            block::<f64>(crate::simd::Portable, shape, &theta, &xs, &y, n, &mut r, Pass::Both(&mut jac, BLOCK), &mut scratch);
            let mut g = vec![0.0; p];
            for s in 0..n {
                let xi: Vec<f64> = (0..inputs).map(|c| x[c][s]).collect();
                let out = forward_grad(shape, &theta, &xi, &mut g);
                prop_assert_eq!(r[s].to_bits(), (out - y[s]).to_bits());
                for q in 0..p {
                    prop_assert_eq!(jac[q * BLOCK + s].to_bits(), g[q].to_bits(), "param {}", q);
                }
            }
        }
    }

    #[test]
    fn every_compiled_path_gives_the_portable_bits() {
        use crate::simd::Isa;
        let shape = Shape {
            inputs: 3,
            hidden: 7,
            hidden2: 4,
        };
        let theta = nguyen_widrow(shape, 3);
        let mut rng = Rng::new(5);
        let x: Vec<Vec<f64>> = (0..3)
            .map(|_| (0..BLOCK).map(|_| 4.0 * rng.uniform() - 2.0).collect())
            .collect();
        let y: Vec<f64> = (0..BLOCK).map(|_| rng.uniform()).collect();
        let xs: Vec<&[f64]> = x.iter().map(|c| c.as_slice()).collect();
        let p = shape.n_params();
        let run = |isa: Isa| {
            let (mut r, mut jac) = (vec![0.0; BLOCK], vec![0.0; p * BLOCK]);
            let mut sc = Scratch::new(shape);
            super::super::problem::block_dispatch(
                isa,
                shape,
                &theta,
                &xs,
                &y,
                BLOCK,
                &mut r,
                Pass::Both(&mut jac, BLOCK),
                &mut sc,
            );
            (r, jac)
        };
        let portable = run(Isa::Portable);
        for isa in Isa::all_available() {
            assert_eq!(run(isa), portable, "{isa:?}");
        }
    }

    #[test]
    fn initialisation_is_seeded_and_tiles_the_input_range() {
        let shape = Shape::one(2, 10);
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
