//! Model files from identification results: the network ([`mlp_file`]) and the campaign's
//! Polach fit with k(T) ([`polach_file`]), in the format `model` reads and evaluates.

use super::mlp::Arch;
use super::polach::{PolachFit, TemperatureFit};
use super::support::{self, support_spec};
use super::{IdentifyError, TrainedMlp};
use crate::contact::polach::ContactPatch;
use crate::model::polach::{PatchSpec, PolachSpec, TEMPERATURE_INPUT};
use crate::model::{
    CreepSpec, InputSpec, Layer, Metrics, Model, ModelFile, ModelKind, OutputSpec, Provenance,
    DEEP_VERSION, FORMAT_ID, FORMAT_VERSION,
};

/// The hidden (tanh) layers and the output (linear) layer of a network θ of any depth
/// ([`Arch`]'s order: per layer W row-major, then b).
pub fn layers(arch: &Arch, th: &[f64]) -> Vec<Layer> {
    let sizes = arch.sizes();
    let mut at = 0;
    sizes
        .windows(2)
        .enumerate()
        .map(|(l, p)| {
            let (n_in, n) = (p[0], p[1]);
            let layer = Layer {
                shape: [n, n_in],
                weights: (0..n)
                    .map(|g| th[at + g * n_in..at + (g + 1) * n_in].to_vec())
                    .collect(),
                biases: th[at + n * n_in..at + n * (n_in + 1)].to_vec(),
                activation: if l + 2 == sizes.len() {
                    "linear"
                } else {
                    "tanh"
                }
                .into(),
            };
            at += n * (n_in + 1);
            layer
        })
        .collect()
}

/// Builds the file of a trained network (format version 2): the network, its data-support
/// grid with the fallback of `polach` (the campaign's Polach model) or else the nearest
/// supported value, an ensemble's spread, and the plausibility audit ([`super::support`]).
pub fn mlp_file(
    t: &TrainedMlp,
    creep: CreepSpec,
    provenance: Provenance,
    polach: Option<&Model>,
) -> Result<ModelFile, IdentifyError> {
    network_file(t, creep, provenance, polach, None, true)
}

/// Builds the file of a residual (grey-box) network: `t` trained on μ − μ_P, `base` the law
/// μ_P (a `polach` model file's section) embedded as the file's `base`; its support grid falls
/// back to the law plus the residual held along the slip rate (`law_held`), and the audit sees
/// the whole model (law plus network) against the data (`t.data` must hold μ, not the
/// residual).
pub fn residual_file(
    t: &TrainedMlp,
    creep: CreepSpec,
    provenance: Provenance,
    base: PolachSpec,
) -> Result<ModelFile, IdentifyError> {
    network_file(t, creep, provenance, None, Some(base), true)
}

/// [`mlp_file`] (`base` none) or [`residual_file`], the audit only when `audit`.
pub(crate) fn network_file(
    t: &TrainedMlp,
    creep: CreepSpec,
    provenance: Provenance,
    polach: Option<&Model>,
    base: Option<PolachSpec>,
    audit: bool,
) -> Result<ModelFile, IdentifyError> {
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
    let mut file = ModelFile {
        format: FORMAT_ID.into(),
        // Deeper networks are version 3 (older readers refuse them by version).
        version: if t.arch.hidden.len() > 1 {
            DEEP_VERSION
        } else {
            FORMAT_VERSION
        },
        kind: ModelKind::Mlp,
        inputs,
        output: OutputSpec {
            name: "mu".into(),
            unit: "1".into(),
            norm_min: t.y_norm.min[0],
            norm_max: t.y_norm.max[0],
        },
        outside_domain: "clamp".into(),
        layers: layers(&t.arch, &t.theta),
        creep: Some(CreepSpec {
            reference_temperature_c: t.reference_temperature_c,
            ..creep
        }),
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
        support: None,
        audit: None,
        base,
    };
    let invalid = |defect| IdentifyError::InvalidModel {
        group: "network".into(),
        defect,
    };
    file.check().map_err(invalid)?;
    let members: Vec<ModelFile> = t
        .members
        .iter()
        .map(|m| ModelFile {
            layers: layers(
                &Arch {
                    inputs: t.arch.inputs,
                    hidden: t.arch.hidden.iter().map(|h| h / t.members.len()).collect(),
                },
                m,
            ),
            history: vec![],
            ..file.clone()
        })
        .collect();
    let model_error = |e: crate::model::ModelError| IdentifyError::Data {
        what: format!("the trained network's support grid: {e}"),
        hint: "report this as a bug".into(),
    };
    file.support = Some(support_spec(&file, &t.occupancy, polach, &members).map_err(model_error)?);
    file.check().map_err(invalid)?;
    if audit {
        let model = Model::named(file.clone(), "trained network").map_err(model_error)?;
        file.audit = Some(support::audit(&model, &t.data, t.audit_mu_max));
    }
    Ok(file)
}

