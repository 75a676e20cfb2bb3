//! The monitor's settings and what it reports: an alarm and its status.

use serde::{Deserialize, Serialize};

#[cfg(doc)]
use super::MIN_SAMPLES;

/// The user's settings of the monitor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MonitorConfig {
    /// Relative growth of the play c1 + c2 to detect (0.1: 10%).
    pub wear_ratio: f64,
    /// Mean number of samples between false alarms.
    pub alarm_period: f64,
    /// Samples of the refine recursion before the reference is frozen.
    pub learn: u64,
    /// The reference play c1 + c2, when known; None: learned.
    pub reference_play: Option<f64>,
    /// After an alarm the reference play becomes the estimated new play (module docs).
    pub follow: bool,
}

impl Default for MonitorConfig {
    fn default() -> Self {
        Self {
            wear_ratio: 0.1,
            alarm_period: 1e6,
            learn: 2000,
            reference_play: None,
            follow: true,
        }
    }
}

/// A setting of the monitor that cannot work, in words.
#[derive(Debug, Clone, thiserror::Error)]
pub enum MonitorError {
    #[error("wear_ratio = {0} is invalid: the relative play growth to detect must be in (0, 10]")]
    WearRatio(f64),
    #[error(
        "alarm_period = {0} is invalid: the mean samples between false alarms must be at least 2"
    )]
    AlarmPeriod(f64),
    #[error(
        "reference play = {0} is invalid: it must be a finite number > 0 (or left to be learned)"
    )]
    ReferencePlay(f64),
    #[error(transparent)]
    Estimator(#[from] crate::plant::ParamError),
}

impl MonitorConfig {
    pub fn validate(&self) -> Result<(), MonitorError> {
        let r = self.wear_ratio;
        if !(r.is_finite() && r > 0.0 && r <= 10.0) {
            return Err(MonitorError::WearRatio(r));
        }
        let a = self.alarm_period;
        if !(a.is_finite() && a >= 2.0) {
            return Err(MonitorError::AlarmPeriod(a));
        }
        if let Some(p) = self.reference_play
            && !(p.is_finite() && p > 0.0)
        {
            return Err(MonitorError::ReferencePlay(p));
        }
        Ok(())
    }
}

/// One alarm: when, since when, and the play before and after with standard errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    /// Sample index of the alarm and its time.
    pub sample: u64,
    pub time: f64,
    /// Sample index and time the change is estimated to have begun.
    pub onset_sample: u64,
    pub onset: f64,
    pub play_before: f64,
    pub play_before_se: f64,
    pub play_after: f64,
    pub play_after_se: f64,
}

/// What the monitor is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Status {
    /// Before the reference is frozen (refine warm-up and learning).
    Learning,
    /// The reference is frozen; the test runs (after [`MIN_SAMPLES`]).
    Testing,
    /// The reference has no play: nothing to detect.
    NoPlay,
}
