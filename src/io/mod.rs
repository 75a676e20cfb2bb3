//! Validated CSV reading and atomic writing.
//!
//! The format is the project's contract: comma-separated, one header line naming the columns, numbers
//! elsewhere. Every error names the file, the line (1-based, the header is line 1) and, where the fault has
//! one, the column, so that a user can open the file at the right place. A `time` column, when required, must
//! increase strictly.
//!
//! [`RowReader`] checks a file row by row in memory independent of its length (one line buffer of at most
//! [`MAX_LINE_BYTES`]); [`Table`] collects the same rows into columns. Both go through the one row checker,
//! so a file that one accepts the other accepts, with the same numbers and the same messages.
//!
//! A header column may carry its unit in brackets, `y [kN]`: it answers to the name `y`, and the unit is
//! kept for the plots ([`RowReader::units`], [`Table::unit`]). Which required column is the time that must
//! increase is said by a [`TimeColumn`]: by default the one named `time` or `t`.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

mod atomic;
mod read_ahead;

pub use atomic::{AtomicFile, write_atomic};
pub use read_ahead::{Batch, READ_AHEAD_ROWS, ReadAhead};

/// The longest line accepted, in bytes (line end included): the reader's buffer never grows beyond it, so a
/// file without line ends cannot exhaust memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Buffer of the file reader behind [`RowReader::open`] and [`Table::read`].
const READ_BUFFER_BYTES: usize = 1 << 16;

/// Longest excerpt of a cell quoted in a message.
const QUOTE_CHARS: usize = 40;

/// What went wrong while reading a data file, and where.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    #[error("{file}: cannot read")]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: the file is empty (a header line naming the columns is expected)")]
    Empty { file: PathBuf },
    #[error("{file}: line 1: no column named '{column}' in the header (columns: {found})")]
    MissingColumn {
        file: PathBuf,
        column: String,
        found: String,
    },
    #[error("{file}: line 1: column '{column}' appears twice in the header")]
    DuplicateColumn { file: PathBuf, column: String },
    #[error("{file}: line {line}, byte {byte}: not valid UTF-8")]
    InvalidUtf8 {
        file: PathBuf,
        line: usize,
        /// 1-based byte offset of the first invalid byte within the line.
        byte: usize,
    },
    #[error(
        "{file}: line {line}: longer than {limit} bytes (a line end is missing, or this is not a CSV file)"
    )]
    LineTooLong {
        file: PathBuf,
        line: usize,
        limit: usize,
    },
    #[error(
        "{file}: line {line}, column {column} ('{name}'): missing: {found} fields, the header has {expected}"
    )]
    MissingField {
        file: PathBuf,
        line: usize,
        /// 1-based number of the first missing column.
        column: usize,
        name: String,
        found: usize,
        expected: usize,
    },
    #[error(
        "{file}: line {line}, column {column}: extra field '{text}': {found} fields, the header has {expected}"
    )]
    ExtraField {
        file: PathBuf,
        line: usize,
        /// 1-based number of the first field beyond the header's columns.
        column: usize,
        text: String,
        found: usize,
        expected: usize,
    },
    #[error("{file}: line {line}, column '{column}': '{text}' is not a number")]
    NotANumber {
        file: PathBuf,
        line: usize,
        column: String,
        text: String,
    },
    #[error("{file}: line {line}, column '{column}': {}", not_finite(.text, *.value))]
    NotFinite {
        file: PathBuf,
        line: usize,
        column: String,
        /// The cell as the file holds it (shortened for long cells).
        text: String,
        value: f64,
    },
    #[error(
        "{file}: line {line}, column '{column}': time {value} does not increase (previous {previous})"
    )]
    NonIncreasingTime {
        file: PathBuf,
        line: usize,
        column: String,
        value: f64,
        previous: f64,
    },
    #[error("{file}: the file has a header but no data rows")]
    NoRows { file: PathBuf },
}

/// Why the cell `text`, read as `value`, is refused: a number too large for a 64-bit float is told as such,
/// with the text the file holds.
fn not_finite(text: &str, value: f64) -> String {
    let spelled = text.trim_start_matches(['+', '-']).to_ascii_lowercase();
    if value.is_infinite() && !spelled.starts_with("inf") {
        format!("'{text}' overflows a 64-bit float (the largest is about 1.8e308)")
    } else {
        format!("'{text}' is not a finite number")
    }
}

/// Which required column is a time that must increase strictly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeColumn<'a> {
    /// The required column named `time` or `t`, if any (the default).
    #[default]
    ByName,
    /// The required column of this name.
    Named(&'a str),
}

