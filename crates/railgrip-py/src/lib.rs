//! The native half of the Python package `railgrip` (`railgrip._native`): thin bindings over
//! the library (logs, estimates, training, campaigns) and the lean model crate (evaluation).
//! The package's Python half (`python/railgrip/`) turns the column dictionaries returned here
//! into pandas DataFrames, broadcasts the evaluator's inputs and documents the API
//! (docs/python.md).
//!
//! Every error the library reports becomes a `railgrip.RailgripError` carrying the library's
//! message (the file, line or channel, and what to do). Long work releases the GIL.

use std::collections::BTreeMap;
use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use railgrip::campaign::{Options, Part, Quiet, Shard};
use railgrip::format::{RunMetadata, Signal};
use railgrip::identify::{EstimateColumns, RunTable};
use railgrip::ingest::RunLog;

create_exception!(
    railgrip,
    RailgripError,
    PyException,
    "An error railgrip reported: the message names the file, line or channel and says what to do."
);

/// Any library error as a `RailgripError` with its message.
fn err(e: impl std::fmt::Display) -> PyErr {
    RailgripError::new_err(e.to_string())
}

/// A checked pipeline file (`railgrip.Pipeline`).
/// A pipeline as it pickles: its text, source and the calibration it carries (JSON).
type PipelineState = (String, String, Option<String>);

#[pyclass(name = "Pipeline", module = "railgrip", frozen)]
struct PyPipeline {
    inner: railgrip::Pipeline,
}

#[pymethods]
impl PyPipeline {
    /// Reads and checks a pipeline file (TOML).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Ok(PyPipeline {
            inner: railgrip::Pipeline::load(Some(&path)).map_err(err)?,
        })
    }

    /// The embedded UIC-Z1 pipeline (what the CLI uses without `--pipeline`).
    #[staticmethod]
    fn default() -> PyResult<Self> {
        Ok(PyPipeline {
            inner: railgrip::Pipeline::load(None).map_err(err)?,
        })
    }

    /// A pipeline from its TOML text; `source` names it in errors and in the outputs'
    /// provenance (its path, for the same bytes as the file).
    #[staticmethod]
    fn from_toml(text: &str, source: &str) -> PyResult<Self> {
        Ok(PyPipeline {
            inner: railgrip::Pipeline::from_toml(text, source).map_err(err)?,
        })
    }

    /// Pickled as its text, source and the campaign calibration it carries (Ray and
    /// multiprocessing send pipelines to workers).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, PipelineState)> {
        let ctor = py.get_type::<PyPipeline>().getattr("_restore")?;
        let cal = self
            .inner
            .calibrated
            .as_ref()
            .map(|c| serde_json::to_string(c).expect("a calibration serialises"));
        Ok((
            ctor,
            (self.inner.text.clone(), self.inner.source.clone(), cal),
        ))
    }

    /// The pipeline of `__reduce__`.
    #[staticmethod]
    fn _restore(text: &str, source: &str, calibration: Option<&str>) -> PyResult<Self> {
        let mut inner = railgrip::Pipeline::from_toml(text, source).map_err(err)?;
        if let Some(c) = calibration {
            inner.calibrated = Some(serde_json::from_str(c).map_err(err)?);
        }
        Ok(PyPipeline { inner })
    }

    /// `estimate.calibration`: "auto" (the default), "pipeline", "campaign" or "dry-run".
    #[getter]
    fn calibration_source(&self) -> &'static str {
        self.inner.estimate.calibration.name()
    }

    /// The campaign calibration this pipeline carries (JSON), if any.
    #[getter]
    fn calibration(&self) -> Option<String> {
        self.inner
            .calibrated
            .as_ref()
            .map(|c| serde_json::to_string(c).expect("a calibration serialises"))
    }

    /// Where the pipeline came from (its path, or the embedded pipeline's name).
    #[getter]
    fn source(&self) -> String {
        self.inner.source.clone()
    }

    /// The pipeline file's text (TOML).
    #[getter]
    fn text(&self) -> String {
        self.inner.text.clone()
    }

    fn __repr__(&self) -> String {
        format!("railgrip.Pipeline({:?})", self.inner.source)
    }
}

