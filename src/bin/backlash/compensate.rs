//! `backlash compensate`: the adaptive compensation loop on a simulated paper plant for a reference file.

use anyhow::{Context, Result};
use backlash::api::{CompensateOptions, compensate, mode_named};
use backlash::compensate::adaptive::{LoopRun, Wear, windowed_rmse};
use backlash::io::{Table, write_atomic};
use backlash::report::plot::{Axes, Series, line_plot};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct CompensateArgs {
    /// Reference file: CSV with columns time and r (the plant output wanted at each sample).
    pub file: PathBuf,
    /// Name of the reference column.
    #[arg(long, default_value = "r")]
    pub r_col: String,
    /// Name of the time column.
    #[arg(long, default_value = "time")]
    pub time_col: String,
    /// Standard deviation of the simulated plant's measurement noise.
    #[arg(long, default_value_t = 0.0)]
    pub noise_std: f64,
    /// Seed of the plant's noise.
    #[arg(long, default_value_t = 0)]
    pub noise_seed: u64,
    /// How the plant's gaps change over the record: none, ramp (linear growth to 1 + ratio) or step (to
    /// 1 + ratio at the middle).
    #[arg(long, default_value = "none", value_parser = ["none", "ramp", "step"])]
    pub wear: String,
    /// Relative growth of both gaps by the end of the record (0.5: 50%).
    #[arg(long, default_value_t = 0.5)]
    pub wear_ratio: f64,
    /// The estimator's memory in samples: it forgets older samples with rho_min = 1/memory, so that the
    /// inverse follows wear. Shorter follows faster and is noisier (docs/RESULTS.md). 0: no forgetting.
    #[arg(long, default_value_t = 500.0)]
    pub memory: f64,
    /// Half-width of the play the reference passes before the backlash inverse (0 = exact inverse); about 4
    /// noise standard deviations of a noisy reference.
    #[arg(long, default_value_t = 0.0)]
    pub smoothing: f64,
    /// Samples by which the estimate the adaptive inverses use lags the latest: 0, or 1 as in a master that
    /// passes values between units only at communication points (libcosim, FMPy's SSP).
    #[arg(long, default_value_t = 0)]
    pub estimate_lag: usize,
    /// Modes to run, comma-separated: none, fixed, adaptive, no-play [default: all].
    #[arg(long, value_delimiter = ',')]
    pub modes: Vec<String>,
    /// Write time, r and each mode's plant input u and output y to this CSV.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write a PNG of each mode's tracking error (RMS of y - r over windows of 500 samples) against time.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON object on stdout and nothing else there.
    #[arg(long)]
    pub json: bool,
}

fn options(a: &CompensateArgs) -> Result<CompensateOptions> {
    let wear = match a.wear.as_str() {
        "ramp" => Wear::Ramp {
            ratio: a.wear_ratio,
        },
        "step" => Wear::Step {
            ratio: a.wear_ratio,
        },
        _ => Wear::None,
    };
    let mut o = CompensateOptions {
        noise_std: a.noise_std,
        noise_seed: a.noise_seed,
        wear,
        memory: (a.memory != 0.0).then_some(a.memory),
        smoothing: a.smoothing,
        estimate_lag: a.estimate_lag,
        ..CompensateOptions::default()
    };
    if !a.modes.is_empty() {
        o.modes = a
            .modes
            .iter()
            .map(|m| mode_named(m))
            .collect::<Result<_, _>>()?;
    }
    Ok(o)
}

pub fn run(a: &CompensateArgs) -> Result<()> {
    let o = options(a)?;
    let table = Table::read(&a.file, &[a.time_col.as_str(), a.r_col.as_str()])?;
    let (t, r) = (
        table.column(&a.time_col).unwrap_or_default(),
        table.column(&a.r_col).unwrap_or_default(),
    );
    let (runs, mut out) =
        compensate(r, &o).with_context(|| format!("{}: cannot compensate", a.file.display()))?;
    if let Some(path) = &a.out {
        write_csv(path, t, r, &runs)
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    if let Some(path) = &a.plot {
        plot(path, t, r, &runs, &a.time_col)?;
    }
    out["file"] = serde_json::json!(a.file.display().to_string());
    if a.json {
        println!("{out}");
        return Ok(());
    }
    println!(
        "tracking RMSE of y - r on {} ({} samples):",
        a.file.display(),
        r.len()
    );
    for run in &runs {
        println!(
            "  {:<9} {:.4} (last quarter {:.4})",
            run.mode.name(),
            run.rmse,
            run.rmse_last_quarter
        );
    }
    Ok(())
}

fn write_csv(path: &Path, t: &[f64], r: &[f64], runs: &[LoopRun]) -> std::io::Result<()> {
    write_atomic(path, |f| {
        write!(f, "time,r")?;
        for run in runs {
            let m = run.mode.name();
            write!(f, ",u_{m},y_{m}")?;
        }
        writeln!(f)?;
        for k in 0..r.len() {
            write!(f, "{},{}", t[k], r[k])?;
            for run in runs {
                write!(f, ",{},{}", run.u[k], run.y[k])?;
            }
            writeln!(f)?;
        }
        Ok(())
    })
}

fn plot(path: &Path, t: &[f64], r: &[f64], runs: &[LoopRun], time: &str) -> Result<()> {
    let series: Vec<Series> = runs
        .iter()
        .enumerate()
        .map(|(i, run)| {
            let points = windowed_rmse(&run.y, r, 500)
                .into_iter()
                .map(|(k, e)| (t[k], e))
                .collect();
            Series::line(run.mode.name(), points).color(i)
        })
        .collect();
    let axes = Axes {
        y: backlash::report::plot::Scale::Log,
        ..Axes::LINEAR
    };
    line_plot(
        path,
        "tracking error of the compensation loops",
        time,
        "RMS of y - r over 500 samples",
        &series,
        axes,
    )?;
    Ok(())
}