/// A header cell split into its name and its unit: `y [kN]` is `("y", Some("kN"))`, `y` is `("y", None)`.
pub fn split_unit(cell: &str) -> (&str, Option<&str>) {
    let cell = cell.trim();
    if let Some(body) = cell.strip_suffix(']')
        && let Some(open) = body.rfind('[')
    {
        let name = body[..open].trim_end();
        let unit = body[open + 1..].trim();
        if !name.is_empty() && !unit.is_empty() {
            return (name, Some(unit));
        }
    }
    (cell, None)
}

/// `text` cut to [`QUOTE_CHARS`] characters for a message.
fn quote(text: &str) -> String {
    match text.char_indices().nth(QUOTE_CHARS) {
        Some((i, _)) => format!("{}...", &text[..i]),
        None => text.to_string(),
    }
}

/// A field as a number, exactly as `f64::from_str` reads it (the same syntax accepted, the same value): the
/// `fast-float2` parser for the finite decimal numbers that make up data files, the standard library's for
/// anything it does not take as one (then an error, an infinity or NaN, with the standard library's answer).
fn parse_number(text: &str) -> Option<f64> {
    match fast_float2::parse::<f64, _>(text) {
        Ok(v) if v.is_finite() => Some(v),
        _ => text.parse().ok(),
    }
}

/// The checks of one data row against the header: the one implementation behind [`RowReader`] and [`Table`].
#[derive(Debug, Default)]
struct RowChecker {
    file: PathBuf,
    header: Vec<String>,
    /// Header position of each required column.
    idx: Vec<usize>,
    /// Whether each required column is a time that must increase strictly.
    is_time: Vec<bool>,
    /// The unit each required column's header cell gives (`y [kN]`), if any.
    units: Vec<Option<String>>,
    /// The previous row's values (meaningful once a row was accepted).
    prev: Vec<f64>,
    has_prev: bool,
    /// Byte ranges of the fields of the current line (reused).
    spans: Vec<(usize, usize)>,
    /// For each header column, the row position it fills if it is required (see [`RowChecker::check_plain`]);
    /// empty when a column is required twice, which leaves every line to [`RowChecker::check`].
    slots: Vec<Option<usize>>,
}

impl RowChecker {
    /// Check the header line (already decoded, line end removed).
    fn new(
        file: PathBuf,
        header: &str,
        required: &[&str],
        time: TimeColumn,
    ) -> Result<RowChecker, CsvError> {
        let header: Vec<String> = header
            .trim_start_matches('\u{feff}')
            .split(',')
            .map(|s| s.trim().to_string())
            .collect();
        if header.len() == 1 && header[0].is_empty() {
            return Err(CsvError::Empty { file });
        }
        for (i, h) in header.iter().enumerate() {
            if header[..i].contains(h) {
                return Err(CsvError::DuplicateColumn {
                    file,
                    column: h.clone(),
                });
            }
        }
        let mut idx = Vec::with_capacity(required.len());
        for &name in required {
            // The cell of that name, else the one whose name before a unit is it (`y [kN]` for y).
            let exact = header.iter().position(|h| h == name);
            match exact.or_else(|| header.iter().position(|h| split_unit(h).0 == name)) {
                Some(i) => idx.push(i),
                None => {
                    return Err(CsvError::MissingColumn {
                        file,
                        column: name.to_string(),
                        found: header.join(","),
                    });
                }
            }
        }
        let is_time = required
            .iter()
            .map(|n| match time {
                TimeColumn::ByName => *n == "time" || *n == "t",
                TimeColumn::Named(t) => *n == t,
            })
            .collect();
        let units = idx
            .iter()
            .map(|&i| split_unit(&header[i]).1.map(str::to_string))
            .collect();
        Ok(RowChecker {
            file,
            spans: Vec::with_capacity(header.len() + 1),
            slots: slots(header.len(), &idx),
            header,
            idx,
            is_time,
            units,
            prev: vec![0.0; required.len()],
            has_prev: false,
        })
    }

