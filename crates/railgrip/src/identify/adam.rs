//! Networks of any depth and width trained by mini-batch Adam or AdamW through burn:
//! the alternative to Levenberg–Marquardt ([`super::lm`]) for networks whose Jacobian is too
//! big for the normal equations (LM's memory and time grow with parameters², Adam's with
//! parameters).
//!
//! The network is seed 002's (002_8d8769283f5e9cb6.txt, "Neural network") with any number of
//! tanh hidden layers: t_l = tanh(W_l t_(l−1) + b_l), t_0 the mapminmax-normalised inputs,
//! ŷ = w_o · t_L + b_o, trained on the normalised μ with the mean squared error
//! E = (1/m) Σ (ŷ − y)² of each mini-batch of m samples. Adam (Kingma & Ba 2015, Algorithm 1:
//! m ← β1 m + (1 − β1) g, v ← β2 v + (1 − β2) g², θ ← θ − α m̂/(√v̂ + ε)) or AdamW (Loshchilov &
//! Hutter 2019: the same step plus the decoupled decay θ ← θ(1 − α λ)), as burn 0.22's
//! `AdamConfig`/`AdamWConfig` implement them, on burn's pure-Rust `flex` CPU backend in f64.
//!
//! Determinism: the start is [`mlp::nguyen_widrow_layers`] of the seed (not burn's initialiser,
//! whose random source is global), the samples are shuffled each epoch by railgrip's own
//! generator ([`crate::rng::Rng`]) from the same seed, and the flex backend's kernels are
//! deterministic — same data and seed, same weights, bit for bit (tested).
//!
//! Early stopping: after every epoch the validation MSE is computed (with railgrip's own
//! [`mlp::forward_layers`], the function the model file evaluates); the weights of the best
//! epoch are kept, and training stops when `patience` epochs pass without a better one
//! (MATLAB's `max_fail`), or after `max_epochs`.
//!
//! θ is in [`mlp::Arch`]'s order (per layer W row-major out × in, then b); burn's `Linear`
//! stores W transposed (`[d_in, d_out]`), converted here both ways.

use std::time::Instant;

use burn::module::{Module, Param};
use burn::nn::Linear;
use burn::optim::{AdamConfig, AdamWConfig, GradientsParams, ModuleOptimizer};
use burn::prelude::{Device, Tensor};
use burn::tensor::activation::tanh;
use burn::tensor::{FloatDType, TensorData};

use super::lm::StopReason;
use super::mlp::{self, Arch};
use super::IdentifyError;
use crate::model::Epoch;
use crate::rng::Rng;

pub use crate::config::train::Optimizer;

/// Settings of an Adam/AdamW training.
#[derive(Debug, Clone, PartialEq)]
pub struct AdamSettings {
    pub optimizer: Optimizer,
    /// Step size α (normalised units).
    pub learning_rate: f64,
    /// λ: AdamW's decoupled decay per step, Adam's L2 penalty (0: none).
    pub weight_decay: f64,
    /// Samples per mini-batch.
    pub batch: usize,
    pub max_epochs: usize,
    /// Epochs without a better validation MSE before stopping.
    pub patience: usize,
}

impl Default for AdamSettings {
    fn default() -> Self {
        AdamSettings {
            optimizer: Optimizer::Adam,
            learning_rate: 1e-3,
            weight_decay: 0.0,
            batch: 256,
            max_epochs: 200,
            patience: 20,
        }
    }
}

impl AdamSettings {
    /// Settings a user can get wrong, checked before any work.
    pub fn check(&self) -> Result<(), IdentifyError> {
        let bad = |what: String| {
            Err(IdentifyError::Data {
                what,
                hint: "see docs/training.md#training-deeper-networks".into(),
            })
        };
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0 && self.learning_rate < 1.0)
        {
            return bad(format!(
                "learning_rate = {} is outside (0, 1)",
                self.learning_rate
            ));
        }
        if !(self.weight_decay.is_finite() && (0.0..1.0).contains(&self.weight_decay)) {
            return bad(format!(
                "weight_decay = {} is outside [0, 1)",
                self.weight_decay
            ));
        }
        if self.batch == 0 || self.max_epochs == 0 || self.patience == 0 {
            return bad("batch, max_epochs and patience must be at least 1".into());
        }
        Ok(())
    }
}

