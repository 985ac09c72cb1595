//! Training data for the identification: the valid estimates of each run ([`RunTable`]),
//! split into training and validation sets ([`SplitConfig`]; seed 002 trains on axle 2 and validates
//! on axle 3, pooled over the runs), decimated, and scaled by mapminmax ([`MapMinMax`]).

use std::path::Path;

use crate::config::SplitConfig;
use crate::estimate::{AxleEstimates, Estimates};
use crate::format::RunMetadata;

use super::{IdentifyError, InputSet};

/// One column of a [`RunTable`]: shared between the clones of a table, so that the model
/// choice's folds and the residual network's tables (a run set without one fold, μ replaced by
/// a residual) cost no copy of the samples. Reads as a slice; the first change to a column
/// that another table shares copies it (copy on write).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Column<T>(std::sync::Arc<Vec<T>>);

impl<T: Clone> Column<T> {
    /// Appends a value (copies the column first when another table shares it). For tests and
    /// small tables: every push checks the sharing; the library builds its columns whole
    /// (`collect`).
    pub fn push(&mut self, x: T) {
        std::sync::Arc::make_mut(&mut self.0).push(x);
    }
}

impl<T> From<Vec<T>> for Column<T> {
    fn from(v: Vec<T>) -> Self {
        Column(std::sync::Arc::new(v))
    }
}

impl<T> FromIterator<T> for Column<T> {
    fn from_iter<I: IntoIterator<Item = T>>(it: I) -> Self {
        Column(std::sync::Arc::new(it.into_iter().collect()))
    }
}

impl<T> std::ops::Deref for Column<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.0
    }
}

impl<T: Clone> std::ops::DerefMut for Column<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        std::sync::Arc::make_mut(&mut self.0).as_mut_slice()
    }
}

impl<'a, T> IntoIterator for &'a Column<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<T: serde::Serialize> serde::Serialize for Column<T> {
    /// As the sequence of its values.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.as_slice().serialize(s)
    }
}

impl<'a, T: Clone> IntoIterator for &'a mut Column<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        std::sync::Arc::make_mut(&mut self.0).iter_mut()
    }
}

/// The columns of an estimates table in memory, one row per sample and axle
/// ([`RunTable::from_columns`]); units as in the table's names.
#[derive(Debug, Clone, Copy)]
pub struct EstimateColumns<'a> {
    /// s
    pub time_s: &'a [f64],
    /// 1..=4
    pub axle: &'a [f64],
    /// m/s
    pub v_mps: &'a [f64],
    /// m/s
    pub dv_mps: &'a [f64],
    /// m/s²
    pub ddv_mps2: &'a [f64],
    /// –
    pub mu: &'a [f64],
    pub valid: &'a [bool],
}

/// Valid estimates of one run. Cloning a table shares its columns ([`Column`]).
#[derive(Debug, Clone, Default)]
pub struct RunTable {
    /// Short name (file stem).
    pub name: String,
    /// The file it came from (a log or an estimates table).
    pub source: String,
    /// SHA-256 of that file, hex.
    pub sha256: String,
    pub metadata: RunMetadata,
    pub axle: Column<u8>,
    pub time_s: Column<f64>,
    pub v_mps: Column<f64>,
    pub dv_mps: Column<f64>,
    pub ddv_mps2: Column<f64>,
    pub mu: Column<f64>,
}

/// The columns of an estimates table a [`RunTable`] reads.
const TABLE_COLUMNS: [&str; 7] = [
    "time_s", "axle", "v_mps", "dv_mps", "ddv_mps2", "mu", "valid",
];

impl RunTable {
    /// The valid samples of `e`, axle by axle in time order.
    pub fn from_estimates(name: &str, source: &str, sha256: &str, e: &Estimates) -> RunTable {
        // (axle index, sample) of every valid sample, axle by axle in time order.
        let rows: Vec<(usize, usize)> = e
            .axles
            .iter()
            .enumerate()
            .flat_map(|(a, ax)| {
                (0..e.len())
                    .filter(move |&i| ax.valid[i])
                    .map(move |i| (a, i))
            })
            .collect();
        let axle = |f: fn(&AxleEstimates) -> &[f64]| -> Column<f64> {
            rows.iter().map(|&(a, i)| f(&e.axles[a])[i]).collect()
        };
        RunTable {
            name: name.to_string(),
            source: source.to_string(),
            sha256: sha256.to_string(),
            metadata: e.metadata.clone(),
            axle: rows.iter().map(|&(a, _)| a as u8 + 1).collect(),
            time_s: rows.iter().map(|&(_, i)| e.time_s[i]).collect(),
            v_mps: rows.iter().map(|&(_, i)| e.v_mps[i]).collect(),
            dv_mps: axle(|x| &x.dv_mps),
            ddv_mps2: axle(|x| &x.ddv_mps2),
            mu: axle(|x| &x.mu),
        }
    }

