//! Developer tool for `diagnose`: run it on many simulated test-bench records, or look inside its decision on
//! one measured record. Not part of the test suite; the checks that gate a change are the tests in
//! `src/diagnose/bench.rs`.
//!
//! ```sh
//! # simulated records (seeds A..B, every effect and clean records unless --effects names some)
//! cargo run --release --example diagnose_dev -- sweep --seeds 0..5 --effects clean,friction --n 3000
//! # a measured record, decimated, with one or more declared structures (na,nb,delay;...); a record of
//! # data/ by its name there (tests/records.rs finds it), or any CSV file by its path
//! cargo run --release --example diagnose_dev -- file brfd/char_0.5Hz_36lb_1in.csv --decimate 16 \
//!     --orders '0,1,1' --validate brfd/KocaeliDBE_36lb.csv
//! ```

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};

use backlash::diagnose::bench::{Scenario, scenario};
use backlash::diagnose::effects::EffectId;
use backlash::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};
use backlash::diagnose::record::decimate;
use backlash::io::Table;

#[path = "../tests/records.rs"]
#[allow(
    dead_code,
    reason = "this tool uses find_record only, not the tests' panicking record"
)]
mod records;

#[derive(Parser)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Diagnose simulated records with one undeclared effect each and count the right answers.
    Sweep {
        /// Seeds, as FIRST..END (END not included).
        #[arg(long, default_value = "0..5")]
        seeds: String,
        /// Comma-separated effect ids, `clean` for records without an effect (default: all and clean).
        #[arg(long)]
        effects: Option<String>,
        /// Samples per record.
        #[arg(long, default_value_t = 3000)]
        n: usize,
        /// Print the tests and candidates of every wrong answer.
        #[arg(long)]
        verbose: bool,
    },
    /// Diagnose a measured record (columns t, u, y) with declared structures.
    File {
        /// A CSV file, or a measured record by its name in data/ (e.g. brfd/char_0.5Hz_36lb_1in.csv).
        path: PathBuf,
        /// Keep every FACTOR-th sample after averaging.
        #[arg(long, default_value_t = 16)]
        decimate: usize,
        /// Declared structures `na,nb,delay`, several separated by `;`.
        #[arg(long, default_value = "0,1,1")]
        orders: String,
        /// Records (columns t, u, y; files or names in data/) to run the fitted models on without refitting.
        #[arg(long, value_delimiter = ',')]
        validate: Vec<PathBuf>,
        /// Print only the summary and the validations, not the tests and candidates.
        #[arg(long)]
        quiet: bool,
    },
}

fn main() -> Result<()> {
    match Cli::parse().command {
        Command::Sweep {
            seeds,
            effects,
            n,
            verbose,
        } => sweep(
            parse_seeds(&seeds)?,
            &parse_effects(effects.as_deref())?,
            n,
            verbose,
        ),
        Command::File {
            path,
            decimate,
            orders,
            validate,
            quiet,
        } => file(&path, decimate, &orders, &validate, quiet),
    }
}

fn parse_seeds(text: &str) -> Result<Range<u64>> {
    let (a, b) = text
        .split_once("..")
        .with_context(|| format!("--seeds {text}: expected FIRST..END, e.g. 0..5"))?;
    let first = a
        .parse()
        .with_context(|| format!("--seeds: '{a}' is not a whole number"))?;
    let end = b
        .parse()
        .with_context(|| format!("--seeds: '{b}' is not a whole number"))?;
    Ok(first..end)
}

/// `None` stands for a clean record.
fn parse_effects(list: Option<&str>) -> Result<Vec<Option<EffectId>>> {
    let Some(list) = list else {
        return Ok(std::iter::once(None)
            .chain(EffectId::all().map(Some))
            .collect());
    };
    list.split(',')
        .map(|name| match name {
            "clean" => Ok(None),
            _ => EffectId::parse(name)
                .map(Some)
                .with_context(|| format!("--effects: '{name}' is not an effect id")),
        })
        .collect()
}

fn effect_name(e: Option<EffectId>) -> String {
    e.map_or_else(|| "null".into(), |e| e.to_string())
}

/// The right answer for a simulated record: exactly its effects named (none for a clean one), with the
/// held-out error falling when there is an effect.
fn right_answer(s: &Scenario, d: &Diagnosis) -> bool {
    let mut named: Vec<EffectId> = d.steps().iter().map(|c| c.id).collect();
    let mut present = s.present.clone();
    named.sort();
    present.sort();
    named == present && (present.is_empty() || d.after_rmse() < d.base_heldout_rmse)
}

