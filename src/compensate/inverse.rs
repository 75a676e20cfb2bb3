//! The backlash inverse with the backlash's direction memory, and its answer to degenerate estimates.
//!
//! For a wanted backlash output `r(k)` and the backlash output `w(k-1)` the inverse delivered last:
//!
//! ```text
//! v(k) = r/m1 + c1                          if r > w(k-1)   (drive the upper border)
//! v(k) = r/m2 - c2                          if r < w(k-1)   (drive the lower border)
//! v(k) = v(k-1), kept inside the zone       otherwise       (hold: the output stays w(k-1))
//! ```
//!
//! so that `backlash(v(k), w(k-1)) = r(k)` (the operator of [`crate::plant::BacklashParams::step`]); the step
//! that commits sample k sets `w(k) = backlash(v(k), w(k-1))`.
//!
//! **Smoothing.** A reversal of the exact inverse moves `v` across the whole gap (c1 + c2 at slope 1); on a
//! noisy reference every sign change of the noise is a reversal, so `v` chatters by the gap every sample.
//! With a smoothing width `s > 0` (in units of r) the inverse aims at the reference through a play of
//! half-width s: the target is `w(k-1)` clamped to `[r - s, r + s]`, so the output holds while r stays
//! within s of it and follows r at distance s once it leaves (an error of at most s); a reversal needs a
//! swing of r of more than 2 s. `s = 0` is the exact inverse. Noise on r of standard deviation sigma needs
//! s of about 4 sigma (measured by [`chattering`] in the tests).
//!
//! **Degenerate estimates** (an estimator's outputs early in a run, or a misconnected input) are answered
//! with a documented value, never NaN, and a [`Degenerate`] saying what was wrong:
//! - a non-finite or non-positive slope m1 or m2, or a non-finite gap: the inverse keeps the last valid
//!   parameters (at first m1 = m2 = 1, c1 = c2 = 0: v = r);
//! - a negative gap: that gap is taken as 0;
//! - borders that cross (possible when m1 != m2: the lower border's input for r lies above the input from
//!   which the upper border drives, so no input gives r): v is the input at that crossing whose output is
//!   nearest r;
//! - a non-finite r, or a v that would overflow: v holds its last value.

use crate::plant::BacklashParams;
use serde::{Deserialize, Serialize};

/// What was degenerate about a sample's inputs, and what the inverse did instead.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum Degenerate {
    #[error("the reference r = {0} is not finite: v holds its last value")]
    Reference(f64),
    #[error("v for the reference r = {0} overflows (a slope near 0?): v holds its last value")]
    Overflow(f64),
    #[error(
        "slope {name} = {value} is not a positive number: the last valid estimate (m1 {m1}, m2 {m2}, c1 {c1}, \
         c2 {c2}) is used"
    )]
    Slope {
        name: &'static str,
        value: f64,
        m1: f64,
        m2: f64,
        c1: f64,
        c2: f64,
    },
    #[error("gap {name} = {value} is not finite: the last valid estimate is used")]
    GapNotFinite { name: &'static str, value: f64 },
    #[error("gap {name} = {value} is negative: it is taken as 0")]
    NegativeGap { name: &'static str, value: f64 },
    #[error(
        "the borders cross: no input gives r = {r} from the last output (the upper border drives from input \
         {upper}, above the lower border's input): v is the input whose output is nearest"
    )]
    CrossedBorders { r: f64, upper: f64 },
}

/// The direction the inverse last drove the backlash in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Direction {
    None,
    Up,
    Down,
}

/// One sample's answer: the backlash input `v`, the backlash output it gives under the parameters used,
/// the direction, and what was degenerate (the first problem found), if anything.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answer {
    pub v: f64,
    pub w: f64,
    pub direction: Direction,
    pub degenerate: Option<Degenerate>,
}

