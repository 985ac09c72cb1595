//! The model file (docs/model-files.md; schema `models/schema/adhesion-model.schema.json`):
//! its types, the exact JSON round trip, and the checks a file passes before an evaluator is
//! built from it. A problem is a [`Defect`], reported as a [`ModelError`] naming the file.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{polach, ModelError};
use railgrip_contact::ContactError;

/// Largest hidden layer the evaluators take.
pub const MAX_HIDDEN: usize = 256;
/// Hidden layers a network file may hold (railgrip's LM trains one or two, burn any of these).
pub const MAX_HIDDEN_LAYERS: usize = 8;
/// Largest |weight| or |bias| a network file may hold (trained ones stay far below).
pub const MAX_WEIGHT: f64 = 1e8;
/// Largest |value| of an input's domain or normalisation bounds and of speeds (m/s, m/s², °C).
pub const MAX_INPUT_VALUE: f64 = 1e6;
/// Largest |value| of the output's normalisation bounds (μ is of order 1).
pub const MAX_MU_RANGE: f64 = 1e3;

/// Most inputs a network takes (Δv, dΔv/dt, v, ambient temperature).
pub const MAX_INPUTS: usize = 4;

/// Which inputs a network takes, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputSet {
    /// (Δv, dΔv/dt) — seed 002.
    DvDdv,
    /// (Δv, dΔv/dt, v) — speed as a third input.
    DvDdvV,
    /// (Δv, dΔv/dt, v, T) — and the run's ambient temperature (°C, metadata
    /// `ambient_temperature_c`) as a fourth: for campaigns whose runs span temperatures
    /// (seed 004 Fig. 2: the adhesion level moves with temperature).
    DvDdvVT,
}

impl InputSet {
    /// Every set, fewest inputs first.
    pub const ALL: [InputSet; 3] = [InputSet::DvDdv, InputSet::DvDdvV, InputSet::DvDdvVT];

    /// Input names (estimates-table column names; the temperature is the runs' metadata key)
    /// and units.
    pub fn names(self) -> &'static [(&'static str, &'static str)] {
        const ALL: [(&str, &str); 4] = [
            ("dv_mps", "m/s"),
            ("ddv_mps2", "m/s²"),
            ("v_mps", "m/s"),
            ("ambient_temperature_c", "°C"),
        ];
        &ALL[..self.count()]
    }
    /// Number of inputs (2, 3 or 4).
    pub fn count(self) -> usize {
        match self {
            InputSet::DvDdv => 2,
            InputSet::DvDdvV => 3,
            InputSet::DvDdvVT => 4,
        }
    }
    /// The set whose names are `names`, if any.
    pub fn from_names<S: AsRef<str>>(names: &[S]) -> Option<InputSet> {
        InputSet::ALL.into_iter().find(|s| {
            s.count() == names.len()
                && s.names()
                    .iter()
                    .zip(names)
                    .all(|((n, _), m)| *n == m.as_ref())
        })
    }
    /// Whether speed is an input.
    pub fn has_speed(self) -> bool {
        self.count() >= 3
    }
    /// Whether ambient temperature is an input.
    pub fn has_temperature(self) -> bool {
        self.count() >= 4
    }
}

/// One row of the training history (seed 002 Fig. 9), as the file stores it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Epoch {
    pub epoch: u64,
    /// Training MSE after the epoch (reported unit).
    pub train_mse: f64,
    /// Validation MSE after the epoch (NaN without validation data; `null` in JSON).
    #[serde(deserialize_with = "null_as_nan")]
    pub val_mse: f64,
    /// μ after the epoch.
    pub mu: f64,
    /// ‖2 Jᵀr‖ at the start of the epoch.
    pub grad_norm: f64,
    /// Seconds since training started. Not written to files (a clock field made the
    /// bytes differ between identical runs); read from older files.
    #[serde(default, skip_serializing)]
    pub elapsed_s: f64,
    /// Effective number of parameters γ after the epoch (Bayesian regularisation only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gamma: Option<f64>,
}

