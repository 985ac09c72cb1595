//! What a simulation writes: the logs (`<stem>.csv` + sidecar when every sensor shares the
//! output rate, `<stem>.mcap`) through the log format's writers, so everything reads back
//! through ingest, and the truth table (`<stem>.truth.parquet`).

use std::path::{Path, PathBuf};

use super::{SimError, SimOutput};
use crate::format::{self, McapCompression, SeriesRef, Signal, AXLES};

/// A truth value as stored: float32 rounded to 16 significant bits (relative resolution
/// 2^-16 ≈ 1.5e-5; μ to ~1e-6, far below any estimator's error). The low mantissa bits of
/// simulated doubles are noise to a compressor; dropping them keeps the bundled archive small.
pub fn truth_f32(x: f64) -> f32 {
    let b = (x as f32).to_bits();
    if !(x as f32).is_finite() {
        return x as f32;
    }
    f32::from_bits(b.wrapping_add(0x80) & !0xFF)
}

/// Output formats of `railgrip simulate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    Csv,
    Mcap,
    Both,
}

/// Column names of the truth table (`<name>.truth.parquet`), one row per sample and axle:
/// `time_s` Float64, `axle` Int32 (1..4), the rest Float32 at 16 significant bits
/// ([`truth_f32`]).
pub const TRUTH_COLUMNS: [&str; 10] = [
    "time_s",
    "axle",
    "v_mps",
    "omega_radps",
    "p_bar",
    "normal_N",
    "tangential_N",
    "mu",
    "dv_mps",
    "ddv_mps2",
];

/// The truth table's extra column with the `thermal` effect: contact temperature, °C.
pub const THERMAL_COLUMN: &str = "contact_temperature_c";

impl SimOutput {
    /// Writes the run to `dir`: `<stem>.csv` + `<stem>.meta.toml` and/or `<stem>.mcap`, and
    /// `<stem>.truth.parquet`. Every file is written atomically. Returns the paths written.
    pub fn write(
        &self,
        dir: &Path,
        stem: &str,
        fmt: OutputFormat,
    ) -> Result<Vec<PathBuf>, SimError> {
        let werr = |path: &Path| {
            let path = path.to_path_buf();
            move |source: std::io::Error| SimError::Write {
                path: path.clone(),
                source,
            }
        };
        std::fs::create_dir_all(dir).map_err(werr(dir))?;
        let mut written = Vec::new();
        if matches!(fmt, OutputFormat::Csv | OutputFormat::Both) {
            if !self.scene.single_rate() {
                return Err(SimError::Scene {
                    scene: self.scene.name.clone(),
                    what: "CSV has one time column, but the scene's sensors run at different rates"
                        .into(),
                    hint: "write MCAP (--format mcap) or give every sensor the output rate".into(),
                });
            }
            let path = dir.join(format!("{stem}.csv"));
            let cols: [&[f64]; 9] = std::array::from_fn(|i| self.channels[i].values.as_slice());
            crate::atomic::write_atomically(&path, |w| {
                format::write_canonical_csv(w, &self.channels[0].time_s, cols)
            })
            .map_err(werr(&path))?;
            written.push(path);
            let side = dir.join(format!("{stem}{}", format::SIDECAR_SUFFIX));
            let text = self.metadata.to_sidecar_toml();
            crate::atomic::write_atomically(&side, |w| {
                std::io::Write::write_all(w, text.as_bytes())
            })
            .map_err(werr(&side))?;
            written.push(side);
        }
        if matches!(fmt, OutputFormat::Mcap | OutputFormat::Both) {
            let path = dir.join(format!("{stem}.mcap"));
            let series: Vec<SeriesRef> = Signal::ALL
                .iter()
                .map(|s| SeriesRef {
                    signal: *s,
                    time_s: &self.channels[s.index()].time_s,
                    values: &self.channels[s.index()].values,
                })
                .collect();
            // A fixed start time keeps the bytes identical for the same scene and seed.
            crate::atomic::write_atomically(&path, |w| {
                let mut buf = std::io::Cursor::new(Vec::new());
                format::write_mcap(
                    &mut buf,
                    &series,
                    &self.metadata,
                    McapCompression::Zstd,
                    1_700_000_000_000_000_000,
                )
                .map_err(std::io::Error::other)?;
                std::io::Write::write_all(w, buf.get_ref())
            })
            .map_err(werr(&path))?;
            written.push(path);
        }
        let path = dir.join(format!("{stem}{}", format::TRUTH_SUFFIX));
        self.write_truth(&path)?;
        written.push(path);
        Ok(written)
    }