    /// A run's table from columns in memory (one row per sample and axle, as `railgrip
    /// estimate` writes them; the Python package's tables): the valid rows, axle by axle in the
    /// rows' order. `name` names the run in errors and in the models' provenance, whose
    /// SHA-256 is that of the columns' bytes (the same table, the same hash). Errors name the
    /// row and column of a bad value: columns of unequal length, an axle outside 1..=4, a
    /// non-finite value in a valid row.
    pub fn from_columns(
        name: &str,
        metadata: RunMetadata,
        c: &EstimateColumns<'_>,
    ) -> Result<RunTable, IdentifyError> {
        let bad = |message: String| {
            IdentifyError::Input {
            file: name.to_string(),
            message,
            hint: "give the table `railgrip.estimate` returns (columns time_s, axle, v_mps, dv_mps, ddv_mps2, mu, valid), or its rows with invalid samples marked valid = False".into(),
        }
        };
        let n = c.valid.len();
        let named: [(&str, &[f64]); 6] = [
            ("time_s", c.time_s),
            ("axle", c.axle),
            ("v_mps", c.v_mps),
            ("dv_mps", c.dv_mps),
            ("ddv_mps2", c.ddv_mps2),
            ("mu", c.mu),
        ];
        for (col, v) in named {
            if v.len() != n {
                return Err(bad(format!(
                    "column {col:?} has {} rows, \"valid\" {n}",
                    v.len()
                )));
            }
        }
        let axles = crate::format::AXLES as u8;
        for i in (0..n).filter(|&i| c.valid[i]) {
            let a = c.axle[i];
            if !(1.0..=f64::from(axles)).contains(&a) || a.fract() != 0.0 {
                return Err(bad(format!(
                    "row {i}: axle = {a} is not one of 1..={axles}"
                )));
            }
            if let Some((col, v)) = named.iter().find(|(_, v)| !v[i].is_finite()) {
                return Err(bad(format!("row {i}: {col} = {} in a valid row", v[i])));
            }
        }
        let rows: Vec<usize> = (1..=axles)
            .flat_map(|a| (0..n).filter(move |&i| c.valid[i] && c.axle[i] == f64::from(a)))
            .collect();
        let mut bytes = Vec::with_capacity(rows.len() * 6 * 8);
        for &i in &rows {
            for (_, v) in named {
                bytes.extend_from_slice(&v[i].to_le_bytes());
            }
        }
        let col = |v: &[f64]| -> Column<f64> { rows.iter().map(|&i| v[i]).collect() };
        Ok(RunTable {
            name: name.to_string(),
            source: format!("{name} (a table in memory)"),
            sha256: crate::hash::sha256_bytes(&bytes),
            metadata,
            axle: rows.iter().map(|&i| c.axle[i] as u8).collect(),
            time_s: col(c.time_s),
            v_mps: col(c.v_mps),
            dv_mps: col(c.dv_mps),
            ddv_mps2: col(c.ddv_mps2),
            mu: col(c.mu),
        })
    }

