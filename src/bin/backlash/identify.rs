//! `backlash identify mrgia`: the recursive MRGIA estimator of paper 000 on a data file.

use anyhow::{Context, Result};
use backlash::api::{InputCheck, MrgiaSettings, mrgia_json};
use backlash::identify::mrgia::StepResult;
use backlash::identify::oe::online::OnlineEstimator;
use backlash::identify::oe::{param_names, theta_of};
use backlash::io::{AtomicFile, ReadAhead};
use backlash::report::plot::{Axes, Series, line_plot};
use indicatif::ProgressBar;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::common::{RecordArgs, bar, print_json, print_warnings};
use super::structure::OrderArgs;

/// Files larger than this (about 200,000 rows) show a progress bar (when not in --json mode).
const PROGRESS_MIN_BYTES: u64 = 5_000_000;

#[derive(clap::Args)]
pub struct MrgiaArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored; names configurable).
    pub file: PathBuf,
    #[command(flatten)]
    pub record: RecordArgs,
    #[command(flatten)]
    pub orders: OrderArgs,
    /// Use the project's recommended on-line setting instead of the paper's (see docs/INTERFACE.md).
    #[arg(long)]
    pub recommended: bool,
    /// Refine on-line to the output-error accuracy after a warm-up, with standard errors (MrgiaEstimator.fmu's
    /// `refine`; see docs/INTERFACE.md). `--rho-min` sets its forgetting.
    #[arg(long)]
    pub refine: bool,
    /// P(0) = P0 I (paper: 1e6).
    #[arg(long, allow_negative_numbers = true)]
    pub p0: Option<f64>,
    /// Convergence factor exponent: rho(k) = (k+1)^-rho_exp (paper: 0.25).
    #[arg(long, allow_negative_numbers = true)]
    pub rho_exp: Option<f64>,
    /// Floor on rho(k), i.e. forgetting, to track wear (paper: 0).
    #[arg(long, allow_negative_numbers = true)]
    pub rho_min: Option<f64>,
    /// Noise threshold of eqs. (37)-(38) (paper: 0).
    #[arg(long, allow_negative_numbers = true)]
    pub eps: Option<f64>,
    /// Sigma(0) (paper: 1).
    #[arg(long, allow_negative_numbers = true)]
    pub sigma0: Option<f64>,
    /// Initial gaps c1(0) = c2(0) (default 0.01).
    #[arg(long, allow_negative_numbers = true)]
    pub c_init: Option<f64>,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
    /// Write the estimates after every sample as CSV (time,a1..,b0..,m2,c1,c2,y_hat,e,updating).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// Write a PNG of the estimates against the sample index (up to 4096 samples all are drawn; beyond, every
    /// s-th, s a power of two, and the last).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

impl MrgiaArgs {
    fn settings(&self) -> MrgiaSettings {
        MrgiaSettings {
            recommended: self.recommended,
            refine: self.refine,
            p0: self.p0,
            rho_exp: self.rho_exp,
            rho_min: self.rho_min,
            eps: self.eps,
            sigma0: self.sigma0,
            c_init: self.c_init,
        }
    }
}

/// The estimate as one vector in the order of `param_names`.
fn flat(est: &OnlineEstimator) -> Vec<f64> {
    theta_of(&est.estimate())
}

/// Points of the trajectory kept for `--plot`: at most this many (plus the last sample) whatever the file's
/// length, so that memory does not grow with it. Up to this many samples every one is drawn; beyond, every
/// s-th, s the smallest power of two that fits (an image 1000 pixels wide shows no more).
pub const PLOT_POINTS: usize = 4096;

/// The estimates at every `stride`-th sample, the stride doubling whenever [`PLOT_POINTS`] are held.
pub(crate) struct Decimated {
    width: usize,
    stride: u64,
    /// Sample index k (0-based) of each kept point.
    k: Vec<u64>,
    /// The estimates of each kept point, `width` values each.
    values: Vec<f64>,
}

impl Decimated {
    pub(crate) fn new(width: usize) -> Self {
        Decimated {
            width,
            stride: 1,
            k: Vec::with_capacity(PLOT_POINTS),
            values: Vec::with_capacity((PLOT_POINTS + 1) * width),
        }
    }

    /// Whether sample `k` would be kept (so that the caller computes its estimates only then).
    pub(crate) fn wants(&self, k: u64) -> bool {
        k.is_multiple_of(self.stride)
    }

