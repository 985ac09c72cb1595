//! What a campaign's fits share: the rail condition that trains them, the median speed, and
//! the pipeline's contact patch and creep region.

use super::dataset::RunTable;
use super::IdentifyError;

/// The contact patch of one wheel at the static wheel load for a pipeline (Hertz, seed 001
/// eq. 1–5; Kalker's c11, c22) and that load Q, N.
pub fn pipeline_patch(
    pipeline: &crate::config::Pipeline,
) -> Result<(crate::contact::polach::ContactPatch, f64), IdentifyError> {
    crate::vehicle::wheel_patch(&pipeline.vehicle, &pipeline.contact).map_err(|e| {
        IdentifyError::Data {
            what: format!("contact patch of the pipeline's [contact] section: {e}"),
            hint: "check [contact] and vehicle.wheel_radius_m in the pipeline file".into(),
        }
    })
}

/// The creep region of a model for a pipeline: Kalker's creep stiffness C = G a b c11 of one
/// wheel's Hertz patch (seed 001 eq. 1–5, 10–11) at the static wheel load Q.
pub fn creep_spec(
    pipeline: &crate::config::Pipeline,
    reference_speed_mps: f64,
) -> Result<crate::model::CreepSpec, IdentifyError> {
    let (patch, q) = pipeline_patch(pipeline)?;
    Ok(crate::model::CreepSpec {
        blend_mps: pipeline.train.creep_blend_mps,
        creep_stiffness_n: patch.g_pa * patch.a_m * patch.b_m * patch.c11,
        wheel_load_n: q,
        reference_speed_mps,
        reference_temperature_c: None,
    })
}

/// The runs that train a campaign's models: one rail condition (run metadata `condition`;
/// runs without it count as `unknown`). Adhesion on dry rail and on soap are different
/// curves, and a dry calibration run in a soap campaign would bend both the network and the
/// Polach fits.
#[derive(Debug)]
pub struct ConditionChoice {
    pub condition: String,
    pub used: Vec<RunTable>,
    /// (run, its condition) of the runs left out.
    pub skipped: Vec<(String, String)>,
}

/// The rail condition of a run, `unknown` without metadata.
pub fn run_condition(t: &RunTable) -> String {
    t.metadata
        .condition
        .clone()
        .unwrap_or_else(|| "unknown".into())
}

/// Keeps the runs of condition `wanted`, or without it of the most common condition (most
/// runs; a tie goes to the alphabetically first).
pub fn select_condition(
    tables: Vec<RunTable>,
    wanted: Option<&str>,
) -> Result<ConditionChoice, IdentifyError> {
    let mut counts: std::collections::BTreeMap<String, usize> = Default::default();
    for t in &tables {
        *counts.entry(run_condition(t)).or_default() += 1;
    }
    let condition = match wanted {
        Some(w) => {
            if !counts.contains_key(w) {
                return Err(IdentifyError::Data {
                    what: format!(
                        "train.condition = \"{w}\": no run has that condition (found {:?})",
                        counts.keys().collect::<Vec<_>>()
                    ),
                    hint: "set train.condition to one of the conditions found, or leave it out"
                        .into(),
                });
            }
            w.to_string()
        }
        None => counts
            .iter()
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(a.0)))
            .map(|(c, _)| c.clone())
            .ok_or_else(|| IdentifyError::Data {
                what: "no runs to train on".into(),
                hint: "give estimates tables or run logs".into(),
            })?,
    };
    let (used, other): (Vec<RunTable>, Vec<RunTable>) = tables
        .into_iter()
        .partition(|t| run_condition(t) == condition);
    Ok(ConditionChoice {
        condition,
        used,
        skipped: other
            .iter()
            .map(|t| (t.name.clone(), run_condition(t)))
            .collect(),
    })
}

/// Median vehicle speed over the valid samples of `tables`, m/s (10 m/s when there are none).
pub fn median_speed(tables: &[RunTable]) -> f64 {
    let mut v: Vec<f64> = tables
        .iter()
        .flat_map(|t| t.v_mps.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    if v.is_empty() {
        return 10.0;
    }
    // The element a sort would put at len/2, in linear time.
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}
