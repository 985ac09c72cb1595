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

/// What the report keeps of a run once its own section is drawn: that section, and the valid
/// samples the sections across runs read (the others' axles left empty).
pub(super) struct KeptRun {
    pub section: String,
    pub valid: [Vec<ValidPoint>; AXLES],
}

pub(super) fn read_run(path: &Path) -> Result<RunData, ReportError> {
    use polars::prelude::*;
    let bad = |message: String| ReportError::Data {
        file: path.display().to_string(),
        message,
    };
    let file = crate::input::open_regular(path).map_err(|source| ReportError::Read {
        file: path.display().to_string(),
        source,
    })?;
    let table = |source| ReportError::Table {
        file: path.display().to_string(),
        source,
    };
    let df = ParquetReader::new(file).finish().map_err(table)?;
    let f = |name: &str| -> Result<Vec<f64>, ReportError> {
        let c = df
            .column(name)
            .map_err(|_| bad(format!("no column {name}")))?
            .cast(&DataType::Float64)
            .map_err(table)?;
        let ca = c.f64().map_err(table)?;
        Ok(ca.iter().map(|x| x.unwrap_or(f64::NAN)).collect())
    };
    let (t, axle, v, p, dv, ddv, mu) = (
        f("time_s")?,
        f("axle")?,
        f("v_mps")?,
        f("p_bar")?,
        f("dv_mps")?,
        f("ddv_mps2")?,
        f("mu")?,
    );
    let vcol = df
        .column("valid")
        .map_err(|_| bad("no column valid".into()))?
        .bool()
        .map_err(table)?
        .clone();
    let valid: Vec<bool> = vcol.iter().map(|x| x.unwrap_or(false)).collect();
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