/// JSON has no NaN: serde_json writes it as `null`; read `null` back as NaN.
fn null_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let v: Option<f64> = serde::Deserialize::deserialize(d)?;
    Ok(v.unwrap_or(f64::NAN))
}

/// What is wrong with the contents of a model file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Defect {
    #[error("kind {kind} needs a \"{section}\" section")]
    MissingSection {
        kind: &'static str,
        section: &'static str,
    },
    #[error("kind {kind} has no {what}")]
    ForeignSection {
        kind: &'static str,
        what: &'static str,
    },
    #[error("inputs {found:?} are not {expected}")]
    Inputs {
        found: Vec<String>,
        expected: String,
    },
    #[error("outside_domain \"{found}\" is not \"{expected}\"{note}")]
    OutsideDomain {
        found: String,
        expected: &'static str,
        note: &'static str,
    },
    #[error("{0}")]
    Layers(String),
    #[error("input {input}: {what}")]
    InputRange { input: String, what: &'static str },
    #[error("a number is not finite")]
    NotFinite,
    #[error("{0}")]
    Value(String),
    #[error("support: {0}")]
    Support(String),
    #[error("polach: {0}")]
    Polach(#[source] ContactError),
    #[error("polach.temperature: at {t_c:.2} °C μ0 = {mu0:.4}, k_A = {k_a:.4}, k_S = {k_s:.4} leave 0 < μ0 <= 1.5 and 0 < k_S <= k_A <= 1")]
    TemperatureLaw {
        t_c: f64,
        mu0: f64,
        k_a: f64,
        k_s: f64,
    },
}

/// Format id written into every model file.
pub const FORMAT_ID: &str = "railgrip-adhesion-model";
/// Current format version: 2 adds the data-support grid ([`SupportSpec`]) and the plausibility
/// audit ([`AuditSpec`]) of networks. Version-1 files still load (no support: the network
/// everywhere, as before).
pub const FORMAT_VERSION: u32 = 2;
/// Versions this railgrip reads.
pub const READ_VERSIONS: [u32; 3] = [1, 2, DEEP_VERSION];
/// The version of files whose network has more than one hidden layer (written only for those:
/// a one-hidden-layer file stays version 2, so readers of version 2 keep reading it, and an
/// older railgrip refuses a deeper network by its version instead of misreading it).
pub const DEEP_VERSION: u32 = 3;
/// Most cells a support grid may have (2²⁰: about 24 MB of JSON at the limit).
pub const MAX_SUPPORT_CELLS: usize = 1 << 20;
/// Most cells per input of a support grid.
pub const MAX_CELLS_PER_INPUT: usize = 1024;

/// Where a network's training data lie (format version 2; docs/model-files.md, "Data
/// support"): a grid over the normalised inputs [−1, 1]ᵏ (after the mirror of step 1 of the
/// evaluation rule), `cells[c]` cells along input c. A cell is supported when at least
/// `min_samples` training and validation samples fall in it. The evaluators return the network
/// where every neighbouring cell centre is supported and blend to `fallback_mu` towards
/// unsupported ones and beyond the grid (see [`crate`], step 3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SupportSpec {
    /// Cells per input, in input order.
    pub cells: Vec<usize>,
    /// Samples a cell needs to count as supported.
    pub min_samples: u64,
    /// Training and validation samples per cell, row-major (the last input varies fastest).
    pub counts: Vec<u64>,
    /// What `fallback_mu` holds: `polach` (the campaign's Polach model at the cell centre),
    /// `nearest` (the network at the nearest supported cell centre), or for a residual network
    /// `law` (0: the law alone) or `law_held` (the residual held along dΔv/dt: at an
    /// unsupported cell the count-weighted mean residual of the supported cells at the same
    /// slip, speed and temperature whose slip rate has the cell's sign, 0 where none has).
    pub fallback: String,
    /// |μ| of the fallback at every cell centre (a residual network: the residual added to
    /// its law there).
    pub fallback_mu: Vec<f64>,
    /// Standard deviation of an ensemble's members' μ at every cell centre (empty for a single
    /// network).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub spread: Vec<f64>,
}

