//! `backlash`: simulate, identify and diagnose backlash models on the command line.
//!
//! One file per command; no logic here beyond parsing and printing (the library does the work).

mod identify;
mod simulate;

use clap::{Parser, Subcommand};

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
}

#[derive(Subcommand)]
enum IdentifyCommand {
    /// Recursive MRGIA estimator of paper 000 (the same code as MrgiaEstimator.fmu).
    Mrgia(identify::MrgiaArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::Identify(IdentifyCommand::Mrgia(a)) => identify::run_mrgia(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
