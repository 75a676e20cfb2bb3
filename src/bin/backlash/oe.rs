//! `backlash identify oe` (output-error refinement from MRGIA, with standard errors), `backlash crb`
//! (Cramer-Rao bound of an input record: plan an experiment) and `backlash study` (Monte Carlo study of the
//! paper's example).

use super::structure::StructureArgs;
use anyhow::{Context, Result, bail};
use backlash::api::{CrbNoise, OeOptions, PlantSpec, crb, identify_oe};
use backlash::identify::mrgia::paper_input;
use backlash::identify::oe::{self, GridConfig, Uncertainty, param_names, simulate, theta_of};
use backlash::io::{Table, write_atomic};
use backlash::report::plot::{Axes, Series, line_plot};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct OeArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored).
    pub file: PathBuf,
    #[command(flatten)]
    pub structure: StructureArgs,
    /// Start only from MRGIA's recommended estimate (default: also from the paper setting's estimate and
    /// from the recommended one with halved gaps, keeping the lowest cost).
    #[arg(long)]
    pub single_start: bool,
    /// Levenberg-Marquardt iterations per start (default 200).
    #[arg(long)]
    pub max_iter: Option<usize>,
    /// Cramer-Rao bound at the fitted model and this input for a noise std S (default: none; with the
    /// estimated noise std the bound equals the reported standard errors).
    #[arg(long, allow_negative_numbers = true)]
    pub crb_noise_std: Option<f64>,
    /// Plan: samples needed so that every parameter's relative standard deviation is at most R (from the
    /// standard errors, or from the CRB with --crb-noise-std, scaled as 1/sqrt(N)).
    #[arg(long, allow_negative_numbers = true)]
    pub target_rel: Option<f64>,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
    /// Write time,u,y,y_oe,e_oe,y_start as CSV (model outputs of the fit and of its start).
    #[arg(long)]
    pub residuals: Option<PathBuf>,
    /// Write a PNG of the measured output, the fitted model's output and its start's (first 150 samples).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

fn print_plan(unc: &Uncertainty, target: f64) -> Result<()> {
    let (per, all) = unc.samples_for(target)?;
    println!(
        "  samples for a relative std <= {target:e} (1/sqrt(N) scaling of N = {}):",
        unc.samples
    );
    for (n, s) in unc.names.iter().zip(&per) {
        match s {
            Some(s) => println!("    {n:>3}: {s}"),
            None => println!("    {n:>3}: - (value 0)"),
        }
    }
    println!("    all: {all}");
    Ok(())
}

