//! The report's figures as data: the held-out part, the residuals, the correlation functions, the steps of
//! the loop and the cross-record validations, each a [`ReportFigure`] (its series and a caption computed from
//! those same series), drawn by [`ReportFigure::draw`]. The evidence figure is the chosen effect's own
//! ([`evidence`]).
//!
//! The words: the model before any effect is the *plain model*, of the structure the user declared or the
//! tool chose ([`Names`]); the final model is named by the effects it adds. Where the final model has a noise
//! model, its residual is shown twice, as it is: the free-run simulation's (what the noise model does not
//! change) and the one-step prediction's (what the noise model whitens).

use std::path::Path;

use crate::diagnose::effects::figure::{Figure, fmt, output_against_input, pts};
use crate::diagnose::report::input::{ReportError, ReportInput, Validation};
use crate::diagnose::residual;
use crate::diagnose::search::engine::{Diagnosis, usable_lags};
use crate::report::plot::{Axes, Panel, PlotError, Series, grid_plot, line_plot};
use crate::stats::rms;

/// Colours of the report's series (indices into the plot palette), the same in every figure.
const MEASURED: usize = 7;
const PLAIN: usize = 3;
const FINAL: usize = 0;
const ONE_STEP: usize = 2;
const REFERENCE: usize = 7;
/// The constant predictor's level in the held-out figure.
const CONSTANT_COLOR: usize = 4;
const CONSTANT: &str = "predicting the fit part's mean";

/// One panel of a report figure, owning its words.
#[derive(Debug, Clone, PartialEq)]
pub struct FigurePanel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series<'static>>,
}

/// A figure of the report as data: what its panels draw and its caption, computed from the same numbers.
/// Tests read this value, never the PNG.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportFigure {
    /// File name in the report's folder.
    pub file: String,
    pub title: String,
    /// One panel: a single plot; several: a grid of two columns.
    pub panels: Vec<FigurePanel>,
    pub caption: String,
}

impl ReportFigure {
    /// Draw the PNG into `dir`.
    pub fn draw(&self, dir: &Path) -> Result<(), PlotError> {
        let path = dir.join(&self.file);
        let panels: Vec<Panel> = self
            .panels
            .iter()
            .map(|p| Panel {
                title: &p.title,
                x_label: &p.x_label,
                y_label: &p.y_label,
                series: p.series.clone(),
                log_x: false,
                log_y: false,
            })
            .collect();
        match panels.as_slice() {
            [one] => line_plot(
                &path,
                &self.title,
                one.x_label,
                one.y_label,
                &one.series,
                Axes::LINEAR,
            ),
            _ => grid_plot(&path, &self.title, &panels, 2),
        }
    }

    /// The series labelled `label` in panel `panel`.
    pub fn series(&self, panel: usize, label: &str) -> Option<&Series<'static>> {
        self.panels
            .get(panel)?
            .series
            .iter()
            .find(|s| s.label == label)
    }
}

/// The models' names in legends and captions.
#[derive(Debug, Clone, PartialEq)]
pub struct Names {
    /// The model before any effect: "plain model (declared structure)" or "(chosen structure)".
    pub plain: String,
    /// The final model as simulated: "plain + saturation + curved-borders" (with a noise model:
    /// "..., free run"); the plain model's name when no effect was found.
    pub after: String,
    /// The final model's one-step predictor, when it has a noise model.
    pub one_step: Option<String>,
}

impl Names {
    pub fn of(d: &Diagnosis) -> Self {
        let plain = format!("plain model ({} structure)", Self::structure_word(d));
        let steps = d.steps();
        if steps.is_empty() {
            return Self {
                after: plain.clone(),
                plain,
                one_step: None,
            };
        }
        let added: Vec<&str> = steps.iter().map(|c| c.id.as_str()).collect();
        let after = format!("plain + {}", added.join(" + "));
        let noise = steps.last().is_some_and(|c| c.model.noise().is_some());
        Self {
            plain,
            after: if noise {
                format!("{after}, free run")
            } else {
                after.clone()
            },
            one_step: noise.then(|| format!("{after}, one-step prediction")),
        }
    }

