//! Sampled-data timing, the same for both protocols: the instance samples its model at the instants
//! t_j = start_time + j Ts that the master's steps reach, whatever their size; outputs hold between instants,
//! inputs are those current at an instant. Any step size a master picks gives the same values at the
//! instants as stepping by Ts.

use super::state::State;
use serde::{Deserialize, Serialize};

/// The one time tolerance, relative to the time it is applied at (an instant t_j, or the instance's clock):
/// 1e-7, above the relative rounding of a float32 (2^-24 = 6e-8), so that a master whose step is a float32
/// (h = float32(0.1) = 0.1000000015) or whose clock is a float32 or float64 sum lands on the instants it
/// means to; for instants it is never more than a quarter of the step nor a quarter of Ts (see
/// [`instant_tolerance`]), so that steps far shorter than the relative tolerance stay exact late in long runs.
pub const TIME_TOLERANCE: f64 = 1e-7;

/// Tolerance for comparing a time with `at` (the master's clock arithmetic): relative to `at`, with `ts` as
/// the floor of the scale so that times near 0 are not compared exactly.
pub fn time_tolerance(at: f64, ts: f64) -> f64 {
    TIME_TOLERANCE * at.abs().max(ts)
}

/// Tolerance for "a step ending at `end` reaches the instant `at`": [`time_tolerance`], at most a quarter of
/// the step `h` and of the sample period `ts` (so that instants never merge and sub-steps stay distinct).
pub fn instant_tolerance(at: f64, ts: f64, h: f64) -> f64 {
    time_tolerance(at, ts).min(0.25 * h.min(ts))
}

/// Time from the start to instant t_j.
fn offset(ts: f64, j: u64) -> f64 {
    j as f64 * ts
}

/// What the core keeps of an instance besides the model (saved with it in an FMU state).
///
/// Timing (sampled data): the sample instants are t_j = start_time + j Ts. `samples` = k means the instants
/// t_1 .. t_k have been reached, so the outputs are sample k's. `time` is the instance's clock, the end of
/// the last step exactly as the master computed it (never snapped to an instant). `latched` holds the inputs
/// current at t_k once a step has started from t_k: they are sample k's inputs, used when t_{k+1} is reached,
/// whatever the master sets in between. `latched` is false while the clock stands at t_k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LayerState {
    pub state: State,
    pub start_time: f64,
    pub stop_time: Option<f64>,
    pub time: f64,
    /// Samples advanced since initialization mode was left.
    pub samples: u64,
    pub latched: bool,
    /// The inputs (in the order of the variable table) latched at t_k, as numbers (meaningful when
    /// `latched`; always one per input, so that stepping does not allocate).
    pub latched_inputs: Vec<f64>,
}

/// What one communication step did: every instant it reached was sampled, or the model's limit cut it short
/// at the returned time (Discard, the last successful time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StepOutcome {
    Complete,
    Cut { at: f64, reached: u64, limit: u64 },
}

impl LayerState {
    pub fn new(inputs: usize) -> Self {
        Self {
            state: State::Instantiated,
            start_time: 0.0,
            stop_time: None,
            time: 0.0,
            samples: 0,
            latched: false,
            latched_inputs: vec![0.0; inputs],
        }
    }

    /// Sample instant t_j.
    pub fn instant(&self, ts: f64, j: u64) -> f64 {
        self.start_time + offset(ts, j)
    }

    /// The end of a step from `t` by `h`, or why the step is refused: both finite, `h` positive, `t` the
    /// clock (within the time tolerance), the end finite, after `t` and not after the stop time.
    pub fn step_end(&self, ts: f64, t: f64, h: f64) -> Result<f64, String> {
        let now = self.time;
        if !t.is_finite() || !h.is_finite() {
            return Err(format!(
                "currentCommunicationPoint {t} and communicationStepSize {h} must be finite"
            ));
        }
        if h <= 0.0 {
            return Err(format!("communicationStepSize {h} must be positive"));
        }
        if (t - now).abs() > time_tolerance(now, ts) {
            return Err(format!(
                "currentCommunicationPoint {t} is not the instance's time {now} (the end of the previous step; \
                 relative tolerance {TIME_TOLERANCE})"
            ));
        }
        let end = t + h;
        if !end.is_finite() {
            return Err(format!("the step would end at {end}, which is not finite"));
        }
        if end <= t {
            return Err(format!(
                "communicationStepSize {h} is below the resolution of the time {t} (t + h = t)"
            ));
        }
        if let Some(stop) = self.stop_time
            && end > stop + time_tolerance(stop, ts)
        {
            return Err(format!(
                "the step would end at {end}, after the stopTime {stop} set for the experiment"
            ));
        }
        Ok(end)
    }

    /// How many instants after t_k a step of size `h` ending at `end` reaches (an instant within
    /// [`instant_tolerance`] of the end counts as reached). Offsets from the start time are compared, so that
    /// a start time far larger than Ts does not swallow the instants.
    pub fn instants_reached(&self, ts: f64, end: f64, h: f64) -> u64 {
        let k = self.samples;
        let since_start = end - self.start_time;
        let reaches = |j: u64| {
            let at = self.instant(ts, j);
            offset(ts, j) - instant_tolerance(at, ts, h) <= since_start
        };
        // The estimate is within one or two of the answer (the tolerance is below Ts / 4), unless the sample
        // count is beyond what a float resolves (2^53), where a few adjustments are as good as any; `as`
        // saturates.
        let mut j = ((since_start / ts).floor().max(0.0) as u64).max(k);
        for _ in 0..4 {
            if j < u64::MAX && reaches(j + 1) {
                j += 1;
            } else if j > k && !reaches(j) {
                j -= 1;
            } else {
                break;
            }
        }
        j - k
    }

