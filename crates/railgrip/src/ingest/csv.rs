//! CSV logs: canonical (data-contract.md) or mapped through `[ingest.csv]`.
//!
//! Fast path: the header is read here, the mapped columns are read with polars as `f64`.
//! A signal's cell without a value (empty, as pandas writes a missing value, or `NaN`) is a
//! missing sample of that channel alone: the channel keeps its other rows, the hole follows
//! the gap rules of [`super::resample`] and a warning names the column and lines. Lines
//! without data (blank, separators only), which polars reads as rows of empty cells, are left
//! out.
//! Error path: when polars fails or a column holds ±inf, the time column an empty or NaN cell,
//! or a time that does not increase, [`diagnose`] rescans the file line by line to name the
//! exact line and column, counting lines as a text editor does (a quoted cell that holds a line
//! end spans two). A last row cut off by the file's end, perhaps before unmapped columns only
//! (which polars does not read), is named by [`last_record_cut_off`] first.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::sync::Arc;

use polars::prelude::*;
use rayon::prelude::*;

use super::{IngestError, Locator, LogSource, RawChannel, Warning, WarningKind};
use crate::config::{CsvColumn, IngestConfig};
use crate::format::{RunMetadata, Signal};

/// The mapped columns of a CSV log: time first, then the nine signals.
fn wanted(cfg: &IngestConfig) -> Vec<(&'static str, &CsvColumn)> {
    let mut v = vec![("time", &cfg.csv_time)];
    v.extend(Signal::ALL.iter().map(|s| (s.key(), cfg.csv_column(*s))));
    v
}

/// Splits one CSV line into trimmed fields, removing surrounding double quotes; a comma inside
/// double quotes belongs to its field, as polars reads it.
fn fields(line: &str) -> Vec<&str> {
    split_fields(line).0
}

/// [`fields`], and whether the line's quotes pair up (where they do not, it ends inside a
/// quoted field: one that spans lines, or a line cut inside one).
fn split_fields(line: &str) -> (Vec<&str>, bool) {
    fn clean(f: &str) -> &str {
        f.trim().trim_matches('"')
    }
    let mut out = Vec::new();
    let (mut quoted, mut start) = (false, 0);
    for (i, c) in line.char_indices() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => {
                out.push(clean(&line[start..i]));
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(clean(&line[start..]));
    (out, !quoted)
}

/// Longest header line read, bytes.
pub const MAX_HEADER_BYTES: u64 = 1 << 20;

fn read_header(src: &LogSource) -> Result<Vec<String>, IngestError> {
    let path = src.name();
    let f = src.open().map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let mut line = String::new();
    let mut r = BufReader::new(f.take(MAX_HEADER_BYTES));
    r.read_line(&mut line).map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    // A header over 1 MiB was once cut there and then reported as "missing columns".
    if !line.ends_with('\n') && line.len() as u64 == MAX_HEADER_BYTES {
        return Err(IngestError::CsvBadLine {
            path: path.to_path_buf(),
            line: 1,
            what: format!("the header line is longer than {MAX_HEADER_BYTES} bytes"),
            hint: "a CSV log's first line names its columns; is this a CSV log, with line ends?"
                .into(),
        });
    }
    let line = line
        .trim_start_matches('\u{feff}')
        .trim_end_matches(['\n', '\r']);
    Ok(fields(line).into_iter().map(str::to_string).collect())
}

/// A log's last record cut off by the file's end ([`last_record_cut_off`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct CutRecord {
    /// Its fields, counted as polars reads cells ([`cells`]; a field left open counts).
    fields: usize,
    /// How many lines it spans (more than one where a quoted field holds a line end).
    lines: usize,
    /// It ends inside a quoted field (one that opens with a quote and never closes).
    open: bool,
    /// The file ends with a line end (inside that open field).
    line_end: bool,
}

