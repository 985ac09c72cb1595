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
//! 3. Data support (version-2 files with a support grid, [`SupportSpec`]): N becomes
//!    w N + (1 − w) F, w the support indicator and F the fallback |μ| of the grid's cells,
//!    interpolated multilinearly between cell centres at the normalised, unclamped inputs,
//!    w fading to 0 over one cell beyond the grid's edge (module `support`). A residual
//!    (grey-box) network, a file with a `base` Polach law ([`polach`]), then adds the law:
//!    N ← w N + (1 − w) F + μ_P(Δv, v, T), its F the residual held along the slip rate
//!    (`fallback = "law_held"`; 0 in files with `"law"`, where the law alone remains outside
//!    the data).
//! 4. Creep region (seed 002 002_8d8769283f5e9cb6.txt: "in the pseudo-slip region the network
//!    is replaced by the linear law", eq. 6–8): below the blend slip Δv_b the model blends, with
//!    the weight w = t²(3 − 2t), t = Δv/Δv_b, from the Kalker linear law saturated by
//!    Shen–Hedrick–Elkins, μ_lin = μ_s·S(k Δv/μ_s) with S(x) = x − x²/3 + x³/27 for x < 3 and 1
//!    above, μ_s = |N(Δv_b, dΔv/dt, v)|, k = C / (Q v) (C = G a b c11 the creep stiffness, N; Q
//!    the wheel load, N; v the speed input or, for two-input models, the median training speed),
//!    to the network at Δv_b: μ = w N(Δv, …) + (1 − w) μ_lin. Continuous in every input.
//!
//! The front door for a simulator, an FMU or a binding that only evaluates models: this crate
//! builds with serde alone (no polars, burn, argmin or plotters).
//!
//! ```
//! use railgrip_model::Model;
//!
//! # let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../models/golden/synthetic_mlp.json");
//! let model = Model::load(path.as_ref())?; // read, checked, ready to evaluate
//! let mu = model.mu(1.2, 0.5); // Δv = 1.2 m/s, dΔv/dt = 0.5 m/s²
//! assert!(mu > 0.0 && mu < 0.6);
//! // Many points at once, vectorised (same bits as the single call): an empty speed slice means
//! // the reference speed.
//! let (dv, ddv) = ([0.1, 1.2, 3.0], [0.2, 0.5, -1.0]);
//! let mut out = [0.0; 3];
//! model.mu_batch(&dv, &ddv, &[], &mut out);
//! assert_eq!(out[1], mu);
//! # Ok::<(), railgrip_model::ModelError>(())
//! ```
//!
//! The C header of the same model ([`c_header`]) computes the same operations in C99.

pub mod c_header;
mod file;
pub mod fmu;
mod net;
pub mod polach;
mod support;

use std::path::Path;

pub(crate) use file::Scaling;
pub use file::{
    gain_offset, AuditSpec, CreepSpec, Defect, Epoch, InputFile, InputSet, InputSpec, Layer,
    Metrics, ModelFile, ModelKind, OutputSpec, Provenance, SupportSpec, DEEP_VERSION, FORMAT_ID,
    FORMAT_VERSION, MAX_CELLS_PER_INPUT, MAX_HIDDEN, MAX_HIDDEN_LAYERS, MAX_INPUTS,
    MAX_SUPPORT_CELLS, READ_VERSIONS,
};
use net::Net;
pub use net::{tanh_fast, LANES};
pub use polach::TemperatureError;

const HINT: &str = "give a model file written by `railgrip train` (format railgrip-adhesion-model, see models/schema/)";

/// Why a model file could not be read, used or written. `file` is the path, or the name given
/// to [`Model::named`].
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("{file}: {source}. Hint: check the path")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a model file: {source}. Hint: {HINT}")]
    Parse {
        file: String,
        #[source]
        source: serde_json::Error,
    },
    #[error("{file}: format \"{found}\" is not \"{FORMAT_ID}\". Hint: {HINT}")]
    Format { file: String, found: String },
    #[error("{file}: format version {found} is not supported (this railgrip reads versions 1 to {DEEP_VERSION}). Hint: {HINT}")]
    Version { file: String, found: u32 },
    #[error("{file}: {defect}. Hint: {HINT}")]
    Invalid {
        file: String,
        #[source]
        defect: Defect,
    },
    #[error("{file}: {problem}. Hint: {}", temperature_hint(.problem))]
    Temperature {
        file: String,
        #[source]
        problem: TemperatureError,
    },
    #[error("{file}: cannot write: {source}")]
    Write {
        file: String,
        #[source]
        source: std::io::Error,
    },
}