/// The pipeline to use: the one given, or the embedded default.
fn pipeline_or_default(p: Option<&PyPipeline>) -> PyResult<railgrip::Pipeline> {
    match p {
        Some(p) => Ok(p.inner.clone()),
        None => railgrip::Pipeline::load(None).map_err(err),
    }
}

fn f64_array<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyAny> {
    PyArray1::from_vec(py, v).into_any()
}

/// The log at `path` (a path, file:// or s3:// location), read with `pipeline`; the error as
/// its message.
fn ingest_at(path: &str, pipeline: &railgrip::Pipeline) -> Result<RunLog, String> {
    let src = railgrip::ingest::LogSource::at(path).map_err(|e| e.to_string())?;
    railgrip::ingest::ingest_source(&src, pipeline).map_err(|e| e.to_string())
}

/// A run log's metadata, warnings and gaps as JSON (the Python half puts them in `attrs`).
fn log_info(log: &RunLog) -> serde_json::Value {
    let gaps: Vec<serde_json::Value> = log
        .gaps
        .iter()
        .map(|g| {
            serde_json::json!({
                "channel": g.signal.runlog_column(),
                "from_s": g.from_s,
                "to_s": g.to_s,
                "bridged": g.bridged,
            })
        })
        .collect();
    serde_json::json!({
        "source": log.source.display().to_string(),
        "format": log.format.to_string(),
        "sample_rate_hz": log.sample_rate_hz,
        "metadata": log.metadata.to_pairs(),
        "start_log_time_ns": log.start_log_time_ns,
        "warnings": log.warnings.iter().map(|w| w.message.clone()).collect::<Vec<_>>(),
        "gaps": gaps,
    })
}

/// Reads a log onto its uniform time base: (columns, info JSON).
#[pyfunction]
#[pyo3(signature = (path, pipeline=None))]
fn read_log<'py>(
    py: Python<'py>,
    path: String,
    pipeline: Option<&PyPipeline>,
) -> PyResult<(Bound<'py, PyDict>, String)> {
    let pipeline = pipeline_or_default(pipeline)?;
    let log = py
        .detach(|| ingest_at(&path, &pipeline))
        .map_err(RailgripError::new_err)?;
    let info = log_info(&log).to_string();
    let cols = PyDict::new(py);
    cols.set_item(
        railgrip::format::RUNLOG_TIME_COLUMN,
        f64_array(py, log.time_s.clone()),
    )?;
    for s in Signal::ALL {
        cols.set_item(s.runlog_column(), f64_array(py, log.signal(s).to_vec()))?;
    }
    cols.set_item(
        railgrip::format::RUNLOG_VALID_COLUMN,
        PyArray1::from_vec(py, log.valid.clone()),
    )?;
    Ok((cols, info))
}

