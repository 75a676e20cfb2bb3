//! Paper 003 on the command line: `identify frequency` (one sine experiment from a CSV file) and `identify
//! stepped-sine` (every step of a stepped-sine record), with the plots and files `experiment` shares.
//! Parsing, the library's calls, printing and plots only: the science is in `backlash::identify::frequency`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;

use super::common::{RecordArgs, spinner};

use backlash::api::{ApiError, FREQUENCY_CONVENTION, frequency_json, identify_frequency};
use backlash::identify::frequency::analysis::{
    Analysis, AnalysisOptions, BodePoint, SteppedAnalysis, analyse_steps,
};
use backlash::identify::frequency::experiment::Record;
use backlash::identify::frequency::{EstimatorPath, FrequencyError, FrequencyEstimate, SineRecord};
use backlash::io::write_atomic;
use backlash::plant::poly::poly_eval;
use backlash::report::plot::{Axes, Panel, Series, grid_plot, line_plot};

/// What a frequency estimate means (printed with every result).
pub(super) const CONVENTION: &str = FREQUENCY_CONVENTION;

/// Identify one sine experiment (paper 003): the steady window, the degree, the phase lag, gain and
/// polynomial borders, and whether the model explains the record.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifyFrequencyArgs {
    /// CSV file with a header line; columns time (or t), u, y (names configurable)
    pub file: PathBuf,
    /// Excitation frequency omega, rad/s, against the time column [default: the input's, in the window]
    #[arg(long)]
    pub omega: Option<f64>,
    /// Excitation amplitude U [default: the input's fitted amplitude in the window; if given, the u column
    /// must agree within 5 %]
    #[arg(long)]
    pub amplitude: Option<f64>,
    /// Degree n of the border polynomials f_a, f_d, between 1 and 6 [default: chosen by the data (BIC)]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Start of the part of the record to use, s [default: detected: whole cycles of a steady sine]
    #[arg(long, allow_negative_numbers = true)]
    pub start: Option<f64>,
    /// End of the part of the record to use, s (inclusive) [default: detected]
    #[arg(long, allow_negative_numbers = true)]
    pub end: Option<f64>,
    /// Seconds to discard at the window's start as transient [default: detect the transient]
    #[arg(long)]
    pub transient: Option<f64>,
    #[command(flatten)]
    pub record: RecordArgs,
    /// Print one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

/// Identify every step of a stepped-sine record (several frequencies one after another): the Bode points,
/// the borders per step and their spread, with plots and a CSV of (omega, gain, phase).
#[derive(clap::Args, Debug, Clone)]
pub struct SteppedSineArgs {
    /// CSV file with a header line; columns time (or t), u, y (names configurable)
    pub file: PathBuf,
    /// Degree n of the border polynomials, between 1 and 6 [default: chosen by the data over all steps]
    #[arg(long)]
    pub degree: Option<usize>,
    /// Seconds to discard at each step's window start as transient [default: detect]
    #[arg(long)]
    pub transient: Option<f64>,
    #[command(flatten)]
    pub record: RecordArgs,
    /// Output folder (created): bode.csv, bode_magnitude.png, bode_phase.png, borders.png, steps.png
    #[arg(long, default_value = "stepped-sine")]
    pub out: PathBuf,
    /// Print one JSON object on stdout and nothing else
    #[arg(long)]
    pub json: bool,
}

/// `backlash identify frequency FILE [--omega W] [--amplitude U] [--degree n] [--json]`.
pub fn run_identify(args: &IdentifyFrequencyArgs) -> Result<()> {
    let rec = args.record.options().read(&args.file, true)?;
    let opts = AnalysisOptions {
        omega: args.omega,
        amplitude: args.amplitude,
        degree: args.degree,
        start: args.start,
        end: args.end,
        transient: args.transient,
    };
    let file = args.file.display();
    let progress = spinner(args.json, "identifying the sine experiment (paper 003)");
    let analysis = identify_frequency(&rec.t, Some(rec.u.as_slice()), &rec.y, &opts);
    progress.finish_and_clear();
    let analysis = analysis.map_err(|e| match e {
        ApiError::Frequency(e @ FrequencyError::SeveralSteps { .. }) => anyhow::anyhow!(
            "{file}: {e}: `backlash identify stepped-sine {file}` identifies them all, `--omega W` picks one"
        ),
        e => anyhow::anyhow!("{file}: frequency identification failed: {e}"),
    })?;
    if args.json {
        let mut out = frequency_json(&analysis);
        out["file"] = serde_json::json!(file.to_string());
        emit(&format!("{out}\n"))
    } else {
        emit(&describe(&args.file, &analysis))
    }
}

