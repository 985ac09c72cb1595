//! Adhesion model files (ONNX-free JSON, schema `models/schema/adhesion-model.schema.json`)
//! and their evaluators.
//!
//! A model file holds everything a simulator needs to evaluate μ(Δv, dΔv/dt[, v]) without
//! railgrip: the inputs with units, mapminmax normalisation and the validity domain seen in
//! training, the network's weights and biases with shapes and activations, the output
//! de-normalisation, the linear creep region used at small slip, provenance and metrics.
//!
//! Evaluation ([`Model::mu`]), exactly as the C header does it ([`c_header`]):
//! 1. Mirror: for Δv < 0 evaluate at (−Δv, −dΔv/dt) and negate (the force follows the slip).
//! 2. Network N(Δv, dΔv/dt, v): each input clamped to its domain [min, max], scaled by
//!    mapminmax (x_n = g x + o), ŷ = b2 + Σ_h w2_h tanh(b1_h + Σ_i W1_hi x_n,i), μ = (ŷ − o_y)/g_y,
//!    with tanh computed by [`tanh_fast`] (a few ulp from the C library's); the products
//!    g x + o and W1_hi x_n,i + … are fused multiply-adds, the output sum runs over the neurons
//!    in order.
//! 3. Creep region (seed 002 002_8d8769283f5e9cb6.txt: "in the pseudo-slip region the network
//!    is replaced by the linear law", eq. 6–8): below the blend slip Δv_b the model blends, with
//!    the weight w = t²(3 − 2t), t = Δv/Δv_b, from the Kalker linear law saturated by
//!    Shen–Hedrick–Elkins, μ_lin = μ_s·S(k Δv/μ_s) with S(x) = x − x²/3 + x³/27 for x < 3 and 1
//!    above, μ_s = |N(Δv_b, dΔv/dt, v)|, k = C / (Q v) (C = G a b c11 the creep stiffness, N; Q
//!    the wheel load, N; v the speed input or, for two-input models, the median training speed),
//!    to the network at Δv_b: μ = w N(Δv, …) + (1 − w) μ_lin. Continuous in every input.

pub mod c_header;
pub mod polach;
use crate::simd;

use simd::Lanes;

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::identify::lm::Epoch;
use crate::identify::{InputSet, TrainedMlp};

/// `Net::block` on lanes `$lanes`, compiled for a target feature (called only after
/// detecting it).
macro_rules! block_with_feature {
    ($name:ident, $feature:literal, $lanes:ty) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $feature)]
        unsafe fn $name(
            &self,
            dv: &[f64; LANES],
            ddv: &[f64; LANES],
            v: &[f64; LANES],
            out: &mut [f64; LANES],
        ) {
            // SAFETY: this function is compiled for the lanes' target feature.
            unsafe { self.block::<$lanes>(dv, ddv, v, out) }
        }
    };
}

/// The instruction set the network evaluators run with, detected once when a model is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Simd {
    /// AVX-512F and VL (with AVX2 and FMA): batch on `__m512d`, single call on `__m256d` with 32
    /// registers.
    #[allow(dead_code)] // only constructed on x86_64
    Avx512,
    /// AVX2 and FMA: `__m256d` for both.
    #[allow(dead_code)]
    Avx2,
    /// Plain f64.
    Baseline,
}

impl Simd {
    fn detect() -> Simd {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx2") && has!("fma") {
                if has!("avx512f") && has!("avx512vl") {
                    return Simd::Avx512;
                }
                return Simd::Avx2;
            }
        }
        Simd::Baseline
    }
}

/// Samples per block of [`Model::mu_batch`].
pub const LANES: usize = 16;

/// Largest hidden layer the evaluators take.
pub const MAX_HIDDEN: usize = 256;

/// Neurons per chunk of the single-call path (one AVX2 register of f64).
const CHUNK: usize = 4;

/// Format id written into every model file.
pub const FORMAT_ID: &str = "railgrip-adhesion-model";
/// Current format version.
pub const FORMAT_VERSION: u32 = 1;

/// Why a model file could not be read or used.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("{file}: {message}. Hint: {hint}")]
    Invalid {
        file: String,
        message: String,
        hint: String,
    },
    #[error("{file}: cannot write: {message}")]
    Write { file: String, message: String },
}

/// Model kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelKind {
    Mlp,
    Polach,
}

/// One input of the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// Estimates-table column name: `dv_mps`, `ddv_mps2`, `v_mps`.
    pub name: String,
    pub unit: String,
    /// mapminmax: the training range mapped to [−1, 1].
    pub norm_min: f64,
    pub norm_max: f64,
    /// Validity domain: the range seen in training and validation data. Inputs outside are
    /// clamped to it.
    pub domain_min: f64,
    pub domain_max: f64,
}

/// The output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    pub name: String,
    pub unit: String,
    pub norm_min: f64,
    pub norm_max: f64,
}

/// One dense layer: `weights[row][col]` maps `col` inputs to `row` outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Layer {
    /// [rows, cols].
    pub shape: [usize; 2],
    pub weights: Vec<Vec<f64>>,
    pub biases: Vec<f64>,
    /// `tanh` or `linear`.
    pub activation: String,
}

