//! `backlash identify mrgia`: the recursive MRGIA estimator of paper 000 on a data file.

use anyhow::{Context, Result};
use backlash::identify::mrgia::{Mrgia, MrgiaConfig};
use backlash::io::{Table, write_atomic};
use backlash::report::plot::{Series, line_plot};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// Files longer than this show a progress bar (when not in --json mode).
const PROGRESS_MIN_SAMPLES: usize = 200_000;

#[derive(clap::Args)]
pub struct MrgiaArgs {
    /// Data file: CSV with columns time,u,y (any order; other columns ignored).
    pub file: PathBuf,
    /// Number of a coefficients (0..4).
    #[arg(long)]
    pub na: usize,
    /// Highest b index (0..4): b0..b_nb are estimated.
    #[arg(long)]
    pub nb: usize,
    /// Input delay in samples (>= 1).
    #[arg(long)]
    pub delay: usize,
    /// Use the project's recommended on-line setting instead of the paper's (see the README).
    #[arg(long)]
    pub recommended: bool,
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
    /// Write a PNG of the estimates against the sample index.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

impl MrgiaArgs {
    fn config(&self) -> Result<MrgiaConfig> {
        let base = if self.recommended {
            MrgiaConfig::recommended(self.na, self.nb, self.delay)
        } else {
            MrgiaConfig::paper(self.na, self.nb, self.delay)
        };
        let cfg = MrgiaConfig {
            p0: self.p0.unwrap_or(base.p0),
            rho_exp: self.rho_exp.unwrap_or(base.rho_exp),
            rho_min: self.rho_min.unwrap_or(base.rho_min),
            eps: self.eps.unwrap_or(base.eps),
            sigma0: self.sigma0.unwrap_or(base.sigma0),
            c_init: self.c_init.unwrap_or(base.c_init),
            ..base
        };
        cfg.validate().context("invalid estimator setting")?;
        Ok(cfg)
    }
}

fn names(cfg: &MrgiaConfig) -> Vec<String> {
    (1..=cfg.na)
        .map(|i| format!("a{i}"))
        .chain((0..=cfg.nb).map(|j| format!("b{j}")))
        .chain(["m2", "c1", "c2"].map(String::from))
        .collect()
}

/// The estimate as one vector in the order of [`names`].
fn flat(est: &Mrgia) -> Vec<f64> {
    let e = est.estimate();
    e.a.iter()
        .chain(&e.b)
        .copied()
        .chain([e.m2, e.c1, e.c2])
        .collect()
}

pub fn run_mrgia(args: &MrgiaArgs) -> Result<()> {
    let cfg = args.config()?;
    let table = Table::read(&args.file, &["time", "u", "y"])?;
    let (t, u, y) = (
        table.column("time").unwrap(),
        table.column("u").unwrap(),
        table.column("y").unwrap(),
    );
    let mut est = Mrgia::new(cfg)?;
    let keep = args.trace.is_some() || args.plot.is_some();
    let mut history: Vec<(Vec<f64>, f64, f64, bool)> = Vec::new();
    let bar = (!args.json && u.len() >= PROGRESS_MIN_SAMPLES).then(|| {
        let b = ProgressBar::new(u.len() as u64);
        b.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} samples ({per_sec}, eta {eta})")
                .expect("valid template"),
        );
        b
    });
    let mut updates = 0u64;
    for k in 0..u.len() {
        let r = est.update(u[k], y[k]);
        updates += u64::from(r.updating);
        if keep {
            history.push((flat(&est), r.y_hat, r.e, r.updating));
        }
        if let Some(b) = &bar
            && k % 65536 == 0
        {
            b.set_position(k as u64);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let e = est.estimate();
    let setting = if args.recommended {
        "recommended"
    } else {
        "paper"
    };

    if let Some(path) = &args.trace {
        let header = names(&cfg).join(",");
        write_atomic(path, |w: &mut dyn Write| {
            writeln!(w, "time,{header},y_hat,e,updating")?;
            for (k, (th, yh, e, up)) in history.iter().enumerate() {
                let vals: Vec<String> = th.iter().map(|v| format!("{v:?}")).collect();
                writeln!(
                    w,
                    "{:?},{},{yh:?},{e:?},{}",
                    t[k],
                    vals.join(","),
                    u8::from(*up)
                )?;
            }
            Ok(())
        })
        .with_context(|| format!("{}: cannot write the trace", path.display()))?;
    }
    if let Some(path) = &args.plot {
        let labels = names(&cfg);
        let series: Vec<Series> = labels
            .iter()
            .enumerate()
            .map(|(i, l)| {
                Series::line(
                    l,
                    history
                        .iter()
                        .enumerate()
                        .map(|(k, h)| ((k + 1) as f64, h.0[i]))
                        .collect(),
                )
                .color(i)
            })
            .collect();
        line_plot(
            path,
            &format!(
                "MRGIA estimates ({setting} setting), {}",
                args.file.display()
            ),
            "sample k",
            "estimate",
            &series,
            false,
            false,
        )?;
    }

    if args.json {
        let out = json!({
            "method": "mrgia",
            "a": e.a,
            "b": e.b,
            "m1": e.m1,
            "m2": e.m2,
            "c1": e.c1,
            "c2": e.c2,
            "samples": u.len(),
            "updates": updates,
            "setting": setting,
            "config": cfg,
            "file": args.file.display().to_string(),
        });
        println!("{out}");
    } else {
        println!(
            "MRGIA ({setting} setting) on {}: {} samples, {updates} updates",
            args.file.display(),
            u.len()
        );
        for (name, v) in names(&cfg).iter().zip(flat(&est)) {
            println!("  {name:>3} = {v:.6}");
        }
        println!("  (m1 = 1 is the normalisation)");
    }
    Ok(())
}