    /// Reads the valid rows of an estimates table written by `railgrip estimate`.
    pub fn read_parquet(path: &Path) -> Result<RunTable, IdentifyError> {
        use polars::prelude::*;
        let bad = |message: String| {
            IdentifyError::Input {
            file: path.display().to_string(),
            message,
            hint: "give an estimates table written by `railgrip estimate` (or the run logs themselves)".into(),
        }
        };
        let file = crate::input::open_regular(path).map_err(|source| IdentifyError::Read {
            file: path.display().to_string(),
            source,
        })?;
        let mut reader = ParquetReader::new(file);
        let metadata = reader
            .get_metadata()
            .ok()
            .and_then(|m| m.key_value_metadata().clone())
            .and_then(|kv| {
                kv.into_iter()
                    .find(|k| k.key == crate::estimate::PARQUET_METADATA_KEY)
                    .and_then(|k| k.value)
            })
            .and_then(|text| {
                let pairs: std::collections::BTreeMap<String, String> =
                    serde_json::from_str(&text).ok()?;
                RunMetadata::from_pairs(&pairs).ok()
            })
            .unwrap_or_default();
        // Only the columns the models read, each file decoded on the calling thread: the
        // callers read many files in parallel, and a decoder waiting on its own parallel column
        // jobs would take up further files meanwhile (rayon's work stealing), holding many
        // half-read tables at once.
        let columns = reader.schema().ok().map(|s| {
            TABLE_COLUMNS
                .iter()
                .filter(|c| s.get(c).is_some())
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
        });
        let df = reader
            .with_columns(columns)
            .read_parallel(ParallelStrategy::None)
            .finish()
            .map_err(|source| IdentifyError::Table {
            file: path.display().to_string(),
            source,
            hint: "give an estimates table written by `railgrip estimate` (or the run logs themselves)".into(),
        })?;
        let f64col = |name: &str| crate::table::f64_column(&df, name).map_err(bad);
        let valid_ca = df
            .column("valid")
            .map_err(|_| bad("no column \"valid\"".into()))?
            .bool()
            .map_err(|e| bad(format!("column \"valid\": {e}")))?
            .clone();
        if valid_ca.null_count() > 0 {
            return Err(bad("column \"valid\" has empty cells".into()));
        }
        let valid: Vec<bool> = valid_ca
            .downcast_iter()
            .flat_map(|arr| arr.values_iter())
            .collect();
        let (time, axle, v, dv, ddv, mu) = (
            f64col("time_s")?,
            f64col("axle")?,
            f64col("v_mps")?,
            f64col("dv_mps")?,
            f64col("ddv_mps2")?,
            f64col("mu")?,
        );
        // Axle-major order like `from_estimates`.
        let rows: Vec<usize> = {
            let (valid, axle) = (&valid, &axle);
            (1..=crate::format::AXLES as u8)
                .flat_map(|a| {
                    (0..valid.len()).filter(move |&i| valid[i] && axle[i] == f64::from(a))
                })
                .collect()
        };
        let col = |c: &[f64]| -> self::Column<f64> { rows.iter().map(|&i| c[i]).collect() };
        let t = RunTable {
            name: path
                .file_name()
                .map(|s| {
                    s.to_string_lossy()
                        .trim_end_matches(".estimates.parquet")
                        .to_string()
                })
                .unwrap_or_default(),
            source: path.display().to_string(),
            sha256: crate::hash::sha256_file(path).map_err(|source| IdentifyError::Read {
                file: path.display().to_string(),
                source,
            })?,
            metadata,
            axle: rows.iter().map(|&i| axle[i] as u8).collect(),
            time_s: col(&time),
            v_mps: col(&v),
            dv_mps: col(&dv),
            ddv_mps2: col(&ddv),
            mu: col(&mu),
        };
        Ok(t)
    }

    /// Appends sample `i` of `other` (all columns).
    pub fn push_row(&mut self, other: &RunTable, i: usize) {
        self.axle.push(other.axle[i]);
        self.time_s.push(other.time_s[i]);
        self.v_mps.push(other.v_mps[i]);
        self.dv_mps.push(other.dv_mps[i]);
        self.ddv_mps2.push(other.ddv_mps2[i]);
        self.mu.push(other.mu[i]);
    }

    /// The same run with only the samples `keep` accepts (by index).
    pub fn subset(&self, mut keep: impl FnMut(usize) -> bool) -> RunTable {
        let rows: Vec<usize> = (0..self.len()).filter(|&i| keep(i)).collect();
        self.rows(&rows)
    }

    /// The same run with the samples at `rows` (indices, in the order given).
    fn rows(&self, rows: &[usize]) -> RunTable {
        fn pick<T: Copy>(c: &Column<T>, rows: &[usize]) -> Column<T> {
            rows.iter().map(|&i| c[i]).collect()
        }
        RunTable {
            name: self.name.clone(),
            source: self.source.clone(),
            sha256: self.sha256.clone(),
            metadata: self.metadata.clone(),
            axle: pick(&self.axle, rows),
            time_s: pick(&self.time_s, rows),
            v_mps: pick(&self.v_mps, rows),
            dv_mps: pick(&self.dv_mps, rows),
            ddv_mps2: pick(&self.ddv_mps2, rows),
            mu: pick(&self.mu, rows),
        }
    }