    /// "declared" or "chosen": the word for how the structure came about.
    pub fn structure_word(d: &Diagnosis) -> &'static str {
        if d.structure.chosen_by == "declared" {
            "declared"
        } else {
            "chosen"
        }
    }
}

/// The plain and the final model's outputs and residuals over the record, and their names.
pub struct Curves<'a> {
    pub before: &'a [f64],
    pub after: &'a [f64],
    /// Residuals y - simulation of the plain and of the final model.
    pub e0: Vec<f64>,
    pub e1: Vec<f64>,
    /// With a noise model: y minus the final model's one-step prediction.
    pub e1_pred: Option<Vec<f64>>,
    pub names: Names,
}

impl<'a> Curves<'a> {
    pub fn new(d: &'a Diagnosis, input: &ReportInput) -> Self {
        let y = &input.y[..d.n];
        let before = &d.base_sim.y;
        let last = d.steps().last().copied();
        let after: &[f64] = last.map_or(before, |c| &c.output);
        let minus = |m: &[f64]| y.iter().zip(m).map(|(a, b)| a - b).collect::<Vec<f64>>();
        let e1_pred = last
            .filter(|c| c.model.noise().is_some())
            .map(|c| minus(&c.model.predict_from(&c.output, y)));
        Self {
            before,
            after,
            e0: minus(before),
            e1: minus(after),
            e1_pred,
            names: Names::of(d),
        }
    }

    /// Whether the final model simulates differently from the plain one (a noise model alone leaves the
    /// simulation as it is: then the figures draw the plain model's free run once, named for both).
    fn extended(&self, d: &Diagnosis) -> bool {
        !d.steps().is_empty() && self.after != self.before
    }

    /// The plain model's name in figures: when the final model's free run is the same, named for both.
    fn plain_label(&self, d: &Diagnosis) -> String {
        if d.steps().is_empty() || self.extended(d) {
            self.names.plain.clone()
        } else {
            format!("{} = {}", self.names.plain, self.names.after)
        }
    }
}

/// Root mean square of the vertical distance between two series drawn over the same x.
pub fn rms_between(a: &Series, b: &Series) -> f64 {
    rms(a.points.iter().zip(&b.points).map(|(p, q)| p.1 - q.1))
}

/// Root mean square of a series' values.
pub fn rms_of(s: &Series) -> f64 {
    rms(s.points.iter().map(|p| p.1))
}

fn panel(title: &str, x: &str, y: &str, series: Vec<Series<'static>>) -> Vec<FigurePanel> {
    vec![FigurePanel {
        title: title.into(),
        x_label: x.into(),
        y_label: y.into(),
        series,
    }]
}

/// Measured output against the models over `t`: the models dashed, the measured trace drawn last (on top).
fn measured_and_models(
    t: &[f64],
    y: &[f64],
    models: &[(&str, &[f64], usize)],
) -> Vec<Series<'static>> {
    let mut series: Vec<Series<'static>> = models
        .iter()
        .map(|(name, m, color)| Series::dashed(name.to_string(), pts(t, m)).color(*color))
        .collect();
    series.push(Series::line("measured", pts(t, y)).color(MEASURED));
    series
}

/// Each model's name, colour and RMSE against the measured trace, from the series of
/// [`measured_and_models`].
fn model_errors(series: &[Series]) -> Vec<String> {
    let measured = series.last().expect("the measured trace");
    series[..series.len() - 1]
        .iter()
        .zip(["red", "blue"])
        .map(|(s, colour)| {
            format!(
                "{} ({colour}, RMSE {})",
                s.label,
                fmt(rms_between(measured, s))
            )
        })
        .collect()
}