/// The data of a training, normalised: `x` row-major (n × inputs), `y` one value per row.
pub struct AdamData<'a> {
    pub x: &'a [f64],
    pub y: &'a [f64],
    pub vx: &'a [f64],
    pub vy: &'a [f64],
    /// Factor from normalised MSE to the reported unit (μ²), as the LM problem's.
    pub scale: f64,
}

/// The result of [`train`].
#[derive(Debug, Clone)]
pub struct AdamFit {
    /// The kept weights (best validation epoch; the last without validation data).
    pub theta: Vec<f64>,
    /// Per epoch: training and validation MSE (μ²), `mu` = the learning rate, `grad_norm` =
    /// the root mean square over the epoch's mini-batches of ‖∇E‖.
    pub history: Vec<Epoch>,
    pub stop: StopReason,
    /// The epoch the kept weights come from (1-based; 0: the start).
    pub best_epoch: usize,
}

/// The network as a burn module: the hidden layers (tanh) and the linear output layer.
#[derive(Module, Debug)]
struct BurnNet {
    layers: Vec<Linear>,
}

impl BurnNet {
    fn forward(&self, mut x: Tensor<2>) -> Tensor<2> {
        let n = self.layers.len();
        for (l, layer) in self.layers.iter().enumerate() {
            x = layer.forward(x);
            if l + 1 < n {
                x = tanh(x);
            }
        }
        x
    }

    /// The module holding θ (W transposed into burn's `[d_in, d_out]`).
    fn from_theta(arch: &Arch, theta: &[f64], device: &Device) -> BurnNet {
        let mut at = 0;
        let layers = arch
            .sizes()
            .windows(2)
            .map(|p| {
                let (n_in, n) = (p[0], p[1]);
                let mut wt = vec![0.0; n * n_in];
                for g in 0..n {
                    for i in 0..n_in {
                        wt[i * n + g] = theta[at + g * n_in + i];
                    }
                }
                let b = theta[at + n * n_in..at + n * (n_in + 1)].to_vec();
                at += n * (n_in + 1);
                Linear {
                    weight: Param::from_tensor(Tensor::<2>::from_data(
                        TensorData::new(wt, [n_in, n]),
                        device,
                    )),
                    bias: Some(Param::from_tensor(Tensor::<1>::from_data(
                        TensorData::new(b, [n]),
                        device,
                    ))),
                }
            })
            .collect();
        BurnNet { layers }
    }

    /// θ in [`Arch`]'s order.
    fn theta(&self, arch: &Arch) -> Vec<f64> {
        let mut theta = Vec::with_capacity(arch.n_params());
        for (layer, p) in self.layers.iter().zip(arch.sizes().windows(2)) {
            let (n_in, n) = (p[0], p[1]);
            let w = f64s(layer.weight.val().into_data());
            for g in 0..n {
                theta.extend((0..n_in).map(|i| w[i * n + g]));
            }
            let b = layer.bias.as_ref().expect("built with biases");
            theta.extend(f64s(b.val().into_data()));
        }
        theta
    }
}

fn f64s(d: TensorData) -> Vec<f64> {
    d.as_slice::<f64>()
        .expect("the device computes in f64 (configured in `device`)")
        .to_vec()
}

/// burn's flex CPU device with autodiff, computing in f64. The device's dtype can be set once
/// per process; later calls find it set.
fn device() -> Result<Device, IdentifyError> {
    let mut dev = Device::flex().autodiff();
    if dev.configure(FloatDType::F64).is_err() {
        // Already configured (an earlier training in this process): check it is f64.
        let probe = Tensor::<1>::from_data(TensorData::new(vec![0.0f64], [1]), &dev);
        if probe.into_data().as_slice::<f64>().is_err() {
            return Err(IdentifyError::Data {
                what: "burn's CPU device computes in another float type than f64".into(),
                hint: "train deeper networks in a process that configured burn for f64".into(),
            });
        }
    }
    Ok(dev)
}

fn mse(arch: &Arch, theta: &[f64], x: &[f64], y: &[f64]) -> f64 {
    let k = arch.inputs;
    let sse: f64 = x
        .chunks_exact(k)
        .zip(y)
        .map(|(xi, yi)| {
            let e = mlp::forward_layers(arch, theta, xi) - yi;
            e * e
        })
        .sum();
    sse / y.len().max(1) as f64
}

