//! The columns of a run's estimates table that the report draws.

use std::path::Path;

use super::ReportError;
use crate::format::AXLES;

/// A valid sample: (Δv m/s, dΔv/dt m/s², μ, t s, v m/s).
pub(super) type ValidPoint = (f64, f64, f64, f64, f64);

/// The columns of an estimates table the report draws, per axle.
pub(super) struct RunData {
    pub time_s: Vec<f64>,
    pub v_mps: Vec<f64>,
    /// Per axle: (t, rω), (t, p), and the valid (Δv, dΔv/dt, μ, t, v).
    pub wheel: [Vec<(f64, f64)>; AXLES],
    pub pressure: [Vec<(f64, f64)>; AXLES],
    pub valid: [Vec<ValidPoint>; AXLES],
}

/// The valid samples of axle `axle` (1-based) in a run's estimates table, reading only its
/// `axle` and `valid` columns (the report sizes its charts across runs with it before it reads
/// the runs).
pub(super) fn count_valid(path: &Path, axle: usize) -> Result<usize, ReportError> {
    let df = open(path, Some(&["axle", "valid"]))?;
    let (axles, valid) = (
        column_f64(&df, path, "axle")?,
        column_bool(&df, path, "valid")?,
    );
    Ok(axles
        .iter()
        .zip(&valid)
        .filter(|(a, v)| **v && (**a as usize).clamp(1, AXLES) == axle)
        .count())
}

/// The table of `path`, every column or only `columns`.
fn open(path: &Path, columns: Option<&[&str]>) -> Result<polars::prelude::DataFrame, ReportError> {
    use polars::prelude::*;
    let file = crate::input::open_regular(path).map_err(|source| ReportError::Read {
        file: path.display().to_string(),
        source,
    })?;
    let mut reader = ParquetReader::new(file);
    if let Some(c) = columns {
        // The same error as a whole table without the column, not the reader's own.
        let schema = reader.schema().map_err(table_error(path))?;
        if let Some(missing) = c.iter().find(|name| !schema.contains(name)) {
            return Err(ReportError::Data {
                file: path.display().to_string(),
                message: format!("no column {missing}"),
            });
        }
        reader = reader.with_columns(Some(c.iter().map(|s| s.to_string()).collect()));
    }
    reader.finish().map_err(table_error(path))
}

/// A table error naming the file.
fn table_error(path: &Path) -> impl Fn(polars::error::PolarsError) -> ReportError + '_ {
    move |source| ReportError::Table {
        file: path.display().to_string(),
        source,
    }
}

/// Column `name`; an error naming the file when it is missing.
fn column<'d>(
    df: &'d polars::prelude::DataFrame,
    path: &Path,
    name: &str,
) -> Result<&'d polars::prelude::Column, ReportError> {
    df.column(name).map_err(|_| ReportError::Data {
        file: path.display().to_string(),
        message: format!("no column {name}"),
    })
}

/// Column `name` as f64 (NaN for nulls).
fn column_f64(
    df: &polars::prelude::DataFrame,
    path: &Path,
    name: &str,
) -> Result<Vec<f64>, ReportError> {
    let c = column(df, path, name)?
        .cast(&polars::prelude::DataType::Float64)
        .map_err(table_error(path))?;
    let ca = c.f64().map_err(table_error(path))?;
    Ok(ca.iter().map(|x| x.unwrap_or(f64::NAN)).collect())
}

/// Column `name` as bool (false for nulls).
fn column_bool(
    df: &polars::prelude::DataFrame,
    path: &Path,
    name: &str,
) -> Result<Vec<bool>, ReportError> {
    let c = column(df, path, name)?.bool().map_err(table_error(path))?;
    Ok(c.iter().map(|x| x.unwrap_or(false)).collect())
}

pub(super) fn read_run(path: &Path) -> Result<RunData, ReportError> {
    let df = open(path, None)?;
    let f = |name: &str| column_f64(&df, path, name);
    let (t, axle, v, p, dv, ddv, mu) = (
        f("time_s")?,
        f("axle")?,
        f("v_mps")?,
        f("p_bar")?,
        f("dv_mps")?,
        f("ddv_mps2")?,
        f("mu")?,
    );
    let valid = column_bool(&df, path, "valid")?;
    let mut d = RunData {
        time_s: vec![],
        v_mps: vec![],
        wheel: Default::default(),
        pressure: Default::default(),
        valid: Default::default(),
    };
    for k in 0..t.len() {
        let a = (axle[k] as usize).clamp(1, AXLES) - 1;
        if a == 0 {
            d.time_s.push(t[k]);
            d.v_mps.push(v[k]);
        }
        if v[k].is_finite() && dv[k].is_finite() {
            d.wheel[a].push((t[k], v[k] - dv[k]));
        }
        d.pressure[a].push((t[k], p[k]));
        if valid[k] {
            d.valid[a].push((dv[k], ddv[k], mu[k], t[k], v[k]));
        }
    }
    Ok(d)
}
