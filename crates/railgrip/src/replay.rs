//! `<run>.railgrip.mcap`: a run's estimates (and a model's μ replayed on them) as an MCAP file
//! that Foxglove shows beside the original log — JSON messages with JSON schemas on the topics
//! [`crate::format::REPLAY_AXLE_FIELDS`] spells, at the input's log times (`t0_ns` + t).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::estimate::{Estimates, ESTIMATE_COLUMNS};
use crate::format::{
    replay_schema, replay_topic, MCAP_MESSAGE_ENCODING, MCAP_SCHEMA_ENCODING, REPLAY_AXLE_FIELDS,
    REPLAY_SPEED_FIELD, REPLAY_SPEED_TOPIC,
};
use crate::model::Model;

const AXLES: usize = 4;

#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("{path}: cannot write the replay MCAP: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot read the estimates table for the replay: {message}. Hint: run `railgrip run --force` to estimate the run again")]
    Read { path: PathBuf, message: String },
    /// The estimates table could not be opened or decoded.
    #[error("{path}: cannot read the estimates table for the replay: {source}. Hint: run `railgrip run --force` to estimate the run again")]
    Table {
        path: PathBuf,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

/// The columns a replay writes, per sample of the run's uniform time base.
#[derive(Debug, Clone, Default)]
pub struct ReplayRun {
    /// s since t = 0 of the run.
    pub time_s: Vec<f64>,
    pub v_mps: Vec<f64>,
    /// Per axle: Δv m/s, dΔv/dt m/s², N N, T N, μ, valid.
    pub dv_mps: [Vec<f64>; AXLES],
    pub ddv_mps2: [Vec<f64>; AXLES],
    pub normal_n: [Vec<f64>; AXLES],
    pub tangential_n: [Vec<f64>; AXLES],
    pub mu: [Vec<f64>; AXLES],
    pub valid: [Vec<bool>; AXLES],
    /// Ambient temperature, °C (NaN when unknown), for 4-input models.
    pub ambient_temperature_c: f64,
}

impl ReplayRun {
    pub fn from_estimates(e: &Estimates) -> ReplayRun {
        ReplayRun {
            time_s: e.time_s.clone(),
            v_mps: e.v_mps.clone(),
            dv_mps: std::array::from_fn(|a| e.axles[a].dv_mps.clone()),
            ddv_mps2: std::array::from_fn(|a| e.axles[a].ddv_mps2.clone()),
            normal_n: std::array::from_fn(|a| e.axles[a].normal_n.clone()),
            tangential_n: std::array::from_fn(|a| e.axles[a].tangential_n.clone()),
            mu: std::array::from_fn(|a| e.axles[a].mu.clone()),
            valid: std::array::from_fn(|a| e.axles[a].valid.clone()),
            ambient_temperature_c: e.metadata.ambient_temperature_c.unwrap_or(f64::NAN),
        }
    }

    /// Reads an estimates table (the long table of [`Estimates::to_dataframe`], rows
    /// time-major, axles 1..4 in each time).
    pub fn read_parquet(
        path: &Path,
        ambient_temperature_c: Option<f64>,
    ) -> Result<ReplayRun, ReplayError> {
        use polars::prelude::*;
        let bad = |message: String| ReplayError::Read {
            path: path.to_path_buf(),
            message,
        };
        let table = |source: Box<dyn std::error::Error + Send + Sync>| ReplayError::Table {
            path: path.to_path_buf(),
            source,
        };
        let df = std::fs::File::open(path)
            .map_err(|e| table(e.into()))
            .and_then(|f| ParquetReader::new(f).finish().map_err(|e| table(e.into())))?;
        let c = ESTIMATE_COLUMNS;
        let col = |name: &str| -> Result<Vec<f64>, ReplayError> {
            let c = df
                .column(name)
                .and_then(|c| c.cast(&DataType::Float64))
                .map_err(|e| bad(format!("column {name}: {e}")))?;
            let ca = c.f64().map_err(|e| bad(format!("column {name}: {e}")))?;
            if ca.null_count() > 0 {
                return Err(bad(format!("column {name} has empty cells")));
            }
            Ok(ca.into_no_null_iter().collect())
        };
        let valid_ca = df
            .column(c[12])
            .map_err(|e| table(e.into()))?
            .bool()
            .map_err(|e| bad(format!("column {}: {e}", c[12])))?
            .clone();
        if valid_ca.null_count() > 0 {
            return Err(bad(format!("column {} has empty cells", c[12])));
        }
        let valid: Vec<bool> = valid_ca
            .downcast_iter()
            .flat_map(|arr| arr.values_iter())
            .collect();
        let axle: Vec<i32> = col(c[1])?.into_iter().map(|a| a as i32).collect();
        let n = axle.len() / AXLES;
        if !axle.len().is_multiple_of(AXLES)
            || axle
                .iter()
                .enumerate()
                .any(|(k, a)| *a != (k % AXLES) as i32 + 1)
        {
            return Err(bad(
                "rows are not time-major with axles 1..4 in each time".into()
            ));
        }
        let split = |v: &[f64]| -> [Vec<f64>; AXLES] {
            std::array::from_fn(|a| (0..n).map(|i| v[i * AXLES + a]).collect())
        };
        let time = col(c[0])?;
        let v = col(c[2])?;
        Ok(ReplayRun {
            time_s: (0..n).map(|i| time[i * AXLES]).collect(),
            v_mps: (0..n).map(|i| v[i * AXLES]).collect(),
            dv_mps: split(&col(c[5])?),
            ddv_mps2: split(&col(c[6])?),
            normal_n: split(&col(c[9])?),
            tangential_n: split(&col(c[10])?),
            mu: split(&col(c[11])?),
            valid: std::array::from_fn(|a| (0..n).map(|i| valid[i * AXLES + a]).collect()),
            ambient_temperature_c: ambient_temperature_c.unwrap_or(f64::NAN),
        })
    }
}

fn number(out: &mut String, x: f64) {
    use std::fmt::Write as _;
    if x.is_finite() {
        let _ = write!(out, "{x:?}");
    } else {
        out.push_str("null");
    }
}

/// Writes `run` (and, with `model`, its μ at every sample) to `path` atomically: zstd chunks
/// with chunk indexes, the log time of sample i = `t0_ns` + round(time_s[i]·1e9).
/// Returns the number of messages written.
pub fn write_replay(
    path: &Path,
    run: &ReplayRun,
    model: Option<&Model>,
    t0_ns: u64,
) -> Result<usize, ReplayError> {
    let err = std::io::Error::other::<mcap::McapError>;
    let mut count = 0;
    crate::atomic::write_atomically(path, |w| -> Result<(), std::io::Error> {
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("")
            .library(concat!("railgrip ", env!("CARGO_PKG_VERSION")))
            // Chunk indexes let readers seek; per-message index records (16 bytes a message,
            // uncompressed) would double the file for these one-number messages.
            .emit_message_indexes(false)
            .create(w)
            .map_err(err)?;
        let mut add =
            |topic: &str, (field, ty, what): (&str, &str, &str)| -> Result<u16, std::io::Error> {
                let schema = replay_schema(field, ty, what);
                let sid = writer
                    .add_schema(
                        &format!("railgrip.{field}"),
                        MCAP_SCHEMA_ENCODING,
                        schema.as_bytes(),
                    )
                    .map_err(err)?;
                writer
                    .add_channel(sid, topic, MCAP_MESSAGE_ENCODING, &BTreeMap::new())
                    .map_err(err)
            };
        let speed = add(REPLAY_SPEED_TOPIC, REPLAY_SPEED_FIELD)?;
        let fields = if model.is_some() {
            &REPLAY_AXLE_FIELDS[..]
        } else {
            &REPLAY_AXLE_FIELDS[..REPLAY_AXLE_FIELDS.len() - 1]
        };
        let mut channels = Vec::new();
        for a in 1..=AXLES {
            for f in fields {
                channels.push(add(&replay_topic(a, f.0), *f)?);
            }
        }
        let mut payload = String::with_capacity(64);
        let mut model_mu = [0.0; AXLES];
        for i in 0..run.time_s.len() {
            let log_time = (t0_ns as i128 + (run.time_s[i] * 1e9).round() as i128).max(0) as u64;
            let mut put = |writer: &mut mcap::Writer<_>,
                           channel: u16,
                           field: &str,
                           value: &dyn Fn(&mut String)| {
                payload.clear();
                payload.push_str("{\"");
                payload.push_str(field);
                payload.push_str("\":");
                value(&mut payload);
                payload.push('}');
                count += 1;
                writer.write_to_known_channel(
                    &mcap::records::MessageHeader {
                        channel_id: channel,
                        sequence: i as u32,
                        log_time,
                        publish_time: log_time,
                    },
                    payload.as_bytes(),
                )
            };
            put(&mut writer, speed, REPLAY_SPEED_FIELD.0, &|s| {
                number(s, run.v_mps[i])
            })
            .map_err(err)?;
            if let Some(m) = model {
                for (a, out) in model_mu.iter_mut().enumerate() {
                    let (dv, ddv) = (run.dv_mps[a][i], run.ddv_mps2[a][i]);
                    *out = if dv.is_finite() && ddv.is_finite() {
                        m.mu_vt(dv, ddv, run.v_mps[i], run.ambient_temperature_c)
                    } else {
                        f64::NAN
                    };
                }
            }
            for a in 0..AXLES {
                let ch = &channels[a * fields.len()..(a + 1) * fields.len()];
                let values = [
                    run.dv_mps[a][i],
                    run.ddv_mps2[a][i],
                    run.normal_n[a][i],
                    run.tangential_n[a][i],
                    run.mu[a][i],
                ];
                for (k, x) in values.iter().enumerate() {
                    put(&mut writer, ch[k], fields[k].0, &|s| number(s, *x)).map_err(err)?;
                }
                let valid = run.valid[a][i];
                put(&mut writer, ch[5], fields[5].0, &|s| {
                    s.push_str(if valid { "true" } else { "false" })
                })
                .map_err(err)?;
                if model.is_some() {
                    let x = model_mu[a];
                    put(&mut writer, ch[6], fields[6].0, &|s| number(s, x)).map_err(err)?;
                }
            }
        }
        writer.finish().map_err(err)?;
        Ok(())
    })
    .map_err(|source| ReplayError::Write {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(count)
}
