//! `backlash study`: the Monte Carlo study of the paper's example (MRGIA, output error and the Cramer-Rao
//! bound against N), on all cores.

use anyhow::{Context, Result, bail};
use backlash::identify::oe::{self, GridConfig, GridResult, StudyResult};
use backlash::io::write_atomic;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::common::bar;

#[derive(clap::Args)]
pub struct StudyArgs {
    /// Number of Monte Carlo runs per (plant, SNR) (seeds FIRST_SEED..FIRST_SEED+SEEDS).
    #[arg(long, default_value_t = 100)]
    pub seeds: u64,
    /// First seed.
    #[arg(long, default_value_t = 0)]
    pub first_seed: u64,
    /// Record lengths, comma-separated (every run is read at each).
    #[arg(long, value_delimiter = ',', default_value = "300,1000,3000,10000")]
    pub ns: Vec<usize>,
    /// Signal-to-noise ratio std(w) / noise std (the paper's 43); the single-value form of --snrs.
    #[arg(long, allow_negative_numbers = true, conflicts_with = "snrs")]
    pub snr: Option<f64>,
    /// Signal-to-noise ratios, comma-separated (default: 43).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub snrs: Option<Vec<f64>>,
    /// Plant variants, comma-separated: paper, wide-gaps, symmetric, reversed-slopes, second-order-b
    /// (`backlash study --list-plants` describes them).
    #[arg(long, value_delimiter = ',', default_value = "paper")]
    pub plants: Vec<String>,
    /// Methods to report, comma-separated: mrgia-paper, mrgia-recommended, refine (MRGIA with the refine
    /// setting), oe, crb (default: all; leaving out refine, oe and crb skips their computation; crb also gives
    /// every estimator's worst-parameter error in CRB std units).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "mrgia-paper,mrgia-recommended,refine,oe,crb"
    )]
    pub methods: Vec<String>,
    /// Worker threads (default: all cores, or RAYON_NUM_THREADS).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Describe the plant variants and exit.
    #[arg(long)]
    pub list_plants: bool,
    /// Folder for the outputs (created if missing): study_runs.csv (one row per plant, SNR, N, seed, method
    /// and parameter), study_summary.csv and study.json (statistics per plant, SNR, method and N),
    /// study_<plant>_snr<SNR>.png (RMSE against N with the CRB); with a single plant and SNR also the
    /// earlier oe_study.png, oe_study.csv and oe_study.json.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    write_atomic(path, |w: &mut dyn Write| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}

/// The grid of the command line, checked.
fn grid(args: &StudyArgs) -> Result<GridConfig> {
    if args.seeds == 0 || args.ns.is_empty() || args.ns.iter().any(|&n| n < 10) {
        bail!("--seeds must be at least 1 and every N in --ns at least 10");
    }
    let snrs = match (&args.snrs, args.snr) {
        (Some(v), _) => v.clone(),
        (None, Some(r)) => vec![r],
        (None, None) => vec![43.0],
    };
    if let Some(r) = snrs.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
        bail!("--snr {r} must be a positive finite number");
    }
    let cfg = GridConfig {
        seeds: args.seeds,
        first_seed: args.first_seed,
        ns: args.ns.clone(),
        snrs,
        plants: args.plants.clone(),
        methods: args.methods.clone(),
    };
    cfg.validate().context("invalid study grid")?;
    Ok(cfg)
}

fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        if t == 0 {
            bail!("--threads must be at least 1");
        }
        b = b.num_threads(t);
    }
    b.build().context("cannot start the worker threads")
}

pub fn run_study(args: &StudyArgs) -> Result<()> {
    if args.list_plants {
        for v in oe::PLANT_VARIANTS {
            println!("{:<16} {}", v.name, v.description);
        }
        return Ok(());
    }
    let cfg = grid(args)?;
    let pool = pool(args.threads)?;
    let threads = pool.current_num_threads();
    let progress = bar(
        args.json,
        cfg.runs(),
        "{bar:40} {pos}/{len} runs (eta {eta})",
    );
    let started = Instant::now();
    let r = pool.install(|| oe::grid_study(&cfg, &|| progress.inc(1)))?;
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let files = match &args.out {
        Some(dir) => write_outputs(dir, &r)?,
        None => vec![],
    };
    if args.json {
        print_json(&cfg, &r, threads, seconds, &files)
    } else {
        print_text(args, &cfg, &r, threads, seconds, &files);
        Ok(())
    }
}