/// Estimates a run: (columns of the long table, info JSON); with `calibration`, a campaign's
/// calibration.json applied as `railgrip estimate --calibration` does (refused for another
/// pipeline file or kind of calibration; a record of "none" leaves the pipeline's values).
#[pyfunction]
#[pyo3(signature = (path, pipeline=None, calibration=None))]
fn estimate<'py>(
    py: Python<'py>,
    path: String,
    pipeline: Option<&PyPipeline>,
    calibration: Option<String>,
) -> PyResult<(Bound<'py, PyDict>, String)> {
    use polars::prelude::DataType;
    use railgrip::campaign::calibration as cal;
    let mut pipeline = pipeline_or_default(pipeline)?;
    use railgrip::config::CalibrationSource;
    if let Some(file) = &calibration {
        let given = cal::read_calibration(std::path::Path::new(file)).map_err(err)?;
        cal::check_for_run(&given, &pipeline, std::path::Path::new(&path)).map_err(err)?;
        if given.source != cal::NONE_SOURCE {
            pipeline.calibrated = Some(given);
        }
    } else if pipeline.calibrated.is_none()
        && !matches!(
            pipeline.estimate.calibration,
            CalibrationSource::Auto | CalibrationSource::Pipeline
        )
    {
        return Err(RailgripError::new_err(format!(
            "{}: estimate.calibration = \"{}\" needs the campaign's calibration. Hint: give it with calibration=FILE (the calibration.json that railgrip.run or `railgrip calibrate --campaign ARCHIVE --out DIR` writes)",
            pipeline.source,
            pipeline.estimate.calibration.name()
        )));
    }
    let (log, est) = py
        .detach(|| -> Result<_, String> {
            let log = ingest_at(&path, &pipeline)?;
            let est = railgrip::estimate::estimate(&log, &pipeline).map_err(|e| e.to_string())?;
            Ok((log, est))
        })
        .map_err(RailgripError::new_err)?;
    let df = est.to_dataframe().map_err(err)?;
    let cols = PyDict::new(py);
    for c in df.columns() {
        let name = c.name().as_str();
        let s = c.as_materialized_series();
        let array = match s.dtype() {
            DataType::Float64 => f64_array(py, s.f64().map_err(err)?.into_no_null_iter().collect()),
            DataType::Int32 => {
                let v: Vec<i32> = s.i32().map_err(err)?.into_no_null_iter().collect();
                PyArray1::from_vec(py, v).into_any()
            }
            DataType::Boolean => {
                let v: Vec<bool> = s
                    .bool()
                    .map_err(err)?
                    .downcast_iter()
                    .flat_map(|arr| arr.values_iter())
                    .collect();
                PyArray1::from_vec(py, v).into_any()
            }
            other => return Err(err(format!("column {name:?} has type {other}"))),
        };
        cols.set_item(name, array)?;
    }
    let mut info = log_info(&log);
    info["filter_mode"] = serde_json::json!(match est.mode {
        railgrip::config::FilterMode::ZeroPhase => "zero-phase",
        railgrip::config::FilterMode::Causal => "causal",
    });
    info["group_delay_s"] = serde_json::json!({
        "radar": est.group_delay_s.radar_s,
        "tachometers": est.group_delay_s.tacho_s,
        "pressures": est.group_delay_s.pressure_s,
    });
    info["despiked"] = serde_json::json!(est.despiked);
    Ok((cols, info.to_string()))
}

/// A model file, checked and ready to evaluate (`railgrip.Model`).
#[pyclass(name = "Model", module = "railgrip", frozen)]
struct PyModel {
    inner: railgrip::Model,
    /// Its path, or the name it was trained under.
    name: String,
    /// The file's own text, for a model loaded from a file (an FMU carries the file as it is).
    text: Option<String>,
}

/// A 1-D float64 array's values; the Python half passes contiguous arrays.
fn slice<'a>(a: &'a PyReadonlyArray1<'_, f64>, what: &str) -> PyResult<&'a [f64]> {
    a.as_slice()
        .map_err(|_| PyValueError::new_err(format!("{what}: pass a contiguous float64 array")))
}

