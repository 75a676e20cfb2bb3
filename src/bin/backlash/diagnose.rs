//! `backlash diagnose`: fit the declared model, test its residual, and name the catalogue effect it lacks.

use super::common::{RecordArgs, print_json, print_warnings, spinner};
use super::structure::StructureArgs;
use anyhow::{Context, Result};
use backlash::api::{
    Rate, Record, RecordOptions, choose_rate, diagnose_with_progress, diagnosis_json, time_budget,
    with_linear_baseline, with_rate,
};
use backlash::diagnose::engine::{DiagnoseConfig, Diagnosis};
use backlash::diagnose::report::{ReportInput, Validation, write_report};
use backlash::report::number;
use serde::Serialize;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored; names configurable).
    pub file: PathBuf,
    #[command(flatten)]
    pub record: RecordArgs,
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
    /// Another record (same columns) to simulate the fitted models on: cross-record validation. Repeatable.
    #[arg(long)]
    pub validate_on: Vec<PathBuf>,
    /// Share of the record used for fitting; the rest is held out (between 0.3 and 0.95).
    #[arg(long, default_value_t = 0.7)]
    pub fit_fraction: f64,
    /// Seed of the fit's perturbed restarts (the result is deterministic for a seed).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

#[derive(Serialize)]
struct ValidationOut {
    file: String,
    samples: usize,
    y_std: f64,
    rmse_before: f64,
    rmse_after: f64,
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map_or("record".into(), |s| s.to_string_lossy().into_owned())
}

impl DiagnoseArgs {
    /// The diagnosis's configuration: the library's defaults with what the command line sets.
    fn config(&self) -> Result<DiagnoseConfig> {
        Ok(DiagnoseConfig {
            structure: self.structure.declared(),
            max_delay: self.structure.max_delay,
            fit_fraction: self.fit_fraction,
            seed: self.seed,
            max_effects: self.max_effects,
            time_budget: time_budget(self.time_budget)?,
            ..DiagnoseConfig::auto()
        })
    }
}

/// `argv`: the command line as typed (the program's name first), for the report.
pub fn run(args: &DiagnoseArgs, argv: &[String]) -> Result<()> {
    let rec = args.record.options().read(&args.file, true)?;
    let cfg = args.config()?;
    let rate = choose_rate(&rec.u, &rec.y, args.record.decimate, cfg.fit_fraction)
        .with_context(|| format!("{}", args.file.display()))?;
    // The record as the rate stage saw it stays for the linear baseline at its own rate.
    let given = rec;
    let (worked, factor) = match rate.chosen_by {
        "data" => (Some(given.clone().decimated(rate.decimate)), rate.decimate),
        _ => (None, 1),
    };
    let rec = worked.as_ref().unwrap_or(&given);
    // The stage on standard error (drawn only on a terminal; not with --json).
    let progress = spinner(args.json, "reading");
    let d = diagnose_with_progress(&rec.u, &rec.y, &cfg, &|stage| {
        progress.set_message(stage.to_owned())
    })
    .with_context(|| format!("{}: cannot diagnose", args.file.display()));
    progress.finish_and_clear();
    let d = d?;
    let validations = validate(args, &d, rate.decimate)?;
    let mut out = diagnosis_json(&d, &rec.u, rec.sample_period(), rec.decimate);
    with_rate(&mut out, &rate);
    with_linear_baseline(&mut out, (&given.u, &given.y), cfg.fit_fraction, &d, factor);
    let warnings: Vec<String> = out["warnings"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|w| w.as_str().map(str::to_owned))
        .collect();
    let report = match &args.report {
        Some(dir) => Some(report(
            args,
            argv,
            dir,
            rec,
            &d,
            (&validations, &rate),
            &warnings,
        )?),
        None => None,
    };
    out["validate_on"] = validation_json(args, &validations)?;
    out["report"] = json!(report.as_ref().map(|p| p.display().to_string()));
    if args.json {
        print_json(out, &args.file);
    } else {
        print_text(args, &d, &validations, report.as_deref(), &out);
    }
    Ok(())
}

/// `--validate-on`: the fitted models on each other record, at the rate of the diagnosis (`decimate`).
fn validate(args: &DiagnoseArgs, d: &Diagnosis, decimate: usize) -> Result<Vec<Validation>> {
    let mut validations = Vec::new();
    let options = RecordOptions {
        decimate,
        ..args.record.options()
    };
    for path in &args.validate_on {
        let rec = options.read(path, true)?;
        let result = d.cross_validate(&rec.u, &rec.y).with_context(|| {
            format!(
                "{}: the fitted models cannot be simulated on it",
                path.display()
            )
        })?;
        validations.push(Validation {
            name: stem(path),
            t: rec.t,
            y: rec.y,
            result,
        });
    }
    Ok(validations)
}