/// The smoothing width in words: it must be finite and not negative.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("smoothing width {0} is invalid: must be a finite number of 0 or more (0 = exact inverse)")]
pub struct SmoothingError(pub f64);

/// Relative size of a change of the reference the inverse takes for rounding (held, not followed).
const ROUNDING: f64 = 1e-12;

/// The identity backlash (no play): the parameters used before any valid estimate.
const IDENTITY: BacklashParams = BacklashParams {
    m1: 1.0,
    m2: 1.0,
    c1: 0.0,
    c2: 0.0,
};

/// The inverse's state: the last committed sample's input and output, the direction, and the last valid
/// parameters (the fallback for degenerate estimates).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BacklashInverse {
    smoothing: f64,
    v: f64,
    w: f64,
    direction: Direction,
    valid: BacklashParams,
}

impl BacklashInverse {
    /// An inverse at rest (v = w = 0) with smoothing width `smoothing` (0 = exact).
    pub fn new(smoothing: f64) -> Result<Self, SmoothingError> {
        if !smoothing.is_finite() || smoothing < 0.0 {
            return Err(SmoothingError(smoothing));
        }
        Ok(Self {
            smoothing,
            ..Self::exact()
        })
    }

    /// The exact inverse (smoothing 0) at rest.
    pub fn exact() -> Self {
        Self {
            smoothing: 0.0,
            v: 0.0,
            w: 0.0,
            direction: Direction::None,
            valid: IDENTITY,
        }
    }

    pub fn smoothing(&self) -> f64 {
        self.smoothing
    }

    /// The backlash output after the last committed sample.
    pub fn output(&self) -> f64 {
        self.w
    }

    /// v(k) for reference `r` and estimate `p`, without committing the sample.
    pub fn evaluate(&self, r: f64, p: &BacklashParams) -> Answer {
        let (q, mut degenerate) = self.usable(p);
        if !r.is_finite() {
            return Answer {
                v: self.v,
                w: self.w,
                direction: self.direction,
                degenerate: Some(Degenerate::Reference(r)),
            };
        }
        let (v, direction, crossed) = self.choose(r, &q);
        if crossed {
            let upper = self.w / q.m1 + q.c1;
            degenerate = degenerate.or(Some(Degenerate::CrossedBorders { r, upper }));
        }
        self.finite(r, v, q.step(v, self.w).0, direction, degenerate)
    }

    /// The answer, or the held last value when the numbers overflowed (an absurd r or a tiny slope).
    fn finite(
        &self,
        r: f64,
        v: f64,
        w: f64,
        direction: Direction,
        degenerate: Option<Degenerate>,
    ) -> Answer {
        if v.is_finite() && w.is_finite() {
            return Answer {
                v,
                w,
                direction,
                degenerate,
            };
        }
        Answer {
            v: self.v,
            w: self.w,
            direction: self.direction,
            degenerate: Some(Degenerate::Overflow(r)),
        }
    }

    /// Which border to drive (or hold): the target is the reference through a play of half-width s
    /// (`w(k-1)` clamped to `[r - s, r + s]`), so the output moves only when r leaves that band. The flag
    /// says the borders cross there (no input gives the target).
    fn choose(&self, r: f64, q: &BacklashParams) -> (f64, Direction, bool) {
        let target = self.w.clamp(r - self.smoothing, r + self.smoothing);
        // Above `hi` the backlash drives the upper border, below `lo` the lower one.
        let (lo, hi) = (self.w / q.m2 - q.c2, self.w / q.m1 + q.c1);
        // A move below ROUNDING (relative) is the rounding of the last border's output, not a reversal: on
        // a held reference it would send v across the gap.
        let tiny = ROUNDING * (1.0 + self.w.abs());
        if target > self.w + tiny {
            (target / q.m1 + q.c1, Direction::Up, false)
        } else if target < self.w - tiny {
            let v = target / q.m2 - q.c2;
            if v > hi {
                (
                    self.nearest_at_crossing(target, q, hi),
                    Direction::Down,
                    true,
                )
            } else {
                (v, Direction::Down, false)
            }
        } else if lo <= hi {
            // Hold w(k-1): v(k-1) moved into the zone of w(k-1) under the current parameters; a v(k-1) on
            // a border up to the rounding of that border (w(k-1) computed from it) stays as it was, so
            // that a held reference and estimate answer the same v bit for bit.
            let slack = ROUNDING * (1.0 + self.v.abs());
            let inside = (lo - slack..=hi + slack).contains(&self.v);
            let v = if inside { self.v } else { self.v.clamp(lo, hi) };
            (v, self.direction, false)
        } else {
            (
                self.nearest_at_crossing(target, q, hi),
                self.direction,
                true,
            )
        }
    }