/// The log's last record where the file's end cut it off, else None: its last record with data
/// (one line, or several where a quoted field holds a line end; [`Records`]) either ends the
/// file without a line end with fewer fields than the header's `header_fields`, or ends inside
/// a quoted field (with or without a line end after it) — and the record with data before it
/// has all the header's fields (a file whose rows all stop short of the header's trailing
/// columns, as an export that drops trailing empty cells writes them, is read as before).
/// Fields are counted as polars reads cells ([`cells`]). A quote inside a cell's text
/// (`5" wheel`, which polars' row splitting counts and its cell reading does not) is named
/// before by [`quote_problem`]; here it leaves nothing to tell.
///
/// From the log's last 64 KiB. Where the tail holds a quote, it is read both as beginning
/// outside a quoted field and inside one; where the two differ, the quotes before the tail
/// decide. None where the tail cannot tell: an object not fetched, a last record (or the record
/// before it) that began before the tail.
fn last_record_cut_off(src: &LogSource, header_fields: usize) -> Option<CutRecord> {
    const TAIL: u64 = 64 * 1024;
    let (bytes, from): (Vec<u8>, u64) = match src {
        LogSource::File(p) => {
            use std::io::{Seek, SeekFrom};
            let mut f = crate::input::open_regular(p).ok()?;
            let len = f.metadata().ok()?.len();
            let from = len.saturating_sub(TAIL);
            f.seek(SeekFrom::Start(from)).ok()?;
            let mut b = Vec::new();
            f.take(TAIL).read_to_end(&mut b).ok()?;
            (b, from)
        }
        LogSource::Memory { bytes, .. } => {
            let from = bytes.len().saturating_sub(TAIL as usize);
            (bytes[from..].to_vec(), from as u64)
        }
        // `ingest_source` fetches an object into memory before it parses it.
        LogSource::Object { .. } => return None,
    };
    let line_end = bytes.ends_with(b"\n");
    let quoted = bytes.contains(&b'"');
    // Without a quote, a file that ends with a line end ends with a whole record.
    if line_end && !quoted {
        return None;
    }
    let text = String::from_utf8_lossy(&bytes);
    let mut lines: Vec<&str> = text.lines().collect();
    if from == 0 || lines.is_empty() {
        return tail_cut(&lines, false, header_fields, line_end);
    }
    // The tail's first line may begin mid-line: only whole lines count.
    let partial = lines.remove(0);
    let outside = tail_cut(&lines, false, header_fields, line_end);
    if !quoted {
        return outside;
    }
    let inside = tail_cut(&lines, true, header_fields, line_end);
    if inside == outside {
        return outside;
    }
    let open = (count_byte(src, from, b'"')? + partial.matches('"').count()) % 2 == 1;
    if open {
        inside
    } else {
        outside
    }
}

/// [`last_record_cut_off`] on the tail's whole `lines`, which begin inside a quoted field where
/// `open`: the rest of that record (its lines up to the one that closes the field) is left out.
fn tail_cut(
    lines: &[&str],
    mut open: bool,
    header_fields: usize,
    line_end: bool,
) -> Option<CutRecord> {
    let mut skip = 0;
    while open && skip < lines.len() {
        open ^= lines[skip].matches('"').count() % 2 == 1;
        skip += 1;
    }
    if open {
        return None;
    }
    let lines = &lines[skip..];
    let mut records: Vec<(usize, usize, String)> = Records::new(lines.iter()).collect();
    let (first, last_line, last) = records.pop()?;
    if no_data(&last) {
        return None;
    }
    let (fields, open) = cells(&last);
    let paired = split_fields(&last).1;
    // Unpaired quotes without an open quoted cell: a quote inside a cell's text, which
    // `quote_problem` names first.
    if !paired && !open {
        return None;
    }
    let cut = CutRecord {
        fields,
        lines: last_line + 1 - first,
        open: open && !paired,
        line_end,
    };
    if !cut.open && (line_end || cut.fields >= header_fields) {
        return None;
    }
    let (_, _, before) = records.iter().rev().find(|r| !no_data(&r.2))?;
    complete(before, header_fields).then_some(cut)
}

/// A record with all the header's fields, none left open.
fn complete(record: &str, header_fields: usize) -> bool {
    let (fields, open) = cells(record);
    fields >= header_fields && !open
}

/// A record's fields as polars reads cells, and whether its last is left open: a field that
/// begins with a quote (its first byte, no space before it) is quoted, and every quote in it
/// toggles its state until a comma outside the quotes ends it (`""` inside is an escaped
/// quote: it toggles twice); a quote elsewhere is text (`5" wheel`).
fn cells(record: &str) -> (usize, bool) {
    let (mut fields, mut at_start, mut quoted, mut in_quotes) = (1, true, false, false);
    for c in record.chars() {
        if at_start {
            at_start = false;
            if c == '"' {
                (quoted, in_quotes) = (true, true);
                continue;
            }
            quoted = false;
        }
        match c {
            '"' if quoted => in_quotes = !in_quotes,
            ',' if !in_quotes => {
                fields += 1;
                at_start = true;
            }
            _ => {}
        }
    }
    (fields, in_quotes)
}

/// What polars' two readings of a log's quotes say wrong ([`quote_problem`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum QuoteProblem {
    /// At the end of this line (1-based) they disagree: a quote inside a cell's text.
    Stray(usize),
    /// A quoted cell opens on this line and the file ends inside it.
    Unclosed(usize),
}

