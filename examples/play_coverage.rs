//! How often the diagnosis's 95% interval on the play, `backlash.play +/- 1.96 backlash.play_se`, covers the
//! true play, on simulated records with play and coloured noise (issue 56, item 2). Not part of the test
//! suite: it runs the whole diagnosis on hundreds of records.
//!
//! ```sh
//! cargo run --release --example play_coverage -- --records 200 --out docs/play_coverage.csv
//! ```
//!
//! Each record: a random stable linear block (first order, or second order with real or complex poles,
//! static gain 0.5..2, delay 1..3) driven by paper 000's white uniform input, then a straight backlash (slopes
//! 0.7..1.5, a gap of 5..25% of the travel of the linear block's output split at random between c1 and c2),
//! and AR(1) measurement noise (phi 0.5..0.9) at a noise level that alternates between records: std(noise-free
//! output) / noise std = 30 and 10. Each record is diagnosed by `backlash::api::diagnose` with
//! `DiagnoseConfig::auto()` (the command line's defaults). The diagnosis fixes the upper slope at 1 (the
//! linear block's gain carries the scale), so the true play in its units is m1 (c1 + c2): the c1 + c2 of the
//! equivalent plant with m1 = 1.
//!
//! The table splits the records by what explains a miss: whether the true borders cross inside the record
//! (a model crossed on more than `MAX_INVERTED_SHARE` of the fit part is refused by the fit, so the truth
//! cannot be found; `--uncrossed` draws only plants whose borders do not, as paper 000's) and whether the
//! final model's held-out error is at the noise level (a fit at the optimum) or above it (a fit that ended
//! elsewhere).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Parser;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rayon::prelude::*;

use backlash::api::diagnose;
use backlash::diagnose::effects::rig::Draw;
use backlash::diagnose::engine::DiagnoseConfig;
use backlash::diagnose::fit::model::MAX_INVERTED_SHARE;
use backlash::diagnose::search::presence::Presence;
use backlash::identify::mrgia::paper_input;
use backlash::plant::PlantParams;
use backlash::plant::backlash::BacklashParams;
use backlash::plant::effects::{ColouredNoise, Effects, simulate_with_effects, zone_inverted};
use backlash::stats::std_dev;

mod sim;
use sim::{FIT, backlash_of, effect_names, linear_block, reversals, run, travel};

#[derive(Parser)]
struct Cli {
    /// Records (the noise levels alternate).
    #[arg(long, default_value_t = 200)]
    records: usize,
    /// Samples per record.
    #[arg(long, default_value_t = 3000)]
    samples: usize,
    /// The first record's seed (record i has seed FIRST + i).
    #[arg(long, default_value_t = 0)]
    first: u64,
    /// One plant for every record (the plant of this record's seed), with a new noise draw in each: the
    /// spread of the estimate over noise draws against its standard error.
    #[arg(long)]
    plant: Option<u64>,
    /// The AR(1) coefficient of the noise, drawn uniformly in LO..HI (0..0: white noise).
    #[arg(long, default_value = "0.5..0.9")]
    phi: String,
    /// One line per record (CSV).
    #[arg(long)]
    out: Option<PathBuf>,
    /// A folder for each diagnosis's JSON (SEED-NOISE.json).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Redraw the slopes and the split of the gap until the borders cross on at most 1% of the fit part, as
    /// paper 000's do (their crossing, at x = -4, lies beyond its record): the plants the diagnosis takes for
    /// a backlash (`MAX_INVERTED_SHARE`).
    #[arg(long)]
    uncrossed: bool,
}

/// The noise levels: std(noise-free output) / noise std.
const SNR: [f64; 2] = [30.0, 10.0];
/// A final model whose held-out RMSE is below this many noise standard deviations fits at the noise level
/// (the true model's is about 1): above it, the fit ended away from the optimum.
const AT_NOISE: f64 = 1.2;
/// `--uncrossed`: the largest share of the fit part where the borders may be crossed.
const UNCROSSED: f64 = 0.01;
/// The two-sided 95% point of the normal distribution, as the interval is read.
const Z95: f64 = 1.96;

/// One diagnosed record.
struct Row {
    /// The plant's seed and the noise draw's.
    seed: u64,
    noise: u64,
    snr: f64,
    phi: f64,
    truth: f64,
    share: f64,
    crossings: usize,
    play: f64,
    se: Option<f64>,
    se_white: Option<f64>,
    presence: Presence,
    effects: String,
    /// The final model's held-out RMSE over the noise's standard deviation (about 1 at the true model).
    excess: f64,
    /// The share of the fit part where the true borders are crossed (upper border left of the lower one).
    inverted: f64,
    /// The chosen structure (na, nb, delay) and the plain model's play (before any effect).
    structure: (usize, usize, usize),
    plain_play: f64,
    what: String,
}

