//! `backlash diagnose`: fit the declared model, test its residual, and name the catalogue effect it lacks.

use super::structure::StructureArgs;
use anyhow::{Context, Result, bail};
use backlash::api::{DiagnoseOptions, diagnose_with_progress, diagnosis_json};
use backlash::diagnose::record::decimate;
use backlash::diagnose::report::{ReportInput, Validation, write_report};
use backlash::io::Table;
use backlash::report::number;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use serde_json::json;
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored; names configurable).
    pub file: PathBuf,
    #[command(flatten)]
    pub structure: StructureArgs,
    /// Wall-clock budget of the diagnosis in seconds; candidates not fitted when it is spent are listed as
    /// not tried.
    #[arg(long, default_value_t = 300.0)]
    pub time_budget: f64,
    /// The most effects the loop adds, one per round (between 1 and 10, the catalogue's size; 1: name the first effect only).
    #[arg(long, default_value_t = 3)]
    pub max_effects: usize,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
    /// Write report.md and PNG figures into this folder (created if needed).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Average blocks of N samples into one before anything else (anti-alias mean, then one sample per
    /// block); for records sampled far faster than their dynamics.
    #[arg(long, default_value_t = 1)]
    pub decimate: usize,
    /// Another record (same columns) to simulate the fitted models on: cross-record validation. Repeatable.
    #[arg(long)]
    pub validate_on: Vec<PathBuf>,
    /// Share of the record used for fitting; the rest is held out (between 0.3 and 0.95).
    #[arg(long, default_value_t = 0.7)]
    pub fit_fraction: f64,
    /// Seed of the fit's perturbed restarts (the result is deterministic for a seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Name of the time column.
    #[arg(long, default_value = "time")]
    pub time_col: String,
    /// Name of the input column.
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// Name of the output column.
    #[arg(long, default_value = "y")]
    pub y_col: String,
}

#[derive(Serialize)]
struct ValidationOut {
    file: String,
    samples: usize,
    y_std: f64,
    rmse_before: f64,
    rmse_after: f64,
}

/// Read (time, u, y) and decimate.
fn load(path: &Path, args: &DiagnoseArgs) -> Result<[Vec<f64>; 3]> {
    let names = [
        args.time_col.as_str(),
        args.u_col.as_str(),
        args.y_col.as_str(),
    ];
    let table = Table::read(path, &names)?;
    let cols: Vec<&[f64]> = names
        .iter()
        .map(|n| table.column(n).expect("required column"))
        .collect();
    let mut d = decimate(&cols, args.decimate).into_iter();
    let (t, u, y) = (d.next().unwrap(), d.next().unwrap(), d.next().unwrap());
    Ok([t, u, y])
}

/// Median sample period.
fn sample_period(t: &[f64]) -> Option<f64> {
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if dt.is_empty() {
        return None;
    }
    dt.sort_by(f64::total_cmp);
    Some(dt[dt.len() / 2])
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map_or("record".into(), |s| s.to_string_lossy().into_owned())
}

