//! The diagnosis report for a test engineer: `report.md` and PNG figures in one folder.
//!
//! Figures (all against the record's time unless said):
//! - `heldout.png`: the held-out part, measured output against the declared and the extended model;
//! - `residual.png`: the residual of both models over the whole record, the fit / held-out split marked;
//! - `correlations.png`: autocorrelation and residual-input cross-correlation on the fit part, before and
//!   after, with the 95% bands of a white residual;
//! - `evidence.png`: the evidence for the chosen effect (what the pointing test saw and what the fit made
//!   of it); for `null`, the measured output against the input with the declared model;
//! - `validate_<name>.png`: for each cross-record validation, measured against both models.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::catalogue::EffectId;
use super::decision::{DECISION_RULE, structure_penalty};
use super::engine::{CrossValidation, Diagnosis, usable_lags};
use super::model::Extension;
use super::residual;
use crate::io::write_atomic;
use crate::plant::Mode;
use crate::report::plot::{Axes, Panel, PlotError, Series, grid_plot, line_plot};

/// Why a report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{path}: cannot create the report folder")]
    Folder {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: cannot write the report")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// A record validated against the fitted models (another file).
#[derive(Debug, Clone, PartialEq)]
pub struct Validation {
    /// Short name (file stem), used in the figure's file name.
    pub name: String,
    pub t: Vec<f64>,
    pub y: Vec<f64>,
    pub result: CrossValidation,
}

/// What the report needs besides the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportInput<'a> {
    /// The data file (for the title).
    pub file: &'a str,
    /// Time of each (decimated) sample.
    pub t: &'a [f64],
    pub u: &'a [f64],
    pub y: &'a [f64],
    pub decimate: usize,
    /// The CSV's names of the time, input and output columns (the figures' axes).
    pub columns: [&'a str; 3],
    /// The command that produced the report (to reproduce it).
    pub command: Option<String>,
    pub validations: &'a [Validation],
}

fn pts(x: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    x.iter().zip(y).map(|(a, b)| (*a, *b)).collect()
}

fn fmt(v: f64) -> String {
    crate::report::number(v)
}

/// Write `report.md` and the figures into `dir` (created if needed). Returns the Markdown file's path.
pub fn write_report(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Folder {
        path: dir.to_path_buf(),
        source,
    })?;
    let n = d.n;
    let nf = d.n_fit;
    let t = &input.t[..n];
    let y = &input.y[..n];
    let before = &d.base_sim.y;
    let steps = d.steps();
    let after: &[f64] = steps.last().map_or(before, |c| &c.output);
    let after_label = if steps.is_empty() {
        "declared model (null)".to_string()
    } else {
        format!(
            "extended: {}",
            steps
                .iter()
                .map(|c| c.id.as_str())
                .collect::<Vec<_>>()
                .join(" + ")
        )
    };
    let e0: Vec<f64> = y.iter().zip(before).map(|(a, b)| a - b).collect();
    let e1: Vec<f64> = y.iter().zip(after).map(|(a, b)| a - b).collect();
    let mut figures: Vec<(String, String)> = Vec::new();

    // Held-out part.
    let th = &t[nf..];
    line_plot(
        &dir.join("heldout.png"),
        "Held-out part: measured output and the two models",
        input.columns[0],
        input.columns[2],
        &[
            Series::line("measured", pts(th, &y[nf..])).color(7),
            Series::line("declared model", pts(th, &before[nf..])).color(3),
            Series::line(&after_label, pts(th, &after[nf..])).color(0),
        ],
        Axes::LINEAR,
    )?;
    figures.push((
        "heldout.png".into(),
        format!(
            "Held-out part ({} samples, not used by any fit): measured (grey), declared model (red, RMSE {}), {} (blue, RMSE {}).",
            n - nf,
            fmt(d.base_heldout_rmse),
            after_label,
            fmt(d.after_rmse())
        ),
    ));

    // Residuals.
    let (lo, hi) = e0
        .iter()
        .chain(&e1)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    line_plot(
        &dir.join("residual.png"),
        "Residual y - y_model over the record",
        input.columns[0],
        &format!("residual of {}", input.columns[2]),
        &[
            Series::line("declared model", pts(t, &e0)).color(3),
            Series::line(&after_label, pts(t, &e1)).color(0),
            Series::dashed("fit | held-out", vec![(t[nf], lo), (t[nf], hi)]).color(7),
        ],
        Axes::LINEAR,
    )?;
    figures.push((
        "residual.png".into(),
        "Residual of the declared model (red) and of the chosen model (blue); left of the dashed line the fit \
         part, right of it the held-out part."
            .into(),
    ));

    // Correlation functions on the fit part.
    let lags = usable_lags(d.config.lags, nf);
    let band = residual::white_band(nf);
    let lagx: Vec<f64> = (1..=lags).map(|l| l as f64).collect();
    let lag0: Vec<f64> = (0..=lags).map(|l| l as f64).collect();
    let bands = |x0: f64| {
        vec![
            Series::dashed("95% band", vec![(x0, band), (lags as f64, band)]).color(7),
            Series::dashed("", vec![(x0, -band), (lags as f64, -band)]).color(7),
        ]
    };
    let acf0 = residual::autocorrelation(&e0[..nf], lags);
    let acf1 = residual::autocorrelation(&e1[..nf], lags);
    let cc0 = residual::cross_correlation(&e0[..nf], &input.u[..nf], lags);
    let cc1 = residual::cross_correlation(&e1[..nf], &input.u[..nf], lags);
    let mut p1 = vec![
        Series::points("declared model", pts(&lagx, &acf0)).color(3),
        Series::points(&after_label, pts(&lagx, &acf1)).color(0),
    ];
    p1.extend(bands(1.0));
    let mut p2 = vec![
        Series::points("declared model", pts(&lag0, &cc0.r)).color(3),
        Series::points(&after_label, pts(&lag0, &cc1.r)).color(0),
    ];
    p2.extend(bands(0.0));
    grid_plot(
        &dir.join("correlations.png"),
        "Correlation functions of the residual (fit part)",
        &[
            Panel {
                title: "autocorrelation r_ee(lag)",
                x_label: "lag",
                y_label: "r",
                series: p1,
                log_x: false,
                log_y: false,
            },
            Panel {
                title: "cross-correlation r_eu(lag)",
                x_label: "lag",
                y_label: "r",
                series: p2,
                log_x: false,
                log_y: false,
            },
        ],
        2,
    )?;
    figures.push((
        "correlations.png".into(),
        format!(
            "Autocorrelation of the residual and its correlation with past inputs on the fit part, declared model \
             (red) and chosen model (blue); dashed: +-{} = 1.96/sqrt(N), the 95% band of a white residual \
             independent of the input.",
            fmt(band)
        ),
    ));

    // Evidence.
    let caption = evidence(dir, d, input, &e0, &e1, &after_label)?;
    figures.push(("evidence.png".into(), caption));
    if !steps.is_empty() {
        figures.push(("steps.png".into(), steps_plot(dir, d, input)?));
    }

    // Cross-record validations.
    for v in input.validations {
        let file = format!("validate_{}.png", v.name);
        line_plot(
            &dir.join(&file),
            &format!("Cross-record validation on {}", v.name),
            input.columns[0],
            input.columns[2],
            &[
                Series::line("measured", pts(&v.t, &v.y)).color(7),
                Series::line("declared model", pts(&v.t, &v.result.before)).color(3),
                Series::line(&after_label, pts(&v.t, &v.result.after)).color(0),
            ],
            Axes::LINEAR,
        )?;
        figures.push((
            file,
            format!(
                "{}: the models fitted here, simulated over that record from rest: RMSE declared {}, chosen {} \
                 (the output's standard deviation is {}).",
                v.name,
                fmt(v.result.rmse_before),
                fmt(v.result.rmse_after),
                fmt(v.result.y_std)
            ),
        ));
    }

    let md = markdown(d, input, &figures);
    let path = dir.join("report.md");
    write_atomic(&path, |w| w.write_all(md.as_bytes())).map_err(|source| ReportError::Write {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// The held-out error after each step of the loop (step 0: the declared model); returns its caption.
fn steps_plot(dir: &Path, d: &Diagnosis, input: &ReportInput) -> Result<String, ReportError> {
    let errors: Vec<(f64, f64)> = std::iter::once(d.base_heldout_rmse)
        .chain(d.steps().iter().map(|c| c.heldout_rmse))
        .enumerate()
        .map(|(i, v)| (i as f64, v))
        .collect();
    let linear = vec![
        (0.0, d.linear.heldout_rmse),
        ((errors.len() - 1) as f64, d.linear.heldout_rmse),
    ];
    line_plot(
        &dir.join("steps.png"),
        "Held-out error at each step of the loop",
        "effects added",
        &format!("held-out RMSE of {}", input.columns[2]),
        &[
            Series::line("declared model, then each effect added", errors.clone()).color(0),
            Series::points("", errors).color(0),
            Series::dashed("best linear model", linear).color(7),
        ],
        Axes::LINEAR,
    )?;
    let names: Vec<String> = d
        .steps()
        .iter()
        .enumerate()
        .map(|(i, c)| format!("{} `{}`", i + 1, c.id))
        .collect();
    Ok(format!(
        "Held-out free-run RMSE of the declared model (0) and after each effect added ({}); the best linear \
         model's for reference (dashed).",
        names.join(", ")
    ))
}

/// The effect-specific figure; returns its caption.
fn evidence(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    e0: &[f64],
    e1: &[f64],
    after_label: &str,
) -> Result<String, ReportError> {
    let path = dir.join("evidence.png");
    let n = d.n;
    let nf = d.n_fit;
    let t = &input.t[..n];
    let sim = &d.base_sim;
    let id = d.effect_id();
    let test = d.pointing_test().unwrap_or("none");
    match (id, d.effect().and_then(|c| c.model.extension(c.id))) {
        (Some(EffectId::GapDrift), Some(Extension::GapDrift { c1_rate, c2_rate })) => {
            // Running means of the declared model's residual on each border, and the drift the fit found.
            let win = (n / 25).max(5);
            let running = |mode: Mode| -> Vec<(f64, f64)> {
                let idx: Vec<usize> = (0..n).filter(|&k| sim.mode[k] == mode).collect();
                running_means(t, e0, &idx, win)
            };
            let c = d.effect().expect("chosen");
            let m2 = c.model.base.m2;
            let [up_line, dn_line] = border_drift_lines(t, *c1_rate, *c2_rate, m2);
            let (ru, rd) = (running(Mode::Up), running(Mode::Down));
            let (lu, ld) = (centred_on(up_line, &ru), centred_on(dn_line, &rd));
            line_plot(
                &path,
                "Evidence for gap-drift: residual of the declared model on each border",
                input.columns[0],
                "running mean of the residual",
                &[
                    Series::line("upper border (driving up)", ru).color(1),
                    Series::line("lower border (driving down)", rd).color(2),
                    Series::dashed("fitted drift, upper", lu).color(1),
                    Series::dashed("fitted drift, lower", ld).color(2),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. Running mean ({win} samples) of the declared model's residual on the upper and \
                 lower borders; with fixed gaps both would stay at zero. Dashed: the change the fitted drift \
                 predicts (c1 rate {}, c2 rate {} per sample).",
                fmt(*c1_rate),
                fmt(*c2_rate)
            ))
        }
        (Some(EffectId::CurvedBorders), Some(Extension::CurvedBorders { upper, lower })) => {
            let mut up = Vec::new();
            let mut dn = Vec::new();
            for ((m, x), e) in sim.mode.iter().zip(&sim.x).zip(e0).take(nf) {
                match m {
                    Mode::Up => up.push((*x, *e)),
                    Mode::Down => dn.push((*x, *e)),
                    Mode::Held => {}
                }
            }
            let c = d.effect().expect("chosen");
            line_plot(
                &path,
                "Evidence for curved-borders: residual against the linear block's output",
                &format!(
                    "x_hat (the linear block's output, from {})",
                    input.columns[1]
                ),
                "residual on the border",
                &[
                    Series::points("upper border samples", up.clone()).color(1),
                    Series::points("lower border samples", dn.clone()).color(2),
                    Series::line(
                        "fitted upper curvature",
                        border_curve(upper, -c.model.base.c1, &up),
                    )
                    .color(1),
                    Series::line(
                        "fitted lower curvature",
                        border_curve(lower, c.model.base.c2, &dn),
                    )
                    .color(2),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. The declared model's residual on engaged samples against its x_hat: straight \
                 borders leave no trend; lines: the quadratic and cubic terms the extension fitted."
            ))
        }
        (Some(EffectId::PeriodicDisturbance), Some(Extension::Periodic { omega, .. })) => {
            let (w, p) = residual::periodogram(&e0[..nf], false);
            let pmax = p.iter().cloned().fold(0.0, f64::max);
            let pmin = p
                .iter()
                .cloned()
                .filter(|v| *v > 0.0)
                .fold(f64::INFINITY, f64::min);
            line_plot(
                &path,
                "Evidence for periodic-disturbance: periodogram of the residual (fit part)",
                "omega, rad/sample",
                "power",
                &[
                    Series::line("declared model's residual", pts(&w, &p)).color(3),
                    Series::dashed("fitted frequency", vec![(*omega, pmin), (*omega, pmax)])
                        .color(0),
                ],
                Axes::LOG_LOG,
            )?;
            Ok(format!(
                "Pointing test: {test}. A line in the residual's spectrum stands far above the noise floor; dashed: \
                 the frequency the fit settled on ({} rad/sample).",
                fmt(*omega)
            ))
        }
        (Some(EffectId::Quantization), Some(Extension::Quantization { step, .. })) => {
            let k0 = nf;
            let k1 = (nf + 150).min(n);
            let c = d.effect().expect("chosen");
            line_plot(
                &path,
                "Evidence for quantization: a stretch of the held-out part",
                input.columns[0],
                input.columns[2],
                &[
                    Series::points("measured", pts(&t[k0..k1], &input.y[k0..k1])).color(7),
                    Series::line("declared model", pts(&t[k0..k1], &sim.y[k0..k1])).color(3),
                    Series::line(after_label, pts(&t[k0..k1], &c.output[k0..k1])).color(0),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. The measured values sit on a grid of step {} (the lattice test); the extended \
                 model predicts the sensor's expected reading on that grid.",
                fmt(*step)
            ))
        }
        (Some(EffectId::ColouredNoise), Some(Extension::ColouredNoise { phi })) => {
            let lags = usable_lags(d.config.lags, nf);
            let band = residual::white_band(nf);
            let lagx: Vec<f64> = (1..=lags).map(|l| l as f64).collect();
            let acf0 = residual::autocorrelation(&e0[..nf], lags);
            let acf1 = residual::autocorrelation(&e1[..nf], lags);
            let model = ar_acf(phi, lags);
            line_plot(
                &path,
                "Evidence for coloured-noise: autocorrelation of the output error",
                "lag",
                "r",
                &[
                    Series::points("declared model's residual", pts(&lagx, &acf0)).color(3),
                    Series::line("fitted AR noise model", pts(&lagx, &model)).color(1),
                    Series::points("one-step prediction errors", pts(&lagx, &acf1)).color(0),
                    Series::dashed("95% band", vec![(1.0, band), (lags as f64, band)]).color(7),
                    Series::dashed("", vec![(1.0, -band), (lags as f64, -band)]).color(7),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. The residual is correlated over many lags (red) in the way an AR({}) \
                 disturbance is (orange); the one-step prediction errors of the model with that noise model are \
                 white (blue).",
                phi.len()
            ))
        }
        (Some(EffectId::DirectionDependent), Some(_)) => {
            // The held-out output over time, at most 400 samples so that single rises and falls show.
            let end = n.min(nf + 400);
            let after = &d.effect().expect("the arm matched an effect").output;
            line_plot(
                &path,
                "Evidence for direction-dependent: rises and falls (held-out part)",
                input.columns[0],
                input.columns[2],
                &[
                    Series::line("measured", pts(&t[nf..end], &input.y[nf..end])).color(7),
                    Series::line("declared model", pts(&t[nf..end], &sim.y[nf..end])).color(3),
                    Series::line(after_label, pts(&t[nf..end], &after[nf..end])).color(0),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. The measured output rises and falls at different speeds; the declared \
                 linear block has one set of coefficients for both (red), the block with a falling set follows \
                 both (blue)."
            ))
        }
        (Some(EffectId::ExtraDelay | EffectId::LinearOrder), _) => {
            let lags = usable_lags(d.config.lags, nf);
            let band = residual::white_band(nf);
            let lag0: Vec<f64> = (0..=lags).map(|l| l as f64).collect();
            let cc0 = residual::cross_correlation(&e0[..nf], &input.u[..nf], lags);
            let cc1 = residual::cross_correlation(&e1[..nf], &input.u[..nf], lags);
            line_plot(
                &path,
                "Evidence: correlation of the residual with past inputs (fit part)",
                "lag",
                "r_eu",
                &[
                    Series::points("declared model", pts(&lag0, &cc0.r)).color(3),
                    Series::points(after_label, pts(&lag0, &cc1.r)).color(0),
                    Series::dashed("95% band", vec![(0.0, band), (lags as f64, band)]).color(7),
                    Series::dashed("", vec![(0.0, -band), (lags as f64, -band)]).color(7),
                ],
                Axes::LINEAR,
            )?;
            Ok(format!(
                "Pointing test: {test}. The declared model's residual still depends on past inputs (red points outside \
                 the band): the linear block misses a term or a delay; the chosen structure leaves none (blue)."
            ))
        }
        _ => {
            // Friction, saturation and null: the output against the input on the held-out part.
            let c = d.effect();
            let mut series = vec![
                Series::points("measured", pts(&input.u[nf..n], &input.y[nf..n])).color(7),
                Series::points("declared model", pts(&input.u[nf..n], &sim.y[nf..n])).color(3),
            ];
            if let Some(c) = c {
                series.push(
                    Series::points(after_label, pts(&input.u[nf..n], &c.output[nf..n])).color(0),
                );
            }
            let title = match id {
                Some(e) => format!("Evidence for {e}: output against input (held-out part)"),
                None => "No effect supported: output against input (held-out part)".to_string(),
            };
            line_plot(
                &path,
                &title,
                input.columns[1],
                input.columns[2],
                &series,
                Axes::LINEAR,
            )?;
            Ok(match id {
                Some(EffectId::Friction) => format!(
                    "Pointing test: {test}. Output against input: the measured force saturates at the slip levels and, \
                     after each reversal, unloads along a steep elastic line; the declared backlash cannot saturate, \
                     the friction element does."
                ),
                Some(EffectId::Saturation) => format!(
                    "Pointing test: {test}. Output against input: the measured output is cut off at its extremes; the \
                     declared model overshoots there, the clipped model does not."
                ),
                Some(e) => format!("Pointing test: {test}. Output against input for {e}."),
                None => "No extension passed both criteria; the declared model against the measured output.".to_string(),
            })
        }
    }
}

/// Autocorrelation r(1..=lags) of the AR process e(k) = sum phi_i e(k-i) + v(k) (Yule-Walker, by simulating
/// its impulse response).
fn ar_acf(phi: &[f64], lags: usize) -> Vec<f64> {
    let len = 4000;
    let mut h = vec![0.0; len];
    h[0] = 1.0;
    for k in 1..len {
        h[k] = phi
            .iter()
            .enumerate()
            .filter(|(i, _)| k > *i)
            .map(|(i, p)| p * h[k - 1 - i])
            .sum();
    }
    let r0: f64 = h.iter().map(|v| v * v).sum();
    (1..=lags)
        .map(|l| h.iter().zip(&h[l..]).map(|(a, b)| a * b).sum::<f64>() / r0)
        .collect()
}

fn list(v: &[f64]) -> String {
    v.iter().map(|x| fmt(*x)).collect::<Vec<_>>().join(", ")
}

/// An effect's parameters (the JSON object of [`Diagnosis::to_json`]) as `name value, ...`.
fn params_text(params: &serde_json::Value) -> String {
    params
        .as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !k.ends_with("unit") && *k != "note")
                .map(
                    |(k, v)| match (v.as_i64(), v.as_f64(), v.as_array(), v.as_str()) {
                        (Some(i), _, _, _) => format!("{k} {i}"),
                        (_, Some(x), _, _) => format!("{k} {}", fmt(x)),
                        (_, _, Some(a), _) => format!(
                            "{k} [{}]",
                            a.iter()
                                .map(|x| x.as_f64().map_or(x.to_string(), fmt))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                        (_, _, _, Some(t)) => format!("{k} {t}"),
                        _ => format!("{k} {v}"),
                    },
                )
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default()
}

/// The loop's steps as a table (effect, the test that pointed to it, fit and held-out errors, BIC) and what
/// each later round tried.
fn loop_section(s: &mut String, d: &Diagnosis) {
    let steps = d.steps();
    if steps.is_empty() {
        return;
    }
    let _ = writeln!(s, "## The loop\n");
    let _ = writeln!(
        s,
        "After an effect is kept, the extended model is the current one: its residual is tested again and the \
         candidates it points to are fitted on top of it (all parameters jointly, so the last step is the \
         joint refit of every effect found). Stopped: {}.\n",
        d.stopped
    );
    let _ = writeln!(
        s,
        "| step | effect | pointed to by | fit RMSE | held-out RMSE | BIC | dBIC |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- |");
    let _ = writeln!(
        s,
        "| 0 | declared model | - | {} | {} | {:.1} | - |",
        fmt(d.base_fit_rmse),
        fmt(d.base_heldout_rmse),
        d.base_bic
    );
    for (i, c) in steps.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {} | {}{} | {:.1} | {:+.1} |",
            i + 1,
            c.id,
            c.pointed_by.first().copied().unwrap_or("-"),
            fmt(c.fit_rmse),
            fmt(c.heldout_rmse),
            c.one_step.map_or(String::new(), |o| format!(
                " (one-step {} -> {})",
                fmt(o.before),
                fmt(o.after)
            )),
            c.bic,
            c.delta_bic
        );
    }
    for (i, r) in d.later.iter().enumerate() {
        let tried: Vec<String> = r
            .found
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "`{}` {} ({})",
                    c.id,
                    if c.supported {
                        "supported"
                    } else {
                        "not supported"
                    },
                    c.reason
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "\nRound {}: {}.",
            i + 2,
            if tried.is_empty() {
                "no residual test pointed to an effect that can still be added".to_string()
            } else {
                tried.join("; ")
            }
        );
    }
    let _ = writeln!(s);
}

