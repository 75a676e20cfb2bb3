//! Records: which columns of a file make one, how it is thinned, and what it cannot support.
//!
//! Every command that reads a record takes the same [`RecordOptions`] (the program's `--time-col`, `--u-col`,
//! `--y-col`, `--decimate`; the Python functions' `decimate=`), and every answer carries the same
//! [`InputCheck`] warnings for records that cannot support it.

use std::path::Path;

use crate::io::{RowReader, Table, TimeColumn, split_unit};
use crate::stats::{BlockMean, block_means, median};

use super::ApiError;

/// Samples per estimated parameter below which an answer is flagged as resting on too little data.
pub const MIN_SAMPLES_PER_PARAMETER: usize = 10;

/// Which columns of a file make the record, and the block length of its decimation.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordOptions {
    /// The time column; `None`: `time`, or `t` when the file has a `t` column and no `time`.
    pub time_col: Option<String>,
    pub u_col: String,
    pub y_col: String,
    /// Average blocks of this many samples into one (1: none).
    pub decimate: usize,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self {
            time_col: None,
            u_col: "u".into(),
            y_col: "y".into(),
            decimate: 1,
        }
    }
}

/// The columns a reader asks for: time, u and, when wanted, y.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordColumns {
    pub names: Vec<String>,
}

impl RecordColumns {
    /// The names in the reader's order (time first).
    pub fn as_strs(&self) -> Vec<&str> {
        self.names.iter().map(String::as_str).collect()
    }
}

impl RecordOptions {
    /// `decimate` checked.
    pub fn check(&self) -> Result<(), ApiError> {
        if self.decimate == 0 {
            return Err(ApiError::Setting(
                "decimate must be at least 1 (1: every sample)".into(),
            ));
        }
        Ok(())
    }

    /// The columns of `path` to read (its header decides the default time column); `with_y`: the output too.
    pub fn columns(&self, path: &Path, with_y: bool) -> Result<RecordColumns, ApiError> {
        self.check()?;
        let time = match &self.time_col {
            Some(t) => t.clone(),
            None => {
                let reader = RowReader::open(path, &[])?;
                let has = |n: &str| reader.header().iter().any(|h| split_unit(h).0 == n);
                if !has("time") && has("t") {
                    "t"
                } else {
                    "time"
                }
                .to_string()
            }
        };
        let mut names = vec![time, self.u_col.clone()];
        if with_y {
            names.push(self.y_col.clone());
        }
        Ok(RecordColumns { names })
    }

    /// A reader of the record's rows (time, u and, `with_y`, y), to be thinned with [`Self::block`].
    pub fn open(
        &self,
        path: &Path,
        with_y: bool,
    ) -> Result<(RowReader<std::io::BufReader<std::fs::File>>, RecordColumns), ApiError> {
        let cols = self.columns(path, with_y)?;
        let names = cols.as_strs();
        let reader = RowReader::open_with(path, &names, TimeColumn::Named(names[0]))?;
        Ok((reader, cols))
    }

    /// The block means of a streamed record of `width` columns.
    pub fn block(&self, width: usize) -> BlockMean {
        BlockMean::new(self.decimate, width)
    }

    /// The whole record, decimated.
    pub fn read(&self, path: &Path, with_y: bool) -> Result<Record, ApiError> {
        let cols = self.columns(path, with_y)?;
        let names = cols.as_strs();
        let table = Table::read_with(path, &names, TimeColumn::Named(names[0]))?;
        let raw: Vec<&[f64]> = names
            .iter()
            .map(|n| table.column(n).expect("a required column"))
            .collect();
        let mut columns = block_means(&raw, self.decimate).into_iter();
        let labels = names
            .iter()
            .map(|n| match table.unit(n) {
                Some(unit) => format!("{n} [{unit}]"),
                None => n.to_string(),
            })
            .collect();
        Ok(Record {
            t: columns.next().unwrap_or_default(),
            u: columns.next().unwrap_or_default(),
            y: columns.next().unwrap_or_default(),
            labels,
            decimate: self.decimate,
        })
    }
}

/// A record read from a file: its columns after decimation, and their labels.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    pub t: Vec<f64>,
    pub u: Vec<f64>,
    /// Empty when the output was not asked for.
    pub y: Vec<f64>,
    /// The columns' names with their units where the header gives them (`y [kN]`), for axes: time, u, y.
    pub labels: Vec<String>,
    pub decimate: usize,
}

impl Record {
    /// The label of column `i` (0 time, 1 u, 2 y).
    pub fn label(&self, i: usize) -> &str {
        self.labels.get(i).map_or("", String::as_str)
    }