fn sweep(seeds: Range<u64>, effects: &[Option<EffectId>], n: usize, verbose: bool) -> Result<()> {
    for &effect in effects {
        let started = Instant::now();
        let mut right = 0;
        for seed in seeds.clone() {
            let s = scenario(effect, seed, n);
            let (na, nb, delay) = s.declared;
            let t = Instant::now();
            let d = diagnose(&s.u, &s.y, &DiagnoseConfig::new(na, nb, delay))?;
            let ok = right_answer(&s, &d);
            right += usize::from(ok);
            println!(
                "{} seed {seed:>5}: {:>20} before {:.4} after {:.4} ({:.2} s, {} plain fits) {}",
                if ok { "right" } else { "WRONG" },
                effect_name(d.effect_id()),
                d.base_heldout_rmse,
                d.after_rmse(),
                t.elapsed().as_secs_f64(),
                d.base_rounds,
                s.description
            );
            if verbose && !ok {
                print_decision(&d);
            }
        }
        println!(
            "== {}: {right} of {} right in {:.1} s",
            effect.map_or_else(|| "clean".into(), |e| e.to_string()),
            seeds.end.saturating_sub(seeds.start),
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// A file given by its path, or else a measured record by its name in data/.
fn locate(path: &Path) -> Result<PathBuf> {
    if path.is_file() {
        return Ok(path.to_path_buf());
    }
    records::find_record(&path.to_string_lossy()).map_err(anyhow::Error::msg)
}

/// The columns u and y of a record, decimated.
fn read_decimated(path: &Path, factor: usize) -> Result<Vec<Vec<f64>>> {
    let path = &locate(path)?;
    let table = Table::read(path, &["t", "u", "y"])?;
    let column = |name| {
        table
            .column(name)
            .with_context(|| format!("{}: no column {name}", path.display()))
    };
    Ok(decimate(&[column("u")?, column("y")?], factor))
}

fn parse_structure(text: &str) -> Result<DiagnoseConfig> {
    let v: Vec<usize> = text
        .split(',')
        .map(|x| x.trim().parse())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--orders: '{text}' is not na,nb,delay"))?;
    let [na, nb, delay] = v[..] else {
        bail!(
            "--orders: '{text}' has {} numbers, expected na,nb,delay",
            v.len()
        );
    };
    Ok(DiagnoseConfig::new(na, nb, delay))
}

fn file(path: &Path, factor: usize, orders: &str, validate: &[PathBuf], quiet: bool) -> Result<()> {
    let record = read_decimated(path, factor)?;
    let others = validate
        .iter()
        .map(|p| read_decimated(p, factor))
        .collect::<Result<Vec<_>>>()?;
    for structure in orders.split(';') {
        let cfg = parse_structure(structure)?;
        let t = Instant::now();
        let d = diagnose(&record[0], &record[1], &cfg)?;
        println!(
            "{} decimated by {factor}, structure {structure}: {} samples -> {} before {:.4} after {:.4} ({:.2} s)",
            path.display(),
            d.n,
            effect_name(d.effect_id()),
            d.base_heldout_rmse,
            d.after_rmse(),
            t.elapsed().as_secs_f64()
        );
        println!("   plain model {:?}", d.base.base);
        for (p, v) in validate.iter().zip(&others) {
            match d.cross_validate(&v[0], &v[1]) {
                Some(cv) => println!(
                    "   on {}: {} samples, y std {:.4}, RMSE plain {:.4}, with the effect {:.4}",
                    p.display(),
                    cv.samples,
                    cv.y_std,
                    cv.rmse_before,
                    cv.rmse_after
                ),
                None => println!("   on {}: the models cannot be run on it", p.display()),
            }
        }
        if !quiet {
            print_decision(&d);
        }
    }
    Ok(())
}

/// Every residual test (R: rejects) and every candidate (+: kept) with its numbers.
fn print_decision(d: &Diagnosis) {
    for t in &d.tests {
        let v = &t.verdict;
        println!(
            "   {} {:>42}: {:.3} / {:.3}  {}",
            if v.rejects { "R" } else { " " },
            v.name,
            v.statistic,
            v.threshold,
            v.detail
        );
    }
    for c in &d.candidates {
        println!(
            "   {} {:>20} held-out {:.4} z {:6.2} dBIC {:8.1} fit {:.4} {:?}",
            if c.supported { "+" } else { "-" },
            c.id,
            c.heldout_rmse,
            c.heldout_z,
            c.delta_bic,
            c.fit_rmse,
            c.model.exts
        );
    }
}
