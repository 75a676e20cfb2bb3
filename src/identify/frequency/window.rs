//! Where in a record the input is a steady sine: the part paper 003's estimator may use.
//!
//! Test rigs do not switch a sine on at full amplitude: they ramp it in and out, pause between
//! frequencies, and step through several frequencies in one record. The estimator needs the part where
//! the input is `U cos(omega t - phi_u)` with constant `U` and `omega`. It is found from the input alone:
//!
//! 1. **Cycles.** The input's upward zero crossings about the centre of its range, with a hysteresis of
//!    [`HYSTERESIS`] of the half range (noise cannot make a crossing; a pause or the quiet start of a ramp
//!    makes none), cut the record into cycles; the crossing instants are interpolated between samples.
//!    Each cycle has a period and an amplitude (half its peak-to-peak range).
//! 2. **Steps.** Consecutive cycles belong to one step while each cycle's period agrees with the previous
//!    one's within [`PERIOD_AGREEMENT`] and its amplitude within [`AMPLITUDE_AGREEMENT`]. A ramp changes the
//!    amplitude from cycle to cycle and breaks the run; a slow ramp that does not is trimmed off the run's
//!    ends, which keep only cycles within the same tolerances of the run's median period and amplitude.
//!    A step needs [`MIN_STEP_CYCLES`] cycles.
//! 3. **Frequency and amplitude.** Over a step's whole cycles the input is fitted by
//!    `A cos(omega t) + B sin(omega t) + C`; `omega` starts at the crossings' mean rate and is refined by a
//!    golden-section search on the fit's residual inside the main lobe (a quarter of `2 pi / length` either
//!    side), which the crossings' estimate lies well inside.
//!
//! A window starts and ends on upward crossings, so it holds whole cycles; the output's own transient
//! inside it is left to the estimator (which drops periods that differ from the steady state).

use std::f64::consts::TAU;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Hysteresis of the zero-crossing detector, as a fraction of the input's half range.
pub const HYSTERESIS: f64 = 0.05;
/// Relative agreement of the periods of the cycles of one step.
pub const PERIOD_AGREEMENT: f64 = 0.01;
/// Relative agreement of the amplitudes of the cycles of one step.
pub const AMPLITUDE_AGREEMENT: f64 = 0.02;
/// Fewest cycles that make a step (one cycle cannot be told from a ramp's).
pub const MIN_STEP_CYCLES: usize = 2;

/// How a window was chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WindowSource {
    /// Found from the input: whole cycles of constant frequency and amplitude.
    Detected,
    /// Given by the user (`start`, `end`).
    Given,
    /// No steady part was found (or there is no input column): the whole record.
    WholeRecord,
}

/// The part of a record that is used, and the sine the input is there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SineWindow {
    /// Time of the first sample used (s, the record's time column).
    pub start: f64,
    /// Time of the last sample used.
    pub end: f64,
    /// Index of the first sample used (0 = the first data row).
    pub first_sample: usize,
    /// Number of samples used.
    pub samples: usize,
    /// Frequency of the input's sine in the window (rad/s): fitted, or the declared one.
    pub omega: f64,
    /// Amplitude of the input's fitted sine (`None` without an input column).
    pub input_amplitude: Option<f64>,
    /// Constant of the input's fitted sine.
    pub input_offset: Option<f64>,
    /// RMS of the input minus its fitted sine.
    pub input_residual: Option<f64>,
    /// Length of the window in periods of `2 pi / omega`.
    pub periods: f64,
    pub source: WindowSource,
}

impl SineWindow {
    /// The window's sample range in the record.
    pub fn range(&self) -> std::ops::Range<usize> {
        self.first_sample..self.first_sample + self.samples
    }
}

/// One input cycle between two upward crossings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cycle {
    pub start: f64,
    pub end: f64,
    /// Half the peak-to-peak range of the input over the cycle.
    pub amplitude: f64,
}

impl Cycle {
    pub fn period(&self) -> f64 {
        self.end - self.start
    }
}

