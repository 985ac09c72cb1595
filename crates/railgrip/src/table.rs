//! Tables out: the one writer of every Parquet and CSV table railgrip produces (run logs,
//! estimates, truth tables, campaign summaries). Parquet is zstd-compressed (polars' default
//! level); CSV has a header row. Both are written atomically ([`crate::atomic`]): a failed
//! write leaves nothing under the final name.

use std::path::{Path, PathBuf};

use polars::prelude::*;

/// A table that could not be written, with the OS or encoder error as its source.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot write: {source}")]
pub struct TableError {
    pub path: PathBuf,
    #[source]
    pub source: std::io::Error,
}

fn error(path: &Path) -> impl Fn(std::io::Error) -> TableError + '_ {
    move |source| TableError {
        path: path.to_path_buf(),
        source,
    }
}

/// Writes `df` to `path` as Parquet, with one key–value metadata pair when given.
pub fn write_parquet(
    df: &mut DataFrame,
    path: &Path,
    metadata: Option<(&str, String)>,
) -> Result<(), TableError> {
    let kv = metadata.map(|(k, v)| {
        polars::io::parquet::write::KeyValueMetadata::from_static(vec![(k.to_string(), v)])
    });
    crate::atomic::write_atomically(path, |f| {
        ParquetWriter::new(f)
            .with_compression(ParquetCompression::Zstd(None))
            .with_key_value_metadata(kv)
            .finish(df)
            .map(|_| ())
            .map_err(std::io::Error::other)
    })
    .map_err(error(path))
}

/// Writes `df` to `path` as CSV with a header row.
pub fn write_csv(df: &mut DataFrame, path: &Path) -> Result<(), TableError> {
    crate::atomic::write_atomically(path, |f| {
        CsvWriter::new(f)
            .include_header(true)
            .finish(df)
            .map_err(std::io::Error::other)
    })
    .map_err(error(path))
}

/// A data frame from columns, or the error a writer would report for `path`.
pub fn frame(height: usize, columns: Vec<Column>, path: &Path) -> Result<DataFrame, TableError> {
    DataFrame::new(height, columns).map_err(|e| TableError {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })
}

/// A column of `df` as f64 values (any numeric type cast), or why not — no such column, not
/// numeric, empty cells — as text the reader puts beside the file's name.
pub fn f64_column(df: &DataFrame, name: &str) -> Result<Vec<f64>, String> {
    let c = df
        .column(name)
        .map_err(|_| format!("no column \"{name}\""))?
        .cast(&DataType::Float64)
        .map_err(|e| format!("column \"{name}\": {e}"))?;
    let ca = c.f64().map_err(|e| e.to_string())?;
    if ca.null_count() > 0 {
        return Err(format!("column \"{name}\" has empty cells"));
    }
    Ok(ca.into_no_null_iter().collect())
}