    /// The common line read quickly: ASCII, the header's number of fields, each required field a finite number
    /// spelled without spaces, times increasing. Then its required columns are in `row` and the line is
    /// accepted (`true`), exactly as [`RowChecker::check`] would accept it with the same values (a field
    /// `fast-float2` reads to its end is one that [`parse_number`] reads to the same value). Any other line
    /// gives `false`, and the caller hands it to `check`, which decides and says why.
    fn check_plain(&mut self, line: &[u8], row: &mut [f64]) -> bool {
        if self.slots.is_empty() || !line.is_ascii() {
            return false;
        }
        let mut pos = 0;
        for (p, slot) in self.slots.iter().enumerate() {
            if p > 0 {
                if line.get(pos) != Some(&b',') {
                    return false;
                }
                pos += 1;
            }
            let rest = &line[pos..];
            pos += match slot {
                Some(c) => match fast_float2::parse_partial::<f64, _>(rest) {
                    Ok((v, n)) if v.is_finite() => {
                        row[*c] = v;
                        n
                    }
                    _ => return false,
                },
                None => rest.iter().position(|&b| b == b',').unwrap_or(rest.len()),
            };
        }
        if pos != line.len() || !self.times_increase(row) {
            return false;
        }
        self.prev.copy_from_slice(row);
        self.has_prev = true;
        true
    }

    /// A read of this checker's file that failed.
    fn io_error(&self, source: std::io::Error) -> CsvError {
        CsvError::Io {
            file: self.file.clone(),
            source,
        }
    }

    /// Whether every time column of `row` is above the previous row's.
    fn times_increase(&self, row: &[f64]) -> bool {
        !self.has_prev
            || self
                .is_time
                .iter()
                .zip(row.iter().zip(&self.prev))
                .all(|(&t, (v, p))| !t || v > p)
    }

    /// Check data line `line_no` (non-blank, line end removed) and put the required columns into `row`.
    fn check(&mut self, line_no: usize, line: &str, row: &mut [f64]) -> Result<(), CsvError> {
        // Fields by a plain byte scan: on lines of a few dozen bytes this is cheaper than `split`'s search.
        self.spans.clear();
        let mut start = 0;
        for (i, &b) in line.as_bytes().iter().enumerate() {
            if b == b',' {
                self.spans.push((start, i));
                start = i + 1;
            }
        }
        self.spans.push((start, line.len()));
        let (found, expected) = (self.spans.len(), self.header.len());
        if found < expected {
            return Err(CsvError::MissingField {
                file: self.file.clone(),
                line: line_no,
                column: found + 1,
                name: self.header[found].clone(),
                found,
                expected,
            });
        }
        if found > expected {
            let (a, b) = self.spans[expected];
            return Err(CsvError::ExtraField {
                file: self.file.clone(),
                line: line_no,
                column: expected + 1,
                text: quote(&line[a..b]),
                found,
                expected,
            });
        }
        for (c, &i) in self.idx.iter().enumerate() {
            let (a, b) = self.spans[i];
            let mut text = &line[a..b];
            // `trim` only where there is something to trim (it is a tenth of the parse otherwise).
            if text.starts_with(char::is_whitespace) || text.ends_with(char::is_whitespace) {
                text = text.trim();
            }
            let v = parse_number(text).ok_or_else(|| CsvError::NotANumber {
                file: self.file.clone(),
                line: line_no,
                column: self.header[i].clone(),
                text: quote(text),
            })?;
            if !v.is_finite() {
                return Err(CsvError::NotFinite {
                    file: self.file.clone(),
                    line: line_no,
                    column: self.header[i].clone(),
                    text: quote(text),
                    value: v,
                });
            }
            if self.is_time[c] && self.has_prev && v <= self.prev[c] {
                return Err(CsvError::NonIncreasingTime {
                    file: self.file.clone(),
                    line: line_no,
                    column: self.header[i].clone(),
                    value: v,
                    previous: self.prev[c],
                });
            }
            row[c] = v;
        }
        self.prev.copy_from_slice(row);
        self.has_prev = true;
        Ok(())
    }
}

/// A data file read and checked one row at a time, in memory independent of the file's length.
///
/// ```no_run
/// # use backlash::io::RowReader;
/// let mut rows = RowReader::open("data.csv".as_ref(), &["time", "u", "y"])?;
/// while let Some(row) = rows.next_row()? {
///     let (t, u, y) = (row[0], row[1], row[2]);
///     # let _ = (t, u, y);
/// }
/// # Ok::<(), backlash::io::CsvError>(())
/// ```
#[derive(Debug)]
pub struct RowReader<R> {
    reader: R,
    checker: RowChecker,
    /// The current line as read (at most [`MAX_LINE_BYTES`]).
    buf: Vec<u8>,
    row: Vec<f64>,
    /// Number of the line read last (1 = the header).
    line: usize,
    bytes: u64,
    rows: u64,
    done: bool,
}

impl RowReader<BufReader<File>> {
    /// Open `path` and check its header; `required` as for [`RowReader::new`].
    pub fn open(path: &Path, required: &[&str]) -> Result<Self, CsvError> {
        Self::open_with(path, required, TimeColumn::ByName)
    }