/// A sine fitted to samples: `u = amplitude cos(omega t - phase) + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineFit {
    pub amplitude: f64,
    pub phase: f64,
    pub offset: f64,
    /// RMS of the samples minus the fit.
    pub residual: f64,
}

/// Least-squares fit of `A cos(omega t) + B sin(omega t) (+ C)` at a known `omega`. A singular normal
/// matrix (fewer than three distinct phases) gives the zero sine with the samples' RMS as residual.
pub fn fit_sine(t: &[f64], u: &[f64], omega: f64, with_offset: bool) -> SineFit {
    let mut m = Matrix3::<f64>::zeros();
    let mut r = Vector3::<f64>::zeros();
    for (&ti, &ui) in t.iter().zip(u) {
        let (s, c) = (omega * ti).sin_cos();
        let v = Vector3::new(c, s, if with_offset { 1.0 } else { 0.0 });
        m += v * v.transpose();
        r += v * ui;
    }
    if !with_offset {
        m[(2, 2)] = 1.0;
    }
    let coef = m
        .cholesky()
        .map(|ch| ch.solve(&r))
        .filter(|c| c.iter().all(|v| v.is_finite()))
        .unwrap_or_else(Vector3::zeros);
    let (a, b, c0) = (coef[0], coef[1], coef[2]);
    let ss: f64 = t
        .iter()
        .zip(u)
        .map(|(&ti, &ui)| {
            let (s, c) = (omega * ti).sin_cos();
            (ui - a * c - b * s - c0).powi(2)
        })
        .sum();
    SineFit {
        amplitude: a.hypot(b),
        phase: b.atan2(a),
        offset: c0,
        residual: (ss / t.len().max(1) as f64).sqrt(),
    }
}

/// The input's cycles: upward crossings of the centre of its range with a hysteresis of [`HYSTERESIS`].
pub fn cycles(t: &[f64], u: &[f64]) -> Vec<Cycle> {
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let centre = 0.5 * (hi + lo);
    let h = HYSTERESIS * 0.5 * (hi - lo);
    // Upward crossings: after the input went below -h, the last zero crossing before it reaches +h.
    let mut crossings = Vec::new();
    let mut armed = false;
    let mut last_negative: Option<usize> = None;
    for (i, &ui) in u.iter().enumerate() {
        let v = ui - centre;
        if v <= -h {
            armed = true;
        }
        if v < 0.0 {
            last_negative = Some(i);
        }
        if armed
            && v >= h
            && let Some(j) = last_negative
            && j + 1 < u.len()
        {
            let (v0, v1) = (u[j] - centre, u[j + 1] - centre);
            let f = if v1 > v0 { -v0 / (v1 - v0) } else { 0.0 };
            crossings.push((t[j] + f * (t[j + 1] - t[j]), j + 1));
            armed = false;
        }
    }
    crossings
        .windows(2)
        .map(|w| {
            let ((start, i0), (end, i1)) = (w[0], w[1]);
            let (l, h) = u[i0..i1]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                    (l.min(v), h.max(v))
                });
            Cycle {
                start,
                end,
                amplitude: 0.5 * (h - l),
            }
        })
        .collect()
}

fn agree(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs())
}

/// The steps of a record: maximal runs of cycles of one frequency and amplitude (module documentation),
/// as `(first cycle, last cycle)` index pairs into `cycles`, inclusive.
pub fn steps(cycles: &[Cycle]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut begin = 0;
    for i in 1..=cycles.len() {
        let breaks = i == cycles.len()
            || !agree(cycles[i].period(), cycles[i - 1].period(), PERIOD_AGREEMENT)
            || !agree(
                cycles[i].amplitude,
                cycles[i - 1].amplitude,
                AMPLITUDE_AGREEMENT,
            );
        if breaks {
            if i > begin {
                runs.push((begin, i - 1));
            }
            begin = i;
        }
    }
    runs.into_iter()
        .filter_map(|(a, b)| trim(cycles, a, b))
        .filter(|(a, b)| b + 1 - a >= MIN_STEP_CYCLES)
        .collect()
}