/// The linear creep region at small slip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CreepSpec {
    /// Δv_b: below it the model blends from the linear law into the network, m/s.
    pub blend_mps: f64,
    /// C = G a b c11, Kalker's longitudinal creep stiffness of one wheel's patch, N.
    pub creep_stiffness_n: f64,
    /// Q, the static wheel load the patch was computed for, N.
    pub wheel_load_n: f64,
    /// Speed used for the creepage when the model has no speed input, m/s.
    pub reference_speed_mps: f64,
}

/// Where the model came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Provenance {
    /// Input files with their SHA-256.
    pub inputs: Vec<InputFile>,
    /// Pipeline file name and the SHA-256 of its text.
    pub pipeline: String,
    pub pipeline_sha256: String,
    pub seed: u64,
    pub crate_version: String,
    /// UTC, RFC 3339.
    pub created: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputFile {
    pub path: String,
    pub sha256: String,
}

/// Quality figures.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metrics {
    pub train_samples: usize,
    pub val_samples: usize,
    /// Mean squared errors of μ.
    pub train_mse: f64,
    pub val_mse: Option<f64>,
    pub epochs: usize,
    pub stop_reason: String,
}

/// A model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    pub format: String,
    pub version: u32,
    pub kind: ModelKind,
    pub inputs: Vec<InputSpec>,
    pub output: OutputSpec,
    /// What the evaluator does with inputs outside the domain: `clamp` (mlp) or `law`
    /// (polach: Δv and v by the physical law, temperature clamped; see [`polach`]).
    pub outside_domain: String,
    /// kind mlp: the hidden (tanh) and output (linear) layers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layers: Vec<Layer>,
    /// kind mlp: the linear creep region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creep: Option<CreepSpec>,
    /// kind polach: parameters, contact patch and temperature law.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polach: Option<polach::PolachSpec>,
    pub provenance: Provenance,
    pub metrics: Metrics,
    /// Training history per epoch (kind mlp; empty for polach).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub history: Vec<Epoch>,
}

impl ModelFile {
    /// Builds the file of a trained network.
    pub fn from_trained(t: &TrainedMlp, creep: CreepSpec, provenance: Provenance) -> ModelFile {
        let k = t.shape.inputs;
        let nh = t.shape.hidden;
        let inputs = t
            .inputs
            .names()
            .iter()
            .enumerate()
            .map(|(c, (name, unit))| InputSpec {
                name: name.to_string(),
                unit: unit.to_string(),
                norm_min: t.x_norm.min[c],
                norm_max: t.x_norm.max[c],
                domain_min: t.domain[c].0,
                domain_max: t.domain[c].1,
            })
            .collect();
        let th = &t.theta;
        let hidden = Layer {
            shape: [nh, k],
            weights: (0..nh).map(|h| th[h * k..(h + 1) * k].to_vec()).collect(),
            biases: th[nh * k..nh * k + nh].to_vec(),
            activation: "tanh".into(),
        };
        let out = Layer {
            shape: [1, nh],
            weights: vec![th[nh * k + nh..nh * k + 2 * nh].to_vec()],
            biases: vec![th[nh * k + 2 * nh]],
            activation: "linear".into(),
        };
        ModelFile {
            format: FORMAT_ID.into(),
            version: FORMAT_VERSION,
            kind: ModelKind::Mlp,
            inputs,
            output: OutputSpec {
                name: "mu".into(),
                unit: "1".into(),
                norm_min: t.y_norm.min[0],
                norm_max: t.y_norm.max[0],
            },
            outside_domain: "clamp".into(),
            layers: vec![hidden, out],
            creep: Some(creep),
            polach: None,
            provenance,
            metrics: Metrics {
                train_samples: t.n_train,
                val_samples: t.n_val,
                train_mse: t.train_mse,
                val_mse: t.val_mse.is_finite().then_some(t.val_mse),
                epochs: t.history.len(),
                stop_reason: t.stop.text().into(),
            },
            history: t.history.clone(),
        }
    }