    pub(crate) fn push(&mut self, k: u64, values: &[f64]) {
        if !self.wants(k) {
            return;
        }
        if self.k.len() == PLOT_POINTS {
            // Keep the points at multiples of twice the stride: every other one, as k = 0, s, 2s, ...
            let w = self.width;
            for i in 0..PLOT_POINTS / 2 {
                self.k[i] = self.k[2 * i];
                self.values.copy_within(2 * i * w..(2 * i + 1) * w, i * w);
            }
            self.k.truncate(PLOT_POINTS / 2);
            self.values.truncate(PLOT_POINTS / 2 * w);
            self.stride *= 2;
            if !self.wants(k) {
                return;
            }
        }
        self.k.push(k);
        self.values.extend_from_slice(values);
    }

    /// Add the last sample `k` (drawn even when the stride skips it); no push after this.
    pub(crate) fn finish(&mut self, k: u64, values: &[f64]) {
        if self.k.last() != Some(&k) {
            self.k.push(k);
            self.values.extend_from_slice(values);
        }
    }

    /// The series of estimate `i` as (sample number k + 1, value).
    pub(crate) fn series(&self, i: usize) -> Vec<(f64, f64)> {
        self.k
            .iter()
            .zip(self.values.chunks_exact(self.width))
            .map(|(&k, v)| ((k + 1) as f64, v[i]))
            .collect()
    }
}

/// The estimator over a record with what it writes on the way: the trace, the plot's points, the counts.
struct Pass {
    est: OnlineEstimator,
    labels: Vec<String>,
    trace: Option<(AtomicFile, PathBuf)>,
    plot: Option<Decimated>,
    check: InputCheck,
    updates: u64,
    k: u64,
}

impl Pass {
    fn new(args: &MrgiaArgs, settings: &MrgiaSettings) -> Result<Self> {
        let cfg = settings
            .config(args.orders.na, args.orders.nb, args.orders.delay)
            .context("invalid estimator setting")?;
        let labels = param_names(cfg.na, cfg.nb);
        let trace = match &args.trace {
            Some(path) => {
                let mut f = AtomicFile::create(path)
                    .with_context(|| format!("{}: cannot write the trace", path.display()))?;
                writeln!(f, "time,{},y_hat,e,updating", labels.join(","))
                    .with_context(|| format!("{}: cannot write the trace", path.display()))?;
                Some((f, path.clone()))
            }
            None => None,
        };
        Ok(Pass {
            est: OnlineEstimator::new(cfg, args.refine)?,
            plot: args.plot.as_ref().map(|_| Decimated::new(labels.len())),
            labels,
            trace,
            check: InputCheck::default(),
            updates: 0,
            k: 0,
        })
    }

    /// One sample (t, u, y).
    fn step(&mut self, row: &[f64]) -> Result<()> {
        let r = self.est.update(row[1], row[2]);
        self.updates += u64::from(r.updating);
        self.check.push(row[1]);
        if let Some((w, path)) = &mut self.trace {
            write_trace_row(w, row[0], &flat(&self.est), &r)
                .with_context(|| format!("{}: cannot write the trace", path.display()))?;
        }
        if let Some(p) = &mut self.plot
            && p.wants(self.k)
        {
            p.push(self.k, &flat(&self.est));
        }
        self.k += 1;
        Ok(())
    }

    /// Every row of the file (decimated), read and parsed on a second thread one batch ahead.
    fn read(&mut self, args: &MrgiaArgs, progress: &ProgressBar) -> Result<()> {
        let options = args.record.options();
        let (rows, _) = options.open(&args.file, true)?;
        let mut block = options.block(3);
        let mut rows = ReadAhead::spawn(rows);
        while let Some(batch) = rows.next_batch()? {
            for row in batch.values.chunks_exact(3) {
                if let Some(mean) = block.push(row) {
                    self.step(mean)?;
                }
            }
            progress.set_position(batch.bytes_read);
            progress.set_message(format!("{} samples", self.k));
            rows.recycle(batch);
        }
        Ok(())
    }
}