/// Trim a run's ends to the cycles that agree with its median period and amplitude.
fn trim(cycles: &[Cycle], mut a: usize, mut b: usize) -> Option<(usize, usize)> {
    let run = &cycles[a..=b];
    let median = |v: Vec<f64>| crate::stats::median(&v).expect("a run holds a cycle");
    let period = median(run.iter().map(Cycle::period).collect());
    let amplitude = median(run.iter().map(|c| c.amplitude).collect());
    let fits = |c: &Cycle| {
        agree(c.period(), period, PERIOD_AGREEMENT)
            && agree(c.amplitude, amplitude, AMPLITUDE_AGREEMENT)
    };
    while a <= b && !fits(&cycles[a]) {
        a += 1;
    }
    while b > a && !fits(&cycles[b]) {
        b -= 1;
    }
    (a <= b && fits(&cycles[a])).then_some((a, b))
}

/// Samples `i` with `from <= t[i] < to`.
pub fn sample_range(t: &[f64], from: f64, to: f64) -> std::ops::Range<usize> {
    let first = t.partition_point(|&v| v < from);
    let end = t.partition_point(|&v| v < to);
    first..end.max(first)
}

/// Refine `omega0` by minimising the sine fit's residual over `t` (module documentation, step 3).
pub fn refine_omega(t: &[f64], u: &[f64], omega0: f64) -> f64 {
    let span = t.last().copied().unwrap_or(0.0) - t.first().copied().unwrap_or(0.0);
    if span.is_nan() || span <= 0.0 {
        return omega0;
    }
    let half = 0.25 * TAU / span;
    let cost = |w: f64| fit_sine(t, u, w, true).residual;
    golden_min(cost, (omega0 - half).max(0.5 * omega0), omega0 + half)
}

/// Golden-section minimum of a unimodal function on `[lo, hi]` (bounded: 100 iterations).
fn golden_min(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..100 {
        if hi - lo <= 1e-13 * hi.abs() {
            break;
        }
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = f(x2);
        }
    }
    0.5 * (lo + hi)
}

/// A window over `range` of the record: the input's sine fitted there, at `omega` if given, else at the
/// crossings' rate refined by [`refine_omega`]. `None` when no frequency is given and the input has fewer
/// than two upward crossings there.
pub fn window_over(
    t: &[f64],
    u: &[f64],
    range: std::ops::Range<usize>,
    omega: Option<f64>,
    source: WindowSource,
) -> Option<SineWindow> {
    let (tw, uw) = (&t[range.clone()], &u[range.clone()]);
    let omega = match omega {
        Some(w) => w,
        None => {
            let cyc = cycles(tw, uw);
            let (first, last) = (cyc.first()?, cyc.last()?);
            let w0 = TAU * cyc.len() as f64 / (last.end - first.start);
            refine_omega(tw, uw, w0)
        }
    };
    let fit = fit_sine(tw, uw, omega, true);
    Some(SineWindow {
        start: tw[0],
        end: tw[tw.len() - 1],
        first_sample: range.start,
        samples: range.len(),
        omega,
        input_amplitude: Some(fit.amplitude),
        input_offset: Some(fit.offset),
        input_residual: Some(fit.residual),
        periods: (tw[tw.len() - 1] - tw[0]) * omega / TAU,
        source,
    })
}