    /// JSON text (f64 in shortest round-trip form: reading it back gives the same bits).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("model files serialise") + "\n"
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), ModelError> {
        let text = self.to_json();
        crate::atomic::write_atomically(path, |w| std::io::Write::write_all(w, text.as_bytes()))
            .map_err(|e: std::io::Error| ModelError::Write {
                file: path.display().to_string(),
                message: e.to_string(),
            })
    }

    /// Parses and checks a model file's text; `file` names it in errors.
    pub fn from_json(text: &str, file: &str) -> Result<ModelFile, ModelError> {
        let bad = |message: String| {
            ModelError::Invalid {
            file: file.to_string(),
            message,
            hint: "give a model file written by `railgrip train` (format railgrip-adhesion-model, see models/schema/)".into(),
        }
        };
        let m: ModelFile =
            serde_json::from_str(text).map_err(|e| bad(format!("not a model file: {e}")))?;
        if m.format != FORMAT_ID {
            return Err(bad(format!(
                "format \"{}\" is not \"{FORMAT_ID}\"",
                m.format
            )));
        }
        if m.version != FORMAT_VERSION {
            return Err(bad(format!(
                "format version {} is not supported (this railgrip reads version {FORMAT_VERSION})",
                m.version
            )));
        }
        m.check().map_err(bad)?;
        Ok(m)
    }

    /// Reads a model file.
    pub fn read(path: &Path) -> Result<ModelFile, ModelError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ModelError::Invalid {
            file: file.clone(),
            message: e.to_string(),
            hint: "check the path".into(),
        })?;
        Self::from_json(&text, &file)
    }

    /// Shapes, names and numbers are consistent and finite.
    fn check(&self) -> Result<(), String> {
        match self.kind {
            ModelKind::Mlp => self.check_mlp(),
            ModelKind::Polach => polach::check(self),
        }
    }

    fn check_mlp(&self) -> Result<(), String> {
        if self.polach.is_some() {
            return Err("kind mlp has no \"polach\" section".into());
        }
        let Some(c) = &self.creep else {
            return Err("kind mlp needs a \"creep\" section".into());
        };
        let k = self.inputs.len();
        let names: Vec<&str> = self.inputs.iter().map(|i| i.name.as_str()).collect();
        if names != ["dv_mps", "ddv_mps2"] && names != ["dv_mps", "ddv_mps2", "v_mps"] {
            return Err(format!(
                "inputs {names:?} are not [dv_mps, ddv_mps2] or [dv_mps, ddv_mps2, v_mps]"
            ));
        }
        if self.outside_domain != "clamp" {
            return Err(format!(
                "outside_domain \"{}\" is not \"clamp\"",
                self.outside_domain
            ));
        }
        let [h, o] = match self.layers.as_slice() {
            [h, o] => [h, o],
            _ => return Err(format!("{} layers; an MLP model has 2", self.layers.len())),
        };
        let nh = h.shape[0];
        if h.activation != "tanh" || o.activation != "linear" {
            return Err("activations must be tanh (hidden) and linear (output)".into());
        }
        if h.shape != [nh, k]
            || h.weights.len() != nh
            || h.weights.iter().any(|r| r.len() != k)
            || h.biases.len() != nh
            || o.shape != [1, nh]
            || o.weights.len() != 1
            || o.weights[0].len() != nh
            || o.biases.len() != 1
            || nh == 0
            || nh > MAX_HIDDEN
        {
            return Err("layer shapes do not match the inputs and each other".into());
        }
        let mut nums: Vec<f64> = h
            .weights
            .iter()
            .flatten()
            .chain(&h.biases)
            .copied()
            .collect();
        nums.extend(o.weights[0].iter().chain(&o.biases));
        for i in &self.inputs {
            nums.extend([i.norm_min, i.norm_max, i.domain_min, i.domain_max]);
            if i.domain_min > i.domain_max || i.norm_min > i.norm_max {
                return Err(format!("input {}: min above max", i.name));
            }
        }
        nums.extend([self.output.norm_min, self.output.norm_max]);
        nums.extend([
            c.blend_mps,
            c.creep_stiffness_n,
            c.wheel_load_n,
            c.reference_speed_mps,
        ]);
        if nums.iter().any(|v| !v.is_finite()) {
            return Err("a number is not finite".into());
        }
        if !(c.blend_mps > 0.0
            && c.creep_stiffness_n > 0.0
            && c.wheel_load_n > 0.0
            && c.reference_speed_mps > 0.0)
        {
            return Err("creep: blend_mps, creep_stiffness_n, wheel_load_n and reference_speed_mps must be > 0".into());
        }
        Ok(())
    }

    pub fn input_set(&self) -> InputSet {
        if self.inputs.len() == 3 {
            InputSet::DvDdvV
        } else {
            InputSet::DvDdv
        }
    }
}

/// The numbers the evaluators work with, derived once from a model file (shared by the Rust
/// evaluator and the C header so both start from the same doubles).
pub(crate) struct Scaling {
    /// Input domain per input (unused inputs 0).
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    /// mapminmax gain and offset per input, x_n = g x + o.
    pub gx: [f64; 3],
    pub ox: [f64; 3],
    /// Output mapminmax gain and offset.
    pub gy: f64,
    pub oy: f64,
    /// Hidden-layer weights, column-major: w1c[c · hidden + h] = W1[h][c].
    pub w1c: Vec<f64>,
}

impl ModelFile {
    pub(crate) fn scaling(&self) -> Scaling {
        let k = self.inputs.len();
        let mut s = Scaling {
            lo: [0.0; 3],
            hi: [0.0; 3],
            gx: [1.0; 3],
            ox: [0.0; 3],
            gy: 1.0,
            oy: 0.0,
            w1c: (0..k)
                .flat_map(|c| self.layers[0].weights.iter().map(move |row| row[c]))
                .collect(),
        };
        for (c, i) in self.inputs.iter().enumerate() {
            s.lo[c] = i.domain_min;
            s.hi[c] = i.domain_max;
            (s.gx[c], s.ox[c]) = gain_offset(i.norm_min, i.norm_max);
        }
        (s.gy, s.oy) = gain_offset(self.output.norm_min, self.output.norm_max);
        s
    }
}

/// mapminmax gain and offset for a (min, max) range: constant ranges pass through.
#[inline]
fn gain_offset(min: f64, max: f64) -> (f64, f64) {
    let range = max - min;
    if range > 0.0 {
        let g = 2.0 / range;
        (g, -1.0 - g * min)
    } else {
        (1.0, 0.0)
    }
}

/// A loaded model, ready to evaluate without allocating.
#[derive(Debug, Clone)]
pub struct Model {
    pub file: ModelFile,
    law: Law,
}