/// `argv`: the command line as typed (the program's name first), for the report.
pub fn run(args: &DiagnoseArgs, argv: &[String]) -> Result<()> {
    if args.decimate == 0 {
        bail!("--decimate must be at least 1");
    }
    let [t, u, y] = load(&args.file, args)?;
    let ts = sample_period(&t);
    let opts = DiagnoseOptions {
        structure: args.structure.declared(),
        max_delay: args.structure.max_delay,
        fit_fraction: args.fit_fraction,
        seed: args.seed,
        max_effects: args.max_effects,
        time_budget: args.time_budget,
    };
    // A spinner with the stage on standard error (drawn only on a terminal; not with --json).
    let spinner = if args.json {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new_spinner();
        b.set_style(
            ProgressStyle::with_template("{spinner} {elapsed:>4} {msg}").expect("valid template"),
        );
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        b
    };
    let d = diagnose_with_progress(&u, &y, &opts, &|stage| {
        spinner.set_message(stage.to_owned())
    })
    .with_context(|| format!("{}: cannot diagnose", args.file.display()));
    spinner.finish_and_clear();
    let d = d?;

    let mut validations = Vec::new();
    for path in &args.validate_on {
        let [tv, uv, yv] = load(path, args)?;
        let result = d.cross_validate(&uv, &yv).with_context(|| {
            format!(
                "{}: the fitted models cannot be simulated on it",
                path.display()
            )
        })?;
        validations.push(Validation {
            name: stem(path),
            t: tv,
            y: yv,
            result,
        });
    }

    let mut report_path = None;
    if let Some(dir) = &args.report {
        // The command as a user would type it (the program's own path replaced by its name).
        let command = std::iter::once("backlash")
            .chain(argv.iter().skip(1).map(String::as_str))
            .collect::<Vec<_>>()
            .join(" ");
        let file = args.file.display().to_string();
        let input = ReportInput {
            file: &file,
            t: &t,
            u: &u,
            y: &y,
            decimate: args.decimate,
            columns: [&args.time_col, &args.u_col, &args.y_col],
            command: Some(command),
            validations: &validations,
        };
        report_path = Some(
            write_report(dir, &d, &input)
                .with_context(|| format!("{}: cannot write the report", dir.display()))?,
        );
    }

    if args.json {
        let validate_on: Vec<ValidationOut> = args
            .validate_on
            .iter()
            .zip(&validations)
            .map(|(p, v)| ValidationOut {
                file: p.display().to_string(),
                samples: v.result.samples,
                y_std: v.result.y_std,
                rmse_before: v.result.rmse_before,
                rmse_after: v.result.rmse_after,
            })
            .collect();
        let mut out = diagnosis_json(&d, ts);
        out["file"] = json!(args.file.display().to_string());
        out["decimate"] = json!(args.decimate);
        out["validate_on"] = serde_json::to_value(validate_on)?;
        out["report"] = json!(report_path.as_ref().map(|p| p.display().to_string()));
        println!("{out}");
        return Ok(());
    }

    println!(
        "Diagnosis of {} ({} samples{}; fit on the first {}, {} held out)",
        args.file.display(),
        d.n,
        if args.decimate > 1 {
            format!(" after decimation by {}", args.decimate)
        } else {
            String::new()
        },
        d.n_fit,
        d.n - d.n_fit
    );
    println!(
        "  structure ({}): {}",
        d.structure.chosen_by, d.structure.reason
    );
    println!("  initial state: {}", d.initial.reason);
    let steps = d.steps();
    if steps.is_empty() {
        println!(
            "  effect: null (no extension is supported); held-out RMSE {}",
            number(d.base_heldout_rmse)
        );
    }
    let mut before = d.base_heldout_rmse;
    for (i, c) in steps.iter().enumerate() {
        println!(
            "  step {}: {} (pointed to by: {}); held-out RMSE {} -> {} ({} error)",
            i + 1,
            c.id,
            c.pointed_by.first().copied().unwrap_or("-"),
            number(before),
            number(c.heldout_rmse),
            c.error_kind
        );
        before = c.heldout_rmse;
    }
    if !steps.is_empty() {
        println!("  loop: {}", d.stopped);
    }
    println!("  residual tests (fit part of the declared model's residual, first round):");
    for t in &d.tests {
        println!(
            "    [{}] {}: {:.3} (threshold {:.3})",
            if t.verdict.rejects {
                "reject"
            } else {
                "  ok  "
            },
            t.verdict.name,
            t.verdict.statistic,
            t.verdict.threshold
        );
    }
    if !d.candidates.is_empty() {
        println!("  candidates of the first round:");
        for c in &d.candidates {
            println!(
                "    {:<22} held-out {} (z {:.2}), dBIC {:+.1}: {}",
                c.id.as_str(),
                number(c.heldout_rmse),
                c.heldout_z,
                c.delta_bic,
                c.reason
            );
        }
    }
    for v in &validations {
        println!(
            "  validation on {}: RMSE declared {}, chosen {} (output std {})",
            v.name,
            number(v.result.rmse_before),
            number(v.result.rmse_after),
            number(v.result.y_std)
        );
    }
    if let Some(p) = report_path {
        println!("  report: {}", p.display());
    }
    Ok(())
}
