//! The evidence figure an effect draws for the report: what it is drawn from ([`Figure`]) and the drawing
//! helpers the effects share.

use std::path::Path;

use crate::diagnose::fit::model::{EffectModel, Simulation};
use crate::diagnose::id::EffectId;
use crate::diagnose::residual;
use crate::report::plot::{Axes, PlotError, Series, line_plot};
use crate::stats::{mean, quantile};

/// What an evidence figure is drawn from: the record, the plain model and the first effect found.
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
    /// The plain model's simulation (before any effect; of the declared or the chosen structure), its name
    /// in legends and its residual over the record.
    pub declared: &'a Simulation,
    pub plain_label: &'a str,
    pub e0: &'a [f64],
    /// The effect's model's residual y - simulation over the record.
    pub e1: &'a [f64],
    /// With a noise model: its residual y - one-step prediction over the record.
    pub e1_pred: Option<&'a [f64]>,
    /// The effect's model's name in legends.
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

/// The measured output, the plain model's and (with `after`) the extended model's against the input on the
/// held-out part, titled `title`; the measured points drawn last (on top).
pub fn output_against_input(fig: &Figure, title: &str, after: bool) -> Result<(), PlotError> {
    let (nf, n) = (fig.n_fit, fig.n);
    let u = &fig.u[nf..n];
    let mut series = vec![Series::points(fig.plain_label, pts(u, &fig.declared.y[nf..n])).color(3)];
    if after {
        series.push(Series::points(fig.after_label, pts(u, &fig.output[nf..n])).color(0));
    }
    series.push(Series::points("measured", pts(u, &fig.y[nf..n])).color(7));
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

/// A stretch of the record over time, samples `k0..k1`: the plain model and the extended one (dashed), and
/// on top the measured output (as points or as a line).
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
            Series::dashed(fig.plain_label, pts(t, &fig.declared.y[k0..k1])).color(3),
            Series::dashed(fig.after_label, pts(t, &fig.output[k0..k1])).color(0),
            measured.color(7),
        ],
        Axes::LINEAR,
    )
}

/// The first `len` samples of the held-out part, fewer where the record ends: a stretch short enough for
/// single moves to show in [`over_time`].
pub fn held_out_stretch(fig: &Figure, len: usize) -> (usize, usize) {
    (fig.n_fit, fig.n.min(fig.n_fit + len))
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

/// The plain and the effect's model's residual against past inputs on the fit part, with the 95% band;
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
            Series::points(fig.plain_label, pts(&lag0, &cc0.r)).color(3),
            Series::points(fig.after_label, pts(&lag0, &cc1.r)).color(0),
            Series::dashed("95% band", vec![(0.0, band), (lags as f64, band)]).color(7),
            Series::dashed("", vec![(0.0, -band), (lags as f64, -band)]).color(7),
        ],
        Axes::LINEAR,
    )?;
    Ok(format!(
        "Pointing test: {}. The {}'s residual depends on past inputs where its red points leave the band \
         ({} of {} lags outside): the linear block misses a term or a delay; {} of {} lags outside with the \
         extension (blue).",
        fig.test,
        fig.plain_label,
        outside(&cc0.r, band),
        cc0.r.len(),
        outside(&cc1.r, band),
        cc1.r.len()
    ))
}

/// The share of the held-out samples at each end of the measured output that [`at_extremes`] averages over.
pub const EXTREME_SHARE: f64 = 0.02;

/// Where the measured output (held-out part) is at its extremes (at or above its 98% quantile, at or below
/// its 2%), the mean of `model - y` there: (top, bottom). Positive at the top / negative at the bottom: the
/// model goes beyond the measured extreme.
pub fn at_extremes(fig: &Figure, model: &[f64]) -> (f64, f64) {
    let (nf, n) = (fig.n_fit, fig.n);
    let y = &fig.y[nf..n];
    let (Some(hi), Some(lo)) = (quantile(y, 1.0 - EXTREME_SHARE), quantile(y, EXTREME_SHARE))
    else {
        return (0.0, 0.0);
    };
    let diff = |keep: &dyn Fn(f64) -> bool| {
        let d: Vec<f64> = y
            .iter()
            .zip(&model[nf..n])
            .filter(|(v, _)| keep(**v))
            .map(|(v, m)| m - v)
            .collect();
        mean(&d)
    };
    (diff(&|v| v >= hi), diff(&|v| v <= lo))
}

/// In words, what `at_extremes` found for a model: "goes above it by 0.12 at the top and stays above it by
/// 0.05 at the bottom".
pub fn extremes_in_words((top, bottom): (f64, f64)) -> String {
    let side = |v: f64, beyond: &str, short: &str| {
        if v == 0.0 {
            "meets it".to_string()
        } else {
            format!(
                "{} it by {}",
                if v > 0.0 { beyond } else { short },
                fmt(v.abs())
            )
        }
    };
    format!(
        "{} at the top and {} at the bottom",
        side(top, "goes above", "stays below"),
        side(-bottom, "goes below", "stays above")
    )
}

/// The caption of an output-against-input evidence figure: how the plain and the effect's model meet the
/// measured extremes, computed from the plotted values.
pub fn extremes_caption(fig: &Figure) -> String {
    format!(
        "Where the measured output is at its extremes (its top and bottom {:.0}% in the held-out part), the {} \
         {} on average, and {} {}.",
        100.0 * EXTREME_SHARE,
        fig.plain_label,
        extremes_in_words(at_extremes(fig, &fig.declared.y)),
        fig.after_label,
        extremes_in_words(at_extremes(fig, fig.output))
    )
}

