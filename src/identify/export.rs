//! Model files from identification results: the network ([`mlp_file`]) and the campaign's
//! Polach fit with k(T) ([`polach_file`]), in the format `model` reads and evaluates.

use super::polach_fit::{PolachFit, TemperatureFit};
use super::{IdentifyError, TrainedMlp};
use crate::contact::polach::ContactPatch;
use crate::model::polach::{PatchSpec, PolachSpec, TemperatureSpec, TEMPERATURE_INPUT};
use crate::model::{
    CreepSpec, InputSpec, Layer, Metrics, ModelFile, ModelKind, OutputSpec, Provenance, FORMAT_ID,
    FORMAT_VERSION,
};

/// Builds the file of a trained network.
pub fn mlp_file(t: &TrainedMlp, creep: CreepSpec, provenance: Provenance) -> ModelFile {
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

/// A `polach` model file from a campaign fit: `fit` gives μ0, A, B, k_A, k_S; `temperature`
/// (when present) k_A(T), k_S(T). `dv_range`, `v_range` are the slip and speed ranges of
/// the fitted samples (m/s), `v_ref` the speed for callers that give none (m/s).
#[allow(clippy::too_many_arguments)]
pub fn polach_file(
    fit: &PolachFit,
    patch: &ContactPatch,
    wheel_load_n: f64,
    temperature: Option<&TemperatureFit>,
    dv_range: (f64, f64),
    v_range: (f64, f64),
    v_ref: f64,
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
    let temperature = temperature.map(|t| TemperatureSpec {
        k_a: t.k_a.clone(),
        k_s: t.k_s.clone(),
        fitted_range_c: [t.fitted_range_c.0, t.fitted_range_c.1],
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
            mu0: fit.mu0,
            a_ratio: fit.a_ratio,
            b_s_per_m: fit.b_s_per_m,
            k_a: fit.k_a,
            k_s: fit.k_s,
            standard_errors: fit.se.map(|e| e.is_finite().then_some(e)),
            patch: PatchSpec {
                a_m: patch.a_m,
                b_m: patch.b_m,
                shear_modulus_pa: patch.g_pa,
                c11: patch.c11,
            },
            wheel_load_n,
            reference_speed_mps: v_ref,
            temperature,
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
    };
    file.check().map_err(|defect| IdentifyError::InvalidModel {
        group: fit.group.clone(),
        defect,
    })?;
    Ok(file)
}