#[pymethods]
impl PyModel {
    /// Reads and checks a model file (`.json`, `.polach.json`).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let inner = railgrip::Model::load(&path).map_err(err)?;
        Ok(PyModel {
            inner,
            name: path.display().to_string(),
            text: std::fs::read_to_string(&path).ok(),
        })
    }

    /// μ at every element of the inputs (equal lengths; `v` and `t` may be empty: the
    /// reference values). The same bits as the Rust evaluator and the C header's networks.
    fn mu<'py>(
        &self,
        py: Python<'py>,
        dv: PyReadonlyArray1<'py, f64>,
        ddv: PyReadonlyArray1<'py, f64>,
        v: PyReadonlyArray1<'py, f64>,
        t: PyReadonlyArray1<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (dv, ddv, v, t) = (
            slice(&dv, "dv")?,
            slice(&ddv, "ddv")?,
            slice(&v, "v")?,
            slice(&t, "t")?,
        );
        let n = dv.len();
        if ddv.len() != n || !(v.is_empty() || v.len() == n) || !(t.is_empty() || t.len() == n) {
            return Err(PyValueError::new_err(format!(
                "inputs of unequal length: dv {n}, ddv {}, v {}, t {}",
                ddv.len(),
                v.len(),
                t.len()
            )));
        }
        let mut out = vec![0.0; n];
        py.detach(|| self.inner.mu_batch_t(dv, ddv, v, t, &mut out));
        Ok(PyArray1::from_vec(py, out))
    }

    /// The model file as JSON (the file's own text when loaded, the trained model's otherwise).
    #[getter]
    fn json(&self) -> String {
        self.inner.file.to_json()
    }

    /// The path it was loaded from, or its name among trained models.
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }

    /// Writes the model as an FMI 2.0 FMU at `path` (`railgrip export --fmu`): what was written,
    /// as JSON (path, model identifier, GUID, platform, variables).
    #[pyo3(signature = (path, sources_only=false))]
    fn export_fmu(&self, py: Python<'_>, path: PathBuf, sources_only: bool) -> PyResult<String> {
        let json = self
            .text
            .clone()
            .unwrap_or_else(|| self.inner.file.to_json());
        let options = railgrip::fmu::FmuOptions {
            sources_only,
            compiler: None,
        };
        let f = py
            .detach(|| {
                railgrip::fmu::export_fmu_bytes(json.as_bytes(), &self.name, &path, &options)
            })
            .map_err(err)?;
        Ok(serde_json::json!({
            "path": f.path.display().to_string(),
            "model_identifier": f.model_identifier,
            "guid": f.guid,
            "platform": f.platform,
            "size": f.size,
            "variables": f.variables.iter().map(|v| serde_json::json!({
                "name": v.name,
                "value_reference": v.value_reference,
                "unit": v.unit,
                "start": v.start,
                "description": v.description,
            })).collect::<Vec<_>>(),
        })
        .to_string())
    }

    fn __repr__(&self) -> String {
        format!(
            "railgrip.Model({:?}, {}, inputs {})",
            self.name,
            self.inner.file.architecture(),
            self.inner
                .file
                .inputs
                .iter()
                .map(|i| i.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// One input of `train`: a path (log, estimates table, folder, archive) or a table in memory
/// (run name, metadata pairs, columns).
#[derive(FromPyObject)]
enum TrainItem {
    Path(PathBuf),
    Table(
        String,
        BTreeMap<String, String>,
        BTreeMap<String, Owned<f64>>,
    ),
}

/// A column handed over from Python, copied (the tables are read once).
struct Owned<T>(Vec<T>);

impl<'a, 'py, T: numpy::Element + Copy> FromPyObject<'a, 'py> for Owned<T> {
    type Error = PyErr;

    fn extract(ob: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let a: PyReadonlyArray1<'py, T> = ob.extract()?;
        Ok(Owned(a.as_array().to_vec()))
    }
}

/// The run tables of `items`, in order; consecutive paths are read together (in parallel).
fn tables_of(
    py: Python<'_>,
    items: Vec<TrainItem>,
    pipeline: &railgrip::Pipeline,
) -> PyResult<Vec<RunTable>> {
    let mut out = Vec::new();
    let mut paths: Vec<PathBuf> = Vec::new();
    let flush = |paths: &mut Vec<PathBuf>, out: &mut Vec<RunTable>| -> PyResult<()> {
        if !paths.is_empty() {
            let p = std::mem::take(paths);
            out.extend(
                py.detach(|| railgrip::campaign::load_tables(&p, pipeline))
                    .map_err(err)?,
            );
        }
        Ok(())
    };
    for item in items {
        match item {
            TrainItem::Path(p) => paths.push(p),
            TrainItem::Table(name, meta, cols) => {
                flush(&mut paths, &mut out)?;
                out.push(table_of(&name, &meta, &cols)?);
            }
        }
    }
    flush(&mut paths, &mut out)?;
    Ok(out)
}

/// A table in memory as a run table (its metadata from the pairs `estimate` put in `attrs`).
fn table_of(
    name: &str,
    meta: &BTreeMap<String, String>,
    cols: &BTreeMap<String, Owned<f64>>,
) -> PyResult<RunTable> {
    let metadata = RunMetadata::from_pairs(meta).map_err(|e| {
        err(format!(
            "{name}: metadata {} = {:?} is not {}. Hint: fix attrs[\"metadata\"] of the table",
            e.key, e.value, e.expected
        ))
    })?;
    let col = |c: &str| -> PyResult<&[f64]> {
        cols.get(c).map(|a| a.0.as_slice()).ok_or_else(|| {
            err(format!(
                "{name}: no column {c:?}. Hint: give the table railgrip.estimate returns"
            ))
        })
    };
    // NaN (a missing cell) is not valid.
    let valid: Vec<bool> = col("valid")?.iter().map(|v| *v == 1.0).collect();
    RunTable::from_columns(
        name,
        metadata,
        &EstimateColumns {
            time_s: col("time_s")?,
            axle: col("axle")?,
            v_mps: col("v_mps")?,
            dv_mps: col("dv_mps")?,
            ddv_mps2: col("ddv_mps2")?,
            mu: col("mu")?,
            valid: &valid,
        },
    )
    .map_err(err)
}

/// Trains the campaign's models on the items: ({name: Model}, info JSON).
#[pyfunction]
#[pyo3(signature = (items, pipeline=None))]
fn train<'py>(
    py: Python<'py>,
    items: Vec<TrainItem>,
    pipeline: Option<&PyPipeline>,
) -> PyResult<(Bound<'py, PyDict>, String)> {
    let pipeline = pipeline_or_default(pipeline)?;
    let tables = tables_of(py, items, &pipeline)?;
    let models = py
        .detach(|| railgrip::campaign::train_models(tables, &pipeline, None))
        .map_err(err)?;
    let out = PyDict::new(py);
    for (name, file) in models.files() {
        let model = railgrip::Model::named(file.clone(), name).map_err(err)?;
        out.set_item(
            name,
            PyModel {
                inner: model,
                name: name.to_string(),
                text: None,
            },
        )?;
    }
    let info = serde_json::json!({
        "condition": models.condition,
        "runs": models.runs,
        "samples": models.samples,
        "skipped": models.skipped,
        "notes": models.notes,
        "chosen": models.choice.chosen,
        "choice": models.choice,
    });
    Ok((out, info.to_string()))
}

/// Runs a campaign as `railgrip run` does (the same files; paths, file:// or s3:// locations):
/// the outcome as JSON.
#[pyfunction]
#[pyo3(signature = (archive, out, pipeline=None, jobs=None, force=false, mcap=false, stage="all", shard=None))]
#[allow(clippy::too_many_arguments)]
fn run(
    py: Python<'_>,
    archive: String,
    out: String,
    pipeline: Option<&PyPipeline>,
    jobs: Option<usize>,
    force: bool,
    mcap: bool,
    stage: &str,
    shard: Option<(usize, usize)>,
) -> PyResult<String> {
    if jobs == Some(0) {
        return Err(PyValueError::new_err(
            "jobs = 0: give at least 1 (None: one per core)",
        ));
    }
    let part = match (stage, shard) {
        ("all", None) => Part::All,
        ("models", None) => Part::Models,
        ("calibrate", None) => Part::Calibrate,
        ("estimate", Some((k, n))) if k >= 1 && k <= n => Part::Estimate(Shard { k, n }),
        ("estimate", None) => Part::Estimate(Shard { k: 1, n: 1 }),
        _ => {
            return Err(PyValueError::new_err(format!(
                "stage = {stage:?}, shard = {shard:?}: give stage \"all\", \"calibrate\", \"models\", or \"estimate\" with shard = (k, n), 1 ≤ k ≤ n"
            )))
        }
    };
    let pipeline = pipeline_or_default(pipeline)?;
    let options = Options {
        jobs,
        force,
        mcap,
        part,
        tables: false,
    };
    let o = py
        .detach(|| railgrip::campaign::run_at(&archive, &out, &pipeline, options, &Quiet))
        .map_err(err)?;
    Ok(outcome_json(&o).to_string())
}

/// A campaign's outcome as the JSON the Python half turns into a `Campaign`.
fn outcome_json(o: &railgrip::campaign::Outcome) -> serde_json::Value {
    let path = |p: &PathBuf| p.display().to_string();
    serde_json::json!({
        "archive": path(&o.archive),
        "records": o.records,
        "failed": o.failed(),
        "reused": o.reused(),
        "condition": o.condition,
        "models": o.models.iter().map(path).collect::<Vec<_>>(),
        "model_error": o.model_error,
        "chosen": o.chosen_json(),
        "choice": o.choice,
        "notes": o.notes,
        "report": o.report.as_ref().map(path),
        "stages": o.stages,
        "skipped": o.skipped.iter().map(|s| serde_json::json!({"path": s.path.display().to_string(), "why": s.reason})).collect::<Vec<_>>(),
    })
}

/// The runs of a campaign (a path, file:// or s3:// location) in its order, as `run` finds
/// them with its output at `out`: (run name, its log's name, its log's location — None for a
/// member of an archive).
#[pyfunction]
#[pyo3(signature = (archive, out=None))]
fn campaign_runs(
    py: Python<'_>,
    archive: String,
    out: Option<String>,
) -> PyResult<Vec<(String, String, Option<String>)>> {
    py.detach(|| railgrip::campaign::campaign_logs_at(&archive, out.as_deref()))
        .map_err(err)
}

/// The campaign's calibration (`estimate.calibration` "auto", "campaign" or "dry-run" of
/// `pipeline`) fitted over the runs of `archive`, written as `calibration.json` into `out` (a
/// path, file:// or s3://), and the pipeline carrying it — what every estimate task is then
/// given. A pipeline with "pipeline" comes back as it is; so does one with "auto" where no
/// calibration can be fitted (fewer than 3 runs with samples for the balance, or a fit that
/// fails), and then `calibration.json` records that, and why, for the tasks.
#[pyfunction]
#[pyo3(signature = (archive, out, pipeline, jobs=None))]
fn calibrate_campaign(
    py: Python<'_>,
    archive: String,
    out: String,
    pipeline: &PyPipeline,
    jobs: Option<usize>,
) -> PyResult<PyPipeline> {
    let p = pipeline.inner.clone();
    if p.estimate.calibration.fitted().is_none() {
        return Ok(PyPipeline { inner: p });
    }
    py.detach(|| -> Result<PyPipeline, String> {
        let s = |e: &dyn std::fmt::Display| e.to_string();
        let out_at = railgrip::store::Location::parse(&out).map_err(|e| s(&e))?;
        let (root, (logs, _)) =
            railgrip::campaign::sources_at(&archive, Some(&out_at)).map_err(|e| s(&e))?;
        let options = railgrip::campaign::Options {
            jobs,
            ..Default::default()
        };
        let c = railgrip::campaign::calibration::calibrated_pipeline(
            &logs, &p, options, true, true, &root, None,
        )
        .map_err(|e| s(&e))?;
        let folder = railgrip::store::OutFolder::at(&out).map_err(|e| s(&e))?;
        std::fs::create_dir_all(folder.dir())
            .map_err(|e| format!("{}: cannot create the folder: {e}", folder.dir().display()))?;
        let written = match &c.record {
            Some(record) => {
                vec![
                    railgrip::campaign::calibration::write_calibration(folder.dir(), record)
                        .map_err(|e| s(&e))?,
                ]
            }
            None => vec![],
        };
        folder.finish(&written).map_err(|e| s(&e))?;
        Ok(PyPipeline { inner: c.pipeline })
    })
    .map_err(err)
}

/// A run table handed across: (run name, source, the log's SHA-256, metadata pairs, axle,
/// time_s, v_mps, dv_mps, ddv_mps2, mu) — the valid samples, axle by axle in time order.
type TableParts<'py> = (
    String,
    String,
    String,
    BTreeMap<String, String>,
    Bound<'py, PyArray1<u8>>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
);

/// A run table as its parts (no copy on the way out but the one into numpy arrays).
fn table_parts<'py>(py: Python<'py>, t: &RunTable) -> TableParts<'py> {
    let f = |c: &[f64]| f64_array(py, c.to_vec());
    (
        t.name.clone(),
        t.source.clone(),
        t.sha256.clone(),
        t.metadata.to_pairs(),
        PyArray1::from_slice(py, &t.axle),
        f(&t.time_s),
        f(&t.v_mps),
        f(&t.dv_mps),
        f(&t.ddv_mps2),
        f(&t.mu),
    )
}

