//! What a report is written from besides the diagnosis, and why it may fail.

use std::path::PathBuf;

use crate::diagnose::search::engine::CrossValidation;
use crate::report::plot::PlotError;

/// Why a report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{path}: cannot create the report folder")]
    Folder {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot write the report")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// A record validated against the fitted models (another file).
#[derive(Debug, Clone, PartialEq)]
pub struct Validation {
    /// Short name (file stem), used in the figure's file name.
    pub name: String,
    pub t: Vec<f64>,
    pub y: Vec<f64>,
    pub result: CrossValidation,
}

/// What the report needs besides the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportInput<'a> {
    /// The data file (for the title).
    pub file: &'a str,
    /// Time of each (decimated) sample.
    pub t: &'a [f64],
    pub u: &'a [f64],
    pub y: &'a [f64],
    pub decimate: usize,
    /// How the rate was chosen and why (`None`: not said).
    pub rate: Option<String>,
    /// The CSV's names of the time, input and output columns with their units where the header gives them
    /// (`y [kN]`): the figures' axes.
    pub columns: [&'a str; 3],
    /// The command that produced the report (to reproduce it).
    pub command: Option<String>,
    /// What the record cannot support (the JSON's `warnings`), shown near the top of the report.
    pub warnings: &'a [String],
    pub validations: &'a [Validation],
}