impl SupportSpec {
    /// Number of cells (the product of `cells`).
    pub fn len(&self) -> usize {
        self.cells.iter().product()
    }
    /// True for a grid without cells (never for a checked file).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether cell `j` (flat index) is supported.
    pub fn supported(&self, j: usize) -> bool {
        self.counts[j] >= self.min_samples
    }
}

/// The plausibility audit a network passed or failed before export (format version 2;
/// docs/model-files.md#plausibility-audit).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AuditSpec {
    pub passed: bool,
    /// The ceiling μ_max of the check 0 ≤ μ ≤ μ_max on supported cells.
    pub mu_max: f64,
    /// Loss-minus-recovery difference μ(Δv, +q) − μ(Δv, −q) of the training data and of the
    /// model on the same supported cells (`null` without such cells).
    pub hysteresis_data: Option<f64>,
    pub hysteresis_model: Option<f64>,
    /// Supported cells that failed.
    pub failing_cells: usize,
    /// What failed, the first cells by name (at most 50 lines).
    pub failures: Vec<String>,
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
    /// Speed used for the creepage when the model has no speed input, and for calls that
    /// give no speed, m/s.
    pub reference_speed_mps: f64,
    /// Ambient temperature for calls that give none, °C (networks with a temperature input
    /// only: the median over the training samples).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_temperature_c: Option<f64>,
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
    /// UTC, RFC 3339. Empty and not written: the time is in the output
    /// folder's `timings.json` (files of older versions carry it).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub created: String,
    /// The campaign generation that wrote the file (see `CampaignRecord::generation`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generation: Option<String>,
    /// The calibration the estimates were made with, in one line (a campaign's or a dry
    /// run's; absent when `[vehicle]`'s α and the radar were taken as given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<String>,
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
    /// kind mlp, version 2: where the training data lie.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub support: Option<SupportSpec>,
    /// kind mlp, version 2: the plausibility audit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub audit: Option<AuditSpec>,
    /// kind mlp: the Polach law (with its temperature and speed laws) the network is a residual
    /// over — a grey-box model, μ = μ_P(Δv, v, T) + N(Δv, dΔv/dt, …) (see [`crate`], step 3);
    /// its support grid falls back to the law plus the residual held along the slip rate
    /// (`fallback = "law_held"`) or, in files before that, to the law itself (`fallback =
    /// "law"`, `fallback_mu` all 0).
    /// An older railgrip refuses such a file by its unknown field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<polach::PolachSpec>,
}