/// The held-out part: the measured output on top of the plain and the final model (dashed).
pub fn heldout_figure(d: &Diagnosis, input: &ReportInput, c: &Curves) -> ReportFigure {
    let (n, nf) = (d.n, d.n_fit);
    let th = &input.t[nf..n];
    let plain = c.plain_label(d);
    let mut models = vec![(plain.as_str(), &c.before[nf..], PLAIN)];
    if c.extended(d) {
        models.push((c.names.after.as_str(), &c.after[nf..], FINAL));
    }
    let mut series = measured_and_models(th, &input.y[nf..n], &models);
    let errors = model_errors(&series);
    // The first baseline a user tries: the fit part's mean, as a level under the models.
    let level = crate::stats::mean(&input.y[..nf]);
    let constant =
        Series::dashed(CONSTANT, th.iter().map(|t| (*t, level)).collect()).color(CONSTANT_COLOR);
    let constant_rmse = rms(input.y[nf..n].iter().map(|v| v - level));
    series.insert(0, constant);
    ReportFigure {
        file: "heldout.png".into(),
        title: "Held-out part: measured output and the models (free run)".into(),
        caption: format!(
            "Held-out part ({} samples, used by no fit): measured (grey, drawn on top) and the models simulated \
             free-run from the start of the record (dashed): {}; predicting the fit part's mean, the level \
             drawn under them, gives RMSE {} (fit {:.1}% for the final model).",
            n - nf,
            errors.join("; "),
            fmt(constant_rmse),
            d.explained.fit_percent
        ),
        panels: panel("", input.columns[0], input.columns[2], series),
    }
}

/// The residuals over the record (free run; with a noise model also the one-step prediction's), with the fit
/// / held-out split marked.
pub fn residual_figure(d: &Diagnosis, input: &ReportInput, c: &Curves) -> ReportFigure {
    let t = &input.t[..d.n];
    let mut series = vec![
        Series::line(
            format!("{}: y - simulation", c.plain_label(d)),
            pts(t, &c.e0),
        )
        .color(PLAIN),
    ];
    if c.extended(d) {
        series.push(
            Series::line(format!("{}: y - simulation", c.names.after), pts(t, &c.e1)).color(FINAL),
        );
    }
    if let (Some(name), Some(e)) = (&c.names.one_step, &c.e1_pred) {
        series.push(Series::line(format!("{name}: y - prediction"), pts(t, e)).color(ONE_STEP));
    }
    let held: Vec<String> = series
        .iter()
        .map(|s| format!("{} {}", s.label, fmt(rms_of(&held_out(s, d.n_fit)))))
        .collect();
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    series.push(
        Series::dashed("fit | held-out", vec![(t[d.n_fit], lo), (t[d.n_fit], hi)]).color(REFERENCE),
    );
    ReportFigure {
        file: "residual.png".into(),
        title: "Residual over the record".into(),
        caption: format!(
            "Residuals over the record; left of the dashed line the fit part, right of it the held-out part. \
             Held-out RMS: {}.",
            held.join("; ")
        ),
        panels: panel(
            "",
            input.columns[0],
            &format!("residual of {}", input.columns[2]),
            series,
        ),
    }
}

/// The held-out points (from sample `n_fit` on) of a series drawn over the record.
fn held_out(s: &Series, n_fit: usize) -> Series<'static> {
    Series::line("", s.points[n_fit.min(s.points.len())..].to_vec())
}

/// The residuals the correlation figures are drawn from: name, residual, colour.
fn correlated<'c>(d: &Diagnosis, c: &'c Curves) -> Vec<(String, &'c [f64], usize)> {
    let mut out = vec![(
        format!("{}: y - simulation", c.plain_label(d)),
        c.e0.as_slice(),
        PLAIN,
    )];
    if c.extended(d) {
        out.push((
            format!("{}: y - simulation", c.names.after),
            c.e1.as_slice(),
            FINAL,
        ));
    }
    if let (Some(name), Some(e)) = (&c.names.one_step, &c.e1_pred) {
        out.push((format!("{name}: y - prediction"), e.as_slice(), ONE_STEP));
    }
    out
}

