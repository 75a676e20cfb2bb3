//! The report's figures: the held-out part, the residuals, the correlation functions, the steps of the loop,
//! the evidence (drawn by the chosen effect) and the cross-record validations. Each returns its file name
//! or caption for `report.md`.

use std::path::Path;

use crate::diagnose::effects::figure::{Figure, fmt, output_against_input, pts};
use crate::diagnose::report::input::{ReportError, ReportInput, Validation};
use crate::diagnose::residual;
use crate::diagnose::search::engine::{Diagnosis, usable_lags};
use crate::report::plot::{Axes, Panel, Series, grid_plot, line_plot};

/// The declared and the final model's outputs and residuals over the record, and the final model's name in
/// the legends.
pub(super) struct Curves<'a> {
    pub(super) before: &'a [f64],
    pub(super) after: &'a [f64],
    pub(super) after_label: String,
    pub(super) e0: Vec<f64>,
    pub(super) e1: Vec<f64>,
}

impl<'a> Curves<'a> {
    pub(super) fn new(d: &'a Diagnosis, input: &ReportInput) -> Self {
        let y = &input.y[..d.n];
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
        Self {
            before,
            after,
            e0: y.iter().zip(before).map(|(a, b)| a - b).collect(),
            e1: y.iter().zip(after).map(|(a, b)| a - b).collect(),
            after_label,
        }
    }
}

/// The held-out part: measured output against the declared and the final model.
pub(super) fn heldout_figure(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    c: &Curves,
) -> Result<(String, String), ReportError> {
    let (n, nf) = (d.n, d.n_fit);
    let th = &input.t[nf..n];
    line_plot(
        &dir.join("heldout.png"),
        "Held-out part: measured output and the two models",
        input.columns[0],
        input.columns[2],
        &[
            Series::line("measured", pts(th, &input.y[nf..n])).color(7),
            Series::line("declared model", pts(th, &c.before[nf..])).color(3),
            Series::line(&c.after_label, pts(th, &c.after[nf..])).color(0),
        ],
        Axes::LINEAR,
    )?;
    Ok((
        "heldout.png".into(),
        format!(
            "Held-out part ({} samples, not used by any fit): measured (grey), declared model (red, RMSE {}), {} (blue, RMSE {}).",
            n - nf,
            fmt(d.base_heldout_rmse),
            c.after_label,
            fmt(d.after_rmse())
        ),
    ))
}

/// The residual of both models over the record, the fit / held-out split marked.
pub(super) fn residual_figure(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    c: &Curves,
) -> Result<(String, String), ReportError> {
    let t = &input.t[..d.n];
    let (lo, hi) =
        c.e0.iter()
            .chain(&c.e1)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
    line_plot(
        &dir.join("residual.png"),
        "Residual y - y_model over the record",
        input.columns[0],
        &format!("residual of {}", input.columns[2]),
        &[
            Series::line("declared model", pts(t, &c.e0)).color(3),
            Series::line(&c.after_label, pts(t, &c.e1)).color(0),
            Series::dashed("fit | held-out", vec![(t[d.n_fit], lo), (t[d.n_fit], hi)]).color(7),
        ],
        Axes::LINEAR,
    )?;
    Ok((
        "residual.png".into(),
        "Residual of the declared model (red) and of the chosen model (blue); left of the dashed line the fit \
         part, right of it the held-out part."
            .into(),
    ))
}

/// Autocorrelation and residual-input cross-correlation on the fit part, before and after, with the 95%
/// bands of a white residual.
pub(super) fn correlations_figure(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    c: &Curves,
) -> Result<(String, String), ReportError> {
    let nf = d.n_fit;
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
    let acf0 = residual::autocorrelation(&c.e0[..nf], lags);
    let acf1 = residual::autocorrelation(&c.e1[..nf], lags);
    let cc0 = residual::cross_correlation(&c.e0[..nf], &input.u[..nf], lags);
    let cc1 = residual::cross_correlation(&c.e1[..nf], &input.u[..nf], lags);
    let mut p1 = vec![
        Series::points("declared model", pts(&lagx, &acf0)).color(3),
        Series::points(&c.after_label, pts(&lagx, &acf1)).color(0),
    ];
    p1.extend(bands(1.0));
    let mut p2 = vec![
        Series::points("declared model", pts(&lag0, &cc0.r)).color(3),
        Series::points(&c.after_label, pts(&lag0, &cc1.r)).color(0),
    ];
    p2.extend(bands(0.0));
    let panel = |title, series| Panel {
        title,
        x_label: "lag",
        y_label: "r",
        series,
        log_x: false,
        log_y: false,
    };
    grid_plot(
        &dir.join("correlations.png"),
        "Correlation functions of the residual (fit part)",
        &[
            panel("autocorrelation r_ee(lag)", p1),
            panel("cross-correlation r_eu(lag)", p2),
        ],
        2,
    )?;
    Ok((
        "correlations.png".into(),
        format!(
            "Autocorrelation of the residual and its correlation with past inputs on the fit part, declared model \
             (red) and chosen model (blue); dashed: +-{} = 1.96/sqrt(N), the 95% band of a white residual \
             independent of the input.",
            fmt(band)
        ),
    ))
}

/// A cross-record validation: measured against both models over that record.
pub(super) fn validation_figure(
    dir: &Path,
    v: &Validation,
    input: &ReportInput,
    c: &Curves,
) -> Result<(String, String), ReportError> {
    let file = format!("validate_{}.png", v.name);
    line_plot(
        &dir.join(&file),
        &format!("Cross-record validation on {}", v.name),
        input.columns[0],
        input.columns[2],
        &[
            Series::line("measured", pts(&v.t, &v.y)).color(7),
            Series::line("declared model", pts(&v.t, &v.result.before)).color(3),
            Series::line(&c.after_label, pts(&v.t, &v.result.after)).color(0),
        ],
        Axes::LINEAR,
    )?;
    Ok((
        file,
        format!(
            "{}: the models fitted here, simulated over that record from rest: RMSE declared {}, chosen {} \
             (the output's standard deviation is {}).",
            v.name,
            fmt(v.result.rmse_before),
            fmt(v.result.rmse_after),
            fmt(v.result.y_std)
        ),
    ))
}

/// The held-out error after each step of the loop (step 0: the declared model); returns its caption.
pub(super) fn steps_plot(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
) -> Result<String, ReportError> {
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

/// The evidence figure: the first effect's own ([`crate::diagnose::effects::Effect::evidence`]), or for
/// `null` the declared model against the measured output; returns its caption.
pub(super) fn evidence(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    e0: &[f64],
    e1: &[f64],
    after_label: &str,
) -> Result<String, ReportError> {
    let path = dir.join("evidence.png");
    let chosen = d.effect();
    let fig = Figure {
        path: &path,
        test: d.pointing_test().unwrap_or("none"),
        n: d.n,
        n_fit: d.n_fit,
        t: &input.t[..d.n],
        u: input.u,
        y: input.y,
        columns: input.columns,
        declared: &d.base_sim,
        e0,
        e1,
        after_label,
        model: chosen.map_or(&d.base, |c| &c.model),
        output: chosen.map_or(&d.base_sim.y, |c| &c.output),
        lags: usable_lags(d.config.lags, d.n_fit),
    };
    Ok(match chosen {
        Some(c) => c.id.effect().evidence(&fig)?,
        None => {
            output_against_input(
                &fig,
                "No effect supported: output against input (held-out part)",
                false,
            )?;
            "No extension passed both criteria; the declared model against the measured output."
                .to_string()
        }
    })
}