    /// Where the borders cross no input gives the target: of the inputs just at and just above `hi` (the
    /// lower border below it, the upper above), the one whose output is nearer the target.
    fn nearest_at_crossing(&self, target: f64, q: &BacklashParams, hi: f64) -> f64 {
        let above = hi.next_up();
        let (at, up) = (q.step(hi, self.w).0, q.step(above, self.w).0);
        if (at - target).abs() <= (up - target).abs() {
            hi
        } else {
            above
        }
    }

    /// v(k) as [`evaluate`](Self::evaluate), and the sample committed: w(k), the direction and the last
    /// valid parameters become those of this answer.
    pub fn commit(&mut self, r: f64, p: &BacklashParams) -> Answer {
        let a = self.evaluate(r, p);
        let (q, _) = self.usable(p);
        self.valid = q;
        self.v = a.v;
        self.w = a.w;
        self.direction = a.direction;
        a
    }

    /// The parameters the inverse works with for estimate `p` (module docs), and the first problem found.
    fn usable(&self, p: &BacklashParams) -> (BacklashParams, Option<Degenerate>) {
        let l = self.valid;
        for (name, value) in [("m1", p.m1), ("m2", p.m2)] {
            if !(value.is_finite() && value > 0.0) {
                let d = Degenerate::Slope {
                    name,
                    value,
                    m1: l.m1,
                    m2: l.m2,
                    c1: l.c1,
                    c2: l.c2,
                };
                return (l, Some(d));
            }
        }
        for (name, value) in [("c1", p.c1), ("c2", p.c2)] {
            if !value.is_finite() {
                return (l, Some(Degenerate::GapNotFinite { name, value }));
            }
        }
        let degenerate = [("c1", p.c1), ("c2", p.c2)]
            .into_iter()
            .find(|&(_, value)| value < 0.0)
            .map(|(name, value)| Degenerate::NegativeGap { name, value });
        let q = BacklashParams {
            c1: p.c1.max(0.0),
            c2: p.c2.max(0.0),
            ..*p
        };
        (q, degenerate)
    }

    /// A state from outside (an FMU state) is consistent: finite numbers, a valid smoothing width and valid
    /// fallback parameters.
    pub fn check(&self) -> Result<(), String> {
        let l = &self.valid;
        let finite = [self.v, self.w, l.m1, l.m2, l.c1, l.c2]
            .iter()
            .all(|x| x.is_finite());
        if !finite || l.m1 <= 0.0 || l.m2 <= 0.0 || l.c1 < 0.0 || l.c2 < 0.0 {
            return Err("the compensator's state holds invalid numbers".into());
        }
        Self::new(self.smoothing)
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

/// Chattering of a sequence of backlash inputs: the fraction of samples at which `v` moves by more than
/// half the gap `gap` (a reversal through the memory zone).
pub fn chattering(v: &[f64], gap: f64) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let jumps = v
        .windows(2)
        .filter(|p| (p[1] - p[0]).abs() > 0.5 * gap)
        .count();
    jumps as f64 / (v.len() - 1) as f64
}

#[cfg(test)]
#[path = "inverse_tests.rs"]
mod tests;