/// The file is read, checked and estimated in one pass, row by row: memory does not depend on its length
/// (the trace is written as it goes, the plot keeps at most [`PLOT_POINTS`] points).
pub fn run_mrgia(args: &MrgiaArgs) -> Result<()> {
    let settings = args.settings();
    let mut pass = Pass::new(args, &settings)?;
    let file_bytes = std::fs::metadata(&args.file).map_or(0, |m| m.len());
    let progress = bar(
        args.json || file_bytes < PROGRESS_MIN_BYTES,
        file_bytes,
        "{bar:40} {bytes}/{total_bytes} ({bytes_per_sec}, eta {eta}) {msg}",
    );
    pass.read(args, &progress)?;
    progress.finish_and_clear();
    if pass.k == 0 {
        anyhow::bail!(
            "{}: fewer rows than one block of --decimate {}: nothing to estimate",
            args.file.display(),
            args.record.decimate()
        );
    }
    if let Some((w, path)) = pass.trace.take() {
        w.commit()
            .with_context(|| format!("{}: cannot write the trace", path.display()))?;
    }
    if let (Some(path), Some(p)) = (&args.plot, pass.plot.take()) {
        plot_estimates(path, &args.file, settings.name(), &pass, p)?;
    }
    let out = mrgia_json(
        &pass.est,
        pass.k,
        pass.updates,
        settings.name(),
        &pass.check,
    );
    if args.json {
        print_json(out, &args.file);
    } else {
        print_text(args, &pass, &out);
    }
    Ok(())
}

fn plot_estimates(
    path: &Path,
    file: &Path,
    setting: &str,
    pass: &Pass,
    mut p: Decimated,
) -> Result<()> {
    p.finish(pass.k - 1, &flat(&pass.est));
    let series: Vec<Series> = pass
        .labels
        .iter()
        .enumerate()
        .map(|(i, l)| Series::line(l, p.series(i)).color(i))
        .collect();
    line_plot(
        path,
        &format!("MRGIA estimates ({setting} setting), {}", file.display()),
        "sample k",
        "estimate",
        &series,
        Axes::LINEAR,
    )?;
    Ok(())
}

fn print_text(args: &MrgiaArgs, pass: &Pass, out: &serde_json::Value) {
    let est = &pass.est;
    println!(
        "MRGIA ({} setting) on {}: {} samples, {} updates",
        args.settings().name(),
        args.file.display(),
        pass.k,
        pass.updates
    );
    for (i, (name, v)) in pass.labels.iter().zip(flat(est)).enumerate() {
        if args.refine {
            println!("  {name:>3} = {v:.6}  (std err {:.2e})", est.std_err_at(i));
        } else {
            println!("  {name:>3} = {v:.6}");
        }
    }
    if args.refine && est.std_err().is_none() {
        println!(
            "  (std err 0: not known yet, the warm-up of the refine setting was not completed)"
        );
    }
    println!("  (m1 = 1 is the normalisation)");
    print_warnings(out);
}

/// One line of the trace: time, the estimates, y_hat, e, updating (0/1); numbers in Rust's shortest
/// round-trip form.
fn write_trace_row(
    w: &mut impl Write,
    t: f64,
    theta: &[f64],
    r: &StepResult,
) -> std::io::Result<()> {
    write!(w, "{t:?}")?;
    for v in theta {
        write!(w, ",{v:?}")?;
    }
    writeln!(w, ",{:?},{:?},{}", r.y_hat, r.e, u8::from(r.updating))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kept samples against a direct computation: every one up to PLOT_POINTS; beyond, the multiples of
    /// the smallest power of two s with ceil(n / s) <= PLOT_POINTS, plus the last sample; values follow k.
    #[test]
    fn plot_decimation_keeps_a_bounded_regular_subset() {
        for n in [
            1u64,
            2,
            4095,
            4096,
            4097,
            8192,
            8193,
            10_000,
            1 << 20,
            3_000_017,
        ] {
            let mut d = Decimated::new(2);
            for k in 0..n {
                if d.wants(k) {
                    d.push(k, &[k as f64, -(k as f64)]);
                }
            }
            d.finish(n - 1, &[(n - 1) as f64, -((n - 1) as f64)]);
            let mut s = 1u64;
            while n.div_ceil(s) > PLOT_POINTS as u64 {
                s *= 2;
            }
            let mut want: Vec<u64> = (0..n).step_by(s as usize).collect();
            if want.last() != Some(&(n - 1)) {
                want.push(n - 1);
            }
            assert_eq!(d.k, want, "n = {n}");
            assert!(d.k.len() <= PLOT_POINTS + 1);
            let x: Vec<f64> = want.iter().map(|&k| (k + 1) as f64).collect();
            let s0 = d.series(0);
            let s1 = d.series(1);
            assert_eq!(s0.iter().map(|p| p.0).collect::<Vec<_>>(), x);
            assert!(s0.iter().all(|&(x, v)| v == x - 1.0));
            assert!(s1.iter().all(|&(x, v)| v == 1.0 - x));
        }
    }
}