pub fn run_oe(args: &OeArgs) -> Result<()> {
    let max_delay = args.structure.max_delay()?;
    let table = Table::read(&args.file, &["time", "u", "y"])?;
    let (t, u, y) = (
        table.column("time").unwrap(),
        table.column("u").unwrap(),
        table.column("y").unwrap(),
    );
    let opts = OeOptions {
        structure: args.structure.declared(),
        max_delay,
        single_start: args.single_start,
        max_iter: args.max_iter,
        crb_noise_std: args.crb_noise_std,
    };
    let run = identify_oe(u, y, &opts).with_context(|| format!("{}", args.file.display()))?;
    let (f, cfg, structure) = (&run.fit, &run.cfg, &run.structure);
    let names = param_names(cfg.na, cfg.nb);
    let bound = run.bound.as_ref();

    if args.residuals.is_some() || args.plot.is_some() {
        let w = simulate(&f.estimate, cfg.delay, u)?;
        let w0 = simulate(&f.start, cfg.delay, u)?;
        if let Some(path) = &args.residuals {
            write_atomic(path, |out: &mut dyn Write| {
                writeln!(out, "time,u,y,y_oe,e_oe,y_start")?;
                for k in 0..u.len() {
                    writeln!(
                        out,
                        "{:?},{:?},{:?},{:?},{:?},{:?}",
                        t[k],
                        u[k],
                        y[k],
                        w[k],
                        y[k] - w[k],
                        w0[k]
                    )?;
                }
                Ok(())
            })
            .with_context(|| format!("{}: cannot write the residuals", path.display()))?;
        }
        if let Some(path) = &args.plot {
            let n = u.len().min(150);
            let pts = |v: &[f64]| -> Vec<(f64, f64)> { (0..n).map(|k| (t[k], v[k])).collect() };
            line_plot(
                path,
                &format!("Output-error fit, {}", args.file.display()),
                "time",
                "output",
                &[
                    Series::points("measured y", pts(y)).color(7),
                    Series::line("OE model", pts(&w)).color(0),
                    Series::dashed(&format!("start ({})", f.start_method), pts(&w0)).color(1),
                ],
                Axes::LINEAR,
            )?;
        }
    }

    if args.json {
        let mut out = run.json(args.target_rel)?;
        out["file"] = json!(args.file.display().to_string());
        println!("{out}");
    } else {
        println!("Structure: {} ({})", structure.reason, structure.chosen_by);
        println!(
            "Output-error fit on {}: {} samples, {} iterations from {} ({}), {:.1} ms",
            args.file.display(),
            f.samples,
            f.iterations,
            f.start_method,
            if f.converged {
                "converged"
            } else {
                "iteration limit reached"
            },
            run.seconds * 1e3
        );
        let est = theta_of(&f.estimate);
        for (i, n) in names.iter().enumerate() {
            print!("  {n:>3} = {:.6} +/- {:.6}", est[i], f.uncertainty.std[i]);
            if let Some(c) = bound {
                print!("   (CRB std at noise {:e}: {:.6})", c.noise_std, c.std[i]);
            }
            println!();
        }
        println!(
            "  residual std {:.6e} (N - p = {} degrees of freedom); start rmse {:.6e}",
            f.sigma,
            f.samples - names.len(),
            f.start_rmse
        );
        println!(
            "  (m1 = 1 is the normalisation; +/- is one standard error from the Fisher information)"
        );
        if let Some(r) = args.target_rel {
            print_plan(run.plan_basis(), r)?;
        }
    }
    Ok(())
}

#[derive(clap::Args)]
pub struct CrbArgs {
    /// Input record: CSV with columns time,u (y and other columns ignored). Omit it with --paper-input.
    pub file: Option<PathBuf>,
    /// Use N samples of the paper's input (uniform white noise of variance 1.93) instead of a file.
    #[arg(long, conflicts_with = "file")]
    pub paper_input: Option<usize>,
    /// Seed of --paper-input.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// True a1..a_na, comma-separated (default: the paper's 0.45,0.55).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub a: Option<Vec<f64>>,
    /// True b0..b_nb, comma-separated (default: the paper's 0.8).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub b: Option<Vec<f64>>,
    /// Delay in samples (default 1).
    #[arg(long)]
    pub delay: Option<usize>,
    /// True m1 (default 1; the bound is for the m1 = 1 normalisation: b, c scaled by m1, m2 divided).
    #[arg(long, allow_negative_numbers = true)]
    pub m1: Option<f64>,
    /// True m2 (default 1.5).
    #[arg(long, allow_negative_numbers = true)]
    pub m2: Option<f64>,
    /// True c1 (default 0.5).
    #[arg(long, allow_negative_numbers = true)]
    pub c1: Option<f64>,
    /// True c2 (default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub c2: Option<f64>,
    /// Measurement noise standard deviation.
    #[arg(long, allow_negative_numbers = true, required_unless_present = "snr")]
    pub noise_std: Option<f64>,
    /// Instead of --noise-std: noise std = std(w) / SNR, w the noise-free output on this input.
    #[arg(long, allow_negative_numbers = true, conflicts_with = "noise_std")]
    pub snr: Option<f64>,
    /// Plan: samples needed so that every parameter's relative CRB std is at most R.
    #[arg(long, allow_negative_numbers = true)]
    pub target_rel: Option<f64>,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
}

impl CrbArgs {
    fn truth(&self) -> PlantSpec {
        PlantSpec {
            a: self.a.clone(),
            b: self.b.clone(),
            delay: self.delay,
            m1: self.m1,
            m2: self.m2,
            c1: self.c1,
            c2: self.c2,
            noise_std: None,
            noise_seed: None,
        }
    }
}