fn markdown(d: &Diagnosis, input: &ReportInput, figures: &[(String, String)]) -> String {
    let mut s = String::new();
    let effect = d.effect();
    let _ = writeln!(s, "# Diagnosis of {}\n", input.file);
    if let Some(c) = &input.command {
        let _ = writeln!(s, "Produced by `{c}`.\n");
    }
    let st = &d.structure;
    let _ = writeln!(
        s,
        "Model: pseudo-Wiener with backlash, {} ({}; m1 = 1 is the normalisation). Record: {} samples \
         after decimation by {}; the first {} (about {:.0}%) fit the models, the last {} are held out and only \
         used to judge them (the models are simulated over the whole record, so the held-out part starts from \
         the right state). Every held-out error below is this free-run simulation error. Initial state: {}.\n",
        st.chosen,
        st.chosen_by,
        d.n,
        input.decimate.max(1),
        d.n_fit,
        100.0 * d.n_fit as f64 / d.n as f64,
        d.n - d.n_fit,
        d.initial.reason
    );
    if !st.candidates.is_empty() {
        let _ = writeln!(s, "## Structure\n");
        let _ = writeln!(
            s,
            "Chosen on the fit part only ({} samples estimate, the next {} validate): {}.\n\nCriterion: {}.\n",
            st.estimation_samples, st.validation_samples, st.reason, st.criterion
        );
        let _ = writeln!(
            s,
            "| na | nb | delay | equation-error fit, validation RMSE | backlash model, validation RMSE | chosen |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
        let opt = |v: Option<f64>| v.map_or("-".to_string(), fmt);
        for c in st.candidates.iter().take(12) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} |",
                c.structure.na,
                c.structure.nb,
                c.structure.delay,
                opt(c.arx_rmse),
                opt(c.model_rmse),
                if c.chosen { "**yes**" } else { "" }
            );
        }
        let _ = writeln!(
            s,
            "\n({} structures compared in all; the table shows those fitted fully, then the best of the rest.)\n",
            st.candidates.len()
        );
    }
    let _ = writeln!(s, "## Backlash or a straight line?\n");
    let _ = writeln!(
        s,
        "{}.\n\nThe best linear output-error model of the same structure (the backlash with c1 = -c2, m2 = 1) has \
         held-out RMSE {} (fit part {}); the backlash model {} (fit part {}). The backlash fit starts from the \
         linear model among others, so its fit-part error is never above it.\n",
        d.backlash.verdict,
        fmt(d.linear.heldout_rmse),
        fmt(d.linear.fit_rmse),
        fmt(d.base_heldout_rmse),
        fmt(d.base_fit_rmse)
    );
    let _ = writeln!(s, "## Result\n");
    let steps = d.steps();
    if steps.len() > 1 {
        let names: Vec<String> = steps.iter().map(|c| format!("`{}`", c.id)).collect();
        let _ = writeln!(
            s,
            "**Effects found, in order: {}.** Held-out RMSE {} with the declared model, **{}** with all of them \
             (steps in the section *The loop*). The first:\n",
            names.join(", then "),
            fmt(d.base_heldout_rmse),
            fmt(d.after_rmse())
        );
    }
    match effect {
        Some(c) => {
            let _ = writeln!(
                s,
                "**Effect: `{}`** — {}.\n\nPointed to by the test *{}*. Held-out RMSE {} with the declared model, \
                 **{}** with the extension ({:.1}x lower; {} error; Diebold-Mariano z = {:.1}); BIC on the fit part \
                 {} lower.\n",
                c.id,
                c.id.describe(),
                d.pointing_test().unwrap_or("-"),
                fmt(d.base_heldout_rmse),
                fmt(c.heldout_rmse),
                d.base_heldout_rmse / c.heldout_rmse.max(f64::MIN_POSITIVE),
                c.error_kind,
                c.heldout_z,
                fmt(-c.delta_bic)
            );
            if let Some(o) = c.one_step {
                let _ = writeln!(
                    s,
                    "A noise model is judged by one-step-ahead prediction, y(k) - [s(k) + sum phi_i (y(k-i) - s(k-i))] \
                     with s the simulated output: held-out one-step error {} before (the plain model's predictor \
                     is its simulation) and {} after. The errors above are free-run simulation errors, as \
                     everywhere in this report.\n",
                    fmt(o.before),
                    fmt(o.after)
                );
            }
        }
        None => {
            let _ = writeln!(
                s,
                "**Effect: null** — no extension of the catalogue is supported by the evidence. Held-out RMSE of the \
                 declared model: {}.\n",
                fmt(d.base_heldout_rmse)
            );
        }
    }
    loop_section(&mut s, d);
    let _ = writeln!(s, "Decision rule: {}.\n", DECISION_RULE);
    for why in &d.set_aside {
        let _ = writeln!(s, "Set aside: {why}.\n");
    }
    if !d.not_tried.is_empty() {
        let names: Vec<String> = d.not_tried.iter().map(|e| format!("`{e}`")).collect();
        let _ = writeln!(
            s,
            "**Not tried** (the time budget of {:.0} s was spent first): {}.\n",
            d.config.time_budget.as_secs_f64(),
            names.join(", ")
        );
    }

    let _ = writeln!(s, "## Residual tests\n");
    let _ = writeln!(
        s,
        "On the fit part of the declared model's residual (samples 0..{}). A test that rejects points to the \
         effects listed; those effects are fitted as candidates.\n",
        d.n_fit
    );
    let _ = writeln!(
        s,
        "| test | statistic | threshold | rejects | points to | detail |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
    for t in &d.tests {
        let to: Vec<String> = t.points_to.iter().map(|e| format!("`{e}`")).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            t.verdict.name,
            fmt(t.verdict.statistic),
            fmt(t.verdict.threshold),
            if t.verdict.rejects { "**yes**" } else { "no" },
            to.join(", "),
            t.verdict.detail.replace('|', "/")
        );
    }
    let _ = writeln!(s, "\n## Candidates\n");
    if d.candidates.is_empty() {
        let _ = writeln!(s, "No test rejected: no candidate was fitted.\n");
    } else {
        let _ = writeln!(
            s,
            "Each candidate extension is fitted on the fit part (Levenberg-Marquardt on the simulated output, \
             started from the declared fit). BIC = N ln(RSS/N) + k ln N (+ ln of the number of structures \
             searched: extra-delay {:.2}, linear-order {:.2}); dBIC < 0 favours the extension.\n",
            structure_penalty(EffectId::ExtraDelay),
            structure_penalty(EffectId::LinearOrder)
        );
        let _ = writeln!(
            s,
            "| effect | pointed by | parameters | fit RMSE | held-out RMSE | z | dBIC | supported | why |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
        let json = d.to_json(None);
        for (i, c) in d.candidates.iter().enumerate() {
            let p = params_text(&json["candidates"][i]["parameters"]);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} | {:+.1} | {} | {} |",
                if Some(i) == d.chosen {
                    format!("**`{}`** (chosen)", c.id)
                } else {
                    format!("`{}`", c.id)
                },
                c.pointed_by.join(", "),
                p,
                fmt(c.fit_rmse),
                fmt(c.heldout_rmse),
                c.heldout_z,
                c.delta_bic,
                if c.supported { "yes" } else { "no" },
                c.reason
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Models\n");
    let b = &d.base.base;
    let _ = writeln!(
        s,
        "Declared model fitted: a = [{}], b = [{}], m1 = 1, m2 = {}, c1 = {}, c2 = {}; fit RMSE {}, held-out RMSE {}.\n",
        list(&b.a),
        list(&b.b),
        fmt(b.m2),
        fmt(b.c1),
        fmt(b.c2),
        fmt(d.base_fit_rmse),
        fmt(d.base_heldout_rmse)
    );
    if let Some(c) = effect {
        let b = &c.model.base;
        let _ = writeln!(
            s,
            "Extended model ({}): na = {}, nb = {}, delay = {}, a = [{}], b = [{}], m1 = 1, m2 = {}, c1 = {}, c2 = {}; {}: {}.\n",
            c.id,
            b.na,
            b.nb,
            b.delay,
            list(&b.a),
            list(&b.b),
            fmt(b.m2),
            fmt(b.c1),
            fmt(b.c2),
            c.id,
            params_text(&d.to_json(None)["effect"]["parameters"])
        );
    }
    if !input.validations.is_empty() {
        let _ = writeln!(s, "## Cross-record validation\n");
        let _ = writeln!(
            s,
            "The models fitted above, simulated over other records from rest (no refit).\n\n| record | samples | output std | RMSE declared | RMSE {} |\n| --- | --- | --- | --- | --- |",
            effect.map_or("chosen (null)".to_string(), |c| c.id.to_string())
        );
        for v in input.validations {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                v.name,
                v.result.samples,
                fmt(v.result.y_std),
                fmt(v.result.rmse_before),
                fmt(v.result.rmse_after)
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Figures\n");
    for (f, cap) in figures {
        let _ = writeln!(s, "![{f}]({f})\n\n{cap}\n");
    }
    let _ = writeln!(
        s,
        "## Why no \"offset\" effect\n\nA constant output offset d is not in the catalogue: with straight borders \
         it is absorbed exactly into the gaps, m1 (x - c1) + d = m1 (x - (c1 - d/m1)) and likewise \
         m2 (x + c2) + d = m2 (x + (c2 + d/m2)), so the declared model already fits it and no data can show it \
         (an input offset passes through the linear block and is absorbed the same way)."
    );
    s
}

/// The change of each border a fitted gap drift predicts against the declared fit: the upper border
/// `y = m1 (x - c1(k))` (m1 = 1) falls by `c1_rate k`, the lower `y = m2 (x + c2(k))` rises by
/// `m2 c2_rate k`.
fn border_drift_lines(t: &[f64], c1_rate: f64, c2_rate: f64, m2: f64) -> [Vec<(f64, f64)>; 2] {
    [drift_line(t, -c1_rate), drift_line(t, m2 * c2_rate)]
}

/// `line` moved up or down so that its mean equals the mean of `data`'s y (the declared fit absorbed the
/// average gap, so only the change over time is the drift's).
fn centred_on(line: Vec<(f64, f64)>, data: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let ml = line.iter().map(|p| p.1).sum::<f64>() / line.len().max(1) as f64;
    let md = data.iter().map(|p| p.1).sum::<f64>() / data.len().max(1) as f64;
    line.into_iter().map(|(a, b)| (a, b - ml + md)).collect()
}

/// The line `slope k` (k the sample index) at about 200 of the times `t`.
fn drift_line(t: &[f64], slope: f64) -> Vec<(f64, f64)> {
    (0..t.len())
        .step_by((t.len() / 200).max(1))
        .map(|k| (t[k], slope * k as f64))
        .collect()
}

/// Means of `e` over windows of `win` consecutive samples of `idx` (every `win / 4`-th window), each at the
/// time `t` of its middle sample.
fn running_means(t: &[f64], e: &[f64], idx: &[usize], win: usize) -> Vec<(f64, f64)> {
    idx.windows(win)
        .step_by((win / 4).max(1))
        .map(|w| {
            (
                t[w[w.len() / 2]],
                w.iter().map(|&k| e[k]).sum::<f64>() / w.len() as f64,
            )
        })
        .collect()
}

/// A fitted border curvature `s^2 (coef[0] + coef[1] s)`, `s = x + shift`, at 101 evenly spaced x over the
/// range the border's `samples` (x, residual) cover (nothing when there are none: a curve is never drawn
/// where the data do not reach).
fn border_curve(coef: &[f64; 2], shift: f64, samples: &[(f64, f64)]) -> Vec<(f64, f64)> {
    if samples.is_empty() {
        return Vec::new();
    }
    let (xmin, xmax) = samples
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (x, _)| {
            (a.min(*x), b.max(*x))
        });
    (0..=100)
        .map(|i| {
            let x = xmin + (xmax - xmin) * i as f64 / 100.0;
            let s = x + shift;
            (x, s * s * (coef[0] + s * coef[1]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parameters in words, in the JSON object's (sorted) key order: integers as they are, numbers with
    /// four decimals or in exponent form below 1e-3, lists element by element, text as it is; units and
    /// notes left out; anything else (here a flag) as JSON.
    #[test]
    fn parameters_in_words() {
        let p = serde_json::json!({
            "delay": 3,
            "c1_rate": 0.00002,
            "rate_unit": "per sample",
            "note": "a remark",
            "phi": [0.5, -0.25, "x"],
            "form": "Series",
            "flag": true,
        });
        assert_eq!(
            params_text(&p),
            "c1_rate 2.000e-5, delay 3, flag true, form Series, phi [0.5000, -0.2500, \"x\"]"
        );
        assert_eq!(params_text(&serde_json::json!(null)), "");
        assert_eq!(params_text(&serde_json::json!({})), "");
    }

    /// The autocorrelation of AR processes by Yule-Walker: AR(1) with phi 0.5 has r(l) = 0.5^l; AR(2) with
    /// phi (0.5, 0.3) has r(1) = phi1 / (1 - phi2) = 5/7 and r(2) = phi1 r(1) + phi2 = 23/35.
    #[test]
    fn ar_autocorrelation_by_yule_walker() {
        let r = ar_acf(&[0.5], 3);
        for (l, v) in r.iter().enumerate() {
            assert!((v - 0.5f64.powi(l as i32 + 1)).abs() < 1e-12, "{r:?}");
        }
        let r = ar_acf(&[0.5, 0.3], 2);
        assert!(
            (r[0] - 5.0 / 7.0).abs() < 1e-12 && (r[1] - 23.0 / 35.0).abs() < 1e-12,
            "{r:?}"
        );
    }
}

#[cfg(test)]
mod mutation_tests;