/// How many of the correlations `r` lie outside the band `+-band`.
pub fn outside(r: &[f64], band: f64) -> usize {
    r.iter().filter(|v| v.abs() > band).count()
}

/// A record for the effects' evidence tests: the paper's plain model and a model with one effect, both
/// driven by the same input, the record being the latter's output.
#[cfg(test)]
pub(crate) struct TestRecord {
    pub t: Vec<f64>,
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    pub declared: Simulation,
    /// The plain model's residual over the record, and the effect's model's (zero: it is the record).
    pub e0: Vec<f64>,
    pub e1: Vec<f64>,
}

#[cfg(test)]
impl TestRecord {
    /// `n` samples of the test input through the paper's plain model and through `with` (the record).
    pub fn of(with: &EffectModel, n: usize) -> Self {
        use crate::diagnose::fit::model::Rest;
        use crate::diagnose::fit::model::tests::{input, paper_base};
        let u = input(n);
        let declared = EffectModel::plain(paper_base())
            .simulate(&u, Rest::ZERO, n, 1e9)
            .expect("the plain model runs");
        let y = with
            .simulate(&u, Rest::ZERO, n, 1e9)
            .expect("the model with the effect runs")
            .y;
        let e0 = y.iter().zip(&declared.y).map(|(a, b)| a - b).collect();
        Self {
            t: (0..n).map(|k| k as f64).collect(),
            u,
            declared,
            e0,
            e1: vec![0.0; n],
            y,
        }
    }

    /// The figure of this record with its first `n_fit` samples the fit part, drawn to `path` for the test
    /// `test`, the effect's model `model` (named `after_label`) followed by the record itself.
    pub fn figure<'a>(
        &'a self,
        path: &'a Path,
        test: &'a str,
        n_fit: usize,
        after_label: &'a str,
        model: &'a EffectModel,
    ) -> Figure<'a> {
        Figure {
            path,
            test,
            n: self.y.len(),
            n_fit,
            t: &self.t,
            u: &self.u,
            y: &self.y,
            columns: ["t", "u", "y"],
            declared: &self.declared,
            plain_label: "plain",
            e0: &self.e0,
            e1: &self.e1,
            e1_pred: None,
            after_label,
            model,
            output: &self.y,
            lags: 10,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::model::tests::paper_base;

    /// `f` on the figure of the record `y` whose first `n_fit` samples are the fit part, with the model
    /// output `output` (the other curves are the record's own).
    fn on_figure<R>(y: &[f64], n_fit: usize, output: &[f64], f: impl FnOnce(&Figure) -> R) -> R {
        let t: Vec<f64> = (0..y.len()).map(|k| k as f64).collect();
        let (declared, model) = (Simulation::default(), EffectModel::plain(paper_base()));
        f(&Figure {
            path: Path::new("unused.png"),
            test: "test",
            n: y.len(),
            n_fit,
            t: &t,
            u: &t,
            y,
            columns: ["t", "u", "y"],
            declared: &declared,
            plain_label: "plain",
            e0: y,
            e1: y,
            e1_pred: None,
            after_label: "after",
            model: &model,
            output,
            lags: 5,
        })
    }

    /// The held-out output -50..49 has its top 2% at 47, 48, 49 and its bottom at -50, -49, -48 (the
    /// quantiles' nearest ranks 97 and 2 of 0..99); a model 10% beyond the measurement is 4.8 above at
    /// the top and 4.9 below at the bottom. The fit part (20 samples at 100, the model at 1000) is not
    /// looked at; no held-out part, nothing found.
    #[test]
    fn extremes_by_hand() {
        let mut y = vec![100.0; 20];
        y.extend((0..100).map(|k| f64::from(k) - 50.0));
        let mut model = vec![1000.0; 20];
        model.extend(y[20..].iter().map(|v| 1.1 * v));
        let (top, bottom) = on_figure(&y, 20, &model, |fig| at_extremes(fig, &model));
        assert!((top - 4.8).abs() < 1e-12, "{top}");
        assert!((bottom + 4.9).abs() < 1e-12, "{bottom}");
        let all_fit = on_figure(&y, 120, &model, |fig| at_extremes(fig, &model));
        assert_eq!(all_fit, (0.0, 0.0));
    }

    /// A stretch starts at the held-out part and ends after `len` samples or at the record's end.
    #[test]
    fn stretches_start_at_the_held_out_part() {
        let y = vec![0.0; 120];
        on_figure(&y, 20, &y, |fig| {
            assert_eq!(held_out_stretch(fig, 50), (20, 70));
            assert_eq!(held_out_stretch(fig, 400), (20, 120));
        });
    }

    /// The figures' curves pair each x with its y, in order, one point per sample (a curve of one point
    /// would draw nothing the reader can check).
    #[test]
    fn points_pair_every_sample_in_order() {
        let got = pts(&[0.5, 1.5, 2.5], &[-1.0, 4.0, 9.0]);
        assert_eq!(got, vec![(0.5, -1.0), (1.5, 4.0), (2.5, 9.0)]);
    }

    /// The words follow the numbers' signs: a model above the measured top goes above it, one below the
    /// measured bottom goes below it, and the reverse stays short.
    #[test]
    fn extremes_in_words_follow_the_signs() {
        assert_eq!(
            extremes_in_words((1.9, 0.5)),
            "goes above it by 1.9000 at the top and stays above it by 0.5000 at the bottom"
        );
        assert_eq!(
            extremes_in_words((-1.9, -0.5)),
            "stays below it by 1.9000 at the top and goes below it by 0.5000 at the bottom"
        );
        assert_eq!(
            extremes_in_words((0.0, 0.0)),
            "meets it at the top and meets it at the bottom"
        );
    }
}