/// The parts of a run table from Python (as `table_parts` made them), checked: equal lengths,
/// axles 1–4, metadata that parses.
#[derive(FromPyObject)]
struct GivenTable(
    String,
    String,
    String,
    BTreeMap<String, String>,
    Owned<u8>,
    Owned<f64>,
    Owned<f64>,
    Owned<f64>,
    Owned<f64>,
    Owned<f64>,
);

impl GivenTable {
    fn table(self) -> PyResult<RunTable> {
        let GivenTable(name, source, sha256, meta, axle, time_s, v, dv, ddv, mu) = self;
        let axle = axle.0;
        let n = axle.len();
        if [&time_s, &v, &dv, &ddv, &mu].iter().any(|c| c.0.len() != n) {
            return Err(err(format!(
                "{name}: the run table's columns differ in length. Hint: hand over the table the run's estimate task returned, unchanged"
            )));
        }
        if let Some(a) = axle.iter().find(|a| !(1..=4).contains(*a)) {
            return Err(err(format!(
                "{name}: axle {a} in the run table (axles are 1–4). Hint: hand over the table the run's estimate task returned, unchanged"
            )));
        }
        let metadata = RunMetadata::from_pairs(&meta).map_err(|e| {
            err(format!(
                "{name}: metadata {} = {:?} is not {}",
                e.key, e.value, e.expected
            ))
        })?;
        Ok(RunTable {
            name,
            source,
            sha256,
            metadata,
            axle: axle.into(),
            time_s: time_s.0.into(),
            v_mps: v.0.into(),
            dv_mps: dv.0.into(),
            ddv_mps2: ddv.0.into(),
            mu: mu.0.into(),
        })
    }
}