/// Autocorrelation and residual-input cross-correlation on the fit part, of every residual of
/// `correlated`, with the 95% bands of a white residual.
pub fn correlations_figure(d: &Diagnosis, input: &ReportInput, c: &Curves) -> ReportFigure {
    let nf = d.n_fit;
    let lags = usable_lags(d.config.lags, nf);
    let band = residual::white_band(nf);
    let lagx: Vec<f64> = (1..=lags).map(|l| l as f64).collect();
    let lag0: Vec<f64> = (0..=lags).map(|l| l as f64).collect();
    let bands = |x0: f64| {
        vec![
            Series::dashed("95% band", vec![(x0, band), (lags as f64, band)]).color(REFERENCE),
            Series::dashed("", vec![(x0, -band), (lags as f64, -band)]).color(REFERENCE),
        ]
    };
    let (mut acf, mut ccf) = (Vec::new(), Vec::new());
    for (name, e, colour) in correlated(d, c) {
        let r = residual::autocorrelation(&e[..nf], lags);
        acf.push(Series::points(name.clone(), pts(&lagx, &r)).color(colour));
        let x = residual::cross_correlation(&e[..nf], &input.u[..nf], lags);
        ccf.push(Series::points(name, pts(&lag0, &x.r)).color(colour));
    }
    let lag1: Vec<String> = acf
        .iter()
        .map(|s| format!("{} {}", s.label, fmt(s.points[0].1)))
        .collect();
    acf.extend(bands(1.0));
    ccf.extend(bands(0.0));
    let one = |title: &str, series| FigurePanel {
        title: title.into(),
        x_label: "lag [samples]".into(),
        y_label: "r".into(),
        series,
    };
    ReportFigure {
        file: "correlations.png".into(),
        title: "Correlation functions of the residuals (fit part)".into(),
        caption: format!(
            "Autocorrelation of each residual and its correlation with past inputs, on the fit part; dashed: \
             +-{} = 1.96/sqrt(N), the 95% band of a white residual independent of the input. Lag-1 \
             autocorrelation: {}.",
            fmt(band),
            lag1.join("; ")
        ),
        panels: vec![
            one("autocorrelation r_ee(lag)", acf),
            one("cross-correlation r_eu(lag)", ccf),
        ],
    }
}

/// A cross-record validation: measured on top of both models (dashed) over that record (one model when the
/// final model simulates as the plain one).
pub fn validation_figure(
    d: &Diagnosis,
    v: &Validation,
    input: &ReportInput,
    c: &Curves,
) -> ReportFigure {
    let plain = c.plain_label(d);
    let mut models = vec![(plain.as_str(), v.result.before.as_slice(), PLAIN)];
    if c.extended(d) {
        models.push((c.names.after.as_str(), &v.result.after, FINAL));
    }
    let series = measured_and_models(&v.t, &v.y, &models);
    ReportFigure {
        file: format!("validate_{}.png", v.name),
        title: format!("Cross-record validation on {}", v.name),
        caption: format!(
            "{}: the models fitted here, simulated over that record from rest (dashed; measured in grey on \
             top): {} (the output's standard deviation is {}).",
            v.name,
            model_errors(&series).join("; "),
            fmt(v.result.y_std)
        ),
        panels: panel("", input.columns[0], input.columns[2], series),
    }
}

/// Points of a curve, (x, y).
type Curve = Vec<(f64, f64)>;

/// The held-out errors after each step of the loop (step 0: the plain model), free run and, where the last
/// step adds a noise model, one-step prediction (before it the predictor is the simulation, so the two
/// coincide).
fn step_errors(d: &Diagnosis) -> (Curve, Option<Curve>) {
    let steps = d.steps();
    let free: Vec<(f64, f64)> = std::iter::once(d.base_heldout_rmse)
        .chain(steps.iter().map(|c| c.heldout_rmse))
        .enumerate()
        .map(|(i, v)| (i as f64, v))
        .collect();
    let one_step = steps.last().and_then(|c| c.one_step).map(|o| {
        let mut p = free.clone();
        let last = p.len() - 1;
        p[last - 1].1 = o.before;
        p[last].1 = o.after;
        p
    });
    (free, one_step)
}