    /// Whether a step of size `h` ending at `end` went on past the last instant reached (by more than the
    /// instant tolerance): it has then held the inputs there, which are that sample's.
    pub fn past_last_instant(&self, ts: f64, end: f64, h: f64) -> bool {
        let last = self.instant(ts, self.samples);
        let since = (end - self.start_time) - offset(ts, self.samples);
        since > instant_tolerance(last, ts, h)
    }

    /// The clock and the sample count agree as a step leaves them: the clock stands at or after instant t_k
    /// (within the time tolerance) and before t_{k+1}, which any step ending there would have reached; and
    /// not after the stop time (a step may not end there).
    pub fn check_clock(&self, ts: f64) -> Result<(), String> {
        let since = self.time - self.start_time;
        let (k, next) = (
            offset(ts, self.samples),
            offset(ts, self.samples.saturating_add(1)),
        );
        if since < k - time_tolerance(self.start_time + k, ts) || since >= next {
            return Err(format!(
                "the FMU state is inconsistent: its time {} is not between sample instant {} (samples) and \
                 the next one (start_time {}, Ts = {ts})",
                self.time, self.samples, self.start_time
            ));
        }
        // A step may end at most the time tolerance after the stop time (`step_end`).
        if let Some(stop) = self.stop_time
            && self.time > stop + time_tolerance(stop, ts)
        {
            return Err(format!(
                "the FMU state is inconsistent: its time {} lies after its stop_time {stop}",
                self.time
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first guess at the instants a step reaches, floor((end - start) / Ts), can be one too many:
    /// 1.7 / 0.1 rounds to 17, but t_17 = 17 * 0.1 is 1.7000000000000002, one ulp after the end. A step of
    /// one ulp to 1.7 from sample 16 (tolerance a quarter of the step) reaches no instant; a step of 0.05
    /// (tolerance 1e-7 relative) reaches t_17.
    #[test]
    fn an_instant_after_the_end_beyond_the_tolerance_is_not_reached() {
        let ulp = 1.7 - f64::from_bits(1.7f64.to_bits() - 1);
        assert!(17.0 * 0.1 > 1.7 && (1.7f64 / 0.1).floor() == 17.0);
        let mut l = LayerState::new(1);
        l.samples = 16;
        assert_eq!(l.instants_reached(0.1, 1.7, ulp), 0);
        assert_eq!(l.instants_reached(0.1, 1.7, 0.05), 1);
    }

    /// An end beyond every sample count a u64 holds saturates the count instead of wrapping it.
    #[test]
    fn instants_beyond_the_counter_saturate() {
        let l = LayerState::new(1);
        assert_eq!(l.instants_reached(1.0, 1e30, 1.0), u64::MAX);
    }

    /// A clock before its stop time or at it passes the check; one beyond it by more than the time tolerance
    /// does not.
    #[test]
    fn a_clock_after_the_stop_time_is_inconsistent() {
        let mut l = LayerState::new(1);
        l.stop_time = Some(10.0);
        (l.samples, l.time) = (50, 5.0);
        assert_eq!(l.check_clock(0.1), Ok(()));
        // A step may end at the stop time itself.
        (l.samples, l.time) = (20, 10.0);
        assert_eq!(l.check_clock(0.5), Ok(()));
        (l.samples, l.time) = (110, 11.0);
        let e = l.check_clock(0.1).unwrap_err();
        assert!(e.contains("after its stop_time 10"), "{e}");
    }

    /// A step reaches t_k when it ends within the time tolerance before it, relative to t_k (a float32 clock
    /// late in a run, or far from time 0): the clock such a step leaves passes the check; a clock further
    /// before t_k does not. From start time 1000, t_1000 at Ts = 0.1 is 1100 (tolerance 1.1e-4).
    #[test]
    fn a_clock_just_before_the_instant_it_reached_is_consistent() {
        for (start, early, too_early) in [(0.0, 5e-6, 2e-5), (1000.0, 1e-4, 1.2e-4)] {
            let mut l = LayerState::new(1);
            l.start_time = start;
            let t_k = start + 100.0;
            (l.samples, l.time) = (999, start + 99.9);
            let end = t_k - early;
            assert_eq!(l.instants_reached(0.1, end, end - l.time), 1, "{start}");
            (l.samples, l.time) = (1000, end);
            assert_eq!(l.check_clock(0.1), Ok(()), "{start}");
            l.time = t_k - too_early;
            let e = l.check_clock(0.1).unwrap_err();
            assert!(
                e.contains("not between sample instant 1000"),
                "{start}: {e}"
            );
        }
    }

    /// currentCommunicationPoint may differ from the clock by the time tolerance itself (relative to the clock,
    /// Ts the floor of the scale): a step from there is accepted, one from twice as far is refused.
    #[test]
    fn a_step_may_start_the_time_tolerance_off_the_clock() {
        let l = LayerState::new(1);
        let tol = time_tolerance(0.0, 1.0);
        assert_eq!(tol, TIME_TOLERANCE);
        assert_eq!(l.step_end(1.0, tol, 1.0), Ok(tol + 1.0));
        let e = l.step_end(1.0, 2.0 * tol, 1.0).unwrap_err();
        assert!(e.contains("is not the instance's time"), "{e}");
    }
}