fn validation_json(args: &DiagnoseArgs, validations: &[Validation]) -> Result<Value> {
    let v: Vec<ValidationOut> = args
        .validate_on
        .iter()
        .zip(validations)
        .map(|(p, v)| ValidationOut {
            file: p.display().to_string(),
            samples: v.result.samples,
            y_std: v.result.y_std,
            rmse_before: v.result.rmse_before,
            rmse_after: v.result.rmse_after,
        })
        .collect();
    Ok(serde_json::to_value(v)?)
}

/// `--report DIR`: report.md and the figures, with the axes named after the columns (and their units).
fn report(
    args: &DiagnoseArgs,
    argv: &[String],
    dir: &Path,
    rec: &Record,
    d: &Diagnosis,
    (validations, rate): (&[Validation], &Rate),
    warnings: &[String],
) -> Result<PathBuf> {
    // The command as a user would type it (the program's own path replaced by its name).
    let command = std::iter::once("backlash")
        .chain(argv.iter().skip(1).map(String::as_str))
        .collect::<Vec<_>>()
        .join(" ");
    let file = args.file.display().to_string();
    let input = ReportInput {
        file: &file,
        t: &rec.t,
        u: &rec.u,
        y: &rec.y,
        decimate: rec.decimate,
        rate: Some(rate.reason.clone()),
        columns: [rec.label(0), rec.label(1), rec.label(2)],
        command: Some(command),
        validations,
        warnings,
    };
    write_report(dir, d, &input)
        .with_context(|| format!("{}: cannot write the report", dir.display()))
}

fn print_text(
    args: &DiagnoseArgs,
    d: &Diagnosis,
    validations: &[Validation],
    report: Option<&Path>,
    out: &Value,
) {
    println!("{}", d.backlash.headline());
    for r in &d.backlash.reasons {
        println!("  - {r}");
    }
    println!(
        "Diagnosis of {} ({} samples{}; fit on the first {}, {} held out)",
        args.file.display(),
        d.n,
        match out["rate"]["decimate"].as_u64() {
            Some(f) if f > 1 => format!(" after decimation by {f}"),
            _ => String::new(),
        },
        d.n_fit,
        d.n - d.n_fit
    );
    println!(
        "  structure ({}): {}",
        d.structure.chosen_by, d.structure.reason
    );
    println!(
        "  rate ({}): {}",
        out["rate"]["chosen_by"].as_str().unwrap_or(""),
        out["rate"]["reason"].as_str().unwrap_or("")
    );
    println!("  initial state: {}", d.initial.reason);
    print_steps(d);
    print_tests(d);
    for v in validations {
        println!(
            "  validation on {}: RMSE declared {}, chosen {} (output std {})",
            v.name,
            number(v.result.rmse_before),
            number(v.result.rmse_after),
            number(v.result.y_std)
        );
    }
    if let Some(p) = report {
        println!("  report: {}", p.display());
    }
    print_warnings(out);
}

/// The effects added, one per round, with the held-out error after each.
fn print_steps(d: &Diagnosis) {
    let steps = d.steps();
    if steps.is_empty() {
        println!(
            "  effect: null (no extension is supported); held-out RMSE {}",
            number(d.base_heldout_rmse)
        );
    }
    let mut before = d.base_heldout_rmse;
    for (i, c) in steps.iter().enumerate() {
        let change = match c.one_step {
            Some(o) => format!(
                "one-step prediction RMSE {} -> {} (the free run, {}, is unchanged by a noise model)",
                number(o.before),
                number(o.after),
                number(c.heldout_rmse)
            ),
            None => format!(
                "held-out RMSE {} -> {} (free-run simulation)",
                number(before),
                number(c.heldout_rmse)
            ),
        };
        println!(
            "  step {}: {} (pointed to by: {}); {change}",
            i + 1,
            c.id,
            c.pointed_by.first().copied().unwrap_or("-"),
        );
        before = c.heldout_rmse;
    }
    if !steps.is_empty() {
        println!("  loop: {}", d.stopped);
    }
    println!(
        "  held-out fit of the final model: {:.1}% (free-run RMSE {}; predicting the fit part's mean: {})",
        d.explained.fit_percent,
        number(d.after_rmse()),
        number(d.explained.constant_rmse)
    );
}

/// The residual tests and the candidates of the first round.
fn print_tests(d: &Diagnosis) {
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
}