fn temperature_hint(p: &TemperatureError) -> &'static str {
    match p {
        TemperatureError::Outside { .. } => {
            "stay inside the temperature range the law was fitted over"
        }
        _ => "drop the temperature dependence or use the .polach.json model of a campaign with several ambient temperatures",
    }
}

/// A loaded model, ready to evaluate without allocating.
#[derive(Debug, Clone)]
pub struct Model {
    pub file: ModelFile,
    /// The file's path, or the name given to [`Model::named`] (for errors).
    name: String,
    law: Law,
}

/// The evaluator of each kind.
#[derive(Debug, Clone)]
enum Law {
    Mlp(Net),
    Polach(polach::PolachEval),
}

/// Points per input of the load-time check grid (both ends of the domain and 5 between).
const CHECK_POINTS: usize = 7;

/// No model file that evaluates to NaN/±∞ loads: μ must be finite at every point of
/// a grid over the declared input domains ([`CHECK_POINTS`] per input, at most 7⁴ = 2 401
/// evaluations), the evaluator itself doing the work, so that extreme but finite constants
/// (weights 1e308, an output range of ±1e308, a wheel load of 5e-324) are caught where they
/// matter. `file` must have passed the structural checks.
pub(crate) fn check_finite_on_domain(file: &ModelFile) -> Result<(), Defect> {
    let law = match file.kind {
        ModelKind::Mlp => Law::Mlp(Net::new(file)),
        ModelKind::Polach => Law::Polach(polach::PolachEval::new(file)),
    };
    let axes: Vec<(&str, Vec<f64>)> = file
        .inputs
        .iter()
        .map(|i| {
            let pts = (0..CHECK_POINTS)
                .map(|k| {
                    let f = k as f64 / (CHECK_POINTS - 1) as f64;
                    i.domain_min + (i.domain_max - i.domain_min) * f
                })
                .collect();
            (i.name.as_str(), pts)
        })
        .collect();
    let total: usize = axes.iter().map(|a| a.1.len()).product();
    for mut k in 0..total {
        // (dv, ddv, v, t): absent inputs as the evaluators take them (ddv 0, v and t NaN).
        let mut x = [0.0, 0.0, f64::NAN, f64::NAN];
        for (name, pts) in &axes {
            let v = pts[k % pts.len()];
            k /= pts.len();
            let slot = match *name {
                "dv_mps" => 0,
                "ddv_mps2" => 1,
                "v_mps" => 2,
                _ => 3,
            };
            x[slot] = v;
        }
        let mu = match &law {
            Law::Mlp(n) => n.mu_vt(x[0], x[1], x[2], x[3]),
            Law::Polach(p) => p.mu_vt(x[0], x[1], x[2], x[3]),
        };
        if !mu.is_finite() {
            return Err(Defect::Value(format!(
                "μ = {mu} at dv_mps = {}, ddv_mps2 = {}, v_mps = {}, ambient_temperature_c = {} inside the declared domain; a model must be finite there (check the weights, output range and constants for extreme values)",
                x[0], x[1], x[2], x[3]
            )));
        }
    }
    Ok(())
}

impl Model {
    /// Checks `file` and prepares its evaluator; errors call it "model".
    pub fn new(file: ModelFile) -> Result<Model, ModelError> {
        Model::named(file, "model")
    }

    /// Checks `file` and prepares its evaluator; errors name it `name`.
    pub fn named(file: ModelFile, name: &str) -> Result<Model, ModelError> {
        file.check().map_err(|defect| ModelError::Invalid {
            file: name.to_string(),
            defect,
        })?;
        Ok(Model::checked(file, name))
    }

    /// Reads and checks a model file.
    pub fn load(path: &Path) -> Result<Model, ModelError> {
        Ok(Model::checked(
            ModelFile::read(path)?,
            &path.display().to_string(),
        ))
    }

