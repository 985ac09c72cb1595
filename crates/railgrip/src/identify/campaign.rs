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
pub struct ConditionChoice<T = RunTable> {
    pub condition: String,
    pub used: Vec<T>,
    /// (run, its condition) of the runs left out.
    pub skipped: Vec<(String, String)>,
}

/// What choosing a campaign's rail condition and its thinning needs of a run, whether its
/// table is in memory or waits in its estimates file ([`crate::campaign::PooledRun`]).
pub trait CampaignRun {
    fn run_name(&self) -> &str;
    fn run_metadata(&self) -> &crate::format::RunMetadata;
    /// Valid samples of each axle, in the table's order (its axle blocks,
    /// [`RunTable::axle_ranges`]).
    fn axle_counts(&self) -> Vec<usize>;
}

impl CampaignRun for RunTable {
    fn run_name(&self) -> &str {
        &self.name
    }
    fn run_metadata(&self) -> &crate::format::RunMetadata {
        &self.metadata
    }
    fn axle_counts(&self) -> Vec<usize> {
        self.axle_ranges().map(|r| r.len()).collect()
    }
}

/// The rail condition of a run, `unknown` without metadata.
pub fn run_condition<T: CampaignRun + ?Sized>(t: &T) -> String {
    t.run_metadata()
        .condition
        .clone()
        .unwrap_or_else(|| "unknown".into())
}

/// Keeps the runs of condition `wanted`, or without it of the most common condition (most
/// runs; a tie goes to the alphabetically first).
pub fn select_condition<T: CampaignRun>(
    tables: Vec<T>,
    wanted: Option<&str>,
) -> Result<ConditionChoice<T>, IdentifyError> {
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
    let (used, other): (Vec<T>, Vec<T>) = tables
        .into_iter()
        .partition(|t| run_condition(t) == condition);
    Ok(ConditionChoice {
        condition,
        used,
        skipped: other
            .iter()
            .map(|t| (t.run_name().to_string(), run_condition(t)))
            .collect(),
    })
}

/// The thinning that brings the pooled valid samples of `tables` within `limit`: the smallest
/// m ≥ 1 for which keeping every m-th sample of each run and axle ([`RunTable::thin`]) leaves
/// Σ ⌈n_(run, axle) / m⌉ ≤ `limit` samples (1 when they are within it already; `limit` ≥ the
/// number of run-axle pairs, which every limit the pipeline accepts is). The same for any
/// order of the tables.
pub fn pooled_thinning<T: CampaignRun>(tables: &[T], limit: usize) -> usize {
    let counts: Vec<usize> = tables.iter().flat_map(|t| t.axle_counts()).collect();
    let limit = limit.max(counts.len()).max(1);
    let kept = |m: usize| counts.iter().map(|n| n.div_ceil(m)).sum::<usize>();
    let total = kept(1);
    // Σ ⌈n/m⌉ ≥ total/m rules out every m below ⌈total/limit⌉; Σ ⌈n/m⌉ < total/m + pairs
    // puts the answer a few steps past it.
    let mut m = total.div_ceil(limit).max(1);
    while kept(m) > limit {
        m += 1;
    }
    m
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A table with `counts[a]` samples on axle a + 1 (sample values: their index).
    fn table(counts: &[usize]) -> RunTable {
        let mut t = RunTable::default();
        for (a, &n) in counts.iter().enumerate() {
            for i in 0..n {
                t.axle.push(a as u8 + 1);
                for col in [&mut t.time_s, &mut t.v_mps, &mut t.dv_mps, &mut t.ddv_mps2] {
                    col.push(i as f64);
                }
                t.mu.push(i as f64);
            }
        }
        t
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The factor is the smallest that fits, whatever the order of the runs, and thinning
        /// by it leaves exactly the counted samples, every axle's first among them.
        #[test]
        fn pooled_thinning_is_the_smallest_factor_that_fits(
            runs in proptest::collection::vec(proptest::collection::vec(0usize..400, 1..=4), 1..6),
            limit in 1usize..3000,
        ) {
            let tables: Vec<RunTable> = runs.iter().map(|c| table(c)).collect();
            let m = pooled_thinning(&tables, limit);
            let pairs = runs.iter().flatten().filter(|&&n| n > 0).count();
            let kept = |m: usize| runs.iter().flatten().map(|n| n.div_ceil(m)).sum::<usize>();
            prop_assert!(kept(m) <= limit.max(pairs).max(1));
            prop_assert!(m == 1 || kept(m - 1) > limit.max(pairs));
            let mut reversed = tables.clone();
            reversed.reverse();
            prop_assert_eq!(pooled_thinning(&reversed, limit), m);
            let mut thinned = tables;
            for t in &mut thinned {
                t.thin(m);
            }
            prop_assert_eq!(thinned.iter().map(RunTable::len).sum::<usize>(), kept(m));
            for (t, c) in thinned.iter().zip(&runs) {
                // Per axle: samples 0, m, 2m, … of that axle.
                let mut at = 0;
                for (a, &n) in c.iter().enumerate() {
                    let want: Vec<f64> = (0..n).step_by(m).map(|i| i as f64).collect();
                    let k = want.len();
                    prop_assert_eq!(&t.mu[at..at + k], &want[..]);
                    prop_assert!(t.axle[at..at + k].iter().all(|&x| x == a as u8 + 1));
                    at += k;
                }
            }
        }

        /// Thinning by a, then b, keeps what thinning by a · b keeps.
        #[test]
        fn thinning_composes(
            counts in proptest::collection::vec(0usize..300, 1..=4),
            a in 1usize..6,
            b in 1usize..6,
        ) {
            let mut twice = table(&counts);
            twice.thin(a);
            twice.thin(b);
            let mut once = table(&counts);
            once.thin(a * b);
            prop_assert_eq!(twice.mu, once.mu);
            prop_assert_eq!(twice.axle, once.axle);
        }
    }
}