/// The first line at whose end polars' two readings of the quotes disagree, or the line where
/// a quoted cell opens that the file never closes, else None. Its row splitting toggles a
/// quoted state at every double quote (polars 0.55 `CountLines`/`SplitLines`), its cell reading
/// opens a quoted cell only at a quote that is the cell's first character ([`cells`]; polars
/// strips a UTF-8 byte-order mark first). A quote inside a cell's text (`12" wheel`) toggles the
/// first and not the second: what follows is then read as one quoted cell, and rows are merged
/// into it or split — dropped without a word where the cell lies past the last column read. A
/// cell that never closes takes every row after it the same way. Files without a quote (the
/// usual log) are only searched for one.
fn quote_problem(src: &LogSource) -> Option<QuoteProblem> {
    let mut any = false;
    scan_chunks(src, u64::MAX, |chunk| {
        any = chunk.contains(&b'"');
        !any
    })?;
    if !any {
        return None;
    }
    let mut r = BufReader::new(src.open().ok()?);
    let mut buf = Vec::new();
    let (mut row_open, mut cell_quoted, mut in_quotes, mut at_start) = (false, false, false, true);
    let (mut line, mut opened) = (0, 0);
    loop {
        buf.clear();
        if r.read_until(b'\n', &mut buf).ok()? == 0 {
            return in_quotes.then_some(QuoteProblem::Unclosed(opened));
        }
        line += 1;
        let bytes = if line == 1 {
            buf.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&buf)
        } else {
            &buf[..]
        };
        for &b in bytes {
            if b == b'"' {
                row_open = !row_open;
            }
            if at_start {
                at_start = false;
                cell_quoted = b == b'"';
                if cell_quoted {
                    in_quotes = true;
                    opened = line;
                    continue;
                }
            }
            match b {
                b'"' if cell_quoted => in_quotes = !in_quotes,
                b',' | b'\n' if !in_quotes => at_start = true,
                _ => {}
            }
        }
        if row_open != in_quotes {
            return Some(QuoteProblem::Stray(line));
        }
    }
}

/// The error for a double quote inside a cell's text on line `line` ([`quote_problem`]).
fn stray_quote(path: &Path, line: usize) -> IngestError {
    IngestError::CsvBadLine {
        path: path.to_path_buf(),
        line,
        what: "a double quote inside a cell's text (not as its first character): polars splits rows at every quote, so it reads what follows as one quoted cell and may merge, split or drop rows without a word".into(),
        hint: "write the cell quoted with its quote doubled (\"12\"\" wheel\"), as pandas' to_csv does, or remove the quote".into(),
    }
}

/// Hands the log's first `limit` bytes to `f` chunk by chunk while `f` returns true; None where
/// the log cannot be read.
fn scan_chunks(src: &LogSource, limit: u64, mut f: impl FnMut(&[u8]) -> bool) -> Option<()> {
    let mut r = BufReader::new(src.open().ok()?.take(limit));
    loop {
        let buf = r.fill_buf().ok()?;
        if buf.is_empty() || !f(buf) {
            return Some(());
        }
        let used = buf.len();
        r.consume(used);
    }
}

/// How many times `byte` occurs in the log's first `limit` bytes; None where it cannot be read.
fn count_byte(src: &LogSource, limit: u64, byte: u8) -> Option<usize> {
    let mut n = 0;
    scan_chunks(src, limit, |chunk| {
        n += chunk.iter().filter(|b| **b == byte).count();
        true
    })?;
    Some(n)
}

/// The error for a last record cut off by the file's end ([`CutRecord`]), its last line `line`
/// (1-based), with `of` fields in the header.
fn cut_off(path: &Path, line: usize, cut: CutRecord, of: usize) -> IngestError {
    let first = (line + 1).saturating_sub(cut.lines.max(1));
    let (what, delete) = if cut.lines > 1 {
        (
            format!("the last row (lines {first}–{line})"),
            format!("the incomplete last row (lines {first}–{line})"),
        )
    } else {
        (
            "the last line".to_string(),
            "the incomplete last line".to_string(),
        )
    };
    let how = match (cut.open, cut.line_end) {
        (true, true) => "ends inside a quoted field",
        (true, false) => "ends inside a quoted field, with no line end",
        (false, _) => "no line end",
    };
    let count = if cut.fields >= of {
        format!("all {of} fields, but its last")
    } else {
        format!("{} of {of} fields and", cut.fields)
    };
    IngestError::CsvBadLine {
        path: path.to_path_buf(),
        line,
        what: format!(
            "{what} has {count} {how}: the file looks cut off mid-{}",
            if cut.lines > 1 { "row" } else { "line" }
        ),
        hint: format!("the logger or copy was interrupted; delete {delete} or re-export the run"),
    }
}

/// The number of lines of the log (its last line's number, where it ends without a line end).
fn line_count(src: &LogSource) -> Option<usize> {
    Some(count_byte(src, u64::MAX, b'\n')? + 1)
}

