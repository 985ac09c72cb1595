//! The one-row-per-run summary of a campaign (`summary.csv`, `summary.parquet`,
//! [`SUMMARY_COLUMNS`]).

use std::path::PathBuf;

use super::{CampaignError, OutDir, RunRecord};
use crate::format::AXLES;

/// Columns of `summary.csv` / `summary.parquet`, in order.
/// How a run was computed this time (reused, seconds) is in `timings.json` (the same
/// inputs give the same bytes).
pub const SUMMARY_COLUMNS: [&str; 15] = [
    "run",
    "status",
    "error",
    "initial_speed_kmh",
    "ambient_temperature_c",
    "condition",
    "peak_mu_1",
    "peak_mu_2",
    "peak_mu_3",
    "peak_mu_4",
    "max_dv_mps_1",
    "max_dv_mps_2",
    "max_dv_mps_3",
    "max_dv_mps_4",
    "warnings",
];

/// Writes `summary.csv` and `summary.parquet` into `out`, one row per record.
pub fn write_summary(out: &OutDir, records: &[RunRecord]) -> Result<Vec<PathBuf>, CampaignError> {
    use polars::prelude::*;
    let s = |f: &dyn Fn(&RunRecord) -> Option<String>| -> Vec<Option<String>> {
        records.iter().map(f).collect()
    };
    let n = |f: &dyn Fn(&RunRecord) -> Option<f64>| -> Vec<Option<f64>> {
        records.iter().map(f).collect()
    };
    let mut cols: Vec<Column> = vec![
        Column::new("run".into(), s(&|r| Some(r.run.clone()))),
        Column::new("status".into(), s(&|r| Some(r.status.as_str().to_string()))),
        Column::new("error".into(), s(&|r| r.error.clone())),
        Column::new("initial_speed_kmh".into(), n(&|r| r.initial_speed_kmh)),
        Column::new(
            "ambient_temperature_c".into(),
            n(&|r| r.ambient_temperature_c),
        ),
        Column::new("condition".into(), s(&|r| r.condition.clone())),
    ];
    for a in 0..AXLES {
        cols.push(Column::new(
            format!("peak_mu_{}", a + 1).into(),
            n(&|r| r.peak_mu[a]),
        ));
    }
    for a in 0..AXLES {
        cols.push(Column::new(
            format!("max_dv_mps_{}", a + 1).into(),
            n(&|r| r.max_dv_mps[a]),
        ));
    }
    cols.push(Column::new(
        "warnings".into(),
        s(&|r| Some(r.warnings.join("; "))),
    ));
    let (csv, pq) = (out.summary_csv(), out.summary_parquet());
    let mut df = crate::table::frame(records.len(), cols, &pq)?;
    crate::table::write_csv(&mut df, &csv)?;
    crate::table::write_parquet(&mut df, &pq, None)?;
    Ok(vec![csv, pq])
}