/// Trains `arch` from `theta0` on `data` (see the module documentation). `seed` drives the
/// mini-batch order; `progress` sees every epoch.
pub fn train(
    arch: &Arch,
    data: &AdamData,
    theta0: Vec<f64>,
    settings: &AdamSettings,
    seed: u64,
    progress: Option<super::lm::EpochProgress<'_>>,
) -> Result<AdamFit, IdentifyError> {
    settings.check()?;
    let n = check_data(arch, data, &theta0)?;
    let dev = device()?;
    let mut net = BurnNet::from_theta(arch, &theta0, &dev);
    let lr = settings.learning_rate;
    let mut optim = optimizer(settings);
    let has_val = !data.vy.is_empty();
    let mut rng = Rng::new(seed ^ 0x5eed_ada3);
    let mut order: Vec<usize> = (0..n).collect();
    let mut batches = MiniBatches::new(data, arch.inputs, settings.batch, &dev);
    let start = Instant::now();
    let mut history = Vec::new();
    let mut best = (f64::INFINITY, theta0.clone(), 0usize);
    let mut stop = StopReason::Epochs;
    for epoch in 1..=settings.max_epochs {
        shuffle(&mut order, &mut rng);
        let grad_norm;
        (net, grad_norm) = batches.epoch(net, &mut optim, lr, &order);
        let theta = net.theta(arch);
        let (train_mse, val_mse) = epoch_errors(arch, &theta, data, settings, epoch)?;
        let e = Epoch {
            epoch: epoch as u64,
            train_mse,
            val_mse,
            mu: lr,
            grad_norm,
            elapsed_s: start.elapsed().as_secs_f64(),
            gamma: None,
        };
        if let Some(p) = progress {
            p.event(&e);
        }
        history.push(e);
        let score = if has_val { val_mse } else { train_mse };
        if score < best.0 || !has_val {
            best = (score, theta, epoch);
        } else if epoch - best.2 >= settings.patience {
            stop = StopReason::ValidationStop;
            break;
        }
    }
    Ok(AdamFit {
        theta: best.1,
        history,
        stop,
        best_epoch: best.2,
    })
}

/// The data's shapes fit `arch` and `theta0` (asserted: the caller builds them), and there is
/// at least one training sample; returns their number.
fn check_data(arch: &Arch, data: &AdamData, theta0: &[f64]) -> Result<usize, IdentifyError> {
    let k = arch.inputs;
    let n = data.y.len();
    assert_eq!(data.x.len(), n * k, "x holds n × inputs values");
    assert_eq!(data.vx.len(), data.vy.len() * k, "vx holds n_val × inputs");
    assert_eq!(theta0.len(), arch.n_params(), "θ of the architecture");
    if n == 0 {
        return Err(IdentifyError::Data {
            what: "no training samples".into(),
            hint: "train on runs with valid estimates".into(),
        });
    }
    Ok(n)
}

/// burn's optimiser for `settings`: Adam, with λ as burn's L2 weight decay when λ > 0, or
/// AdamW with λ decoupled.
fn optimizer(settings: &AdamSettings) -> ModuleOptimizer {
    let decay = settings.weight_decay as f32;
    match settings.optimizer {
        Optimizer::Adam => {
            let c = AdamConfig::new();
            if decay > 0.0 {
                c.with_weight_decay(Some(burn::optim::decay::WeightDecayConfig::new(decay)))
                    .init()
            } else {
                c.init()
            }
        }
        Optimizer::AdamW => AdamWConfig::new().with_weight_decay(decay).init(),
    }
}

/// Fisher–Yates with railgrip's generator: the same order for the same seed.
fn shuffle(order: &mut [usize], rng: &mut Rng) {
    let n = order.len();
    for i in (1..n).rev() {
        let j = ((i + 1) as f64 * rng.uniform()) as usize;
        order.swap(i, j.min(i));
    }
}

/// The training and validation MSE (reported unit; NaN without validation data) of θ after
/// `epoch`; an error when the training MSE is not finite (training diverged).
fn epoch_errors(
    arch: &Arch,
    theta: &[f64],
    data: &AdamData,
    settings: &AdamSettings,
    epoch: usize,
) -> Result<(f64, f64), IdentifyError> {
    let train_mse = mse(arch, theta, data.x, data.y) * data.scale;
    let val_mse = if !data.vy.is_empty() {
        mse(arch, theta, data.vx, data.vy) * data.scale
    } else {
        f64::NAN
    };
    if !train_mse.is_finite() {
        return Err(IdentifyError::Data {
            what: format!(
                "{} diverged at epoch {epoch} (training MSE {train_mse})",
                settings.optimizer.name()
            ),
            hint: "lower learning_rate".into(),
        });
    }
    Ok((train_mse, val_mse))
}