    /// [`RowReader::open`] with the time column named by `time`.
    pub fn open_with(path: &Path, required: &[&str], time: TimeColumn) -> Result<Self, CsvError> {
        let f = File::open(path).map_err(|source| CsvError::Io {
            file: path.to_path_buf(),
            source,
        })?;
        Self::new_with(
            BufReader::with_capacity(READ_BUFFER_BYTES, f),
            path,
            required,
            time,
        )
    }
}

impl<R: BufRead> RowReader<R> {
    /// Read and check the header. Each row will hold the `required` columns in that order (the header may
    /// have them in any order, and other columns, which are checked for shape only). A required column named
    /// `time` or `t` must increase strictly. `file` is only used in messages.
    pub fn new(reader: R, file: &Path, required: &[&str]) -> Result<Self, CsvError> {
        Self::new_with(reader, file, required, TimeColumn::ByName)
    }

    /// [`RowReader::new`] with the time column named by `time`.
    pub fn new_with(
        reader: R,
        file: &Path,
        required: &[&str],
        time: TimeColumn,
    ) -> Result<Self, CsvError> {
        let mut r = RowReader {
            reader,
            // Replaced by the header's checker below.
            checker: RowChecker {
                file: file.to_path_buf(),
                ..RowChecker::default()
            },
            buf: Vec::with_capacity(256),
            row: vec![0.0; required.len()],
            line: 0,
            bytes: 0,
            rows: 0,
            done: false,
        };
        if !r.read_line()? {
            return Err(CsvError::Empty {
                file: file.to_path_buf(),
            });
        }
        let header = decode(&r.buf, file, r.line)?;
        r.checker = RowChecker::new(file.to_path_buf(), header, required, time)?;
        Ok(r)
    }

    /// The next data row (the required columns, in the order asked for), `None` after the last. Blank lines
    /// are skipped. A file without any data row is an error ([`CsvError::NoRows`]), reported at its end.
    pub fn next_row(&mut self) -> Result<Option<&[f64]>, CsvError> {
        while !self.done {
            if self.next_plain()? {
                return Ok(Some(&self.row));
            }
            if !self.read_line()? {
                self.done = true;
                if self.rows == 0 {
                    return Err(CsvError::NoRows {
                        file: self.checker.file.clone(),
                    });
                }
                break;
            }
            let line = decode(&self.buf, &self.checker.file, self.line)?;
            if line.trim().is_empty() {
                continue;
            }
            self.checker.check(self.line, line, &mut self.row)?;
            self.rows += 1;
            return Ok(Some(&self.row));
        }
        Ok(None)
    }

    /// The header's column names (trimmed, without a byte-order mark).
    pub fn header(&self) -> &[String] {
        &self.checker.header
    }

    /// The unit of each required column, in the order asked for, where its header cell gives one
    /// (`y [kN]`).
    pub fn units(&self) -> &[Option<String>] {
        &self.checker.units
    }

    /// Number of the line read last (1-based; the header is line 1).
    pub fn line(&self) -> usize {
        self.line
    }

    /// Bytes consumed so far (for progress reports).
    pub fn bytes_read(&self) -> u64 {
        self.bytes
    }

    /// Data rows returned so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The next line taken where it lies in the reader's buffer, when it is whole there and the quick path
    /// accepts it ([`RowChecker::check_plain`]): then it is consumed and `row` holds it (`true`). Otherwise
    /// nothing is consumed and [`RowReader::read_line`] reads the same line the general way.
    fn next_plain(&mut self) -> Result<bool, CsvError> {
        let buffered = self
            .reader
            .fill_buf()
            .map_err(|source| self.checker.io_error(source))?;
        // A line within the length limit, line end included (as `read_line` takes it).
        let within = &buffered[..buffered.len().min(MAX_LINE_BYTES)];
        let Some(end) = memchr::memchr(b'\n', within) else {
            return Ok(false);
        };
        let line = &within[..end];
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if !self.checker.check_plain(line, &mut self.row) {
            return Ok(false);
        }
        self.reader.consume(end + 1);
        self.line += 1;
        self.bytes += end as u64 + 1;
        self.rows += 1;
        Ok(true)
    }

    /// Read the next line into `buf` without its line end; false at the end of the input.
    fn read_line(&mut self) -> Result<bool, CsvError> {
        self.buf.clear();
        let limit = MAX_LINE_BYTES as u64;
        let io = |source| self.checker.io_error(source);
        let n = (&mut self.reader)
            .take(limit)
            .read_until(b'\n', &mut self.buf)
            .map_err(io)?;
        if n == 0 {
            return Ok(false);
        }
        self.line += 1;
        self.bytes += n as u64;
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
        } else if n as u64 == limit && !self.reader.fill_buf().map_err(io)?.is_empty() {
            return Err(CsvError::LineTooLong {
                file: self.checker.file.clone(),
                line: self.line,
                limit: MAX_LINE_BYTES,
            });
        }
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        Ok(true)
    }
}

