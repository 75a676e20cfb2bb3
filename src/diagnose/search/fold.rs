//! What a record whose play estimate cannot be looks like instead, when it is a fold: the output turns back
//! where the linear block's output x passes some level, as a sensor that reads |x| (a speed sensor that
//! reads the speed's magnitude) does. The rising and falling branches of a play run parallel; a fold's meet
//! at the turn, and no gap or slope of a play model fits that: a play fitted to it comes out negative, wider
//! than the travel, or between borders no mechanism has.
//!
//! The test, on the fit part: the output against x by least squares as `a + b x + c |x - x0|` (x0 on a grid of
//! x's quantiles, the best kept, then refined) against the straight line `a + b x`. A fold is there when the
//! turn leaves at most [`FOLD_SHARE`] of the line's residual and the slopes on its two sides, `b - c` below x0
//! and `b + c` above, have opposite signs, the smaller at least [`TURN_SHARE`] of the larger (a dead zone or
//! a clipped side is flat there, not turned back). Every border of a play rises with x: an output that falls
//! on one side of a level and rises on the other is no play, whatever curve it follows.

use nalgebra::{SMatrix, SVector};

use crate::report::number as g;
use crate::stats::{mean, quantile, std_dev};

/// The most of a straight line's residual sum of squares a fold may leave to be named.
pub const FOLD_SHARE: f64 = 0.5;
/// The least share of the steeper side's slope the other side's, turned back, must reach.
pub const TURN_SHARE: f64 = 0.2;
/// The quantiles of x the turn is sought at: 10% to 90% in steps of 5%.
const TURNS: usize = 17;
/// The steps between the best turn's neighbours on that grid at which the turn is refined.
const REFINE: usize = 20;

/// A fold of the output against the linear block's output.
#[derive(Debug, Clone, PartialEq)]
pub struct Fold {
    /// Where it turns, in the linear block's units.
    pub at: f64,
    /// The output's slope against x below and above the turn.
    pub slopes: [f64; 2],
    /// Its residual sum of squares as a share of the straight line's.
    pub share: f64,
}

impl Fold {
    /// The fold in `y` against `x` (the same samples), if there is one; `None` for fewer than 20 samples or
    /// an x or y that does not move.
    pub fn of(x: &[f64], y: &[f64]) -> Option<Fold> {
        let n = x.len().min(y.len());
        let (x, y) = (&x[..n], &y[..n]);
        let (sx, sy) = (std_dev(x), std_dev(y));
        if n < 20 || sx <= 0.0 || sy <= 0.0 {
            return None;
        }
        let (mx, my) = (mean(x), mean(y));
        let xs: Vec<f64> = x.iter().map(|v| (v - mx) / sx).collect();
        let ys: Vec<f64> = y.iter().map(|v| (v - my) / sy).collect();
        let line = least_squares(&xs, &ys, |v| [1.0, v])?.1;
        let turn = |x0: f64| Some((x0, least_squares(&xs, &ys, |v| [1.0, v, (v - x0).abs()])?));
        let best = |c: &mut dyn Iterator<Item = f64>| {
            c.filter_map(turn)
                .min_by(|a: &(f64, _), b: &(f64, _)| a.1.1.total_cmp(&b.1.1))
        };
        let grid: Vec<f64> = (0..TURNS)
            .filter_map(|i| quantile(&xs, 0.1 + 0.05 * i as f64))
            .collect();
        let (coarse, _) = best(&mut grid.iter().copied())?;
        // Refined between the grid's neighbours of the best turn.
        let i = grid.iter().position(|&v| v == coarse).unwrap_or(0);
        let (lo, hi) = (grid[i.saturating_sub(1)], grid[(i + 1).min(grid.len() - 1)]);
        let (x0, (th, rss)) =
            best(&mut (0..=REFINE).map(|k| lo + (hi - lo) * k as f64 / REFINE as f64))?;
        let scale = sy / sx;
        let slopes = [(th[1] - th[2]) * scale, (th[1] + th[2]) * scale];
        let turned = slopes[0] * slopes[1] < 0.0
            && slopes[0].abs().min(slopes[1].abs())
                >= TURN_SHARE * slopes[0].abs().max(slopes[1].abs());
        let share = if line > 0.0 { rss / line } else { 1.0 };
        (turned && share <= FOLD_SHARE).then_some(Fold {
            at: mx + x0 * sx,
            slopes,
            share,
        })
    }

    /// The fold in words, for the verdict's reasons.
    pub fn said(&self) -> String {
        format!(
            "the record looks like a fold instead: the output turns back where the linear block's output \
             passes {} (slope {} below, {} above), as a sensor that reads |x| does, and that turn leaves {:.0}% \
             of the residual a straight line leaves on the fit part; a play's borders rise with x and its \
             branches run parallel, a fold's meet at the turn, and no play model fits that",
            g(self.at),
            g(self.slopes[0]),
            g(self.slopes[1]),
            100.0 * self.share
        )
    }
}

/// Least squares of `y` on the regressors `row(x)`: the coefficients and the residual sum of squares; `None`
/// where the normal equations are singular.
fn least_squares<const P: usize>(
    x: &[f64],
    y: &[f64],
    row: impl Fn(f64) -> [f64; P],
) -> Option<(SVector<f64, P>, f64)> {
    let mut h = SMatrix::<f64, P, P>::zeros();
    let mut g = SVector::<f64, P>::zeros();
    for (&v, &t) in x.iter().zip(y) {
        let r = SVector::<f64, P>::from(row(v));
        h += r * r.transpose();
        g += r * t;
    }
    let th = h.cholesky()?.solve(&g);
    let rss = x
        .iter()
        .zip(y)
        .map(|(&v, &t)| {
            let r = SVector::<f64, P>::from(row(v));
            (t - r.dot(&th)).powi(2)
        })
        .sum();
    Some((th, rss))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| (k as f64 * 0.37).sin() * 2.0 + 0.5)
            .collect()
    }

    /// |x - 0.3| with a little noise is a fold at 0.3 with slopes -1 and 1; a rising curve, a dead zone and
    /// a line are not.
    #[test]
    fn a_fold_is_found_where_the_output_turns_back_and_nowhere_else() {
        let x = ramp(2000);
        let noise = |k: usize| 0.01 * ((k * 7919 % 101) as f64 / 50.0 - 1.0);
        let folded: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, v)| (v - 0.3).abs() + noise(k))
            .collect();
        let f = Fold::of(&x, &folded).expect("a fold");
        assert!((f.at - 0.3).abs() < 0.05, "{f:?}");
        assert!(
            (f.slopes[0] + 1.0).abs() < 0.05 && (f.slopes[1] - 1.0).abs() < 0.05,
            "{f:?}"
        );
        assert!(f.share < 0.2, "{f:?}");
        assert!(f.said().contains("turns back"), "{}", f.said());
        let smooth: Vec<f64> = x.iter().map(|v| v.tanh() + 0.1 * v * v * v).collect();
        assert_eq!(Fold::of(&x, &smooth), None);
        let dead: Vec<f64> = x
            .iter()
            .map(|v| (v - 0.5).max(0.0) + (v + 0.5).min(0.0))
            .collect();
        assert_eq!(Fold::of(&x, &dead), None);
        let line: Vec<f64> = x.iter().map(|v| 2.0 * v + 1.0).collect();
        assert_eq!(Fold::of(&x, &line), None);
        assert_eq!(Fold::of(&x[..10], &folded[..10]), None);
        assert_eq!(Fold::of(&x, &vec![1.0; x.len()]), None);
    }
}
