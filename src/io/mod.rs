//! Validated CSV reading and atomic writing.
//!
//! The format is the project's contract: comma-separated, one header line naming the columns, numbers
//! elsewhere. Every error names the file, the line (1-based, the header is line 1) and the column, so that
//! a user can open the file at the right place. A `time` column, when required, must increase strictly.

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};

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
    #[error("{file}: line {line}: {found} fields, the header has {expected}")]
    Ragged {
        file: PathBuf,
        line: usize,
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
    #[error("{file}: line {line}, column '{column}': {value} is not a finite number")]
    NotFinite {
        file: PathBuf,
        line: usize,
        column: String,
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

/// A numeric table: the required columns, in the order asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    names: Vec<String>,
    columns: Vec<Vec<f64>>,
}

impl Table {
    /// Read `path`, keeping the `required` columns (others are ignored but must still be well-formed rows).
    /// A column named `time` or `t`, if required, must increase strictly.
    pub fn read(path: &Path, required: &[&str]) -> Result<Table, CsvError> {
        let file = path.to_path_buf();
        let f = File::open(path).map_err(|source| CsvError::Io {
            file: file.clone(),
            source,
        })?;
        Self::parse(BufReader::new(f), &file, required)
    }

    /// Parse from any reader; `file` is only used in messages.
    pub fn parse(reader: impl BufRead, file: &Path, required: &[&str]) -> Result<Table, CsvError> {
        let file = file.to_path_buf();
        let io = |source| CsvError::Io {
            file: file.clone(),
            source,
        };
        let mut lines = reader.lines();
        let header = match lines.next() {
            None => return Err(CsvError::Empty { file }),
            Some(l) => l.map_err(io)?,
        };
        let header: Vec<String> = header
            .trim_start_matches('\u{feff}')
            .trim_end_matches('\r')
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
            match header.iter().position(|h| h == name) {
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
        let mut columns: Vec<Vec<f64>> = vec![Vec::new(); required.len()];
        let is_time: Vec<bool> = required.iter().map(|n| *n == "time" || *n == "t").collect();
        for (n, line) in lines.enumerate() {
            let line_no = n + 2;
            let line = line.map_err(io)?;
            let line = line.trim_end_matches('\r');
            if line.trim().is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != header.len() {
                return Err(CsvError::Ragged {
                    file,
                    line: line_no,
                    found: fields.len(),
                    expected: header.len(),
                });
            }
            for (c, &i) in idx.iter().enumerate() {
                let text = fields[i].trim();
                let v: f64 = text.parse().map_err(|_| CsvError::NotANumber {
                    file: file.clone(),
                    line: line_no,
                    column: header[i].clone(),
                    text: text.to_string(),
                })?;
                if !v.is_finite() {
                    return Err(CsvError::NotFinite {
                        file,
                        line: line_no,
                        column: header[i].clone(),
                        value: v,
                    });
                }
                if is_time[c]
                    && let Some(&prev) = columns[c].last()
                    && v <= prev
                {
                    return Err(CsvError::NonIncreasingTime {
                        file,
                        line: line_no,
                        column: header[i].clone(),
                        value: v,
                        previous: prev,
                    });
                }
                columns[c].push(v);
            }
        }
        if columns.first().is_none_or(|c| c.is_empty()) {
            return Err(CsvError::NoRows { file });
        }
        Ok(Table {
            names: required.iter().map(|s| s.to_string()).collect(),
            columns,
        })
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

/// Write a file atomically: the content goes to a temporary file beside the target, which is renamed over
/// the target only when everything was written. A failed run leaves no half-written result.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let tmp = dir.join(format!(".{name}.tmp{}", std::process::id()));
    let result = (|| {
        let f = File::create(&tmp)?;
        let mut w = std::io::BufWriter::new(f);
        write(&mut w)?;
        w.flush()?;
        w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Table, CsvError> {
        Table::parse(text.as_bytes(), Path::new("data.csv"), &["time", "u", "y"])
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
            "data.csv: line 2, column 'y': NaN is not a finite number"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2\n0,1,2\n"),
            "data.csv: line 3, column 'time': time 0 does not increase (previous 0)"
        );
        assert_eq!(
            msg("time,u,y\n0,1,2\n1,2\n"),
            "data.csv: line 3: 2 fields, the header has 3"
        );
    }

    #[test]
    fn atomic_write_leaves_nothing_on_failure() {
        let dir = std::env::temp_dir().join(format!("backlash-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let target = dir.join("out.csv");
        write_atomic(&target, |w| w.write_all(b"ok\n")).unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "ok\n");
        let err = write_atomic(&target, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("boom"))
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "ok\n");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