pub fn run_crb(args: &CrbArgs) -> Result<()> {
    let truth = args.truth();
    let (u, source): (Vec<f64>, String) = match (&args.file, args.paper_input) {
        (Some(path), _) => {
            let table = Table::read(path, &["time", "u"])?;
            (
                table.column("u").unwrap().to_vec(),
                path.display().to_string(),
            )
        }
        (None, Some(n)) => (
            paper_input(n, args.seed),
            format!("paper input, seed {}", args.seed),
        ),
        (None, None) => bail!("give an input file or --paper-input N"),
    };
    let noise = match (args.noise_std, args.snr) {
        (Some(s), _) => CrbNoise::Std(s),
        (None, Some(r)) => CrbNoise::Snr(r),
        (None, None) => bail!("give --noise-std or --snr"),
    };
    let run = crb(&u, &truth, noise)?;
    if args.json {
        println!("{}", run.json(&source, args.target_rel)?);
    } else {
        let (c, rel) = (&run.bound, &run.rel);
        println!(
            "Cramer-Rao bound of the output-error model on {source}: {} samples, noise std {:e}",
            c.samples, c.noise_std
        );
        for (i, n) in c.names.iter().enumerate() {
            print!("  {n:>3} = {:<10} std >= {:.3e}", c.theta[i], c.std[i]);
            match rel[i] {
                Some(r) => println!("  ({:.2e} relative)", r),
                None => println!(),
            }
        }
        println!("  (m1 = 1 normalisation; any unbiased estimator's std is at least this)");
        if let Some(r) = args.target_rel {
            print_plan(c, r)?;
        }
    }
    Ok(())
}

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

fn write_text(path: &std::path::Path, text: &str) -> Result<()> {
    write_atomic(path, |w: &mut dyn Write| w.write_all(text.as_bytes()))
        .with_context(|| format!("{}: cannot write", path.display()))
}

pub fn run_study(args: &StudyArgs) -> Result<()> {
    if args.list_plants {
        for v in oe::PLANT_VARIANTS {
            println!("{:<16} {}", v.name, v.description);
        }
        return Ok(());
    }
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
    let pool = {
        let mut b = rayon::ThreadPoolBuilder::new();
        if let Some(t) = args.threads {
            if t == 0 {
                bail!("--threads must be at least 1");
            }
            b = b.num_threads(t);
        }
        b.build().context("cannot start the worker threads")?
    };
    let threads = pool.current_num_threads();
    let bar = if args.json {
        ProgressBar::hidden()
    } else {
        let b = ProgressBar::new(cfg.runs());
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} runs (eta {eta})")
                .expect("valid template"),
        );
        b
    };
    let started = Instant::now();
    let r = pool.install(|| oe::grid_study(&cfg, &|| bar.inc(1)))?;
    bar.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let single = (r.groups.len() == 1).then(|| &r.groups[0]);
    let mut files = vec![];
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create", dir.display()))?;
        let runs = dir.join("study_runs.csv");
        write_text(&runs, &r.rows_csv())?;
        let summary = dir.join("study_summary.csv");
        write_text(&summary, &r.summary_csv())?;
        let js = dir.join("study.json");
        write_text(&js, &serde_json::to_string_pretty(&r)?)?;
        files.extend([runs, summary, js]);
        for g in &r.groups {
            let png = dir.join(format!("study_{}_snr{}.png", g.plant, g.config.snr));
            g.plot(&png)?;
            files.push(png);
        }
        if let Some(g) = single {
            let png = dir.join("oe_study.png");
            g.plot(&png)?;
            let csv = dir.join("oe_study.csv");
            write_text(&csv, &g.to_csv())?;
            let js = dir.join("oe_study.json");
            write_text(&js, &serde_json::to_string_pretty(g)?)?;
            files.extend([png, csv, js]);
        }
    }
    if args.json {
        // With one (plant, SNR) the fields of that study at the top level, as before the grid existed.
        let mut out = match single {
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
        return Ok(());
    }
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
    }
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(())
}