/// For each of `columns` header columns, the row position of the required column it is (`idx` gives the
/// header column of each row position); empty if `idx` names a column twice.
fn slots(columns: usize, idx: &[usize]) -> Vec<Option<usize>> {
    let mut slots = vec![None; columns];
    for (c, &i) in idx.iter().enumerate() {
        if slots[i].replace(c).is_some() {
            return Vec::new();
        }
    }
    slots
}

/// `bytes` as UTF-8, or an error naming the line and the byte.
fn decode<'a>(bytes: &'a [u8], file: &Path, line: usize) -> Result<&'a str, CsvError> {
    std::str::from_utf8(bytes).map_err(|e| CsvError::InvalidUtf8 {
        file: file.to_path_buf(),
        line,
        byte: e.valid_up_to() + 1,
    })
}

/// A numeric table: the required columns, in the order asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    names: Vec<String>,
    units: Vec<Option<String>>,
    columns: Vec<Vec<f64>>,
}

impl Table {
    /// Read `path`, keeping the `required` columns (others are ignored but must still be well-formed rows).
    /// A column named `time` or `t`, if required, must increase strictly.
    pub fn read(path: &Path, required: &[&str]) -> Result<Table, CsvError> {
        Self::collect(RowReader::open(path, required)?, required)
    }

    /// [`Table::read`] with the time column named by `time`.
    pub fn read_with(path: &Path, required: &[&str], time: TimeColumn) -> Result<Table, CsvError> {
        Self::collect(RowReader::open_with(path, required, time)?, required)
    }

    /// Parse from any reader; `file` is only used in messages.
    pub fn parse(reader: impl BufRead, file: &Path, required: &[&str]) -> Result<Table, CsvError> {
        Self::collect(RowReader::new(reader, file, required)?, required)
    }

