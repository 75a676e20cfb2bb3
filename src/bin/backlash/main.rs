//! `backlash`: simulate, identify and diagnose backlash models on the command line.
//!
//! One file per command; no logic here beyond parsing and printing (the library does the work).

mod common;
mod compensate;
mod diagnose;
mod experiment;
mod frequency;
mod identify;
mod monitor;
mod oe;
mod simulate;
mod structure;
mod study;

use clap::{Parser, Subcommand};
use std::io::Write;

#[derive(Parser)]
#[command(
    name = "backlash",
    version,
    about = "Backlash identification: simulate, identify, diagnose"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the pseudo-Wiener backlash plant on an input CSV (time,u) and write time,u,x,w,y.
    Simulate(simulate::SimulateArgs),
    /// Identify a backlash model from a data file.
    #[command(subcommand)]
    Identify(IdentifyCommand),
    /// Run sine experiments on a simulated plant (continuous block + polynomial-border backlash) at several
    /// frequencies, identify each with paper 003's estimators, and plot |G(jw)| and the borders.
    Experiment(experiment::ExperimentArgs),
    /// Diagnose a record: fit the declared model, test its residual, name the catalogue effect it lacks (or null).
    Diagnose(diagnose::DiagnoseArgs),
    /// Cramer-Rao bound of the output-error model on an input record: plan an experiment.
    Crb(oe::CrbArgs),
    /// Wear monitor: stream a record through the refined estimator and raise an alarm when the play grows.
    Monitor(monitor::MonitorArgs),
    Compensate(compensate::CompensateArgs),
    /// Monte Carlo study of the paper's example: MRGIA, output error and the Cramer-Rao bound against N.
    Study(study::StudyArgs),
}

#[derive(Subcommand)]
enum IdentifyCommand {
    /// Recursive MRGIA estimator of paper 000 (the same code as MrgiaEstimator.fmu).
    Mrgia(identify::MrgiaArgs),
    /// Frequency identification of paper 003 from one sine experiment (u = U cos(w t)), with its window and verdict.
    Frequency(frequency::IdentifyFrequencyArgs),
    /// Every step of a stepped-sine record (several frequencies one after another): Bode points and borders.
    SteppedSine(frequency::SteppedSineArgs),
    /// Output-error (prediction-error) refinement from MRGIA's estimate, with standard errors.
    Oe(oe::OeArgs),
}

/// A reader that closes the pipe early (`backlash ... | head -1`) is no error: `println!` panics on a closed
/// stdout, and that one panic ends the process quietly with status 0 (the reader wanted no more); every other
/// panic keeps the default report. One place for every command; installed once however often `run` is called
/// (the Python package calls it once per command in one process).
fn quiet_on_closed_stdout() {
    static INSTALL: std::sync::Once = std::sync::Once::new();
    INSTALL.call_once(install_quiet_hook);
}

fn install_quiet_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let msg = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if msg.starts_with("failed printing to stdout") && msg.contains("Broken pipe") {
            std::process::exit(0);
        }
        default(info);
    }));
}

fn main() {
    std::process::exit(run(std::env::args_os()));
}

/// The whole program on a command line (the program's name first): parses, runs the command, reports an
/// error on standard error; returns the exit status. The Python package's `backlash` command calls this too
/// (the extension includes these files), so the program and the command are the same code.
pub fn run<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    quiet_on_closed_stdout();
    let argv: Vec<std::ffi::OsString> = args.into_iter().map(Into::into).collect();
    let typed: Vec<String> = argv
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let cli = Cli::parse_from(&argv);
    let result = match &cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::Identify(IdentifyCommand::Mrgia(a)) => identify::run_mrgia(a),
        Command::Identify(IdentifyCommand::Frequency(a)) => frequency::run_identify(a),
        Command::Identify(IdentifyCommand::SteppedSine(a)) => frequency::run_stepped_sine(a),
        Command::Experiment(a) => experiment::run_experiment(a),
        Command::Identify(IdentifyCommand::Oe(a)) => oe::run_oe(a),
        Command::Crb(a) => oe::run_crb(a),
        Command::Diagnose(a) => diagnose::run(a, &typed),
        Command::Study(a) => study::run_study(a),
        Command::Monitor(a) => monitor::run(a),
        Command::Compensate(a) => compensate::run(a),
    };
    match result {
        Ok(()) => 0,
        Err(e) if closed_pipe(&e) => 0,
        Err(e) => {
            // Standard error may be the same closed pipe (`2>&1 | head -1`): nothing is left to tell then, and
            // `eprintln!` would panic.
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            1
        }
    }
}

/// Whether a command failed only because the reader of its output went away (`| head -1`): the reader wanted
/// no more, so the program ends quietly with success, as `cat` and `seq` do.
fn closed_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}