/// Lower-case alphanumerics only, for "did you mean" suggestions.
fn normalise(s: &str) -> String {
    s.chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_lowercase()
}

/// Reads a CSV log: the header is checked against the mapped columns, polars reads those
/// columns as `f64`, each is converted to its canonical unit and checked, and the nine
/// channels share the time column.
pub(super) fn read(
    src: &LogSource,
    cfg: &IngestConfig,
) -> Result<(Vec<RawChannel>, Vec<Warning>), IngestError> {
    let path = src.name();
    let header = read_header(src)?;
    let wanted = wanted(cfg);
    check_header(path, &header, &wanted)?;
    let names: Vec<PlSmallStr> = wanted
        .iter()
        .map(|(_, c)| PlSmallStr::from(c.column.as_str()))
        .collect();
    let df = read_frame(src, cfg, &names)?;
    let extracted = extract_columns(df, &wanted, &names);
    let mut columns: Vec<(Vec<f64>, usize)> = Vec::with_capacity(wanted.len());
    for (v, (_, c)) in extracted.into_iter().zip(&wanted) {
        match v {
            Some(v) => columns.push(v),
            None => {
                return Err(diagnose(src, cfg).unwrap_or_else(|| IngestError::CsvParse {
                    path: path.to_path_buf(),
                    message: format!(
                        "column {:?} holds a value that is not finite in its unit",
                        c.column
                    ),
                }))
            }
        }
    }
    // polars reads a short row's absent fields, a blank line and a line of separators as empty
    // cells: a rescan names a short row (and anything else wrong in the file) before cells left
    // empty on purpose are read as missing samples. polars reads only the mapped columns, so a
    // last line cut off before unmapped columns alone would pass unseen, its last mapped value
    // perhaps cut short (12.3 of 12.345): the end of the file is looked at too. Before it, a
    // quote inside a cell's text, which makes polars drop rows without a word.
    let quotes = quote_problem(src);
    if let Some(QuoteProblem::Stray(line)) = quotes {
        return Err(stray_quote(path, line));
    }
    if let Some(cut) = last_record_cut_off(src, header.len()) {
        // A file that ends with a line end has its last line before it.
        let line = line_count(src)
            .unwrap_or(0)
            .saturating_sub(usize::from(cut.line_end));
        return Err(cut_off(path, line, cut, header.len()));
    }
    // A quoted cell that opened further back than the tail looked, never closed.
    if let Some(QuoteProblem::Unclosed(line)) = quotes {
        return Err(IngestError::CsvBadLine {
            path: path.to_path_buf(),
            line,
            what: "a quoted cell opens here and the file ends inside it: polars reads every row after it as part of that cell".into(),
            hint: "close the quote if it was left open, or, if the file was cut off, re-export the run".into(),
        });
    }
    if columns.iter().any(|(_, missing)| *missing > 0) {
        if let Some(e) = diagnose(src, cfg) {
            return Err(e);
        }
    }
    // The rescan found every line with data holding its time, so a row without one is a line
    // without data (blank, or separators only): left out, as `line_of_row` counts rows.
    if columns[0].1 > 0 {
        let keep: Vec<bool> = columns[0].0.iter().map(|t| !t.is_nan()).collect();
        for (v, missing) in &mut columns {
            let mut k = keep.iter();
            v.retain(|_| *k.next().expect("one flag per row"));
            *missing = v.iter().filter(|x| x.is_nan()).count();
        }
    }
    if columns[0].0.is_empty() {
        return Err(IngestError::CsvBadLine {
            path: path.to_path_buf(),
            line: 2,
            what: "the file has a header but no data rows".into(),
            hint: "the logger stopped before recording; re-export the run".into(),
        });
    }
    if let Some(((_, c), _)) = wanted
        .iter()
        .zip(&columns)
        .find(|(_, (v, missing))| v.len() - missing < 2)
    {
        return Err(IngestError::CsvParse {
            path: path.to_path_buf(),
            message: format!(
                "column {:?} has fewer than two values (its other cells are empty or NaN): is the signal mapped to the right column?",
                c.column
            ),
        });
    }
    let (time, _) = columns.remove(0);
    if time.windows(2).any(|w| w[1] <= w[0]) {
        return Err(diagnose(src, cfg).unwrap_or_else(|| IngestError::CsvParse {
            path: path.to_path_buf(),
            message: "the time column does not increase strictly".into(),
        }));
    }
    Ok(channels(src, cfg, time, columns))
}

