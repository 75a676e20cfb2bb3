//! The evidence figure an effect draws for the report: what it is drawn from ([`Figure`]) and the drawing
//! helpers the effects share.

use std::path::Path;

use crate::diagnose::fit::model::{EffectModel, Simulation};
use crate::diagnose::id::EffectId;
use crate::diagnose::residual;
use crate::report::plot::{Axes, PlotError, Series, line_plot};

/// What an evidence figure is drawn from: the record, the declared model and the first effect found.
pub struct Figure<'a> {
    /// Where the PNG goes.
    pub path: &'a Path,
    /// The test that pointed to the effect.
    pub test: &'a str,
    /// Samples of the record and of its fit part.
    pub n: usize,
    pub n_fit: usize,
    /// Time, input and output of the record.
    pub t: &'a [f64],
    pub u: &'a [f64],
    pub y: &'a [f64],
    /// The CSV's names of the time, input and output columns (the axes).
    pub columns: [&'a str; 3],
    /// The declared model's simulation and its residual over the record.
    pub declared: &'a Simulation,
    pub e0: &'a [f64],
    /// The final model's residual over the record.
    pub e1: &'a [f64],
    /// The final model's name in legends.
    pub after_label: &'a str,
    /// The effect's fitted model and its output over the record.
    pub model: &'a EffectModel,
    pub output: &'a [f64],
    /// Lags of the correlation figures (as the residual tests use them).
    pub lags: usize,
}

/// Pairs `(x[i], y[i])`.
pub fn pts(x: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    x.iter().zip(y).map(|(a, b)| (*a, *b)).collect()
}

/// A number as the report writes it.
pub fn fmt(v: f64) -> String {
    crate::report::number(v)
}

/// The measured output, the declared model's and (with `after`) the extended model's against the input on
/// the held-out part, titled `title`.
pub fn output_against_input(fig: &Figure, title: &str, after: bool) -> Result<(), PlotError> {
    let (nf, n) = (fig.n_fit, fig.n);
    let u = &fig.u[nf..n];
    let mut series = vec![
        Series::points("measured", pts(u, &fig.y[nf..n])).color(7),
        Series::points("declared model", pts(u, &fig.declared.y[nf..n])).color(3),
    ];
    if after {
        series.push(Series::points(fig.after_label, pts(u, &fig.output[nf..n])).color(0));
    }
    line_plot(
        fig.path,
        title,
        fig.columns[1],
        fig.columns[2],
        &series,
        Axes::LINEAR,
    )
}

/// [`output_against_input`] titled as the evidence for `effect`.
pub fn effect_against_input(fig: &Figure, effect: &str) -> Result<(), PlotError> {
    output_against_input(
        fig,
        &format!("Evidence for {effect}: output against input (held-out part)"),
        true,
    )
}

/// A stretch of the record over time, samples `k0..k1`: measured (as points or as a line), the declared
/// model and the extended one.
pub fn over_time(
    fig: &Figure,
    title: &str,
    (k0, k1): (usize, usize),
    measured_as_points: bool,
) -> Result<(), PlotError> {
    let t = &fig.t[k0..k1];
    let measured = pts(t, &fig.y[k0..k1]);
    let measured = if measured_as_points {
        Series::points("measured", measured)
    } else {
        Series::line("measured", measured)
    };
    line_plot(
        fig.path,
        title,
        fig.columns[0],
        fig.columns[2],
        &[
            measured.color(7),
            Series::line("declared model", pts(t, &fig.declared.y[k0..k1])).color(3),
            Series::line(fig.after_label, pts(t, &fig.output[k0..k1])).color(0),
        ],
        Axes::LINEAR,
    )
}

/// The evidence when the fitted model lacks the effect's own extension (it never does for a chosen effect):
/// output against input.
pub fn generic(fig: &Figure, id: EffectId) -> Result<String, PlotError> {
    effect_against_input(fig, id.as_str())?;
    Ok(format!(
        "Pointing test: {}. Output against input for {id}.",
        fig.test
    ))
}

/// The declared and the final model's residual against past inputs on the fit part, with the 95% band;
/// returns the caption (the evidence of a missing term or delay in the linear block).
pub fn input_correlation(fig: &Figure) -> Result<String, PlotError> {
    let (nf, lags) = (fig.n_fit, fig.lags);
    let band = residual::white_band(nf);
    let lag0: Vec<f64> = (0..=lags).map(|l| l as f64).collect();
    let cc0 = residual::cross_correlation(&fig.e0[..nf], &fig.u[..nf], lags);
    let cc1 = residual::cross_correlation(&fig.e1[..nf], &fig.u[..nf], lags);
    line_plot(
        fig.path,
        "Evidence: correlation of the residual with past inputs (fit part)",
        "lag",
        "r_eu",
        &[
            Series::points("declared model", pts(&lag0, &cc0.r)).color(3),
            Series::points(fig.after_label, pts(&lag0, &cc1.r)).color(0),
            Series::dashed("95% band", vec![(0.0, band), (lags as f64, band)]).color(7),
            Series::dashed("", vec![(0.0, -band), (lags as f64, -band)]).color(7),
        ],
        Axes::LINEAR,
    )?;
    Ok(format!(
        "Pointing test: {}. The declared model's residual still depends on past inputs (red points outside \
         the band): the linear block misses a term or a delay; the chosen structure leaves none (blue).",
        fig.test
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The figures' curves pair each x with its y, in order, one point per sample (a curve of one point
    /// would draw nothing the reader can check).
    #[test]
    fn points_pair_every_sample_in_order() {
        let got = pts(&[0.5, 1.5, 2.5], &[-1.0, 4.0, 9.0]);
        assert_eq!(got, vec![(0.5, -1.0), (1.5, 4.0), (2.5, 9.0)]);
    }
}