impl Row {
    /// Whether `play +/- 1.96 se` covers the truth; `None` without a standard error.
    fn covers(&self, se: Option<f64>) -> Option<bool> {
        se.map(|s| (self.play - self.truth).abs() <= Z95 * s)
    }
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    let phi = parse_range(&cli.phi)?;
    let start = Instant::now();
    let done = AtomicUsize::new(0);
    let rows: Vec<Row> = (0..cli.records as u64)
        .into_par_iter()
        .map(|i| {
            let seed = cli.first + i;
            let (plant, noise) = match cli.plant {
                Some(plant) => (plant, seed),
                None => (seed, seed ^ 0x5EED),
            };
            let draws = (phi, cli.uncrossed);
            let row = record(plant, noise, cli.samples, draws, cli.json.as_deref());
            let k = done.fetch_add(1, Ordering::Relaxed) + 1;
            eprintln!(
                "[{k}/{} {:.0} s] seed {} noise {}: play {:.4} +/- {} against {:.4}, {:?}",
                cli.records,
                start.elapsed().as_secs_f64(),
                row.seed,
                row.noise,
                row.play,
                row.se.map_or("none".into(), |s| format!("{s:.4}")),
                row.truth,
                row.presence
            );
            row
        })
        .collect();
    println!("{}", summary(&rows));
    println!("total {:.0} s", start.elapsed().as_secs_f64());
    if let Some(path) = cli.out {
        write_csv(&path, &rows).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The plant and noise level of record `seed`, simulated with the noise draw `noise` and diagnosed; the
/// noise's AR coefficient drawn in `lo..hi`, the borders `uncrossed` if asked.
fn record(
    seed: u64,
    noise: u64,
    n: usize,
    ((lo, hi), uncrossed): ((f64, f64), bool),
    json: Option<&Path>,
) -> Row {
    let mut d = Draw(ChaCha8Rng::seed_from_u64(seed));
    let u = paper_input(n, seed);
    let arx = linear_block(&mut d);
    let x: Vec<f64> = run(arx, backlash_of(&mut d, 0.0), &Effects::default(), &u)
        .iter()
        .map(|o| o.x)
        .collect();
    let share = d.uniform(0.05, 0.25);
    let mut bl = backlash_of(&mut d, share * travel(&x));
    for _ in 0..1000 {
        if !uncrossed || inverted_share(&bl, &x) <= UNCROSSED {
            break;
        }
        bl = backlash_of(&mut d, share * travel(&x));
    }
    assert!(
        !uncrossed || inverted_share(&bl, &x) <= UNCROSSED,
        "seed {seed}: no uncrossed borders in 1000 draws"
    );
    let phi = d.uniform(lo, hi);
    let snr = SNR[(seed % 2) as usize];
    let effects = Effects {
        coloured_noise: Some(ColouredNoise { phi }),
        ..Effects::default()
    };
    let clean = run(arx, bl, &effects, &u);
    let f: Vec<f64> = clean.iter().map(|o| o.f).collect();
    let w: Vec<f64> = clean.iter().map(|o| o.w).collect();
    let inverted = inverted_share(&bl, &x);
    let params = PlantParams {
        arx,
        backlash: bl,
        noise_std: std_dev(&f) / snr,
        noise_seed: noise,
    };
    let y: Vec<f64> = simulate_with_effects(&params, &effects, &u, noise)
        .expect("the drawn plant is valid")
        .iter()
        .map(|o| o.y)
        .collect();
    let diag = diagnose(&u, &y, &DiagnoseConfig::auto()).expect("the record is valid");
    if let Some(dir) = json {
        let path = dir.join(format!("{seed}-{noise}.json"));
        let text = serde_json::to_string_pretty(&diag.to_json(None)).expect("JSON");
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
    }
    let b = &diag.backlash;
    Row {
        seed,
        noise,
        snr,
        phi,
        truth: bl.m1 * (bl.c1 + bl.c2),
        share,
        crossings: reversals(&w),
        play: b.play,
        se: b.play_se,
        se_white: b.play_se_white,
        presence: b.presence,
        effects: effect_names(&diag),
        structure: (
            diag.structure.chosen.na,
            diag.structure.chosen.nb,
            diag.structure.chosen.delay,
        ),
        plain_play: diag.base.play(),
        excess: b.heldout_rmse / params.noise_std,
        inverted,
        what: format!(
            "a {:.3} {:.3}, b0 {:.3}, delay {}; m1 {:.3}, m2 {:.3}, c1 {:.4}, c2 {:.4}",
            arx.a[0], arx.a[1], arx.b[0], arx.delay, bl.m1, bl.m2, bl.c1, bl.c2
        ),
    }
}

/// The share of the fit part of the linear block's output `x` where the borders of `bl` are crossed (the
/// upper border left of the lower one).
fn inverted_share(bl: &BacklashParams, x: &[f64]) -> f64 {
    let fit = &x[..(FIT * x.len() as f64) as usize];
    fit.iter().filter(|&&v| zone_inverted(bl, None, v)).count() as f64 / fit.len() as f64
}

/// `LO..HI` as two numbers, each in (-1, 1).
fn parse_range(text: &str) -> Result<(f64, f64)> {
    let (a, b) = text
        .split_once("..")
        .with_context(|| format!("--phi {text}: expected LO..HI, e.g. 0.5..0.9"))?;
    let parse = |v: &str| -> Result<f64> {
        let x: f64 = v
            .parse()
            .with_context(|| format!("--phi: '{v}' is not a number"))?;
        anyhow::ensure!(x.abs() < 1.0, "--phi: {x} is not between -1 and 1");
        Ok(x)
    };
    Ok((parse(a)?, parse(b)?))
}

/// Coverage of one group of rows with one standard error: "covered / with se (percent)".
fn coverage<'a>(rows: impl Iterator<Item = &'a Row>, se: impl Fn(&Row) -> Option<f64>) -> String {
    let (mut with, mut covered) = (0, 0);
    for r in rows {
        if let Some(c) = r.covers(se(r)) {
            with += 1;
            covered += usize::from(c);
        }
    }
    let pct = if with == 0 {
        f64::NAN
    } else {
        100.0 * covered as f64 / with as f64
    };
    format!("{covered} / {with} ({pct:.1}%)")
}

/// The coverage table in Markdown: all records, per noise level, per verdict and per final model (bare or
/// with effects), with the sandwich standard error (`play_se`) and the white one (`play_se_white`).
fn summary(rows: &[Row]) -> String {
    let mut s = String::from(
        "| records | N | no se | covered, play_se (sandwich) | covered, play_se_white |\n\
         | --- | ---: | ---: | ---: | ---: |\n",
    );
    let mut line = |name: String, keep: &dyn Fn(&Row) -> bool| {
        let group: Vec<&Row> = rows.iter().filter(|r| keep(r)).collect();
        if group.is_empty() {
            return;
        }
        s += &format!(
            "| {name} | {} | {} | {} | {} |\n",
            group.len(),
            group.iter().filter(|r| r.se.is_none()).count(),
            coverage(group.iter().copied(), |r| r.se),
            coverage(group.iter().copied(), |r| r.se_white),
        );
    };
    line("all".into(), &|_| true);
    for snr in SNR {
        line(format!("noise level {snr}"), &|r| r.snr == snr);
    }
    for p in [Presence::Present, Presence::Absent, Presence::Undetermined] {
        line(format!("{p:?}"), &|r| r.presence == p);
    }
    line(
        format!("true borders crossed on at most {MAX_INVERTED_SHARE} of the fit part"),
        &|r| r.inverted <= MAX_INVERTED_SHARE,
    );
    line(
        format!("true borders crossed on more than {MAX_INVERTED_SHARE} of the fit part"),
        &|r| r.inverted > MAX_INVERTED_SHARE,
    );
    line(
        format!("held-out RMSE below {AT_NOISE} noise std (a fit at the optimum)"),
        &|r| r.excess < AT_NOISE,
    );
    line(
        format!("held-out RMSE at least {AT_NOISE} noise std (a fit elsewhere)"),
        &|r| r.excess >= AT_NOISE,
    );
    line("final model plain".into(), &|r| r.effects.is_empty());
    line("final model with effects".into(), &|r| {
        !r.effects.is_empty()
    });
    s
}

/// A CSV field, quoted.
fn field(s: &str) -> String {
    format!("\"{}\"", s.replace('"', "\"\""))
}

/// One line per record: the truth, the estimate and whether its intervals cover the truth.
fn write_csv(path: &Path, rows: &[Row]) -> std::io::Result<()> {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        f,
        "seed,noise_seed,snr,phi,true_play,true_share,true_crossings,play,play_se,play_se_white,covered,\
         covered_white,presence,effects,structure,plain_play,heldout_over_noise,true_inverted_share,plant"
    )?;
    let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.6}"));
    let flag = |v: Option<bool>| v.map_or(String::new(), |c| c.to_string());
    for r in rows {
        writeln!(
            f,
            "{},{},{},{:.3},{:.6},{:.4},{},{:.6},{},{},{},{},{:?},{},{} {} {},{:.6},{:.3},{:.4},{}",
            r.seed,
            r.noise,
            r.snr,
            r.phi,
            r.truth,
            r.share,
            r.crossings,
            r.play,
            opt(r.se),
            opt(r.se_white),
            flag(r.covers(r.se)),
            flag(r.covers(r.se_white)),
            r.presence,
            field(&r.effects),
            r.structure.0,
            r.structure.1,
            r.structure.2,
            r.plain_play,
            r.excess,
            r.inverted,
            field(&r.what),
        )?;
    }
    f.flush()
}
