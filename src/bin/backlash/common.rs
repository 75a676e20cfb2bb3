//! What several commands share: the record options, the plant's parameters as flags, progress on standard
//! error and the JSON answer on standard output.

use std::path::Path;

use anyhow::{Context, Result};
use backlash::api::{LIST_NAMES, PlantSpec, RecordOptions};
use clap::{Arg, ArgMatches, Command};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{Value, json};

/// The options of every command that reads a record: which columns, and the decimation. Flattened into each
/// such command (`#[command(flatten)] record: RecordArgs`).
#[derive(clap::Args, Debug, Clone)]
pub struct RecordArgs {
    /// Name of the time column [default: time, or t when the file has a t column and no time]. A header
    /// cell may carry a unit, `y [kN]`: it answers to `y`, and the plots show the unit.
    #[arg(long)]
    pub time_col: Option<String>,
    /// Name of the input column.
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Name of the output column (commands that read an output).
    #[arg(long, default_value = "y")]
    pub y_col: String,
    /// Average blocks of N samples into one before anything else (anti-alias mean, then one sample per
    /// block); for records sampled far faster than their dynamics. Orders and delays count the decimated
    /// samples. Without it, `diagnose` and `identify oe` choose the rate from the data (a record sampled far
    /// faster than its dynamics is decimated, and the answer says why); the other commands use every sample.
    #[arg(long)]
    pub decimate: Option<usize>,
}

impl RecordArgs {
    pub fn options(&self) -> RecordOptions {
        RecordOptions {
            time_col: self.time_col.clone(),
            u_col: self.u_col.clone(),
            y_col: self.y_col.clone(),
            decimate: self.decimate(),
        }
    }

    /// `--decimate`, 1 when not given.
    pub fn decimate(&self) -> usize {
        self.decimate.unwrap_or(1)
    }
}

/// A spinner with a message and the elapsed time on standard error, drawn only on a terminal and never with
/// `--json` (`hidden`).
pub fn spinner(hidden: bool, message: &str) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new_spinner();
    b.set_style(
        ProgressStyle::with_template("{spinner} {elapsed:>4} {msg}").expect("valid template"),
    );
    b.enable_steady_tick(std::time::Duration::from_millis(200));
    b.set_message(message.to_string());
    b
}

/// A bar of `len` steps with `template` (indicatif's), as [`spinner`] drawn only on a terminal.
pub fn bar(hidden: bool, len: u64, template: &str) -> ProgressBar {
    if hidden {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(len);
    b.set_style(ProgressStyle::with_template(template).expect("valid template"));
    b
}

/// Prints a JSON answer with the file it is about.
pub fn print_json(mut out: Value, file: &Path) {
    out["file"] = json!(file.display().to_string());
    println!("{out}");
}

/// The warnings of a JSON answer, printed for a person.
pub fn print_warnings(out: &Value) {
    for w in out["warnings"].as_array().into_iter().flatten() {
        println!("  warning: {}", w.as_str().unwrap_or_default());
    }
}

/// The plant's parameters as flags, one per parameter of the plant FMU (`--c1-rate` for `c1_rate`), with
/// `--a` and `--b` as comma-separated lists; unset ones keep the FMU's start values.
#[derive(Debug, Clone, Default)]
pub struct PlantArgs {
    pub spec: PlantSpec,
}

/// Only the parameters of the model a Cramer-Rao bound is computed for ([`backlash::api::CRB_NAMES`]).
#[derive(Debug, Clone, Default)]
pub struct ModelArgs {
    pub spec: PlantSpec,
}

/// The flag of a parameter: lower case, `-` for `_`. The names come from the FMU's variable table, which
/// lives as long as the program; the flag texts are made once per command line and kept as long.
fn flag(name: &'static str) -> &'static str {
    let f = name.to_lowercase().replace('_', "-");
    if f == name {
        name
    } else {
        Box::leak(f.into_boxed_str())
    }
}

fn add_flags(mut cmd: Command, names: &[&'static str]) -> Command {
    for &name in names {
        let arg = Arg::new(name)
            .long(flag(name))
            .value_parser(clap::value_parser!(f64))
            .allow_negative_numbers(true)
            .help_heading("Plant parameters (BacklashPlant.fmu's names; unset: its start values)");
        cmd = cmd.arg(if LIST_NAMES.contains(&name) {
            arg.value_delimiter(',').num_args(1).help(format!(
                "{name}: comma-separated list ({})",
                if name == "a" {
                    "a1..a_na; na is their number"
                } else {
                    "b0..b_nb; nb + 1 values"
                }
            ))
        } else {
            arg.help(format!(
                "{name} ({})",
                PlantSpec::describe(name).unwrap_or_default()
            ))
        });
    }
    cmd
}

fn read_flags(m: &ArgMatches, names: &[&'static str]) -> Result<PlantSpec, clap::Error> {
    let mut spec = PlantSpec::default();
    let invalid = |e: backlash::api::ApiError| {
        clap::Error::raw(clap::error::ErrorKind::InvalidValue, format!("{e}\n"))
    };
    for &name in names {
        if LIST_NAMES.contains(&name) {
            if let Some(v) = m.get_many::<f64>(name) {
                spec.set_list(name, &v.copied().collect::<Vec<_>>())
                    .map_err(invalid)?;
            }
        } else if let Some(v) = m.get_one::<f64>(name) {
            spec.set(name, *v).map_err(invalid)?;
        }
    }
    Ok(spec)
}

macro_rules! plant_flags {
    ($ty:ty, $names:expr) => {
        impl clap::FromArgMatches for $ty {
            fn from_arg_matches(m: &ArgMatches) -> Result<Self, clap::Error> {
                Ok(Self {
                    spec: read_flags(m, &$names)?,
                })
            }
            fn update_from_arg_matches(&mut self, m: &ArgMatches) -> Result<(), clap::Error> {
                *self = Self::from_arg_matches(m)?;
                Ok(())
            }
        }
        impl clap::Args for $ty {
            fn augment_args(cmd: Command) -> Command {
                add_flags(cmd, &$names)
            }
            fn augment_args_for_update(cmd: Command) -> Command {
                add_flags(cmd, &$names)
            }
        }
    };
}

plant_flags!(PlantArgs, PlantSpec::names());
plant_flags!(ModelArgs, backlash::api::CRB_NAMES);

/// The parameters of a JSON file (`{"a": [...], "c1_rate": 0.01, ...}`, the FMU's names), if one is given.
pub fn spec_file(path: Option<&Path>) -> Result<PlantSpec> {
    let Some(path) = path else {
        return Ok(PlantSpec::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    PlantSpec::from_json(&text)
        .with_context(|| format!("{}: not a valid parameter file", path.display()))
}