/// Checks the header against the mapped columns: a column named twice is an error (it once
/// silently took the first), then every mapped column must be present, with "did you mean"
/// suggestions for the missing ones.
fn check_header(
    path: &Path,
    header: &[String],
    wanted: &[(&'static str, &CsvColumn)],
) -> Result<(), IngestError> {
    for (key, c) in wanted {
        let at: Vec<usize> = header
            .iter()
            .enumerate()
            .filter(|(_, h)| **h == c.column)
            .map(|(i, _)| i + 1)
            .collect();
        if at.len() > 1 {
            return Err(IngestError::CsvBadLine {
                path: path.to_path_buf(),
                line: 1,
                what: format!(
                    "column {:?} ({key}) appears {} times in the header, at positions {}",
                    c.column,
                    at.len(),
                    at.iter()
                        .map(|i| i.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                hint: "rename the columns so that each is named once, or map the signal to the one you mean under another name".into(),
            });
        }
    }
    let missing: Vec<_> = wanted
        .iter()
        .filter(|(_, c)| !header.contains(&c.column))
        .collect();
    if missing.is_empty() {
        return Ok(());
    }
    Err(IngestError::CsvMissingColumns {
        path: path.to_path_buf(),
        missing: missing
            .iter()
            .map(|(k, c)| format!("{:?} ({k})", c.column))
            .collect::<Vec<_>>()
            .join(", "),
        present: header
            .iter()
            .map(|h| format!("{h:?}"))
            .collect::<Vec<_>>()
            .join(", "),
        hint: missing_columns_hint(header, &missing),
    })
}

/// The hint for missing columns: a mapping line for every missing signal whose column name
/// resembles a header name (compared [`normalise`]d), else a generic example.
fn missing_columns_hint(header: &[String], missing: &[&(&'static str, &CsvColumn)]) -> String {
    let mut hints = Vec::new();
    for (key, c) in missing {
        let n = normalise(&c.column);
        if let Some(h) = header.iter().find(|h| {
            let hn = normalise(h);
            !hn.is_empty() && (hn == n || hn.contains(&n) || n.contains(&hn))
        }) {
            hints.push(format!(
                "{key} = {{ column = {h:?}, unit = \"{}\" }}",
                c.unit
            ));
        }
    }
    if hints.is_empty() {
        "map each signal to its column and unit in [ingest.csv] of a pipeline file (--pipeline), e.g. v_radar = { column = \"speed\", unit = \"km/h\" }".to_string()
    } else {
        format!(
            "map them in [ingest.csv] of a pipeline file (--pipeline), e.g. {}",
            hints.join("; ")
        )
    }
}

/// Reads the mapped columns `names` (each once) with polars as `f64`. A parser error or a
/// panic inside polars becomes the line-exact rescan's error or the parser's message; a
/// file with a header and no rows is an error.
fn read_frame(
    src: &LogSource,
    cfg: &IngestConfig,
    names: &[PlSmallStr],
) -> Result<DataFrame, IngestError> {
    let path = src.name();
    let mut unique = names.to_vec();
    unique.sort();
    unique.dedup();
    let schema: Schema = unique
        .iter()
        .map(|n| Field::new(n.clone(), DataType::Float64))
        .collect();
    let options = CsvReadOptions::default()
        .with_has_header(true)
        .with_columns(Some(unique.clone().into()))
        .with_schema_overwrite(Some(Arc::new(schema)));
    // polars 0.55 panics on some malformed rows (found by fuzzing: a 731-byte CSV with a row
    // cut inside a number panicked in `csv/read/builder.rs` — "slice index starts at 1 but
    // ends at 0" — and took down `railgrip run`). The panic is caught here and becomes an
    // error like polars' own: the line-exact rescan, or the parser's message.
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match src {
        LogSource::File(p) => options
            .try_into_reader_with_file_path(Some(p.clone()))
            .and_then(|r| r.finish()),
        LogSource::Memory { bytes, .. } => options
            .into_reader_with_file_handle(std::io::Cursor::new(Arc::clone(bytes)))
            .finish(),
        // `ingest_source` fetches an object before it parses it.
        LogSource::Object { .. } => Err(polars::prelude::PolarsError::ComputeError(
            "a log in a bucket is parsed after it is fetched".into(),
        )),
    }));
    let df = match read {
        Ok(Ok(df)) => df,
        Ok(Err(e)) => {
            return Err(diagnose(src, cfg).unwrap_or_else(|| IngestError::CsvParse {
                path: path.to_path_buf(),
                message: e.to_string(),
            }))
        }
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("no message");
            return Err(diagnose(src, cfg).unwrap_or_else(|| IngestError::CsvParse {
                path: path.to_path_buf(),
                message: format!("the CSV reader failed ({what})"),
            }));
        }
    };
    if df.height() == 0 {
        return Err(IngestError::CsvBadLine {
            path: path.to_path_buf(),
            line: 2,
            what: "the file has a header but no data rows".into(),
            hint: "the logger stopped before recording; re-export the run".into(),
        });
    }
    Ok(df)
}

/// Copies each mapped column out of polars' chunks (one copy, no rechunk), converting its
/// unit; columns in parallel. Each column comes with its count of cells without a value (empty
/// or NaN), which hold NaN; `None` for a column with ±inf. The frame is dropped before
/// returning, ahead of any rescan.
fn extract_columns(
    df: DataFrame,
    wanted: &[(&'static str, &CsvColumn)],
    names: &[PlSmallStr],
) -> Vec<Option<(Vec<f64>, usize)>> {
    wanted
        .par_iter()
        .enumerate()
        .map(|(i, (_, c))| {
            let ca = df
                .column(names[i].as_str())
                .and_then(|c| c.f64().cloned())
                .ok()?;
            let factor = c.unit.to_canonical_factor();
            let mut v = Vec::with_capacity(ca.len());
            for arr in ca.downcast_iter() {
                match arr.validity() {
                    None => v.extend_from_slice(arr.values()),
                    Some(valid) => {
                        v.extend(arr.values().iter().zip(valid.iter()).map(|(x, ok)| {
                            if ok {
                                *x
                            } else {
                                f64::NAN
                            }
                        }))
                    }
                }
            }
            let mut missing = 0;
            for x in &mut v {
                *x *= factor;
                if x.is_infinite() {
                    return None;
                }
                missing += usize::from(x.is_nan());
            }
            Some((v, missing))
        })
        .collect()
}

/// The nine channels of the log, in [`Signal::ALL`] order, sharing one time vector — but a
/// channel with cells without a value, which keeps its own rows with a value (with a map back
/// to the file's rows) and warns.
fn channels(
    src: &LogSource,
    cfg: &IngestConfig,
    time: Vec<f64>,
    columns: Vec<(Vec<f64>, usize)>,
) -> (Vec<RawChannel>, Vec<Warning>) {
    let time = Arc::new(time);
    let source = Arc::new(src.clone());
    let mut warnings = Vec::new();
    // Per warning: its index and its column's first and last row without a value.
    let mut ends: Vec<(usize, usize, usize)> = Vec::new();
    let channels = Signal::ALL
        .iter()
        .zip(columns)
        .map(|(s, (values, missing))| {
            let column = &cfg.csv_column(*s).column;
            let mut ch = RawChannel {
                signal: *s,
                source: format!("column {:?} [{}]", column, cfg.csv_column(*s).unit),
                time_s: Arc::clone(&time),
                values,
                locate: Locator::CsvRows(Arc::clone(&source)),
                dropped: 0,
            };
            if missing > 0 {
                let first = ch.values.iter().position(|x| x.is_nan());
                let last = ch.values.iter().rposition(|x| x.is_nan());
                if let (Some(a), Some(b)) = (first, last) {
                    ends.push((warnings.len(), a, b));
                    warnings.push(Warning {
                        kind: WarningKind::Missing,
                        message: format!(
                            "{s}: {missing} cell(s) of column {column:?} without a value (empty or NaN) read as missing samples"
                        ),
                    });
                }
                let rows: Vec<usize> = (0..ch.values.len())
                    .filter(|&i| !ch.values[i].is_nan())
                    .collect();
                ch.time_s = Arc::new(rows.iter().map(|&i| time[i]).collect());
                ch.values = rows.iter().map(|&i| ch.values[i]).collect();
                ch.locate = Locator::CsvRowsOf(Arc::clone(&source), Arc::new(rows));
            }
            ch
        })
        .collect();
    // The first and last such cell's lines, all channels' in one pass over the file.
    let rows: Vec<usize> = ends.iter().flat_map(|&(_, a, b)| [a, b]).collect();
    let lines = lines_of_rows(src, &rows);
    for (k, &(w, a, b)) in ends.iter().enumerate() {
        let (la, lb) = (lines[2 * k], lines[2 * k + 1]);
        warnings[w].message += &if a == b {
            format!(", line {la}")
        } else {
            format!(", the first at line {la}, the last at line {lb}")
        };
    }
    (channels, warnings)
}

/// What is wrong with one cell, and the hint: `None` for a number, and for a signal's empty or
/// NaN cell (a missing sample); the time column needs a finite number.
fn cell_problem(cell: &str, is_time: bool) -> Option<(String, &'static str)> {
    const TIME_HINT: &str = "every row needs its time; fill or delete this row";
    match cell.parse::<f64>() {
        _ if cell.is_empty() => is_time.then(|| ("empty cell".into(), TIME_HINT)),
        Err(_) => Some((
            format!("{cell:?} is not a number"),
            "numbers use '.' as decimal point and no thousands separator",
        )),
        Ok(x) if x.is_nan() && !is_time => None,
        Ok(x) if !x.is_finite() => Some((
            format!("{cell:?} is not a finite number"),
            if is_time {
                TIME_HINT
            } else {
                "inf is not a measurement; leave the cell empty (or NaN) for a missing sample"
            },
        )),
        Ok(_) => None,
    }
}

/// Rescans the file and returns the first problem with its line and column, or `None` if the
/// rescan finds nothing (then the caller reports polars' own message).
pub(super) fn diagnose(src: &LogSource, cfg: &IngestConfig) -> Option<IngestError> {
    let path = src.name();
    let mut bytes = Vec::new();
    src.open().ok()?.read_to_end(&mut bytes).ok()?;
    let text = String::from_utf8_lossy(&bytes);
    let ends_with_newline = text.ends_with('\n');
    let mut lines = Records::new(text.lines().map(|l| l.trim_end_matches('\r')));
    let (_, _, header_line) = lines.next()?;
    let header: Vec<String> = fields(header_line.trim_start_matches('\u{feff}'))
        .into_iter()
        .map(str::to_string)
        .collect();
    let wanted = wanted(cfg);
    let idx: Vec<(usize, &CsvColumn)> = wanted
        .iter()
        .map(|(_, c)| {
            (
                header
                    .iter()
                    .position(|h| *h == c.column)
                    .unwrap_or(usize::MAX),
                *c,
            )
        })
        .collect();
    let total_lines = text.lines().count();
    let time_col = idx[0].0;
    let time_factor = cfg.csv_time.unit.to_canonical_factor();
    let mut prev_t: Option<f64> = None;
    let bad = |line: usize, column: &str, what: String, hint: &str| IngestError::CsvBadCell {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        what,
        hint: hint.to_string(),
    };
    for (line_no, last_line_no, line) in lines {
        if no_data(&line) {
            continue;
        }
        let (f, paired) = split_fields(&line);
        // The last record, inside a quoted field or short without a line end: cut off (as
        // `last_record_cut_off` judges it).
        let (cell_count, cell_open) = cells(&line);
        let open = !paired && cell_open;
        if last_line_no == total_lines
            && (open || (!ends_with_newline && cell_count < header.len()))
        {
            let cut = CutRecord {
                fields: cell_count,
                lines: last_line_no + 1 - line_no,
                open,
                line_end: ends_with_newline,
            };
            return Some(cut_off(path, last_line_no, cut, header.len()));
        }
        // Quotes inside cells' text that pair up across cells: the row has all its cells as
        // polars reads them, but its row splitting quotes the commas between them.
        if f.len() != header.len() && cell_count == header.len() {
            return Some(stray_quote(path, line_no));
        }
        if f.len() < header.len() {
            return Some(IngestError::CsvBadLine {
                path: path.to_path_buf(),
                line: line_no,
                what: format!("{} fields, but the header has {}", f.len(), header.len()),
                hint: "every row needs all of the header's fields (leave a cell empty for a missing sample); repair or delete this row".into(),
            });
        }
        if f.len() > header.len() {
            return Some(IngestError::CsvBadLine {
                path: path.to_path_buf(),
                line: line_no,
                what: format!("{} fields, but the header has {}", f.len(), header.len()),
                hint: "check the separator: railgrip reads ',' separated values with '.' as decimal point".into(),
            });
        }
        for (j, &(col, c)) in idx.iter().enumerate() {
            if let Some((what, hint)) = cell_problem(f[col], j == 0) {
                return Some(bad(line_no, &c.column, what, hint));
            }
        }
        let t = f[time_col].parse::<f64>().ok()? * time_factor;
        if let Some(p) = prev_t {
            if t <= p {
                return Some(IngestError::TimeNotIncreasing {
                    path: path.to_path_buf(),
                    location: super::Location::CsvLine(line_no),
                    channel: format!("column {:?}", cfg.csv_time.column),
                    t_prev_s: p,
                    t_s: t,
                });
            }
        }
        prev_t = Some(t);
    }
    None
}

/// A log's records from its lines: a line whose double quotes do not pair up ends inside a
/// quoted field that holds a line end, and the record goes on over the next lines until they
/// do (or the log ends). Every quote counts, wherever it stands in its cell, as polars 0.55
/// splits a file into rows (`CountLines` and `SplitLines`: each quote character toggles the
/// quoted state), so the rows here are polars' rows. (Within a row polars opens a quoted cell
/// only at a cell's start: a stray quote inside a cell is malformed input on which its row
/// splitting and its cell reading disagree.) Each record with its first and last line's
/// 1-based numbers, its lines joined by `\n`.
struct Records<I> {
    lines: I,
    next_line: usize,
}

impl<I> Records<I> {
    fn new(lines: I) -> Self {
        Records {
            lines,
            next_line: 1,
        }
    }
}

impl<S: AsRef<str>, I: Iterator<Item = S>> Iterator for Records<I> {
    type Item = (usize, usize, String);

    fn next(&mut self) -> Option<Self::Item> {
        let first = self.lines.next()?;
        let mut text = first.as_ref().to_string();
        let start = self.next_line;
        let mut open = text.matches('"').count() % 2 == 1;
        while open {
            let Some(more) = self.lines.next() else { break };
            let more = more.as_ref();
            open ^= more.matches('"').count() % 2 == 1;
            text.push('\n');
            text.push_str(more);
            self.next_line += 1;
        }
        self.next_line += 1;
        Some((start, self.next_line - 1, text))
    }
}

/// A line without data: blank, or separators and whitespace only (polars reads it as a row of
/// empty cells; [`read`] leaves such rows out).
fn no_data(line: &str) -> bool {
    fields(line).iter().all(|f| f.is_empty())
}

/// The 1-based line of data row `row` (0-based), skipping lines without data as [`read`]
/// does: the first line of its record ([`Records`]), so a quoted cell that holds a line end
/// does not shift the lines after it.
pub(super) fn line_of_row(src: &LogSource, row: usize) -> usize {
    lines_of_rows(src, &[row])[0]
}

/// The 1-based lines of data rows `rows` (0-based, any order), in one pass over the file.
/// Where the file cannot be read again, row + 2 (a header and no lines without data).
pub(super) fn lines_of_rows(src: &LogSource, rows: &[usize]) -> Vec<usize> {
    let mut out: Vec<usize> = rows.iter().map(|r| r + 2).collect();
    if rows.is_empty() {
        return out;
    }
    let Ok(f) = src.open() else {
        return out;
    };
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by_key(|&i| rows[i]);
    let mut next = order.iter().peekable();
    let mut seen = 0usize;
    let lines = BufReader::new(f)
        .split(b'\n')
        .map_while(Result::ok)
        .map(|l| String::from_utf8_lossy(&l).into_owned());
    for (line_no, _, line) in Records::new(lines).skip(1) {
        if no_data(&line) {
            continue;
        }
        while let Some(&&k) = next.peek() {
            if rows[k] != seen {
                break;
            }
            out[k] = line_no;
            next.next();
        }
        if next.peek().is_none() {
            break;
        }
        seen += 1;
    }
    out
}

/// Reads `<stem>.meta.toml` beside a CSV log. A missing sidecar is a warning (nothing lost).
pub(super) fn read_sidecar(src: &LogSource) -> Result<(RunMetadata, Vec<Warning>), IngestError> {
    let path = src.name();
    let (sidecar, bytes) = src.sidecar().map_err(|e| IngestError::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let text = match bytes.map(String::from_utf8) {
        Some(Ok(t)) => t,
        Some(Err(_)) => {
            return Err(IngestError::Metadata {
                path: path.to_path_buf(),
                source_name: sidecar.display().to_string(),
                what: "not UTF-8 text".into(),
                hint: "the sidecar is TOML: key = value lines, e.g. ambient_temperature_c = 5.0"
                    .into(),
            })
        }
        None => {
            return Ok((
                RunMetadata::default(),
                vec![Warning {
                    kind: WarningKind::NoMetadata,
                    message: format!(
                        "no metadata: {} not found (ambient temperature, initial speed, condition unknown)",
                        sidecar.display()
                    ),
                }],
            ))
        }
    };
    let name = sidecar.display().to_string();
    let table: toml::Table = toml::from_str(&text).map_err(|e| IngestError::Metadata {
        path: path.to_path_buf(),
        source_name: name.clone(),
        what: e.to_string().trim_end().to_string(),
        hint: "the sidecar is TOML: key = value lines, e.g. ambient_temperature_c = 5.0".into(),
    })?;
    let mut pairs = BTreeMap::new();
    for (k, v) in table {
        let s = match v {
            toml::Value::String(s) => s,
            toml::Value::Float(x) => format!("{x:?}"),
            toml::Value::Integer(i) => i.to_string(),
            toml::Value::Boolean(b) => b.to_string(),
            other => {
                return Err(IngestError::Metadata {
                    path: path.to_path_buf(),
                    source_name: name,
                    what: format!(
                        "{k} is a {}, expected a number or a string",
                        other.type_str()
                    ),
                    hint: "metadata values are plain numbers or strings".into(),
                })
            }
        };
        pairs.insert(k, s);
    }
    Ok((super::metadata_from_pairs(path, &name, &pairs)?, Vec::new()))
}