    fn write_truth(&self, path: &Path) -> Result<(), SimError> {
        use polars::prelude::*;
        let tr = &self.truth;
        let n = tr.time_s.len();
        let long = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            (0..n)
                .flat_map(|i| (0..AXLES).map(move |a| (i, a)))
                .map(|(i, a)| f(i, a))
                .collect()
        };
        let f32col = |name: &str, f: &dyn Fn(usize, usize) -> f64| {
            Float32Chunked::from_vec(name.into(), long(f).into_iter().map(truth_f32).collect())
                .into_column()
        };
        let mut cols = vec![
            Float64Chunked::from_vec(TRUTH_COLUMNS[0].into(), long(&|i, _| tr.time_s[i]))
                .into_column(),
            Int32Chunked::from_vec(
                TRUTH_COLUMNS[1].into(),
                (0..n).flat_map(|_| 1..=AXLES as i32).collect(),
            )
            .into_column(),
            f32col(TRUTH_COLUMNS[2], &|i, _| tr.v_mps[i]),
            f32col(TRUTH_COLUMNS[3], &|i, a| tr.omega_radps[a][i]),
            f32col(TRUTH_COLUMNS[4], &|i, a| tr.p_bar[a][i]),
            f32col(TRUTH_COLUMNS[5], &|i, a| tr.normal_n[a][i]),
            f32col(TRUTH_COLUMNS[6], &|i, a| tr.tangential_n[a][i]),
            f32col(TRUTH_COLUMNS[7], &|i, a| tr.mu[a][i]),
            f32col(TRUTH_COLUMNS[8], &|i, a| tr.dv_mps[a][i]),
            f32col(TRUTH_COLUMNS[9], &|i, a| tr.ddv_mps2[a][i]),
        ];
        // With the `thermal` effect only.
        if tr.contact_temperature_c[0].len() == n {
            cols.push(f32col(THERMAL_COLUMN, &|i, a| {
                tr.contact_temperature_c[a][i]
            }));
        }
        let mut df = crate::table::frame(n * AXLES, cols, path)?;
        let mismatch = self.mismatch.as_ref().map(|m| {
            (
                TRUTH_MISMATCH_KEY,
                serde_json::to_string(m).expect("numbers serialise"),
            )
        });
        Ok(crate::table::write_parquet(&mut df, path, mismatch)?)
    }
}

/// The truth table's metadata key of a run's [`super::Mismatch`] (JSON), when the scene asked
/// for a calibration effect.
pub const TRUTH_MISMATCH_KEY: &str = "railgrip.truth";

/// Reads a truth table (`<stem>.truth.parquet`, [`TRUTH_COLUMNS`]) as scoring samples at the
/// run's ambient temperature `t_c` (°C; NaN when unknown). Errors name the file and column.
pub fn read_truth_samples(path: &Path, t_c: f64) -> Result<Vec<crate::score::Sample>, SimError> {
    use polars::prelude::*;
    let bad = |what: String| SimError::Scene {
        scene: path.display().to_string(),
        what,
        hint: "give the truth table `railgrip simulate` wrote beside the log, or remove it".into(),
    };
    let file = crate::input::open_regular(path).map_err(|e| bad(format!("cannot read: {e}")))?;
    let df = ParquetReader::new(file)
        .finish()
        .map_err(|e| bad(format!("not a Parquet table: {e}")))?;
    let col = |name: &str| crate::table::f64_column(&df, name).map_err(bad);
    let axle = col(TRUTH_COLUMNS[1])?;
    let v = col(TRUTH_COLUMNS[2])?;
    let mu = col(TRUTH_COLUMNS[7])?;
    let dv = col(TRUTH_COLUMNS[8])?;
    let ddv = col(TRUTH_COLUMNS[9])?;
    axle.iter()
        .enumerate()
        .map(|(i, &a)| {
            if !(1.0..=AXLES as f64).contains(&a) || a.fract() != 0.0 {
                return Err(bad(format!("row {i}: axle {a} is not 1..{AXLES}")));
            }
            Ok(crate::score::Sample {
                axle: a as u8,
                dv_mps: dv[i],
                ddv_mps2: ddv[i],
                v_mps: v[i],
                t_c,
                mu: mu[i],
            })
        })
        .collect()
}