/// Write to stdout; a closed pipe (`| head`) is not an error.
pub(super) fn emit(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.context("cannot write to stdout"),
    }
}

pub(super) fn poly_text(name: &str, c: &[f64]) -> String {
    let mut s = format!("{name}(x) = {:.6}", c[0]);
    for (i, v) in c.iter().enumerate().skip(1) {
        let sign = if *v < 0.0 { '-' } else { '+' };
        let pow = if i == 1 {
            "x".to_string()
        } else {
            format!("x^{i}")
        };
        let _ = write!(s, " {sign} {:.6} {pow}", v.abs());
    }
    s
}

fn describe_estimate(s: &mut String, e: &FrequencyEstimate) {
    let path = match e.path {
        EstimatorPath::Ls => format!(
            "LS, eq. (23) (constant stages: tau_a = {:.4} s, tau_d = {:.4} s)",
            e.tau_a, e.tau_d
        ),
        EstimatorPath::Sls => "separable LS, eqs. (24)-(25) (no constant stages)".to_string(),
    };
    let _ = writeln!(s, "  estimator: {path}");
    let _ = writeln!(
        s,
        "  phase lag phi = {:.6} rad ({:.3} deg), gain |G(jw)|/K = {:.6}",
        e.phase,
        e.phase.to_degrees(),
        e.gain
    );
    let _ = writeln!(s, "  {}", poly_text("f_a", &e.fa));
    let _ = writeln!(s, "  {}", poly_text("f_d", &e.fd));
    let _ = writeln!(
        s,
        "  {} steady periods averaged ({} transient dropped), {} samples per period",
        e.periods_used, e.transient_periods, e.samples_per_period
    );
    let _ = writeln!(
        s,
        "  noise std {:.3e}, residual RMS of the averaged output {:.3e}",
        e.noise_std, e.residual_rms
    );
    for w in &e.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
}

fn describe_analysis(s: &mut String, a: &Analysis) {
    let w = &a.window;
    let _ = writeln!(
        s,
        "  window: t = {:.4} to {:.4} s ({:?}: {} samples, {:.2} periods), input amplitude {}",
        w.start,
        w.end,
        w.source,
        w.samples,
        w.periods,
        w.input_amplitude
            .map_or("unknown".to_string(), |v| format!("{v:.6}"))
    );
    let rule = if a.degree_choice.rule == "declared" {
        "declared".to_string()
    } else {
        let tried: Vec<String> = a
            .degree_choice
            .candidates
            .iter()
            .map(|c| match c.bic {
                Some(b) => format!("{}: {b:.4e}", c.degree),
                None => format!("{}: not fitted", c.degree),
            })
            .collect();
        format!("smallest BIC of {}", tried.join(", "))
    };
    let _ = writeln!(s, "  degree {} ({rule})", a.estimate.degree);
    describe_estimate(s, &a.estimate);
    let _ = writeln!(s, "  verdict: {}", a.verdict.summary);
    if !a.verdict.explained {
        let _ = writeln!(
            s,
            "  `backlash diagnose` fits the time-domain model and names the effect it lacks"
        );
    }
}

fn describe(file: &Path, a: &Analysis) -> String {
    let e = &a.estimate;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: paper 003 frequency identification at omega = {} rad/s, U = {}, degree {}",
        file.display(),
        e.omega,
        e.amplitude,
        e.degree
    );
    describe_analysis(&mut s, a);
    let _ = writeln!(s, "  convention: {CONVENTION}");
    s
}

#[derive(Serialize)]
struct SteppedJson<'a> {
    method: &'static str,
    file: String,
    #[serde(flatten)]
    analysis: &'a SteppedAnalysis,
    convention: &'static str,
    bode_convention: &'static str,
    csv: String,
    plots: Vec<String>,
}

const BODE_CONVENTION: &str = "bode: steps by increasing omega, each as the member of its model/dual pair whose phase \
     continues the previous step's (the lowest step as reported); the phase is not wrapped";

/// `backlash identify stepped-sine FILE [--out DIR] [--json]`.
pub fn run_stepped_sine(args: &SteppedSineArgs) -> Result<()> {
    let record = args.record.options().read(&args.file, true)?;
    let (time, u) = (record.t.as_slice(), record.u.as_slice());
    let rec = SineRecord {
        time,
        u: Some(u),
        y: &record.y,
    };
    let file = args.file.display();
    let progress = spinner(args.json, "identifying every step (paper 003)");
    let analysis = analyse_steps(&rec, args.degree, args.transient);
    progress.finish_and_clear();
    let analysis =
        analysis.with_context(|| format!("{file}: stepped-sine identification failed"))?;
    create_dir(&args.out)?;
    let csv = args.out.join("bode.csv");
    write_bode_csv(&csv, &analysis.bode)?;
    let mut plots = bode_plots(
        &args.out,
        None,
        &[("estimated (paper 003)", &analysis.bode)],
    )?;
    plots.extend(border_panels(&args.out, &analysis.bode, None)?);
    let labels = [record.label(0), record.label(1)];
    plots.push(steps_plot(&args.out, time, u, labels, &analysis)?);
    let out = SteppedJson {
        method: "stepped-sine",
        file: file.to_string(),
        analysis: &analysis,
        convention: CONVENTION,
        bode_convention: BODE_CONVENTION,
        csv: csv.display().to_string(),
        plots,
    };
    if args.json {
        emit(&format!("{}\n", serde_json::to_string(&out)?))
    } else {
        emit(&describe_stepped(&out))
    }
}

