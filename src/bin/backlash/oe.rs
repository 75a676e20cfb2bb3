//! `backlash identify oe` (output-error refinement from MRGIA, with standard errors) and `backlash crb`
//! (Cramer-Rao bound of an input record: plan an experiment).

use super::common::{ModelArgs, RecordArgs, print_json, print_warnings, spinner};
use super::structure::StructureArgs;
use anyhow::{Context, Result, bail};
use backlash::api::{
    CrbNoise, CrbRun, OeOptions, OeRun, Record, choose_rate, crb, identify_oe_with_progress,
    with_rate,
};
use backlash::diagnose::engine::DiagnoseConfig;
use backlash::identify::mrgia::paper_input;
use backlash::identify::oe::{Uncertainty, simulate, theta_of};
use backlash::io::write_atomic;
use backlash::report::plot::{Axes, Series, line_plot};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct OeArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored; names configurable).
    pub file: PathBuf,
    #[command(flatten)]
    pub record: RecordArgs,
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
    let rec = args.record.options().read(&args.file, true)?;
    let rate = choose_rate(
        &rec.u,
        &rec.y,
        args.record.decimate,
        DiagnoseConfig::auto().fit_fraction,
    )
    .with_context(|| format!("{}", args.file.display()))?;
    let rec = match rate.chosen_by {
        "data" => rec.decimated(rate.decimate),
        _ => rec,
    };
    let opts = OeOptions {
        structure: args.structure.declared(),
        max_delay: args.structure.max_delay()?,
        single_start: args.single_start,
        max_iter: args.max_iter,
        crb_noise_std: args.crb_noise_std,
    };
    let progress = spinner(args.json, "reading");
    let run = identify_oe_with_progress(&rec.u, &rec.y, &opts, &|s| {
        progress.set_message(s.to_owned())
    });
    progress.finish_and_clear();
    let run = run.with_context(|| format!("{}", args.file.display()))?;
    if args.residuals.is_some() || args.plot.is_some() {
        write_fit_outputs(args, &rec, &run)?;
    }
    let mut out = run.json(args.target_rel)?;
    with_rate(&mut out, &rate);
    if args.json {
        print_json(out, &args.file);
        return Ok(());
    }
    println!("Rate ({}): {}", rate.chosen_by, rate.reason);
    print_oe(args, &run)?;
    print_warnings(&out);
    Ok(())
}

/// `--residuals` and `--plot`: the outputs of the fitted model and of its start.
fn write_fit_outputs(args: &OeArgs, rec: &Record, run: &OeRun) -> Result<()> {
    let (f, delay, u) = (&run.fit, run.cfg.delay, &rec.u);
    let w = simulate(&f.estimate, delay, u)?;
    let w0 = simulate(&f.start, delay, u)?;
    let (t, y) = (&rec.t, &rec.y);
    if let Some(path) = &args.residuals {
        write_atomic(path, |out: &mut dyn Write| {
            writeln!(out, "time,u,y,y_oe,e_oe,y_start")?;
            for k in 0..u.len() {
                let (tk, uk, yk) = (t[k], u[k], y[k]);
                writeln!(
                    out,
                    "{tk:?},{uk:?},{yk:?},{:?},{:?},{:?}",
                    w[k],
                    yk - w[k],
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
            rec.label(0),
            rec.label(2),
            &[
                Series::points(format!("measured {}", rec.label(2)), pts(y)).color(7),
                Series::line("OE model", pts(&w)).color(0),
                Series::dashed(format!("start ({})", f.start_method), pts(&w0)).color(1),
            ],
            Axes::LINEAR,
        )?;
    }
    Ok(())
}

fn print_oe(args: &OeArgs, run: &OeRun) -> Result<()> {
    let f = &run.fit;
    println!(
        "Structure: {} ({})",
        run.structure.reason, run.structure.chosen_by
    );
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
    let names = &f.uncertainty.names;
    for (i, n) in names.iter().enumerate() {
        print!("  {n:>3} = {:.6} +/- {:.6}", est[i], f.uncertainty.std[i]);
        if let Some(c) = &run.bound {
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
    Ok(())
}

#[derive(clap::Args)]
pub struct CrbArgs {
    /// Input record: CSV with columns time,u (y and other columns ignored). Omit it with --paper-input.
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub record: RecordArgs,
    /// Use N samples of the paper's input (uniform white noise of variance 1.93) instead of a file.
    #[arg(long, conflicts_with = "file")]
    pub paper_input: Option<usize>,
    /// Seed of --paper-input.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    // The true model (default: paper 000's example; the bound is for the m1 = 1 normalisation: b, c scaled
    // by m1, m2 divided).
    #[command(flatten)]
    pub truth: ModelArgs,
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

/// The input of `crb`: a file's u column, or the paper's input; with words for where it came from.
fn crb_input(args: &CrbArgs) -> Result<(Vec<f64>, String)> {
    match (&args.file, args.paper_input) {
        (Some(path), _) => Ok((
            args.record.options().read(path, false)?.u,
            path.display().to_string(),
        )),
        (None, Some(n)) => Ok((
            paper_input(n, args.seed),
            format!("paper input, seed {}", args.seed),
        )),
        (None, None) => bail!("give an input file or --paper-input N"),
    }
}

pub fn run_crb(args: &CrbArgs) -> Result<()> {
    let (u, source) = crb_input(args)?;
    let noise = match (args.noise_std, args.snr) {
        (Some(s), _) => CrbNoise::Std(s),
        (None, Some(r)) => CrbNoise::Snr(r),
        (None, None) => bail!("give --noise-std or --snr"),
    };
    let run = crb(&u, &args.truth.spec, noise)?;
    let out = run.json(&source, args.target_rel)?;
    if args.json {
        println!("{out}");
        return Ok(());
    }
    print_crb(&run, &source, args.target_rel)?;
    print_warnings(&out);
    Ok(())
}

fn print_crb(run: &CrbRun, source: &str, target_rel: Option<f64>) -> Result<()> {
    let (c, rel) = (&run.bound, &run.rel);
    println!(
        "Cramer-Rao bound of the output-error model on {source}: {} samples, noise std {:e}",
        c.samples, c.noise_std
    );
    for (i, n) in c.names.iter().enumerate() {
        print!("  {n:>3} = {:<10} std >= {:.3e}", c.theta[i], c.std[i]);
        match rel[i] {
            Some(r) => println!("  ({r:.2e} relative)"),
            None => println!(),
        }
    }
    println!("  (m1 = 1 normalisation; any unbiased estimator's std is at least this)");
    if let Some(r) = target_rel {
        print_plan(c, r)?;
    }
    Ok(())
}