/// Every steady step of the record's input, in time order (module documentation).
pub fn detect(t: &[f64], u: &[f64]) -> Vec<SineWindow> {
    let cyc = cycles(t, u);
    steps(&cyc)
        .into_iter()
        .filter_map(|(a, b)| {
            let range = sample_range(t, cyc[a].start, cyc[b].end);
            (range.len() >= 3).then_some(())?;
            window_over(t, u, range, None, WindowSource::Detected)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sine of frequency `w` ramped in over `ramp` s, held, ramped out over `ramp` s, between pauses.
    fn ramped(w: f64, amp: f64, ramp: f64, hold: f64, pause: f64, ts: f64) -> (Vec<f64>, Vec<f64>) {
        let total = 2.0 * pause + 2.0 * ramp + hold;
        let n = (total / ts) as usize;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
        let u = t
            .iter()
            .map(|&tk| {
                let s = tk - pause;
                let env = if s < 0.0 || s > 2.0 * ramp + hold {
                    0.0
                } else if s < ramp {
                    s / ramp
                } else if s > ramp + hold {
                    (2.0 * ramp + hold - s) / ramp
                } else {
                    1.0
                };
                amp * env * (w * s).sin() + 0.1
            })
            .collect();
        (t, u)
    }

    #[test]
    fn a_ramped_sine_gives_one_window_over_its_steady_cycles() {
        let w = TAU * 0.5;
        let (t, u) = ramped(w, 1.0, 4.0, 6.0, 1.0, 1.0 / 256.0);
        let found = detect(&t, &u);
        assert_eq!(found.len(), 1, "{found:?}");
        let win = &found[0];
        // Steady from t = 5 to 11 (3 periods); the window holds whole cycles inside it.
        assert!(win.start >= 5.0 - 1e-9 && win.end <= 11.0 + 1e-9, "{win:?}");
        assert!((win.periods - 3.0).abs() < 0.01, "{win:?}");
        assert!((win.omega / w - 1.0).abs() < 1e-9, "{}", win.omega);
        assert!((win.input_amplitude.unwrap() - 1.0).abs() < 1e-9);
        assert!((win.input_offset.unwrap() - 0.1).abs() < 1e-9);
    }

    #[test]
    fn a_slow_ramp_is_trimmed_off_the_steady_step() {
        // 1 % more amplitude per cycle over 8 cycles, then 14 steady cycles: the ramp agrees cycle to
        // cycle but not with the step's median.
        let w = 2.0;
        let ts = TAU / w / 100.0;
        let n = 2200;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * ts).collect();
        let u: Vec<f64> = t
            .iter()
            .map(|&tk| {
                let cyc = tk * w / TAU;
                let env = if cyc < 8.0 { 0.92 + 0.01 * cyc } else { 1.0 };
                env * (w * tk).sin()
            })
            .collect();
        let found = detect(&t, &u);
        assert_eq!(found.len(), 1, "{found:?}");
        // Cycles within 2 % of the plateau (from cycle 6 on) belong to the step; the others do not.
        assert!(found[0].start >= 6.0 * TAU / w - ts, "{:?}", found[0]);
    }

    #[test]
    fn steps_of_different_frequencies_are_told_apart() {
        let ts = 0.01;
        let mut t = Vec::new();
        let mut u = Vec::new();
        let mut t0 = 0.0;
        for w in [1.0, 2.0, 3.5] {
            let (tt, uu) = ramped(w, 1.0, TAU / w, 5.0 * TAU / w, 0.5, ts);
            t.extend(tt.iter().map(|v| v + t0));
            u.extend(uu);
            t0 = t.last().unwrap() + ts;
        }
        let found = detect(&t, &u);
        let omegas: Vec<f64> = found.iter().map(|f| f.omega).collect();
        assert_eq!(omegas.len(), 3, "{omegas:?}");
        for (got, want) in omegas.iter().zip([1.0, 2.0, 3.5]) {
            assert!((got / want - 1.0).abs() < 1e-6, "{omegas:?}");
        }
    }

    #[test]
    fn a_record_without_a_sine_has_no_step() {
        let t: Vec<f64> = (0..500).map(|k| k as f64 * 0.01).collect();
        assert!(detect(&t, &vec![0.3; 500]).is_empty());
        let ramp: Vec<f64> = t.iter().map(|v| v * 2.0).collect();
        assert!(detect(&t, &ramp).is_empty());
    }
}