/// The mini-batches of an epoch: the training data, cut in the epoch's sample order into
/// batches of `size` samples (the last one shorter), copied through reused buffers.
struct MiniBatches<'d, 'a> {
    data: &'d AdamData<'a>,
    /// Inputs per sample.
    k: usize,
    size: usize,
    dev: &'d Device,
    bx: Vec<f64>,
    by: Vec<f64>,
}

impl<'d, 'a> MiniBatches<'d, 'a> {
    fn new(data: &'d AdamData<'a>, k: usize, size: usize, dev: &'d Device) -> Self {
        MiniBatches {
            data,
            k,
            size,
            dev,
            bx: Vec::with_capacity(size * k),
            by: Vec::with_capacity(size),
        }
    }

    /// One epoch: a step of `optim` with step size `lr` on the MSE of each mini-batch, in
    /// `order`. Returns the network and the root mean square over the mini-batches of ‖∇E‖.
    fn epoch(
        &mut self,
        mut net: BurnNet,
        optim: &mut ModuleOptimizer,
        lr: f64,
        order: &[usize],
    ) -> (BurnNet, f64) {
        let (data, k) = (self.data, self.k);
        let mut grad_sq = 0.0;
        let mut batches = 0usize;
        for chunk in order.chunks(self.size) {
            self.bx.clear();
            self.by.clear();
            for &i in chunk {
                self.bx.extend_from_slice(&data.x[i * k..(i + 1) * k]);
                self.by.push(data.y[i]);
            }
            let m = chunk.len();
            let x = Tensor::<2>::from_data(TensorData::new(self.bx.clone(), [m, k]), self.dev);
            let y = Tensor::<2>::from_data(TensorData::new(self.by.clone(), [m, 1]), self.dev);
            let e = net.forward(x) - y;
            let loss = (e.clone() * e).mean();
            let grads = loss.backward();
            let grads = GradientsParams::from_grads(grads, &net);
            grad_sq += gradient_sq(&net, &grads);
            batches += 1;
            net = optim.step(lr, net, grads);
        }
        (net, (grad_sq / batches as f64).sqrt())
    }
}

/// ‖∇E‖² of one mini-batch: the squares of every layer's weight and bias gradients, summed
/// layer by layer.
fn gradient_sq(net: &BurnNet, grads: &GradientsParams) -> f64 {
    let mut sq = 0.0;
    for layer in &net.layers {
        if let Some(g) = grads.get::<2>(layer.weight.id) {
            sq += g.clone().mul(g).sum().into_scalar::<f64>();
        }
        if let Some(g) = grads.get::<1>(layer.bias.as_ref().expect("biases").id) {
            sq += g.clone().mul(g).sum().into_scalar::<f64>();
        }
    }
    sq
}

/// ∂ŷ/∂θ at one normalised input `x` by burn's reverse-mode autodiff (θ in [`Arch`]'s order):
/// the independent check of the analytic Jacobian the LM trainer builds
/// ([`mlp::forward_grad`]).
pub fn gradient_by_autodiff(
    arch: &Arch,
    theta: &[f64],
    x: &[f64],
) -> Result<Vec<f64>, IdentifyError> {
    let dev = device()?;
    let net = BurnNet::from_theta(arch, theta, &dev);
    let xt = Tensor::<2>::from_data(TensorData::new(x.to_vec(), [1, arch.inputs]), &dev);
    let grads = net.forward(xt).sum().backward();
    let mut out = Vec::with_capacity(arch.n_params());
    for (layer, p) in net.layers.iter().zip(arch.sizes().windows(2)) {
        let (n_in, n) = (p[0], p[1]);
        let gw = f64s(
            layer
                .weight
                .val()
                .grad(&grads)
                .expect("a weight takes part in the output")
                .into_data(),
        );
        for g in 0..n {
            out.extend((0..n_in).map(|i| gw[i * n + g]));
        }
        let b = layer.bias.as_ref().expect("biases");
        out.extend(f64s(
            b.val()
                .grad(&grads)
                .expect("a bias takes part in the output")
                .into_data(),
        ));
    }
    Ok(out)
}