/// The evaluator of each kind.
#[derive(Debug, Clone)]
enum Law {
    Mlp(Net),
    Polach(polach::PolachEval),
}

impl Model {
    /// Checks `file` and prepares its evaluator.
    pub fn new(file: ModelFile) -> Result<Model, ModelError> {
        file.check().map_err(|message| ModelError::Invalid {
            file: "model".into(),
            message,
            hint: "build model files with ModelFile::from_trained or ModelFile::from_polach".into(),
        })?;
        Ok(Model::checked(file))
    }

    /// Reads and checks a model file.
    pub fn load(path: &Path) -> Result<Model, ModelError> {
        Ok(Model::checked(ModelFile::read(path)?))
    }

    fn checked(file: ModelFile) -> Model {
        let law = match file.kind {
            ModelKind::Mlp => Law::Mlp(Net::new(&file)),
            ModelKind::Polach => Law::Polach(polach::PolachEval::new(&file)),
        };
        Model { file, law }
    }

    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.file.inputs.len()
    }

    /// μ at slip `dv_mps` (m/s), slip rate `ddv_mps2` (m/s²) and speed `v_mps` (m/s; used as
    /// the third input of 3-input networks, for the creep slope and for Polach's creepage;
    /// NaN → the reference speed). Non-finite Δv or dΔv/dt give NaN (Polach models ignore
    /// dΔv/dt).
    #[inline]
    pub fn mu_v(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> f64 {
        match &self.law {
            Law::Mlp(n) => n.mu_v(dv_mps, ddv_mps2, v_mps),
            Law::Polach(p) => p.mu_vt(dv_mps, ddv_mps2, v_mps, f64::NAN),
        }
    }

    /// [`Model::mu_v`] at ambient temperature `t_c` (°C): Polach models with a temperature law
    /// use k_A(T), k_S(T) with T clamped to the fitted range (NaN → the base k_A, k_S); other
    /// models ignore it.
    #[inline]
    pub fn mu_vt(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> f64 {
        match &self.law {
            Law::Mlp(n) => n.mu_v(dv_mps, ddv_mps2, v_mps),
            Law::Polach(p) => p.mu_vt(dv_mps, ddv_mps2, v_mps, t_c),
        }
    }

    /// μ(Δv, dΔv/dt) at the reference speed for models that need a speed.
    #[inline]
    pub fn mu(&self, dv_mps: f64, ddv_mps2: f64) -> f64 {
        self.mu_v(dv_mps, ddv_mps2, f64::NAN)
    }

    /// Batch evaluation into `out` (same length as the inputs); `v_mps` may be empty (the
    /// reference speed). Networks run vectorised across samples, blocks of [`LANES`], with
    /// the widest SIMD the CPU offers (AVX-512F, AVX2 + FMA or plain f64, chosen at run
    /// time); every lane performs the same IEEE operations as [`Model::mu_v`], so the results
    /// are identical (tested), whatever the path.
    pub fn mu_batch(&self, dv_mps: &[f64], ddv_mps2: &[f64], v_mps: &[f64], out: &mut [f64]) {
        assert!(dv_mps.len() == ddv_mps2.len() && out.len() == dv_mps.len());
        assert!(v_mps.is_empty() || v_mps.len() == dv_mps.len());
        match &self.law {
            Law::Mlp(n) => n.mu_batch(dv_mps, ddv_mps2, v_mps, out),
            Law::Polach(p) => {
                for (i, o) in out.iter_mut().enumerate() {
                    let v = v_mps.get(i).copied().unwrap_or(f64::NAN);
                    *o = p.mu_vt(dv_mps[i], ddv_mps2[i], v, f64::NAN);
                }
            }
        }
    }

    /// True when every input lies in the domain seen in training (for Polach models: Δv and
    /// v in the fitted ranges).
    pub fn in_domain(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> bool {
        match &self.law {
            Law::Mlp(n) => n.in_domain(dv_mps, ddv_mps2, v_mps),
            Law::Polach(p) => p.in_domain(dv_mps, v_mps),
        }
    }

    /// The model at a fixed ambient temperature (°C): a Polach model with a temperature law
    /// with k_A, k_S replaced by k_A(T), k_S(T). Errors for other models and for T outside
    /// the fitted range.
    pub fn at_temperature(&self, t_c: f64) -> Result<Model, ModelError> {
        let bad = |message: String, hint: &str| ModelError::Invalid {
            file: "model".into(),
            message,
            hint: hint.into(),
        };
        let Law::Polach(p) = &self.law else {
            return Err(bad(
                "this model has no temperature law (only Polach models fitted at two or more ambient temperatures have one)".into(),
                "drop the temperature dependence or use the .polach.json model of a campaign with several ambient temperatures",
            ));
        };
        let law = p.at_temperature(t_c).map_err(|e| {
            bad(
                e,
                "stay inside the temperature range the law was fitted over",
            )
        })?;
        let mut file = self.file.clone();
        if let Some(s) = file.polach.as_mut() {
            (s.k_a, s.k_s) = law.k();
            s.temperature = None;
        }
        file.inputs.retain(|i| i.name != polach::TEMPERATURE_INPUT);
        Ok(Model {
            file,
            law: Law::Polach(law),
        })
    }
}

/// The network evaluator (kind mlp).
#[derive(Debug, Clone)]
struct Net {
    k: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    gx: [f64; 3],
    ox: [f64; 3],
    /// Hidden neurons, and that number rounded up to a multiple of [`CHUNK`].
    nh: usize,
    pad: usize,
    /// Hidden-layer weights, column-major with stride `pad`: w1c[c · pad + h] = W1[h][c];
    /// `b1` and `w2` likewise padded. The padding neurons have zero weights and are never
    /// summed: they only let the single-call path run in fixed-width chunks.
    w1c: Vec<f64>,
    b1: Vec<f64>,
    w2: Vec<f64>,
    /// The same weights in blocks of [`CHUNK`] neurons for the single-call path.
    blocks: Vec<Block>,
    /// The instruction set of this CPU, detected once.
    simd: Simd,
    /// Output bias (−0.0 stored as +0.0 so that adding the padding neurons' exact +0.0 terms
    /// never changes the sum: see [`Net::net_chunks`]).
    b2: f64,
    gy: f64,
    oy: f64,
    blend: f64,
    /// C / Q: μ per unit creepage.
    creep_per_creepage: f64,
    v_ref: f64,
}

/// [`CHUNK`] hidden neurons' weights, contiguous (padding neurons all zero).
#[derive(Debug, Clone, Default)]
struct Block {
    b1: [f64; CHUNK],
    w1: [[f64; CHUNK]; 3],
    w2: [f64; CHUNK],
}

/// tanh for the evaluators, branch-free and inlinable (glibc's `tanh` is a ~10 ns call; ten of
/// them would be most of an evaluation). With x = 2z clamped to [−40, 40] (beyond, tanh rounds
/// to ±1): x = n ln 2 + r with n = round(x / ln 2) (by the 1.5·2⁵² rounding trick) and
/// |r| ≤ ln 2 / 2 (Cody–Waite split of ln 2, fdlibm's constants); e^r − 1 = r P(r) with
/// `simd::EXPM1_P` (Estrin's scheme); e^x − 1 = 2ⁿ (e^r − 1) + (2ⁿ − 1), exact but for one rounding
/// (a fused multiply-add), in (−1, ∞); tanh z = (e^x − 1)/(e^x − 1 + 2), whose denominator
/// never cancels. Every multiply-add is fused (`f64::mul_add`: correctly rounded, so the AVX2
/// `vfmadd`, a software `fma` and C99 `fma()` give the same bits). Within 4 ulp of the C
/// library's tanh (tested); tanh_fast(−0.0) is +0.0. The C header computes the same operations.
#[inline(always)]
pub fn tanh_fast(z: f64) -> f64 {
    // SAFETY: the f64 implementation needs no target feature.
    unsafe { simd::tanh_of_doubled(2.0 * z) }
}

/// Shen–Hedrick–Elkins saturation S(x) = x − x²/3 + x³/27 below 3, 1 above (seed 002 eq. 8,
/// as corrected in `contact::saturation`).
#[inline]
fn she(x: f64) -> f64 {
    if x < 3.0 {
        x - x * x / 3.0 + x * x * x / 27.0
    } else {
        1.0
    }
}

impl Net {
    fn new(file: &ModelFile) -> Net {
        let k = file.inputs.len();
        let creep = file
            .creep
            .as_ref()
            .expect("checked: kind mlp has a creep section");
        let Scaling {
            lo,
            hi,
            gx,
            ox,
            gy,
            oy,
            w1c,
        } = file.scaling();
        let h = &file.layers[0];
        let o = &file.layers[1];
        let nh = h.biases.len();
        let pad = nh.div_ceil(CHUNK) * CHUNK;
        let padded = |v: &[f64]| {
            let mut p = v.to_vec();
            p.resize(pad, 0.0);
            p
        };
        // Doubled (exact): the evaluators compute 2z, the argument tanh needs as e^(2z).
        let w1c: Vec<f64> = w1c.chunks(nh).flat_map(padded).map(|w| 2.0 * w).collect();
        let b1: Vec<f64> = padded(&h.biases).iter().map(|b| 2.0 * b).collect();
        let w2 = padded(&o.weights[0]);
        let blocks = (0..pad / CHUNK)
            .map(|j| {
                let at = |v: &[f64], c: usize| -> [f64; CHUNK] {
                    v[c * pad + j * CHUNK..c * pad + (j + 1) * CHUNK]
                        .try_into()
                        .expect("chunk")
                };
                let mut b = Block {
                    b1: at(&b1, 0),
                    w2: at(&w2, 0),
                    ..Block::default()
                };
                for c in 0..k {
                    b.w1[c] = at(&w1c, c);
                }
                b
            })
            .collect();
        Net {
            k,
            lo,
            hi,
            gx,
            ox,
            nh,
            pad,
            w1c,
            b1,
            w2,
            blocks,
            simd: Simd::detect(),
            b2: o.biases[0] + 0.0,
            gy,
            oy,
            blend: creep.blend_mps,
            creep_per_creepage: creep.creep_stiffness_n / creep.wheel_load_n,
            v_ref: creep.reference_speed_mps,
        }
    }

    /// The network alone at physical inputs (clamped to the domain). The hidden layer runs in
    /// fixed-width chunks of [`CHUNK`] neurons (zero-padded) so the compiler turns each into
    /// SIMD, with the chunk count a compile-time constant for up to 16 neurons; the output sum
    /// runs over the real neurons in order — the same operations as the batch path and the C
    /// header, same results.
    #[inline(always)]
    fn net<const AVX: bool>(&self, x: [f64; 3]) -> f64 {
        // The usual sizes with the chunk count known at compile time (fully unrolled).
        match self.pad / CHUNK {
            1 => self.net_chunks::<1, AVX>(x),
            2 => self.net_chunks::<2, AVX>(x),
            3 => self.net_chunks::<3, AVX>(x),
            4 => self.net_chunks::<4, AVX>(x),
            _ => self.net_any::<AVX>(x),
        }
    }

    /// [`Net::chunk`] on AVX2 registers with `AVX` (only inside functions compiled for AVX2
    /// and FMA), on plain f64 otherwise.
    #[inline(always)]
    fn chunk_with<const AVX: bool>(&self, b: &Block, xn: &[f64; 3]) -> [f64; CHUNK] {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: AVX is true only in code compiled for (and run on) AVX2 + FMA.
            return unsafe { self.chunk::<std::arch::x86_64::__m256d>(b, xn) };
        }
        // SAFETY: f64 lanes need no target feature.
        unsafe { self.chunk::<f64>(b, xn) }
    }

    /// One block of the hidden layer, w2_h tanh(b1_h + Σ_c W1_hc x_n,c) for its neurons
    /// (weights doubled: the sum is 2z), on lanes `V`.
    ///
    /// # Safety
    /// As [`Lanes`]: `V`'s target features must be enabled in the caller.
    #[inline(always)]
    unsafe fn chunk<V: Lanes>(&self, b: &Block, xn: &[f64; 3]) -> [f64; CHUNK] {
        let mut o = [0.0; CHUNK];
        for i in (0..CHUNK).step_by(V::N) {
            // SAFETY: the caller's contract; slices of CHUNK arrays from i < CHUNK.
            unsafe {
                let mut z2 = V::load(&b.b1[i..]);
                for (c, &xc) in xn.iter().enumerate().take(self.k) {
                    z2 = V::load(&b.w1[c][i..]).fma(V::splat(xc), z2);
                }
                simd::tanh_of_doubled(z2)
                    .mul(V::load(&b.w2[i..]))
                    .store(&mut o[i..]);
            }
        }
        o
    }

    #[inline(always)]
    fn inputs(&self, x: [f64; 3]) -> [f64; 3] {
        let mut xn = [0.0; 3];
        for c in 0..self.k {
            xn[c] = self.gx[c].mul_add(x[c].clamp(self.lo[c], self.hi[c]), self.ox[c]);
        }
        xn
    }

    /// The network with `C` blocks: the output sum runs over all `C` · [`CHUNK`] terms in
    /// order; the padding neurons' terms are exactly +0.0 (zero weights, tanh(+0) = +0), and
    /// y + 0.0 = y for every y but −0.0, which the sum can never hold (it starts at b2 ≠ −0.0,
    /// and a rounded sum is −0.0 only when both terms are) — so the result is that of summing
    /// the real neurons only, as the batch path and the C header do.
    #[inline(always)]
    fn net_chunks<const C: usize, const AVX: bool>(&self, x: [f64; 3]) -> f64 {
        let xn = self.inputs(x);
        let blocks: &[Block; C] = self.blocks[..C].try_into().expect("C blocks");
        let mut y = self.b2;
        for b in blocks {
            for t in self.chunk_with::<AVX>(b, &xn) {
                y += t;
            }
        }
        (y - self.oy) / self.gy
    }

    #[inline(always)]
    fn net_any<const AVX: bool>(&self, x: [f64; 3]) -> f64 {
        let xn = self.inputs(x);
        let mut y = self.b2;
        for b in &self.blocks {
            for t in self.chunk_with::<AVX>(b, &xn) {
                y += t;
            }
        }
        (y - self.oy) / self.gy
    }

    /// [`Model::mu_v`] of the network: four neurons per AVX2 register when the CPU has AVX2
    /// and FMA (compiled with AVX-512VL's 32 registers when it has those), else the portable
    /// path (plain f64; `mul_add` is a libm call on CPUs without FMA). Same bits on every path.
    #[inline]
    fn mu_v(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> f64 {
        match self.simd {
            // SAFETY: `Simd::detect` found AVX-512F/VL, AVX2 and FMA on this CPU.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => unsafe { self.mu_v_avx512vl(dv_mps, ddv_mps2, v_mps) },
            // SAFETY: `Simd::detect` found AVX2 and FMA on this CPU.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => unsafe { self.mu_v_avx2(dv_mps, ddv_mps2, v_mps) },
            _ => self.mu_v_impl::<false>(dv_mps, ddv_mps2, v_mps),
        }
    }

    /// [`Model::mu_v`] on AVX2 registers, compiled with AVX-512VL (its 32 vector registers keep
    /// tanh's constants in registers; about 5 % faster in development measurements). Rust never
    /// contracts a multiply and an add on its own, so only the written `fma`s are fused.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
    unsafe fn mu_v_avx512vl(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> f64 {
        self.mu_v_impl::<true>(dv_mps, ddv_mps2, v_mps)
    }

    /// [`Model::mu_v`] on AVX2 registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn mu_v_avx2(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> f64 {
        self.mu_v_impl::<true>(dv_mps, ddv_mps2, v_mps)
    }

    #[inline(always)]
    fn mu_v_impl<const AVX: bool>(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> f64 {
        if !(dv_mps.is_finite() && ddv_mps2.is_finite()) {
            return f64::NAN;
        }
        let (s, dv, ddv) = if dv_mps < 0.0 {
            (-1.0, -dv_mps, -ddv_mps2)
        } else {
            (1.0, dv_mps, ddv_mps2)
        };
        let v = if v_mps.is_finite() { v_mps } else { self.v_ref };
        let net = self.net::<AVX>([dv, ddv, v]);
        if dv >= self.blend {
            return s * net;
        }
        let sat = self.net::<AVX>([self.blend, ddv, v]).abs();
        let v_creep = if self.k == 3 { v.max(1.0) } else { self.v_ref };
        let slope = self.creep_per_creepage / v_creep;
        let lin = if sat > 0.0 {
            sat * she(slope * dv / sat)
        } else {
            0.0
        };
        let t = dv / self.blend;
        let w = t * t * (3.0 - 2.0 * t);
        s * (w * net + (1.0 - w) * lin)
    }

    /// [`Model::mu_batch`] of the network.
    fn mu_batch(&self, dv_mps: &[f64], ddv_mps2: &[f64], v_mps: &[f64], out: &mut [f64]) {
        let n = out.len();
        let full = n - n % LANES;
        let simd = self.simd;
        for b in (0..full).step_by(LANES) {
            let dv: &[f64; LANES] = dv_mps[b..b + LANES].try_into().expect("block");
            let ddv: &[f64; LANES] = ddv_mps2[b..b + LANES].try_into().expect("block");
            let v: [f64; LANES] = if v_mps.is_empty() {
                [f64::NAN; LANES]
            } else {
                v_mps[b..b + LANES].try_into().expect("block")
            };
            let o: &mut [f64; LANES] = (&mut out[b..b + LANES]).try_into().expect("block");
            self.block_dispatch(simd, dv, ddv, &v, o);
        }
        for i in full..n {
            let v = v_mps.get(i).copied().unwrap_or(f64::NAN);
            out[i] = self.mu_v(dv_mps[i], ddv_mps2[i], v);
        }
    }

    fn block_dispatch(
        &self,
        simd: Simd,
        dv: &[f64; LANES],
        ddv: &[f64; LANES],
        v: &[f64; LANES],
        out: &mut [f64; LANES],
    ) {
        match simd {
            // SAFETY: `Simd::detect` found AVX-512F on this CPU.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx512 => unsafe { self.block_avx512(dv, ddv, v, out) },
            // SAFETY: `Simd::detect` found AVX2 on this CPU.
            #[cfg(target_arch = "x86_64")]
            Simd::Avx2 => unsafe { self.block_avx2(dv, ddv, v, out) },
            // SAFETY: f64 lanes need no target feature.
            _ => unsafe { self.block::<f64>(dv, ddv, v, out) },
        }
    }

    block_with_feature!(block_avx512, "avx512f", std::arch::x86_64::__m512d);
    block_with_feature!(block_avx2, "avx2,fma", std::arch::x86_64::__m256d);

    /// [`Model::mu_v`] for a block of samples on lanes `V`, lane by lane the same operations
    /// as the single call: inputs, then per neuron in order 2z = fma(2W1, x_n, ·) from 2b1,
    /// y += w2 · tanh, then (y − o_y)/g_y; the creep region (rare in a batch) by the scalar rule.
    ///
    /// # Safety
    /// As [`Lanes`]: `V`'s target features must be enabled in the caller.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    unsafe fn block<V: Lanes>(
        &self,
        dv_in: &[f64; LANES],
        ddv_in: &[f64; LANES],
        v_in: &[f64; LANES],
        out: &mut [f64; LANES],
    ) {
        let mut sgn = [1.0; LANES];
        let mut x = [[0.0; LANES]; 3];
        for l in 0..LANES {
            let neg = dv_in[l] < 0.0;
            sgn[l] = if neg { -1.0 } else { 1.0 };
            x[0][l] = if neg { -dv_in[l] } else { dv_in[l] };
            x[1][l] = if neg { -ddv_in[l] } else { ddv_in[l] };
            x[2][l] = if v_in[l].is_finite() {
                v_in[l]
            } else {
                self.v_ref
            };
        }
        let mut xn = [[0.0; LANES]; 3];
        for c in 0..self.k {
            let (lo, hi, g, o) = (self.lo[c], self.hi[c], self.gx[c], self.ox[c]);
            for l in 0..LANES {
                xn[c][l] = g.mul_add(x[c][l].clamp(lo, hi), o);
            }
        }
        let mut net = [0.0; LANES];
        // SAFETY: the caller's contract; every slice starts at i < LANES, a multiple of V::N.
        unsafe {
            let mut y = [V::splat(self.b2); LANES];
            let vectors = LANES / V::N;
            for h in 0..self.nh {
                let b1 = V::splat(self.b1[h]);
                let w2 = V::splat(self.w2[h]);
                for j in 0..vectors {
                    let mut z2 = b1;
                    for c in 0..self.k {
                        let w = V::splat(self.w1c[c * self.pad + h]);
                        z2 = w.fma(V::load(&xn[c][j * V::N..]), z2);
                    }
                    y[j] = y[j].add(w2.mul(simd::tanh_of_doubled(z2)));
                }
            }
            let (oy, gy) = (V::splat(self.oy), V::splat(self.gy));
            for j in 0..vectors {
                y[j].sub(oy).div(gy).store(&mut net[j * V::N..]);
            }
        }
        for l in 0..LANES {
            out[l] = if !(dv_in[l].is_finite() && ddv_in[l].is_finite()) {
                f64::NAN
            } else if x[0][l] >= self.blend {
                sgn[l] * net[l]
            } else {
                self.mu_v(dv_in[l], ddv_in[l], v_in[l])
            };
        }
    }

    fn in_domain(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> bool {
        let x = [
            dv_mps.abs(),
            if dv_mps < 0.0 { -ddv_mps2 } else { ddv_mps2 },
            v_mps,
        ];
        (0..self.k).all(|c| x[c] >= self.lo[c] && x[c] <= self.hi[c])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_compiled_path_gives_the_portable_bits() {
        let text = include_str!("../../models/golden/synthetic_mlp.json");
        let m = Model::new(ModelFile::from_json(text, "golden").unwrap()).unwrap();
        let Law::Mlp(net) = &m.law else {
            panic!("the golden model is a network")
        };
        let mut points = Vec::new();
        for i in 0..400 {
            let dv = -4.5 + 0.0225 * i as f64;
            for ddv in [-3.5, -1.0, -0.01, 0.0, 0.3, 2.9, 7.0] {
                points.push((dv, ddv));
            }
        }
        points.push((f64::NAN, 0.0));
        points.push((0.5, f64::INFINITY));
        let portable: Vec<u64> = points
            .iter()
            .map(|&(dv, ddv)| net.mu_v_impl::<false>(dv, ddv, f64::NAN).to_bits())
            .collect();
        let same = |name: &str, got: &[f64]| {
            for (k, (g, p)) in got.iter().zip(&portable).enumerate() {
                let p = f64::from_bits(*p);
                assert!(
                    g.to_bits() == p.to_bits() || (g.is_nan() && p.is_nan()),
                    "{name} at {:?}: {g} vs {p}",
                    points[k]
                );
            }
        };
        let single: Vec<f64> = points.iter().map(|&(dv, ddv)| m.mu(dv, ddv)).collect();
        same("dispatched single call", &single);
        let (dv, ddv): (Vec<f64>, Vec<f64>) = points.iter().copied().unzip();
        let n = points.len() - points.len() % LANES;
        let v = [f64::NAN; LANES];
        // Every instruction set this CPU has, the widest last.
        let simd = match Simd::detect() {
            Simd::Avx512 => vec![Simd::Baseline, Simd::Avx2, Simd::Avx512],
            Simd::Avx2 => vec![Simd::Baseline, Simd::Avx2],
            Simd::Baseline => vec![Simd::Baseline],
        };
        #[cfg(target_arch = "x86_64")]
        for s in &simd {
            let got: Vec<f64> = points
                .iter()
                .map(|&(a, b)| match s {
                    // SAFETY: detected above.
                    Simd::Avx2 => unsafe { net.mu_v_avx2(a, b, f64::NAN) },
                    // SAFETY: detected above.
                    Simd::Avx512 => unsafe { net.mu_v_avx512vl(a, b, f64::NAN) },
                    Simd::Baseline => net.mu_v_impl::<false>(a, b, f64::NAN),
                })
                .collect();
            same(&format!("{s:?} single call"), &got);
        }
        for s in simd {
            let mut out = vec![0.0; n];
            for b in (0..n).step_by(LANES) {
                let o: &mut [f64; LANES] = (&mut out[b..b + LANES]).try_into().unwrap();
                net.block_dispatch(
                    s,
                    dv[b..b + LANES].try_into().unwrap(),
                    ddv[b..b + LANES].try_into().unwrap(),
                    &v,
                    o,
                );
            }
            same(&format!("{s:?} batch block"), &out);
        }
    }

    #[test]
    fn tanh_fast_matches_the_c_library() {
        let mut worst: f64 = 0.0;
        let mut z = -25.0;
        while z <= 25.0 {
            let (a, b) = (tanh_fast(z), z.tanh());
            let rel = if b == 0.0 {
                a.abs()
            } else {
                ((a - b) / b).abs()
            };
            worst = worst.max(rel);
            z += 0.000_731;
        }
        for z in [
            0.0, -0.0, 1e-300, -1e-300, 1e-9, 0.1733, 0.3466, 0.5, 19.0, 20.0, 40.0, 1e6, -1e6,
        ] {
            let (a, b) = (tanh_fast(z), z.tanh());
            assert!(
                (a - b).abs() <= 4.0 * f64::EPSILON * b.abs().max(f64::MIN_POSITIVE),
                "{z}: {a} vs {b}"
            );
            if b != 0.0 {
                assert_eq!(a.is_sign_negative(), b.is_sign_negative(), "{z}");
            }
        }
        assert!(worst < 4.0 * f64::EPSILON, "{worst:e}");
    }
}