/// The group of a study of one (plant, SNR), whose fields the JSON and the files keep at the top level.
fn single(r: &GridResult) -> Option<&StudyResult> {
    (r.groups.len() == 1).then(|| &r.groups[0])
}

/// The files of `--out`, written; their paths.
fn write_outputs(dir: &Path, r: &GridResult) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let text = |name: &str, content: &str| -> Result<PathBuf> {
        let path = dir.join(name);
        write_text(&path, content)?;
        Ok(path)
    };
    let plot = |name: &str, g: &StudyResult| -> Result<PathBuf> {
        let path = dir.join(name);
        g.plot(&path)?;
        Ok(path)
    };
    let mut files = vec![
        text("study_runs.csv", &r.rows_csv())?,
        text("study_summary.csv", &r.summary_csv())?,
        text("study.json", &serde_json::to_string_pretty(r)?)?,
    ];
    for g in &r.groups {
        files.push(plot(
            &format!("study_{}_snr{}.png", g.plant, g.config.snr),
            g,
        )?);
    }
    if let Some(g) = single(r) {
        files.push(plot("oe_study.png", g)?);
        files.push(text("oe_study.csv", &g.to_csv())?);
        files.push(text("oe_study.json", &serde_json::to_string_pretty(g)?)?);
    }
    Ok(files)
}

fn print_json(
    cfg: &GridConfig,
    r: &GridResult,
    threads: usize,
    seconds: f64,
    files: &[PathBuf],
) -> Result<()> {
    // With one (plant, SNR) the fields of that study at the top level, as before the grid existed.
    let mut out = match single(r) {
        Some(g) => serde_json::to_value(g)?,
        None => json!({}),
    };
    out["grid"] = serde_json::to_value(&r.config)?;
    out["groups"] = serde_json::to_value(&r.groups)?;
    out["runs"] = json!(cfg.runs());
    out["threads"] = json!(threads);
    out["seconds"] = json!(seconds);
    out["files"] = json!(
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
    );
    println!("{out}");
    Ok(())
}

fn print_text(
    args: &StudyArgs,
    cfg: &GridConfig,
    r: &GridResult,
    threads: usize,
    seconds: f64,
    files: &[PathBuf],
) {
    println!(
        "Monte Carlo study: {} runs ({} plant(s) x {} SNR(s) x {} seeds) on {threads} thread(s), {:.1} s",
        cfg.runs(),
        cfg.plants.len(),
        cfg.snrs.len(),
        cfg.seeds,
        seconds
    );
    let mut ns = args.ns.clone();
    ns.sort_unstable();
    ns.dedup();
    for g in &r.groups {
        println!("\nPlant {}, SNR {}:", g.plant, g.config.snr);
        for &n in &ns {
            print_cell(g, n);
        }
    }
    for f in files {
        println!("wrote {}", f.display());
    }
}

/// The table of one (plant, SNR) at one N.
fn print_cell(g: &StudyResult, n: usize) {
    println!("N = {n}: RMSE per parameter (truth {:?})", g.truth);
    print!("  {:<18}", "method");
    for name in &g.names {
        print!("{name:>11}");
    }
    println!("  median max rel  worst/CRB: median, >10, >100, max");
    for m in oe::METHODS {
        if let Some(s) = g.get(m, n) {
            print!("  {m:<18}");
            for v in &s.rmse {
                print!("{v:>11.3e}");
            }
            print!("  {:.3e}", s.median_max_rel);
            match s.crb_units {
                Some(c) => println!(
                    "       {:.2}, {:.1}%, {:.1}%, {:.3}",
                    c.median,
                    100.0 * c.share_over_10,
                    100.0 * c.share_over_100,
                    c.max
                ),
                None => println!(),
            }
        }
    }
    for m in ["refine", "oe"] {
        if let Some(s) = g.get(m, n)
            && let Some(c) = &s.coverage
        {
            print!("  {:<18}", format!("{m} 95% coverage"));
            for v in c {
                print!("{v:>11.2}");
            }
            println!("  ({} failed)", s.failures);
        }
    }
}