    fn checked(file: ModelFile, name: &str) -> Model {
        let law = match file.kind {
            ModelKind::Mlp => Law::Mlp(Net::new(&file)),
            ModelKind::Polach => Law::Polach(polach::PolachEval::new(&file)),
        };
        Model {
            file,
            name: name.to_string(),
            law,
        }
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
            Law::Mlp(n) => n.mu_vt(dv_mps, ddv_mps2, v_mps, f64::NAN),
            Law::Polach(p) => p.mu_vt(dv_mps, ddv_mps2, v_mps, f64::NAN),
        }
    }

    /// [`Model::mu_v`] at ambient temperature `t_c` (°C): Polach models with a temperature law
    /// use k_A(T), k_S(T) with T clamped to the fitted range (NaN → the base k_A, k_S);
    /// networks with a temperature input take it as their fourth input (clamped to the domain
    /// like the others; NaN → the reference temperature); other models ignore it.
    #[inline]
    pub fn mu_vt(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> f64 {
        match &self.law {
            Law::Mlp(n) => n.mu_vt(dv_mps, ddv_mps2, v_mps, t_c),
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
        self.mu_batch_t(dv_mps, ddv_mps2, v_mps, &[], out)
    }

    /// [`Model::mu_batch`] with ambient temperatures `t_c` (°C; empty: the reference or base
    /// values, as [`Model::mu_vt`] with NaN).
    pub fn mu_batch_t(
        &self,
        dv_mps: &[f64],
        ddv_mps2: &[f64],
        v_mps: &[f64],
        t_c: &[f64],
        out: &mut [f64],
    ) {
        assert!(dv_mps.len() == ddv_mps2.len() && out.len() == dv_mps.len());
        assert!(v_mps.is_empty() || v_mps.len() == dv_mps.len());
        assert!(t_c.is_empty() || t_c.len() == dv_mps.len());
        match &self.law {
            Law::Mlp(n) => n.mu_batch(dv_mps, ddv_mps2, v_mps, t_c, out),
            Law::Polach(p) => {
                for (i, o) in out.iter_mut().enumerate() {
                    let v = v_mps.get(i).copied().unwrap_or(f64::NAN);
                    let t = t_c.get(i).copied().unwrap_or(f64::NAN);
                    *o = p.mu_vt(dv_mps[i], ddv_mps2[i], v, t);
                }
            }
        }
    }

    /// True when every input lies in the domain seen in training (for Polach models: Δv and
    /// v in the fitted ranges).
    pub fn in_domain(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> bool {
        self.in_domain_t(dv_mps, ddv_mps2, v_mps, f64::NAN)
    }

    /// [`Model::in_domain`] with the ambient temperature (°C; checked by networks with a
    /// temperature input, NaN → the reference temperature).
    pub fn in_domain_t(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64, t_c: f64) -> bool {
        match &self.law {
            Law::Mlp(n) => n.in_domain(dv_mps, ddv_mps2, v_mps, t_c),
            Law::Polach(p) => p.in_domain(dv_mps, v_mps),
        }
    }

    /// The interpolated data support w ∈ [0, 1] at these inputs (1: the network alone, 0: the
    /// fallback alone); `None` for models without a support grid.
    pub fn support_weight(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> Option<f64> {
        self.support_weight_t(dv_mps, ddv_mps2, v_mps, f64::NAN)
    }

    /// [`Model::support_weight`] at ambient temperature `t_c` (°C; NaN → the reference).
    pub fn support_weight_t(
        &self,
        dv_mps: f64,
        ddv_mps2: f64,
        v_mps: f64,
        t_c: f64,
    ) -> Option<f64> {
        match &self.law {
            Law::Mlp(n) => n.support_weight(dv_mps, ddv_mps2, v_mps, t_c),
            Law::Polach(_) => None,
        }
    }

    /// The ensemble's spread (standard deviation of its members' μ) interpolated at these
    /// inputs; `None` for single networks and other models.
    pub fn spread(&self, dv_mps: f64, ddv_mps2: f64, v_mps: f64) -> Option<f64> {
        match &self.law {
            Law::Mlp(n) => n.spread(dv_mps, ddv_mps2, v_mps, f64::NAN),
            Law::Polach(_) => None,
        }
    }

    /// The model at a fixed ambient temperature (°C): a Polach model with a temperature law
    /// with μ0, k_A, k_S replaced by their values at T. Errors for other models and for T outside
    /// the fitted range.
    pub fn at_temperature(&self, t_c: f64) -> Result<Model, ModelError> {
        let err = |problem| ModelError::Temperature {
            file: self.name.clone(),
            problem,
        };
        let Law::Polach(p) = &self.law else {
            return Err(err(TemperatureError::NotPolach));
        };
        let law = p.at_temperature(t_c).map_err(err)?;
        let mut file = self.file.clone();
        if let Some(s) = file.polach.as_mut() {
            (s.mu0, s.k_a, s.k_s) = law.base();
            s.temperature = None;
        }
        file.inputs.retain(|i| i.name != polach::TEMPERATURE_INPUT);
        Ok(Model {
            file,
            name: self.name.clone(),
            law: Law::Polach(law),
        })
    }
}