fn describe_stepped(out: &SteppedJson) -> String {
    let a = out.analysis;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} steps, degree {} ({}), {} explained by paper 003's model",
        out.file,
        a.steps.len(),
        a.degree,
        a.degree_rule,
        a.explained_steps
    );
    let _ = writeln!(
        s,
        "{:>10} {:>10} {:>10} {:>8} {:>10} {:>9}",
        "omega", "t start", "t end", "periods", "gain", "phase"
    );
    for p in &a.bode {
        let w = a
            .steps
            .iter()
            .find(|st| {
                st.analysis
                    .as_ref()
                    .is_some_and(|x| x.estimate.omega == p.omega)
            })
            .map(|st| &st.window);
        let (t0, t1, per) = w.map_or((f64::NAN, f64::NAN, f64::NAN), |w| {
            (w.start, w.end, w.periods)
        });
        let _ = writeln!(
            s,
            "{:>10.5} {:>10.3} {:>10.3} {:>8.2} {:>10.5} {:>9.5}{}",
            p.omega,
            t0,
            t1,
            per,
            p.gain,
            p.phase,
            if p.explained { "" } else { "  (not explained)" }
        );
    }
    for st in a.steps.iter().filter(|st| st.error.is_some()) {
        let _ = writeln!(
            s,
            "step at omega = {:.5}: {}",
            st.window.omega,
            st.error.as_deref().unwrap_or("")
        );
    }
    if let Some(sp) = &a.border_spread {
        let _ = writeln!(s, "borders over the steps (mean, std):");
        let _ = writeln!(
            s,
            "  {}   std {:?}",
            poly_text("f_a", &sp.fa_mean),
            sp.fa_std
        );
        let _ = writeln!(
            s,
            "  {}   std {:?}",
            poly_text("f_d", &sp.fd_mean),
            sp.fd_std
        );
    }
    let _ = writeln!(s, "{BODE_CONVENTION}");
    let _ = writeln!(s, "csv: {}", out.csv);
    for p in &out.plots {
        let _ = writeln!(s, "plot: {p}");
    }
    s
}

pub(super) fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the folder", dir.display()))
}

pub(super) fn write_bode_csv(path: &Path, points: &[BodePoint]) -> Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "omega,gain,phase")?;
        for p in points {
            writeln!(f, "{},{},{}", p.omega, p.gain, p.phase)?;
        }
        Ok(())
    })
    .with_context(|| format!("{}: cannot write", path.display()))
}

pub(super) fn write_record(path: &Path, r: &Record) -> Result<()> {
    write_atomic(path, |f| {
        writeln!(f, "time,u,x,w,y")?;
        for i in 0..r.t.len() {
            writeln!(f, "{},{},{},{},{}", r.t[i], r.u[i], r.x[i], r.w[i], r.y[i])?;
        }
        Ok(())
    })
    .with_context(|| format!("{}: cannot write", path.display()))
}

/// A true Bode curve: (omega, |G|/K, phase lag rad).
pub(super) type Curve = Vec<(f64, f64, f64)>;

/// True borders of a Bode point and the x range its data excite: (f_a, f_d, U |G|/K).
pub(super) type TrueBorders = (Vec<f64>, Vec<f64>, f64);

