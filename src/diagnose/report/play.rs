//! The figure that shows the play: the measured output against the final model's linear-block output, with
//! the fitted borders, the band between them and the reversals that cross it.

use crate::diagnose::report::figures::{FigurePanel, ReportFigure};
use crate::diagnose::report::input::ReportInput;
use crate::diagnose::search::engine::Diagnosis;
use crate::diagnose::search::presence::reversal_turns;
use crate::report::plot::Series;

/// Points of the borders drawn across the travel.
const BORDER_POINTS: usize = 120;
/// At most this many measured samples are drawn (every k-th beyond): the cloud's shape, not its ink.
const MAX_DRAWN: usize = 20_000;

/// The play figure: y against x_hat (the final model's linear-block output about the operating point) on
/// the fit part, the upper and lower borders of the final model's backlash (straight or curved) in the
/// record's output units, and the samples where x_hat reverses after crossing the play.
pub fn play_figure(d: &Diagnosis, input: &ReportInput) -> ReportFigure {
    let sim = d.steps().last().map_or(&d.base_sim, |c| &c.sim);
    let m = d.final_model();
    let (nf, y0) = (d.n_fit.min(sim.x.len()), d.operating_point.y);
    let x = &sim.x[..nf];
    let step = nf.div_ceil(MAX_DRAWN).max(1);
    let cloud: Vec<(f64, f64)> = (0..nf).step_by(step).map(|k| (x[k], input.y[k])).collect();
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let bl = m.base.backlash();
    let curve = m.effects().curved_borders;
    let border = |upper: bool| -> Vec<(f64, f64)> {
        (0..=BORDER_POINTS)
            .map(|i| lo + (hi - lo) * i as f64 / BORDER_POINTS as f64)
            .map(|v| {
                let w = match (&curve, upper) {
                    (Some(c), true) => c.upper(&bl, v),
                    (Some(c), false) => c.lower(&bl, v),
                    (None, true) => bl.upper(v),
                    (None, false) => bl.lower(v),
                };
                (v, w + y0)
            })
            .collect()
    };
    let marks = reversal_points(x, &input.y[..nf], d.backlash.play.abs());
    let play = &d.backlash;
    let caption = format!(
        "The play as the record shows it: the measured output ({}) against the final model's linear-block \
         output x_hat (fit part, about the operating point u = {:.4e}), with the fitted backlash borders \
         (dashed; the band between them is where the output holds after a reversal) and the {} reversals of \
         x_hat that cross the play (circles). {}. Effects after the backlash (friction, clipping) move the \
         output off the borders.",
        input.columns[2],
        d.operating_point.u,
        marks.len(),
        play.headline()
    );
    ReportFigure {
        file: "play.png".into(),
        title: "The play: output against the linear block's output".into(),
        panels: vec![FigurePanel {
            title: String::new(),
            x_label: format!(
                "x_hat (the linear block's output, from {})",
                input.columns[1]
            ),
            y_label: input.columns[2].to_string(),
            series: vec![
                Series::points("measured (fit part)", cloud).color(7),
                Series::dashed("upper border", border(true)).color(0),
                Series::dashed("lower border", border(false)).color(3),
                Series::points("reversals crossing the play", marks).color(1),
            ],
        }],
        caption,
    }
}

/// The samples where `x` turns after crossing `h`, with the measured output there.
fn reversal_points(x: &[f64], y: &[f64], h: f64) -> Vec<(f64, f64)> {
    reversal_turns(x, h)
        .into_iter()
        .map(|k| (x[k], y[k]))
        .collect()
}