    /// The record decimated further by `factor` (block means of every column; a partial last block
    /// dropped): what a rate chosen from the data does to a record read at the user's rate.
    pub fn decimated(self, factor: usize) -> Record {
        if factor <= 1 {
            return self;
        }
        let cols: Vec<&[f64]> = [&self.t, &self.u, &self.y]
            .into_iter()
            .filter(|c| !c.is_empty())
            .map(Vec::as_slice)
            .collect();
        let mut d = block_means(&cols, factor).into_iter();
        Record {
            t: d.next().unwrap_or_default(),
            u: d.next().unwrap_or_default(),
            y: d.next().unwrap_or_default(),
            decimate: self.decimate * factor,
            labels: self.labels,
        }
    }

    /// The median sample period of the time column; `None` below two samples.
    pub fn sample_period(&self) -> Option<f64> {
        sample_period(&self.t)
    }
}

/// The median step of a time column; `None` below two samples.
pub fn sample_period(t: &[f64]) -> Option<f64> {
    let dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    median(&dt)
}

/// What an input can tell, gathered sample by sample: its range and how often it reverses direction.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InputCheck {
    samples: u64,
    min: f64,
    max: f64,
    sum: f64,
    last: f64,
    /// The direction of the last move: +1, -1, or 0 before any.
    direction: i8,
    reversals: u64,
}

impl InputCheck {
    /// The check of a whole input.
    pub fn of(u: &[f64]) -> Self {
        let mut c = Self::default();
        u.iter().for_each(|&v| c.push(v));
        c
    }

    pub fn push(&mut self, v: f64) {
        if self.samples == 0 {
            (self.min, self.max, self.last) = (v, v, v);
        } else {
            let d = v - self.last;
            let dir = if d > 0.0 {
                1
            } else if d < 0.0 {
                -1
            } else {
                0
            };
            if dir != 0 {
                self.reversals += u64::from(self.direction == -dir);
                self.direction = dir;
            }
            self.last = v;
        }
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        self.sum += v;
        self.samples += 1;
    }

    /// The sentences for an answer of `params` parameters estimated from `samples` samples (those of the fit;
    /// 0 parameters: no count check).
    pub fn warnings(&self, samples: u64, params: usize) -> Vec<String> {
        let mut w = Vec::new();
        let range = self.max - self.min;
        let scale = self.max.abs().max(self.min.abs());
        if self.samples > 0 && range == 0.0 {
            w.push(format!(
                "the input is constant ({} in every sample): a constant input tells nothing about the \
                 dynamics or the backlash, so this record cannot support the estimates",
                self.min
            ));
        } else if self.samples > 0 && range <= 1e-6 * scale {
            w.push(format!(
                "the input is nearly constant (it varies by {range:.3e} around {:.6e}): it tells almost \
                 nothing about the dynamics or the backlash",
                self.sum / self.samples as f64
            ));
        } else if self.samples > 1 && self.reversals == 0 {
            w.push(
                "the input never reverses direction: the record drives one border of the backlash only, so \
                 the other border and the gaps are not seen"
                    .into(),
            );
        }
        if params > 0 && samples < (MIN_SAMPLES_PER_PARAMETER * params) as u64 {
            w.push(format!(
                "{samples} samples for {params} parameters: fewer than {MIN_SAMPLES_PER_PARAMETER} per \
                 parameter, too few to trust the estimates"
            ));
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warnings_name_a_constant_a_one_way_and_a_short_record() {
        assert!(
            InputCheck::of(&[2.0; 50]).warnings(50, 3)[0]
                .starts_with("the input is constant (2 in")
        );
        assert!(
            InputCheck::of(&[1.0, 1.0 + 1e-9, 1.0]).warnings(100, 0)[0]
                .starts_with("the input is nearly constant")
        );
        let ramp: Vec<f64> = (0..100).map(f64::from).collect();
        let w = InputCheck::of(&ramp).warnings(100, 5);
        assert_eq!(w.len(), 1);
        assert!(w[0].starts_with("the input never reverses"));
        let sine: Vec<f64> = (0..100).map(|k| (f64::from(k) * 0.3).sin()).collect();
        assert!(InputCheck::of(&sine).warnings(100, 10).is_empty());
        let w = InputCheck::of(&sine).warnings(99, 10);
        assert_eq!(
            w,
            [
                "99 samples for 10 parameters: fewer than 10 per parameter, too few to trust the estimates"
            ]
        );
    }

    #[test]
    fn the_sample_period_is_the_median_step() {
        assert_eq!(sample_period(&[0.0, 1.0, 2.0, 4.0]), Some(1.0));
        assert_eq!(sample_period(&[0.0]), None);
    }
}