/// bode_magnitude.png and bode_phase.png: the truth (if known) and sets of estimated points.
pub(super) fn bode_plots(
    dir: &Path,
    truth: Option<&Curve>,
    estimates: &[(&str, &[BodePoint])],
) -> Result<Vec<String>> {
    let mut mag = Vec::new();
    let mut ph = Vec::new();
    if let Some(c) = truth {
        mag.push(Series::line(
            "true |G(jw)|/K",
            c.iter().map(|p| (p.0, p.1)).collect(),
        ));
        ph.push(Series::line(
            "true phase lag",
            c.iter().map(|p| (p.0, p.2.to_degrees())).collect(),
        ));
    }
    for (i, (label, points)) in estimates.iter().enumerate() {
        // Estimated phases placed on the branch of the true curve (or of the first point).
        let reference = |w: f64| -> Option<f64> {
            truth.and_then(|c| {
                c.iter()
                    .min_by(|a, b| (a.0 - w).abs().total_cmp(&(b.0 - w).abs()))
                    .map(|p| p.2)
            })
        };
        let phases: Vec<(f64, f64)> = points
            .iter()
            .map(|p| {
                let q = reference(p.omega).unwrap_or(p.phase);
                let ph = p.phase
                    + ((q - p.phase) / std::f64::consts::TAU).round() * std::f64::consts::TAU;
                (p.omega, ph.to_degrees())
            })
            .collect();
        let color = 3 + i;
        mag.push(
            Series::points(*label, points.iter().map(|p| (p.omega, p.gain)).collect()).color(color),
        );
        ph.push(Series::points(*label, phases).color(color));
    }
    let mag_path = dir.join("bode_magnitude.png");
    line_plot(
        &mag_path,
        "Bode magnitude: estimated |G(jw)|/K",
        "omega (rad/s)",
        "gain |G(jw)| / K",
        &mag,
        Axes::LOG_LOG,
    )?;
    let ph_path = dir.join("bode_phase.png");
    line_plot(
        &ph_path,
        "Bode phase: estimated phase lag",
        "omega (rad/s)",
        "phase lag -arg G(jw) (deg)",
        &ph,
        Axes::LOG_X,
    )?;
    Ok(vec![
        mag_path.display().to_string(),
        ph_path.display().to_string(),
    ])
}

/// borders.png: one panel per point, the estimate over its excited range and the truth (if known) a
/// little beyond.
pub(super) fn border_panels(
    dir: &Path,
    points: &[BodePoint],
    truth: Option<&[TrueBorders]>,
) -> Result<Vec<String>> {
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let titles: Vec<String> = points
        .iter()
        .map(|p| format!("omega = {:.4} rad/s", p.omega))
        .collect();
    let curve = |c: &[f64], reach: f64| -> Vec<(f64, f64)> {
        (0..=200)
            .map(|i| -reach + 2.0 * reach * i as f64 / 200.0)
            .map(|x| (x, poly_eval(c, x)))
            .collect()
    };
    let panels: Vec<Panel> = points
        .iter()
        .zip(&titles)
        .enumerate()
        .map(|(i, (p, title))| {
            let mut series = Vec::new();
            let mut reach = p.gain * p.amplitude;
            if let Some((fa, fd, r)) = truth.and_then(|t| t.get(i)) {
                series.push(Series::line("true f_a", curve(fa, 1.15 * r)));
                series.push(Series::line("true f_d", curve(fd, 1.15 * r)).color(1));
                reach = reach.min(1.15 * r);
            }
            series.push(Series::dashed("estimated f_a", curve(&p.fa, reach)).color(2));
            series.push(Series::dashed("estimated f_d", curve(&p.fd, reach)).color(3));
            Panel {
                title: title.as_str(),
                x_label: "x (normalised)",
                y_label: "w",
                series,
                log_x: false,
                log_y: false,
            }
        })
        .collect();
    let path = dir.join("borders.png");
    grid_plot(
        &path,
        "Borders: estimated (dashed, over the excited range)",
        &panels,
        2,
    )?;
    Ok(vec![path.display().to_string()])
}

/// steps.png: the input with each step's window.
/// steps.png: the input against time with the windows used; `labels` name the time and input axes.
pub(super) fn steps_plot(
    dir: &Path,
    t: &[f64],
    u: &[f64],
    labels: [&str; 2],
    a: &SteppedAnalysis,
) -> Result<String> {
    let stride = (t.len() / 20_000).max(1);
    let input: Vec<(f64, f64)> = t
        .iter()
        .zip(u)
        .step_by(stride)
        .map(|(a, b)| (*a, *b))
        .collect();
    let top = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut marks = Vec::new();
    for st in &a.steps {
        let w = &st.window;
        marks.push((w.start, 1.1 * top));
        marks.push((w.end, 1.1 * top));
        marks.push((f64::NAN, f64::NAN));
    }
    let marks: Vec<(f64, f64)> = marks.into_iter().filter(|p| p.0.is_finite()).collect();
    let path = dir.join("steps.png");
    let mut series = vec![Series::line(labels[1], input)];
    for (i, pair) in marks.chunks(2).enumerate() {
        series.push(Series::line(if i == 0 { "window used" } else { "" }, pair.to_vec()).color(3));
    }
    line_plot(
        &path,
        "Stepped-sine record: the input and the windows used",
        labels[0],
        labels[1],
        &series,
        Axes::LINEAR,
    )?;
    Ok(path.display().to_string())
}