/// A `polach` model file from a campaign fit: `fit` gives μ0, A, B, k_A, k_S; a
/// `temperature` law whose chosen form depends on T replaces them: its A, B, and μ0, k_A, k_S
/// at its reference temperature (for callers that give none), with its polynomials. `dv_range`,
/// `v_range` are the slip and speed ranges of the fitted samples (m/s), `v_ref` the speed for
/// callers that give none (m/s), `creepage_speed` the fixed speed the fit took the creepage at
/// (m/s; `None`: each sample's).
#[allow(clippy::too_many_arguments)]
pub fn polach_file(
    fit: &PolachFit,
    patch: &ContactPatch,
    wheel_load_n: f64,
    temperature: Option<&TemperatureFit>,
    dv_range: (f64, f64),
    v_range: (f64, f64),
    v_ref: f64,
    creepage_speed: Option<f64>,
    provenance: Provenance,
) -> Result<ModelFile, IdentifyError> {
    let input = |name: &str, unit: &str, (lo, hi): (f64, f64)| InputSpec {
        name: name.into(),
        unit: unit.into(),
        norm_min: lo,
        norm_max: hi,
        domain_min: lo,
        domain_max: hi,
    };
    let mut inputs = vec![
        input("dv_mps", "m/s", dv_range),
        input("v_mps", "m/s", v_range),
    ];
    let law = temperature.filter(|t| t.has_law());
    let (mu0, a_ratio, b_s_per_m, k_a, k_s, se) = match law {
        Some(t) => {
            let (m, ka, ks) = t.at(t.reference_temperature_c);
            (m, t.a_ratio, t.b_s_per_m, ka, ks, t.se)
        }
        None => (
            fit.mu0,
            fit.a_ratio,
            fit.b_s_per_m,
            fit.k_a,
            fit.k_s,
            fit.se,
        ),
    };
    let temperature = law.filter(|t| t.has_temperature_law()).map(|t| t.spec());
    let speed = law.and_then(|t| t.speed.as_ref()).map(|s| {
        let mut spec = s.spec();
        // The law clamps v to the fitted speeds: the model's v domain.
        spec.fitted_range_mps = [v_range.0, v_range.1];
        spec
    });
    if let Some(t) = &temperature {
        inputs.push(input(
            TEMPERATURE_INPUT,
            "°C",
            (t.fitted_range_c[0], t.fitted_range_c[1]),
        ));
    }
    let file = ModelFile {
        format: FORMAT_ID.into(),
        version: FORMAT_VERSION,
        kind: ModelKind::Polach,
        inputs,
        output: OutputSpec {
            name: "mu".into(),
            unit: "1".into(),
            norm_min: 0.0,
            norm_max: 1.0,
        },
        outside_domain: "law".into(),
        layers: vec![],
        creep: None,
        polach: Some(PolachSpec {
            mu0,
            a_ratio,
            b_s_per_m,
            k_a,
            k_s,
            standard_errors: se.map(|e| e.is_finite().then_some(e)),
            patch: PatchSpec {
                a_m: patch.a_m,
                b_m: patch.b_m,
                shear_modulus_pa: patch.g_pa,
                c11: patch.c11,
            },
            wheel_load_n,
            reference_speed_mps: v_ref,
            temperature,
            speed,
            creepage_speed_mps: creepage_speed,
        }),
        provenance,
        metrics: Metrics {
            train_samples: fit.samples,
            val_samples: 0,
            train_mse: fit.rmse * fit.rmse,
            val_mse: None,
            epochs: fit.iterations,
            stop_reason: fit.stop_reason.clone(),
        },
        history: vec![],
        support: None,
        audit: None,
        base: None,
    };
    file.check().map_err(|defect| IdentifyError::InvalidModel {
        group: fit.group.clone(),
        defect,
    })?;
    Ok(file)
}