/// One run of a campaign into `out`, as an estimate shard of that run alone (`log`: its
/// location, which spares listing the campaign; None reads the archive to find it). Returns
/// (JSON {record, reused, seconds}, the run's table as parts or None for a failed run).
#[pyfunction]
#[pyo3(signature = (archive, run, log, out, pipeline=None, force=false))]
fn estimate_run<'py>(
    py: Python<'py>,
    archive: String,
    run: String,
    log: Option<String>,
    out: String,
    pipeline: Option<&PyPipeline>,
    force: bool,
) -> PyResult<(String, Option<TableParts<'py>>)> {
    let pipeline = pipeline_or_default(pipeline)?;
    let options = Options {
        jobs: Some(1),
        force,
        mcap: false,
        part: Part::Estimate(Shard { k: 1, n: 1 }),
        tables: true,
    };
    let o = py
        .detach(|| {
            railgrip::campaign::estimate_run_at(
                &archive,
                &run,
                log.as_deref(),
                &out,
                &pipeline,
                options,
                &Quiet,
            )
        })
        .map_err(err)?;
    let Some(record) = o.records.first() else {
        return Err(err(format!(
            "{run} (log {}, campaign {archive}, output {out}): no record came back for this run. Hint: check that the run's name is the campaign's (railgrip.ray lists them with _native.campaign_runs)",
            log.as_deref().unwrap_or("in the archive")
        )));
    };
    let seconds = o
        .stages
        .iter()
        .find(|(s, _)| s == "estimate")
        .map_or(0.0, |(_, t)| *t);
    let facts = serde_json::json!({"record": record, "reused": record.reused, "seconds": seconds});
    let table = o.tables.first().map(|t| table_parts(py, t));
    Ok((facts.to_string(), table))
}