    fn collect<R: BufRead>(mut rows: RowReader<R>, required: &[&str]) -> Result<Table, CsvError> {
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); required.len()];
        while let Some(row) = rows.next_row()? {
            for (c, v) in columns.iter_mut().zip(row) {
                c.push(*v);
            }
        }
        Ok(Table {
            names: required.iter().map(|s| s.to_string()).collect(),
            units: rows.units().to_vec(),
            columns,
        })
    }

    /// The unit a required column's header cell gives (`y [kN]`), if any.
    pub fn unit(&self, name: &str) -> Option<&str> {
        let i = self.names.iter().position(|n| n == name)?;
        self.units[i].as_deref()
    }

    /// A required column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.columns[i].as_slice())
    }

    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Table, CsvError> {
        Table::parse(text.as_bytes(), Path::new("data.csv"), &["time", "u", "y"])
    }

    /// `parse_number` gives what `str::parse::<f64>` gives, bit for bit (both refuse alike).
    fn assert_read_as_std(text: &str) {
        let (got, want) = (parse_number(text), text.parse::<f64>().ok());
        let agree = match (got, want) {
            (Some(g), Some(w)) => g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
            (g, w) => g.is_none() && w.is_none(),
        };
        assert!(agree, "{text:?}: {got:?} against {want:?}");
    }

    /// Spellings at the edges of the number syntax: signs, dots, exponents, the limits of f64, words for
    /// infinity and NaN, other radices and separators, spaces, non-ASCII digits.
    const ODD_NUMBERS: &[&str] = &[
        "0",
        "-0",
        "+0",
        "+1",
        "1.",
        ".5",
        "-.5",
        "+.5",
        ".",
        "-",
        "+",
        "",
        "1e5",
        "1E-5",
        "1e",
        "1e+",
        "1e-",
        "e5",
        ".e5",
        "1.e5",
        "1.5e308",
        "1e309",
        "-1e309",
        "4.9e-324",
        "2e-324",
        "1e-400",
        "inf",
        "-inf",
        "+inf",
        "Infinity",
        "-Infinity",
        "INF",
        "iNf",
        "infinit",
        "infinityx",
        "nan",
        "NaN",
        "-nan",
        "+nan",
        "NAN",
        "nan(1)",
        "nanx",
        "0x10",
        "1_000",
        "1,5",
        " 1",
        "1 ",
        "\t1",
        "1..2",
        "1e5.5",
        "00012",
        "-00.000",
        "0.1000000000000000055511151231257827",
        "9007199254740993",
        "123456789012345678901234567890",
        "1.7976931348623157e308",
        "1.7976931348623159e308",
        "2.2250738585072014e-308",
        "2.2250738585072011e-308",
        "1d5",
        "1f",
        "1.0f64",
        "--1",
        "+-1",
        "1e+-5",
        "1e0000000000000000000000000005",
        "0e999999",
        "\u{661}",
        "١",
        "1\u{0}",
    ];

    #[test]
    fn numbers_are_read_as_the_standard_library_reads_them() {
        use rand_core::{Rng, SeedableRng};
        let same = assert_read_as_std;
        for text in ODD_NUMBERS {
            same(text);
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..20_000 {
            let v = f64::from_bits(rng.next_u64());
            for text in [
                format!("{v}"),
                format!("{v:e}"),
                format!("{v:.3}"),
                format!("{:.17}", v * 1e-300),
            ] {
                same(&text);
            }
            same(&format!("{}", rng.next_u64() % 100_000));
        }
    }

    /// Every line the quick path takes, the full checker accepts with the same values bit for bit, whatever
    /// the fields (numbers, spaces, infinities, non-ASCII text, missing or extra fields) and the column order;
    /// a time that does not increase is left to the checker.
    #[test]
    fn the_quick_path_takes_only_lines_the_checker_accepts_with_the_same_values() {
        let fields = [
            "0", "1.5", "-.5", "+1", "1e-3", "1e309", "nan", "-inf", " 2", "2 ", "", "x", "1e",
            "1,5", "\u{661}", "0x10",
        ];
        let mut taken = 0;
        for header in ["time,extra,u,y", "y,u,extra,time"] {
            for (a, b, extra) in fields.iter().flat_map(|a| {
                fields
                    .iter()
                    .flat_map(move |b| ["z", "", "é", "1,2"].map(move |e| (a, b, e)))
            }) {
                let line = format!("{a},{extra},{b},0.25");
                let checker = || {
                    RowChecker::new("f".into(), header, &["time", "u", "y"], TimeColumn::ByName)
                        .unwrap()
                };
                let (mut quick, mut full) = (checker(), checker());
                let (mut r1, mut r2) = ([0.0; 3], [0.0; 3]);
                if quick.check_plain(line.as_bytes(), &mut r1) {
                    taken += 1;
                    assert!(full.check(2, &line, &mut r2).is_ok(), "{line:?}");
                    assert_eq!(r1.map(f64::to_bits), r2.map(f64::to_bits), "{line:?}");
                }
            }
        }
        assert!(taken >= 2 * 5 * 5, "the quick path took {taken} lines");
        let mut c = RowChecker::new(
            "f".into(),
            "time,u,y",
            &["time", "u", "y"],
            TimeColumn::ByName,
        )
        .unwrap();
        let mut row = [0.0; 3];
        assert!(c.check_plain(b"1,2,3", &mut row));
        assert!(
            !c.check_plain(b"1,2,3", &mut row),
            "a repeated time is the checker's to refuse"
        );
        assert!(c.check_plain(b"1.5,2,3", &mut row));
    }

    #[test]
    fn reads_columns_in_any_order_with_extras() {
        let t = parse("y,extra,time,u\n1,x,0,2\n3,y,0.5,4\n").unwrap();
        assert_eq!(t.column("time").unwrap(), &[0.0, 0.5]);
        assert_eq!(t.column("u").unwrap(), &[2.0, 4.0]);
        assert_eq!(t.column("y").unwrap(), &[1.0, 3.0]);
        assert_eq!(t.rows(), 2);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let msg = |t: &str| parse(t).unwrap_err().to_string();
        assert_eq!(
            msg(""),
            "data.csv: the file is empty (a header line naming the columns is expected)"
        );
        assert_eq!(
            msg("time,u,y\n"),
            "data.csv: the file has a header but no data rows"
        );
        assert!(msg("time,u\n0,1\n").contains("no column named 'y'"));
        assert_eq!(
            msg("time,u,y\n0,1,2\n1,abc,2\n"),
            "data.csv: line 3, column 'u': 'abc' is not a number"
        );
        assert_eq!(
            msg("time,u,y\n0,1,NaN\n"),
            "data.csv: line 2, column 'y': 'NaN' is not a finite number"
        );
        assert_eq!(
            msg("time,u,y\n0,1,-inf\n"),
            "data.csv: line 2, column 'y': '-inf' is not a finite number"
        );
        assert_eq!(
            msg("time,u,y\n0,1e400,1\n"),
            "data.csv: line 2, column 'u': '1e400' overflows a 64-bit float (the largest is about 1.8e308)"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2\n0,1,2\n"),
            "data.csv: line 3, column 'time': time 0 does not increase (previous 0)"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2\n1,2\n"),
            "data.csv: line 3, column 3 ('y'): missing: 2 fields, the header has 3"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2\n1,2,3,4,5\n"),
            "data.csv: line 3, column 4: extra field '4': 5 fields, the header has 3"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2,\n"),
            "data.csv: line 2, column 4: extra field '': 4 fields, the header has 3"
        );
        assert_eq!(
            msg("time,u,y\n\n0\n"),
            "data.csv: line 3, column 2 ('u'): missing: 1 fields, the header has 3"
        );
        // Ragged rows are refused in ignored columns too.
        assert_eq!(
            msg("time,u,y,note\n0,1,2\n"),
            "data.csv: line 2, column 4 ('note'): missing: 3 fields, the header has 4"
        );
    }

    #[test]
    fn units_in_the_header_and_a_named_time_column() {
        let text = "t [s],u [V],y [kN],time\n0,1,2,5\n1,3,4,4\n";
        let t = Table::parse(text.as_bytes(), Path::new("d.csv"), &["y", "u"]).unwrap();
        assert_eq!(t.column("y").unwrap(), &[2.0, 4.0]);
        assert_eq!((t.unit("y"), t.unit("u")), (Some("kN"), Some("V")));
        // `time` decreases, but it is not the time column here: `t` is, and it increases.
        let r = RowReader::new_with(
            text.as_bytes(),
            Path::new("d.csv"),
            &["t", "u", "time"],
            TimeColumn::Named("t"),
        )
        .unwrap();
        assert_eq!(
            r.units(),
            [Some("s".to_string()), Some("V".to_string()), None]
        );
        let t = Table::collect(r, &["t", "u", "time"]).unwrap();
        assert_eq!(t.column("time").unwrap(), &[5.0, 4.0]);
        // Named the other way, the decreasing column is refused.
        let e = Table::collect(
            RowReader::new_with(
                text.as_bytes(),
                Path::new("d.csv"),
                &["time"],
                TimeColumn::Named("time"),
            )
            .unwrap(),
            &["time"],
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "d.csv: line 3, column 'time': time 4 does not increase (previous 5)"
        );
        assert_eq!(split_unit(" y [ kN ] "), ("y", Some("kN")));
        assert_eq!(split_unit("[kN]"), ("[kN]", None));
        assert_eq!(split_unit("y"), ("y", None));
    }

    #[test]
    fn invalid_utf8_names_line_and_byte() {
        let msg = |b: &[u8]| {
            Table::parse(b, Path::new("data.csv"), &["time", "u", "y"])
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            msg(b"time,u,y\n0,1,2\n1,\xe9,3\n"),
            "data.csv: line 3, byte 3: not valid UTF-8"
        );
        // In the header, and in a column that is otherwise ignored.
        assert_eq!(
            msg(b"time,u,\xffy\n0,1,2\n"),
            "data.csv: line 1, byte 8: not valid UTF-8"
        );
        assert_eq!(
            msg(b"time,u,y,note\n0,1,2,ok\n1,1,2,caf\xc3\n"),
            "data.csv: line 3, byte 10: not valid UTF-8"
        );
    }

    #[test]
    fn long_cells_are_quoted_shortly_and_long_lines_refused() {
        let long = "x".repeat(1000);
        let m = parse(&format!("time,u,y\n0,{long},1\n"))
            .unwrap_err()
            .to_string();
        assert_eq!(
            m,
            format!(
                "data.csv: line 2, column 'u': '{}...' is not a number",
                "x".repeat(QUOTE_CHARS)
            )
        );
        // A line of exactly MAX_LINE_BYTES (line end included) is read; one byte more is refused.
        let pad = |n: usize| format!("0,1,2,{}", " ".repeat(n - 6));
        let head = "time,u,y,pad\n";
        let ok = format!("{head}{}\n", pad(MAX_LINE_BYTES - 1));
        assert_eq!(ok.len() - head.len(), MAX_LINE_BYTES);
        let t = Table::parse(ok.as_bytes(), Path::new("d.csv"), &["time"]).unwrap();
        assert_eq!(t.rows(), 1);
        // The same line at the end of the file without its line end.
        let ok = format!("{head}{}", pad(MAX_LINE_BYTES));
        assert!(Table::parse(ok.as_bytes(), Path::new("d.csv"), &["time"]).is_ok());
        let bad = format!("{head}{}\n1,1,2,x\n", pad(MAX_LINE_BYTES));
        let e = Table::parse(bad.as_bytes(), Path::new("d.csv"), &["time"]).unwrap_err();
        assert_eq!(
            e.to_string(),
            format!(
                "d.csv: line 2: longer than {MAX_LINE_BYTES} bytes (a line end is missing, or this is \
                 not a CSV file)"
            )
        );
    }

    #[test]
    fn read_ahead_gives_the_reader_s_rows_and_its_first_error() {
        // 2.5 batches of rows, then (in the second file) a fault: all rows before it, then its error.
        let n = READ_AHEAD_ROWS * 5 / 2;
        let mut text = String::from("time,u,y\n");
        for k in 0..n {
            text.push_str(&format!("{k},{},{}\n", k as f64 * 0.5, -(k as f64)));
        }
        let read_all = |text: String| {
            let r = RowReader::new(
                std::io::Cursor::new(text.into_bytes()),
                Path::new("data.csv"),
                &["time", "u", "y"],
            )
            .unwrap();
            let mut ahead = ReadAhead::spawn(r);
            assert_eq!(ahead.width(), 3);
            let mut values = Vec::new();
            let result = loop {
                match ahead.next_batch() {
                    Ok(Some(b)) => {
                        values.extend_from_slice(&b.values);
                        ahead.recycle(b);
                    }
                    Ok(None) => break Ok(ahead.rows()),
                    Err(e) => break Err(e),
                }
            };
            (values, result)
        };
        let (values, result) = read_all(text.clone());
        let t = parse(&text).unwrap();
        assert_eq!(result.unwrap(), Some(n as u64));
        for (c, name) in ["time", "u", "y"].into_iter().enumerate() {
            let col: Vec<f64> = values.chunks_exact(3).map(|r| r[c]).collect();
            assert_eq!(t.column(name).unwrap(), col.as_slice());
        }
        let bad = format!("{text}{n},1,oops\n{},1,1\n", n + 1);
        let (values, result) = read_all(bad.clone());
        assert_eq!(values.len(), 3 * n);
        assert_eq!(
            result.unwrap_err().to_string(),
            parse(&bad).unwrap_err().to_string()
        );
        // A consumer that stops early ends the thread (drop joins it).
        let r = RowReader::new(
            std::io::Cursor::new(text.into_bytes()),
            Path::new("data.csv"),
            &["time", "u", "y"],
        )
        .unwrap();
        let mut ahead = ReadAhead::spawn(r);
        assert!(ahead.next_batch().unwrap().is_some());
        drop(ahead);
    }

    #[test]
    fn row_reader_yields_the_rows_of_the_table() {
        let text = "\u{feff}note, y ,time,u\r\nx,1,0,2\r\n\r\n  \ny,3,0.5,4\nz,-5e-3,7,1e3\n";
        let t = parse(text).unwrap();
        let mut r =
            RowReader::new(text.as_bytes(), Path::new("data.csv"), &["time", "u", "y"]).unwrap();
        assert_eq!(r.header(), ["note", "y", "time", "u"]);
        let mut rows = Vec::new();
        let mut lines = Vec::new();
        while let Some(row) = r.next_row().unwrap() {
            rows.push(row.to_vec());
            lines.push(r.line());
        }
        assert_eq!(lines, [2, 5, 6]);
        assert_eq!(r.rows(), 3);
        assert_eq!(r.bytes_read(), text.len() as u64);
        assert!(r.next_row().unwrap().is_none());
        for (c, name) in ["time", "u", "y"].into_iter().enumerate() {
            let col: Vec<f64> = rows.iter().map(|row| row[c]).collect();
            assert_eq!(t.column(name).unwrap(), col.as_slice());
        }
        assert_eq!(t.column("y").unwrap(), &[1.0, 3.0, -5e-3]);
        // The errors are those of the table, after the rows before the fault.
        let bad = "time,u,y\n0,1,2\n1,2,3\n1,2,3\n";
        let mut r =
            RowReader::new(bad.as_bytes(), Path::new("data.csv"), &["time", "u", "y"]).unwrap();
        assert_eq!(r.next_row().unwrap(), Some(&[0.0, 1.0, 2.0][..]));
        assert_eq!(r.next_row().unwrap(), Some(&[1.0, 2.0, 3.0][..]));
        assert_eq!(
            r.next_row().unwrap_err().to_string(),
            parse(bad).unwrap_err().to_string()
        );
        // Header only: NoRows at the end, as the table.
        let mut r = RowReader::new(&b"time,u,y\n\n"[..], Path::new("data.csv"), &["time"]).unwrap();
        assert!(matches!(r.next_row(), Err(CsvError::NoRows { .. })));
    }
}