impl ModelFile {
    /// JSON text (f64 in shortest round-trip form: reading it back gives the same bits).
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("model files serialise") + "\n"
    }

    /// Writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), ModelError> {
        let text = self.to_json();
        railgrip_io::atomic::write_atomically(path, |w| {
            std::io::Write::write_all(w, text.as_bytes())
        })
        .map_err(|source| ModelError::Write {
            file: path.display().to_string(),
            source,
        })
    }

    /// Parses and checks a model file's text; `file` names it in errors.
    pub fn from_json(text: &str, file: &str) -> Result<ModelFile, ModelError> {
        let m: ModelFile = serde_json::from_str(text).map_err(|source| ModelError::Parse {
            file: file.to_string(),
            source,
        })?;
        if m.format != FORMAT_ID {
            return Err(ModelError::Format {
                file: file.to_string(),
                found: m.format,
            });
        }
        if !READ_VERSIONS.contains(&m.version) {
            return Err(ModelError::Version {
                file: file.to_string(),
                found: m.version,
            });
        }
        m.check().map_err(|defect| ModelError::Invalid {
            file: file.to_string(),
            defect,
        })?;
        Ok(m)
    }

    /// Reads a model file.
    pub fn read(path: &Path) -> Result<ModelFile, ModelError> {
        let file = path.display().to_string();
        let text = railgrip_io::input::read_text_limited(
            path,
            railgrip_io::input::MAX_MODEL_BYTES,
            "model file",
        )
        .map_err(|source| ModelError::Read {
            file: file.clone(),
            source,
        })?;
        Self::from_json(&text, &file)
    }

    /// Shapes, names and numbers are consistent and finite.
    pub fn check(&self) -> Result<(), Defect> {
        // Units are the inputs' own (a free-text unit once reached the C header's
        // comment unescaped), and μ is dimensionless.
        for i in &self.inputs {
            let want = InputSet::ALL
                .iter()
                .flat_map(|s| s.names().iter())
                .find(|(n, _)| *n == i.name)
                .map(|(_, u)| *u);
            if let Some(u) = want {
                if i.unit != u {
                    return Err(Defect::Value(format!(
                        "inputs[{}].unit = {:?}; the unit of {} is {u:?}",
                        i.name, i.unit, i.name
                    )));
                }
            }
        }
        if self.output.unit != "1" || self.output.name != "mu" {
            return Err(Defect::Value(format!(
                "output is {:?} in {:?}; it must be \"mu\" in \"1\"",
                self.output.name, self.output.unit
            )));
        }
        // NaN fails too.
        if self.output.norm_min.partial_cmp(&self.output.norm_max) != Some(std::cmp::Ordering::Less)
        {
            return Err(Defect::Value(format!(
                "output.norm_min = {} must be below output.norm_max = {}",
                self.output.norm_min, self.output.norm_max
            )));
        }
        match self.kind {
            ModelKind::Mlp => self.check_mlp()?,
            ModelKind::Polach
                if self.support.is_some() || self.audit.is_some() || self.base.is_some() =>
            {
                return Err(Defect::ForeignSection {
                    kind: "polach",
                    what: "\"support\", \"audit\" or \"base\" section",
                })
            }
            ModelKind::Polach => polach::check(self)?,
        }
        super::check_finite_on_domain(self)
    }

    fn check_mlp(&self) -> Result<(), Defect> {
        self.check_mlp_core()?;
        if self.version < 2 && (self.support.is_some() || self.audit.is_some()) {
            return Err(Defect::Value(format!(
                "version {} has no \"support\" or \"audit\" (version 2 does)",
                self.version
            )));
        }
        if let Some(s) = &self.support {
            check_support(s, self.inputs.len())?;
            let law = s.fallback == "law" || s.fallback == "law_held";
            if law != self.base.is_some() {
                return Err(Defect::Support(
                    "fallback \"law\" or \"law_held\" goes with a \"base\" Polach law (a residual network), and a residual network falls back to its law".into(),
                ));
            }
            if s.fallback == "law" && s.fallback_mu.iter().any(|&f| f != 0.0) {
                return Err(Defect::Support(
                    "fallback \"law\" needs every fallback_mu 0 (the residual vanishes outside the data; the law remains); \"law_held\" holds a residual there".into(),
                ));
            }
        }
        if let Some(b) = &self.base {
            polach::check_spec(b).map_err(|d| Defect::Value(format!("base: {d}")))?;
        }
        if let Some(a) = &self.audit {
            if !(a.mu_max.is_finite() && a.mu_max > 0.0) {
                return Err(Defect::Value("audit.mu_max must be finite and > 0".into()));
            }
        }
        Ok(())
    }

    /// The checks of a kind-mlp file's own sections, in the order they report: the sections
    /// present, the inputs, the outside-domain rule, the layers, and the numbers.
    fn check_mlp_core(&self) -> Result<(), Defect> {
        let c = self.check_mlp_sections()?;
        self.check_mlp_inputs(c)?;
        if self.outside_domain != "clamp" {
            return Err(Defect::OutsideDomain {
                found: self.outside_domain.clone(),
                expected: "clamp",
                note: "",
            });
        }
        self.check_mlp_layers()?;
        self.check_mlp_numbers(c)?;
        self.check_mlp_magnitudes(c)?;
        self.check_mlp_gains()
    }

    /// A network file has a `creep` section (returned) and no `polach` section.
    fn check_mlp_sections(&self) -> Result<&CreepSpec, Defect> {
        if self.polach.is_some() {
            return Err(Defect::ForeignSection {
                kind: "mlp",
                what: "\"polach\" section",
            });
        }
        let Some(c) = &self.creep else {
            return Err(Defect::MissingSection {
                kind: "mlp",
                section: "creep",
            });
        };
        Ok(c)
    }

    /// The inputs are one of the [`InputSet`]s, a temperature input needs version 2, and
    /// `creep.reference_temperature_c` is given (finite) exactly when temperature is an input.
    fn check_mlp_inputs(&self, c: &CreepSpec) -> Result<(), Defect> {
        let names: Vec<&str> = self.inputs.iter().map(|i| i.name.as_str()).collect();
        let Some(set) = InputSet::from_names(&names) else {
            return Err(Defect::Inputs {
                found: names.iter().map(|n| n.to_string()).collect(),
                expected: "[dv_mps, ddv_mps2], [dv_mps, ddv_mps2, v_mps] or [dv_mps, ddv_mps2, v_mps, ambient_temperature_c]".into(),
            });
        };
        if set.has_temperature() && self.version < 2 {
            return Err(Defect::Value(format!(
                "version {} has no temperature input (version 2 does)",
                self.version
            )));
        }
        match (set.has_temperature(), c.reference_temperature_c) {
            (true, None) => {
                return Err(Defect::Value(
                    "a network with the input ambient_temperature_c needs creep.reference_temperature_c".into(),
                ))
            }
            (false, Some(_)) => {
                return Err(Defect::Value(
                    "creep.reference_temperature_c belongs to networks with the input ambient_temperature_c only".into(),
                ))
            }
            (true, Some(t)) if !t.is_finite() => return Err(Defect::NotFinite),
            _ => {}
        }
        Ok(())
    }

    /// 1 to [`MAX_HIDDEN_LAYERS`] tanh layers and one linear output layer (more than one
    /// hidden layer from [`DEEP_VERSION`] on), each shaped from the previous layer's width
    /// (the inputs for the first) to its own.
    fn check_mlp_layers(&self) -> Result<(), Defect> {
        let n_layers = self.layers.len();
        if !(2..=MAX_HIDDEN_LAYERS + 1).contains(&n_layers) {
            return Err(Defect::Layers(format!(
                "{n_layers} layers; an MLP model has 1 to {MAX_HIDDEN_LAYERS} hidden (tanh) layers and one linear output layer"
            )));
        }
        if n_layers > 2 && self.version < DEEP_VERSION {
            return Err(Defect::Value(format!(
                "version {} holds one hidden layer; a network with {} is version {DEEP_VERSION}",
                self.version,
                n_layers - 1
            )));
        }
        let (hidden, out) = self.layers.split_at(n_layers - 1);
        if hidden.iter().any(|l| l.activation != "tanh") || out[0].activation != "linear" {
            return Err(Defect::Layers(
                "activations must be tanh (hidden layers) and linear (output)".into(),
            ));
        }
        // Layer l maps the previous layer's width (the inputs for the first) to its own.
        let mut width_in = self.inputs.len();
        for (l, layer) in self.layers.iter().enumerate() {
            let n = layer.shape[0];
            let last = l + 1 == n_layers;
            if layer.shape != [n, width_in]
                || layer.weights.len() != n
                || layer.weights.iter().any(|r| r.len() != width_in)
                || layer.biases.len() != n
                || n == 0
                || (last && n != 1)
                || (!last && n > MAX_HIDDEN)
            {
                return Err(Defect::Layers(format!(
                    "layers[{l}]: shape {:?} with {} weight rows and {} biases does not follow from {width_in} inputs to the layer (hidden layers 1 to {MAX_HIDDEN} neurons, output 1)",
                    layer.shape,
                    layer.weights.len(),
                    layer.biases.len()
                )));
            }
            width_in = n;
        }
        Ok(())
    }

    /// Every input range runs from min to max, every number (weights, biases, ranges, creep
    /// constants) is finite, and the creep constants are positive.
    fn check_mlp_numbers(&self, c: &CreepSpec) -> Result<(), Defect> {
        let mut nums: Vec<f64> = self
            .layers
            .iter()
            .flat_map(|l| l.weights.iter().flatten().chain(&l.biases))
            .copied()
            .collect();
        for i in &self.inputs {
            nums.extend([i.norm_min, i.norm_max, i.domain_min, i.domain_max]);
            if i.domain_min > i.domain_max || i.norm_min > i.norm_max {
                return Err(Defect::InputRange {
                    input: i.name.clone(),
                    what: "min above max",
                });
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
            return Err(Defect::NotFinite);
        }
        if !(c.blend_mps > 0.0
            && c.creep_stiffness_n > 0.0
            && c.wheel_load_n > 0.0
            && c.reference_speed_mps > 0.0)
        {
            return Err(Defect::Value(
                "creep: blend_mps, creep_stiffness_n, wheel_load_n and reference_speed_mps must be > 0".into(),
            ));
        }
        Ok(())
    }

    /// Every number within its sane magnitude (the first beyond it, in file order, is
    /// reported: weights and biases, input ranges, output range, creep constants), and a wheel
    /// load of at least 1 N.
    fn check_mlp_magnitudes(&self, c: &CreepSpec) -> Result<(), Defect> {
        // Sane magnitudes: finite but extreme constants (weights 1e308) passed, and
        // the evaluators' derived numbers overflowed.
        let mut fields: Vec<(String, f64, f64)> = Vec::new();
        for (l, layer) in self.layers.iter().enumerate() {
            for (r, row) in layer.weights.iter().enumerate() {
                for (j, w) in row.iter().enumerate() {
                    fields.push((format!("layers[{l}].weights[{r}][{j}]"), *w, MAX_WEIGHT));
                }
            }
            for (r, b) in layer.biases.iter().enumerate() {
                fields.push((format!("layers[{l}].biases[{r}]"), *b, MAX_WEIGHT));
            }
        }
        for i in &self.inputs {
            for (what, v) in [
                ("domain_min", i.domain_min),
                ("domain_max", i.domain_max),
                ("norm_min", i.norm_min),
                ("norm_max", i.norm_max),
            ] {
                fields.push((format!("inputs[{}].{what}", i.name), v, MAX_INPUT_VALUE));
            }
        }
        for (what, v, limit) in [
            ("output.norm_min", self.output.norm_min, MAX_MU_RANGE),
            ("output.norm_max", self.output.norm_max, MAX_MU_RANGE),
            ("creep.blend_mps", c.blend_mps, MAX_INPUT_VALUE),
            ("creep.creep_stiffness_n", c.creep_stiffness_n, 1e12),
            ("creep.wheel_load_n", c.wheel_load_n, 1e7),
            (
                "creep.reference_speed_mps",
                c.reference_speed_mps,
                MAX_INPUT_VALUE,
            ),
        ] {
            fields.push((what.to_string(), v, limit));
        }
        if let Some((what, v, limit)) = fields.iter().find(|(_, v, l)| v.abs() > *l) {
            return Err(Defect::Value(format!(
                "{what} = {v:e} is beyond ±{limit:e}; railgrip never writes such a value (a damaged or hand-edited file)"
            )));
        }
        if c.wheel_load_n < 1.0 {
            return Err(Defect::Value(format!(
                "creep.wheel_load_n = {:e} N: a wheel load below 1 N is not a railway wheel",
                c.wheel_load_n
            )));
        }
        Ok(())
    }

    /// The evaluators' own numbers (mapminmax gains of very narrow ranges) must be finite
    /// too: a header constant `inf` does not compile.
    fn check_mlp_gains(&self) -> Result<(), Defect> {
        let s = self.scaling();
        if s.gx
            .iter()
            .chain(&s.ox)
            .chain(&s.w1c)
            .chain([&s.gy, &s.oy])
            .any(|v| !v.is_finite())
        {
            return Err(Defect::Value(
                "an input or output normalisation range is so narrow that its gain overflows"
                    .into(),
            ));
        }
        Ok(())
    }

    /// Neurons per hidden layer of a network file, in order (empty for kind polach).
    pub fn hidden_widths(&self) -> Vec<usize> {
        let n = self.layers.len().saturating_sub(1);
        self.layers[..n].iter().map(|l| l.shape[0]).collect()
    }

    /// Weights and biases of a network file.
    pub fn n_weights(&self) -> usize {
        self.layers
            .iter()
            .map(|l| l.shape[0] * (l.shape[1] + 1))
            .sum()
    }

    /// The network's widths from inputs to output, `3-32-32-1` (empty for kind polach).
    pub fn architecture(&self) -> String {
        if self.layers.is_empty() {
            return String::new();
        }
        std::iter::once(self.inputs.len())
            .chain(self.layers.iter().map(|l| l.shape[0]))
            .map(|n| n.to_string())
            .collect::<Vec<_>>()
            .join("-")
    }

    /// Whether the audit marked this model as failing.
    pub fn audit_failed(&self) -> bool {
        self.audit.as_ref().is_some_and(|a| !a.passed)
    }

    /// The network's inputs (checked when the file was read).
    pub fn input_set(&self) -> InputSet {
        let names: Vec<&str> = self.inputs.iter().map(|i| i.name.as_str()).collect();
        InputSet::from_names(&names).unwrap_or(InputSet::DvDdv)
    }
}