    /// The index ranges of the table's axles (samples of one axle are contiguous: the table
    /// is axle by axle), in order.
    pub fn axle_ranges(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let n = self.len();
        let mut start = 0;
        (1..=n)
            .filter(move |&i| i == n || self.axle[i] != self.axle[i - 1])
            .map(move |end| {
                let r = start..end;
                start = end;
                r
            })
    }

    /// Keeps every `m`-th sample of each axle (its first, then every `m`-th after it), in
    /// place, and gives the memory of the rest back. `thin(a)` then `thin(b)` keeps what
    /// `thin(a · b)` keeps.
    pub fn thin(&mut self, m: usize) {
        if m > 1 {
            let rows: Vec<usize> = self.axle_ranges().flat_map(|r| r.step_by(m)).collect();
            *self = self.rows(&rows);
        }
    }

    pub fn len(&self) -> usize {
        self.mu.len()
    }
    pub fn is_empty(&self) -> bool {
        self.mu.is_empty()
    }

    /// Appends sample `i`'s inputs; `t_c` is the run's ambient temperature (used by
    /// [`InputSet::DvDdvVT`]).
    fn input(&self, inputs: InputSet, i: usize, t_c: f64, out: &mut Vec<f64>) {
        out.push(self.dv_mps[i]);
        out.push(self.ddv_mps2[i]);
        if inputs.has_speed() {
            out.push(self.v_mps[i]);
        }
        if inputs.has_temperature() {
            out.push(t_c);
        }
    }

    /// The run's ambient temperature (metadata `ambient_temperature_c`), °C: an error naming
    /// the run when it is missing or not finite.
    pub fn ambient_temperature_c(&self) -> Result<f64, IdentifyError> {
        match self.metadata.ambient_temperature_c {
            Some(t) if t.is_finite() => Ok(t),
            _ => Err(IdentifyError::Input {
                file: self.source.clone(),
                message: "the network's inputs include ambient_temperature_c, but this run's metadata has no ambient temperature".into(),
                hint: "give the log the metadata key ambient_temperature_c (°C; docs/input-logs.md), or leave ambient_temperature_c out of [train] inputs".into(),
            }),
        }
    }
}

/// Training and validation sets in physical units; `x` is row-major, `inputs.count()` columns.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub inputs: InputSet,
    pub train_x: Vec<f64>,
    pub train_y: Vec<f64>,
    pub val_x: Vec<f64>,
    pub val_y: Vec<f64>,
}

/// A [`Dataset`] scaled as the network sees it: mapminmax fitted on the training set and
/// applied to both sets (seed 002; MATLAB's `mapminmax`).
#[derive(Debug, Clone, PartialEq)]
pub struct Normalised {
    /// Row-major inputs and targets of the training and validation sets, in [−1, 1].
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub vx: Vec<f64>,
    pub vy: Vec<f64>,
    pub x_norm: MapMinMax,
    pub y_norm: MapMinMax,
    /// Normalised MSE → μ²: (max − min)² / 4 of the training target.
    pub scale: f64,
}

impl Dataset {
    /// The sets scaled by mapminmax fitted on the training set.
    pub fn normalised(&self) -> Normalised {
        let k = self.inputs.count();
        let x_norm = MapMinMax::fit(&self.train_x, k);
        let y_norm = MapMinMax::fit(&self.train_y, 1);
        let scaled = |v: &[f64], m: &MapMinMax| {
            let mut v = v.to_vec();
            m.apply(&mut v);
            v
        };
        let (g, _) = y_norm.gain_offset(0);
        Normalised {
            x: scaled(&self.train_x, &x_norm),
            y: scaled(&self.train_y, &y_norm),
            vx: scaled(&self.val_x, &x_norm),
            vy: scaled(&self.val_y, &y_norm),
            scale: 1.0 / (g * g),
            x_norm,
            y_norm,
        }
    }

    /// The first `n` training and (at most) `n` validation samples.
    pub fn head(&self, n: usize) -> Dataset {
        let k = self.inputs.count();
        let (nt, nv) = (self.n_train().min(n), self.n_val().min(n));
        Dataset {
            inputs: self.inputs,
            train_x: self.train_x[..nt * k].to_vec(),
            train_y: self.train_y[..nt].to_vec(),
            val_x: self.val_x[..nv * k].to_vec(),
            val_y: self.val_y[..nv].to_vec(),
        }
    }