/// The record JSON of run `run` (log `source`) that failed for `error` before anything was
/// known of it (a task that never finished).
#[pyfunction]
fn failed_record(run: &str, source: &str, error: String) -> String {
    serde_json::to_string(&railgrip::campaign::failed_record(run, source, Some(error)))
        .unwrap_or_default()
}

/// The runs a models part trains on, gathered one by one as their estimate tasks return them
/// (`railgrip._native.RunSet`): each table is copied in when added, so the caller can let go
/// of its own (an Arrow table in Ray's object store) before the next one arrives.
#[pyclass(name = "RunSet", module = "railgrip")]
#[derive(Default)]
struct RunSet {
    runs: Vec<(railgrip::campaign::RunRecord, Option<RunTable>)>,
}

#[pymethods]
impl RunSet {
    #[new]
    fn new() -> Self {
        RunSet::default()
    }

    /// Adds a run: its record (JSON, as `estimate_run` or `failed_record` gave it), its
    /// table's parts (None for a run without one), and how its task got it (`reused`, and the
    /// seconds it took: `timings.json` has them; the record's JSON does not).
    #[pyo3(signature = (record, table=None, reused=false, seconds=0.0))]
    fn add(
        &mut self,
        record: &str,
        table: Option<GivenTable>,
        reused: bool,
        seconds: f64,
    ) -> PyResult<()> {
        let mut rec: railgrip::campaign::RunRecord = serde_json::from_str(record)
            .map_err(|e| err(format!("a run record does not parse: {e}. Hint: hand over the record the run's estimate task returned, unchanged")))?;
        rec.reused = reused;
        rec.duration_s = seconds;
        let table = table.map(GivenTable::table).transpose()?;
        self.runs.push((rec, table));
        Ok(())
    }