/// A support grid fits its model's inputs and holds finite, consistent numbers.
fn check_support(s: &SupportSpec, inputs: usize) -> Result<(), Defect> {
    let bad = |what: String| Err(Defect::Support(what));
    if s.cells.len() != inputs {
        return bad(format!(
            "{} grid dimensions for {inputs} inputs",
            s.cells.len()
        ));
    }
    if let Some(n) = s
        .cells
        .iter()
        .find(|&&n| !(2..=MAX_CELLS_PER_INPUT).contains(&n))
    {
        return bad(format!(
            "{n} cells along an input (2..={MAX_CELLS_PER_INPUT})"
        ));
    }
    let n = s
        .cells
        .iter()
        .try_fold(1usize, |a, &c| a.checked_mul(c))
        .filter(|&n| n <= MAX_SUPPORT_CELLS);
    let Some(n) = n else {
        return bad(format!(
            "{:?} cells exceed the limit of {MAX_SUPPORT_CELLS}",
            s.cells
        ));
    };
    if s.counts.len() != n
        || s.fallback_mu.len() != n
        || !(s.spread.is_empty() || s.spread.len() == n)
    {
        return bad(format!(
            "counts, fallback_mu and spread must hold {n} values (one per cell); they hold {}, {} and {}",
            s.counts.len(),
            s.fallback_mu.len(),
            s.spread.len()
        ));
    }
    if s.min_samples == 0 {
        return bad("min_samples must be at least 1".into());
    }
    if !["polach", "nearest", "law", "law_held"].contains(&s.fallback.as_str()) {
        return bad(format!(
            "fallback \"{}\" is not \"polach\", \"nearest\", \"law\" or \"law_held\"",
            s.fallback
        ));
    }
    if s.fallback_mu.iter().any(|v| !v.is_finite())
        || s.spread.iter().any(|v| !(v.is_finite() && *v >= 0.0))
    {
        return Err(Defect::NotFinite);
    }
    if !(0..n).any(|j| s.supported(j)) {
        return bad("no cell is supported".into());
    }
    Ok(())
}

/// The numbers the evaluators work with, derived once from a model file (shared by the Rust
/// evaluator and the C header so both start from the same doubles).
pub(crate) struct Scaling {
    /// Input domain per input (unused inputs 0).
    pub lo: [f64; MAX_INPUTS],
    pub hi: [f64; MAX_INPUTS],
    /// mapminmax gain and offset per input, x_n = g x + o.
    pub gx: [f64; MAX_INPUTS],
    pub ox: [f64; MAX_INPUTS],
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
            lo: [0.0; MAX_INPUTS],
            hi: [0.0; MAX_INPUTS],
            gx: [1.0; MAX_INPUTS],
            ox: [0.0; MAX_INPUTS],
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

/// mapminmax gain and offset for a (min, max) range, x_n = g x + o: constant ranges pass
/// through (the evaluators' rule; the support grid's occupancy uses it too).
#[inline]
pub fn gain_offset(min: f64, max: f64) -> (f64, f64) {
    let range = max - min;
    if range > 0.0 {
        let g = 2.0 / range;
        (g, -1.0 - g * min)
    } else {
        (1.0, 0.0)
    }
}