/// The held-out error at each step of the loop, on an axis of whole steps.
pub fn steps_figure(d: &Diagnosis, input: &ReportInput, c: &Curves) -> ReportFigure {
    let (free, one_step) = step_errors(d);
    let last = (free.len() - 1) as f64;
    let mut series = vec![
        Series::line("held-out free-run RMSE", free.clone()).color(FINAL),
        Series::points("", free.clone()).color(FINAL),
    ];
    let list = |p: &[(f64, f64)]| {
        p.iter()
            .map(|(i, v)| format!("step {i}: {}", fmt(*v)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut caption = format!(
        "Held-out RMSE at each step (0: the {}; then {}), free run: {}",
        c.names.plain,
        d.steps()
            .iter()
            .enumerate()
            .map(|(i, s)| format!("{} `{}`", i + 1, s.id))
            .collect::<Vec<_>>()
            .join(", "),
        list(&free)
    );
    if let Some(p) = one_step {
        caption.push_str(&format!(
            "; one-step prediction: {} (before the noise model the predictor is the simulation)",
            list(&p[p.len() - 2..])
        ));
        series.push(Series::dashed("held-out one-step prediction RMSE", p.clone()).color(ONE_STEP));
        series.push(Series::points("", p).color(ONE_STEP));
    }
    caption.push_str(&format!(
        "; the best linear model's free run {} for reference (grey).",
        fmt(d.linear.heldout_rmse)
    ));
    series.push(
        Series::dashed(
            "best linear model, free run",
            vec![(0.0, d.linear.heldout_rmse), (last, d.linear.heldout_rmse)],
        )
        .color(REFERENCE),
    );
    ReportFigure {
        file: "steps.png".into(),
        title: "Held-out error at each step of the loop".into(),
        caption,
        panels: panel(
            "",
            "effects added",
            &format!("held-out RMSE of {}", input.columns[2]),
            series,
        ),
    }
}

/// Every figure of the report but the evidence figure, in the report's order.
pub fn figures(d: &Diagnosis, input: &ReportInput, c: &Curves) -> Vec<ReportFigure> {
    let mut out = vec![
        heldout_figure(d, input, c),
        residual_figure(d, input, c),
        correlations_figure(d, input, c),
    ];
    if !d.steps().is_empty() {
        out.push(steps_figure(d, input, c));
    }
    out.extend(
        input
            .validations
            .iter()
            .map(|v| validation_figure(d, v, input, c)),
    );
    out
}

/// The evidence figure: the first effect's own ([`crate::diagnose::effects::Effect::evidence`]), or for
/// `null` the plain model against the measured output; returns its caption.
pub fn evidence(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
    c: &Curves,
) -> Result<String, ReportError> {
    let path = dir.join("evidence.png");
    let chosen = d.effect();
    // The first effect's own residual (it is the final model only when it is the one step).
    let first_e: Vec<f64> = chosen.map_or_else(
        || c.e0.clone(),
        |m| {
            input.y[..d.n]
                .iter()
                .zip(&m.output)
                .map(|(a, b)| a - b)
                .collect()
        },
    );
    let first_pred: Option<Vec<f64>> = chosen.filter(|m| m.model.noise().is_some()).map(|m| {
        let p = m.model.predict_from(&m.output, &input.y[..d.n]);
        input.y[..d.n].iter().zip(&p).map(|(a, b)| a - b).collect()
    });
    let first_label = chosen.map_or(c.names.plain.clone(), |m| format!("plain + {}", m.id));
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
        plain_label: &c.names.plain,
        e0: &c.e0,
        e1: &first_e,
        e1_pred: first_pred.as_deref(),
        after_label: &first_label,
        model: chosen.map_or(&d.base, |m| &m.model),
        output: chosen.map_or(&d.base_sim.y, |m| &m.output),
        lags: usable_lags(d.config.lags, d.n_fit),
    };
    Ok(match chosen {
        Some(m) => m.id.effect().evidence(&fig)?,
        None => {
            output_against_input(
                &fig,
                "No effect supported: output against input (held-out part)",
                false,
            )?;
            format!(
                "No extension passed both criteria; the {} against the measured output.",
                c.names.plain
            )
        }
    })
}