    /// Builds the sets: valid samples only (the tables hold nothing else), every `decimate`-th
    /// sample of each run and axle.
    pub fn build(
        tables: &[RunTable],
        inputs: InputSet,
        split: &SplitConfig,
        decimate: usize,
    ) -> Result<Dataset, IdentifyError> {
        let decimate = decimate.max(1);
        let mut d = Dataset {
            inputs,
            train_x: Vec::new(),
            train_y: Vec::new(),
            val_x: Vec::new(),
            val_y: Vec::new(),
        };
        for (r, t) in tables.iter().enumerate() {
            let t_c = if inputs.has_temperature() {
                t.ambient_temperature_c()?
            } else {
                f64::NAN
            };
            let mut kept = [0usize; 256];
            let t0 = t.time_s.first().copied().unwrap_or(0.0);
            for i in 0..t.len() {
                let a = t.axle[i];
                let k = &mut kept[a as usize];
                *k += 1;
                if (*k - 1) % decimate != 0 {
                    continue;
                }
                let to_val = match split {
                    SplitConfig::Axles { train, val } => {
                        if val.contains(&a) {
                            Some(true)
                        } else if train.contains(&a) {
                            Some(false)
                        } else {
                            None
                        }
                    }
                    SplitConfig::Runs { every } => Some(*every > 0 && r % every == every - 1),
                    SplitConfig::Blocks { block_s, every } => {
                        let b = ((t.time_s[i] - t0) / block_s).floor() as usize;
                        Some(*every > 0 && b % every == every - 1)
                    }
                };
                match to_val {
                    Some(true) => {
                        t.input(inputs, i, t_c, &mut d.val_x);
                        d.val_y.push(t.mu[i]);
                    }
                    Some(false) => {
                        t.input(inputs, i, t_c, &mut d.train_x);
                        d.train_y.push(t.mu[i]);
                    }
                    None => {}
                }
            }
        }
        if d.train_y.is_empty() {
            return Err(IdentifyError::Data {
                what: format!("no valid samples for training ({split:?}) in {} run(s)", tables.len()),
                hint: "check that the runs brake with slip (railgrip estimate prints valid samples per axle) and that [train] split names axles that exist".into(),
            });
        }
        Ok(d)
    }

    pub fn n_train(&self) -> usize {
        self.train_y.len()
    }
    pub fn n_val(&self) -> usize {
        self.val_y.len()
    }
}

/// MATLAB `mapminmax` to [−1, 1] per row: y = 2 (x − min)/(max − min) − 1; a constant row
/// passes through unchanged (range 0 → identity).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MapMinMax {
    pub min: Vec<f64>,
    pub max: Vec<f64>,
}

impl MapMinMax {
    /// Fits the ranges of the columns of row-major `x` with `k` columns.
    pub fn fit(x: &[f64], k: usize) -> MapMinMax {
        let mut min = vec![f64::INFINITY; k];
        let mut max = vec![f64::NEG_INFINITY; k];
        for row in x.chunks_exact(k) {
            for c in 0..k {
                min[c] = min[c].min(row[c]);
                max[c] = max[c].max(row[c]);
            }
        }
        MapMinMax { min, max }
    }

    /// (gain, offset) of column `c`: y = gain·x + offset.
    #[inline]
    pub fn gain_offset(&self, c: usize) -> (f64, f64) {
        let range = self.max[c] - self.min[c];
        if range > 0.0 && range.is_finite() {
            let g = 2.0 / range;
            (g, -1.0 - g * self.min[c])
        } else {
            (1.0, 0.0)
        }
    }

    /// Scales row-major `x` in place.
    pub fn apply(&self, x: &mut [f64]) {
        let k = self.min.len();
        let go: Vec<(f64, f64)> = (0..k).map(|c| self.gain_offset(c)).collect();
        for row in x.chunks_exact_mut(k) {
            for c in 0..k {
                row[c] = go[c].0 * row[c] + go[c].1;
            }
        }
    }

    /// Inverse of `apply` for column `c`.
    #[inline]
    pub fn reverse(&self, c: usize, y: f64) -> f64 {
        let (g, o) = self.gain_offset(c);
        (y - o) / g
    }
}
