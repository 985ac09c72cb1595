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

/// One cell of a [`CsvText`] row.
#[derive(Debug, Clone, Copy)]
pub enum Cell<'a> {
    /// Free text (names, messages): always quoted, `"` doubled inside.
    Text(&'a str),
    /// An identifier (a key, a family, an architecture such as `2-10-1`): written as it is,
    /// quoted only if it holds a comma, a quote or a line break.
    Name(&'a str),
    /// A real number in Rust's shortest round-trip form (`0.1`, `1e-5`, `NaN`); `None`: empty.
    Real(Option<f64>),
    /// A count; `None`: empty.
    Count(Option<u64>),
    /// `true` or `false`.
    Flag(bool),
}

/// A small CSV table written as text (results tables such as `study.csv` and a network's
/// training history): a header row, then one line per row, `,`-separated, `\n`-terminated.
/// Write it with [`crate::atomic::write_atomically`] like any other output.
#[derive(Debug, Clone)]
pub struct CsvText {
    text: String,
    columns: usize,
}

impl CsvText {
    /// A table with these column names.
    pub fn new(header: &[&str]) -> CsvText {
        CsvText {
            text: header.join(",") + "\n",
            columns: header.len(),
        }
    }

    /// Appends a row; it must have one cell per column.
    pub fn row(&mut self, cells: &[Cell<'_>]) {
        debug_assert_eq!(cells.len(), self.columns, "one cell per column");
        for (i, c) in cells.iter().enumerate() {
            if i > 0 {
                self.text.push(',');
            }
            match *c {
                Cell::Text(t) => quoted(&mut self.text, t),
                Cell::Name(t) if t.contains([',', '"', '\n', '\r']) => quoted(&mut self.text, t),
                Cell::Name(t) => self.text.push_str(t),
                Cell::Real(Some(x)) => self.text.push_str(&format!("{x:?}")),
                Cell::Count(Some(n)) => self.text.push_str(&n.to_string()),
                Cell::Real(None) | Cell::Count(None) => {}
                Cell::Flag(b) => self.text.push_str(if b { "true" } else { "false" }),
            }
        }
        self.text.push('\n');
    }

    /// The table's text.
    pub fn into_text(self) -> String {
        self.text
    }
}

fn quoted(out: &mut String, t: &str) {
    out.push('"');
    out.push_str(&t.replace('"', "\"\""));
    out.push('"');
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_text_quotes_text_and_writes_numbers_round_trip() {
        let mut t = CsvText::new(&["key", "name", "x", "n", "ok"]);
        t.row(&[
            Cell::Name("a1"),
            Cell::Text("say \"hi\", twice"),
            Cell::Real(Some(0.1)),
            Cell::Count(None),
            Cell::Flag(true),
        ]);
        t.row(&[
            Cell::Name("b,2"),
            Cell::Text(""),
            Cell::Real(Some(f64::NAN)),
            Cell::Count(Some(7)),
            Cell::Flag(false),
        ]);
        assert_eq!(
            t.into_text(),
            "key,name,x,n,ok\na1,\"say \"\"hi\"\", twice\",0.1,,true\n\"b,2\",\"\",NaN,7,false\n"
        );
    }
}