    fn __len__(&self) -> usize {
        self.runs.len()
    }
}

/// The models part of a campaign trained on `runs` as their estimate tasks returned them
/// (every run of the campaign; the set is used up, also when this fails). The outcome as JSON.
#[pyfunction]
#[pyo3(signature = (archive, out, runs, pipeline=None, jobs=None, mcap=false))]
fn run_models(
    py: Python<'_>,
    archive: String,
    out: String,
    runs: &Bound<'_, RunSet>,
    pipeline: Option<&PyPipeline>,
    jobs: Option<usize>,
    mcap: bool,
) -> PyResult<String> {
    if jobs == Some(0) {
        return Err(PyValueError::new_err(
            "jobs = 0: give at least 1 (None: one per core)",
        ));
    }
    let pipeline = pipeline_or_default(pipeline)?;
    let given = std::mem::take(&mut runs.borrow_mut().runs);
    let options = Options {
        jobs,
        force: false,
        mcap,
        part: Part::Models,
        tables: false,
    };
    let o = py
        .detach(|| railgrip::campaign::models_at(&archive, &out, &pipeline, options, &Quiet, given))
        .map_err(err)?;
    Ok(outcome_json(&o).to_string())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("RailgripError", m.py().get_type::<RailgripError>())?;
    m.add_class::<PyPipeline>()?;
    m.add_class::<PyModel>()?;
    m.add_class::<RunSet>()?;
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_function(wrap_pyfunction!(estimate, m)?)?;
    m.add_function(wrap_pyfunction!(train, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(campaign_runs, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate_campaign, m)?)?;
    m.add_function(wrap_pyfunction!(estimate_run, m)?)?;
    m.add_function(wrap_pyfunction!(failed_record, m)?)?;
    m.add_function(wrap_pyfunction!(run_models, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
