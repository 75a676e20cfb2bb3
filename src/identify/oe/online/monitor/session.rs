//! A monitored record as one session: the estimator, the monitor and every alarm, and its summary.

use serde::Serialize;

use super::{Alarm, Monitor, MonitorConfig, MonitorError, Status, play_of};
use crate::identify::oe::online::Refined;

/// A monitored record, sample by sample: the estimator, the monitor and every alarm (the memory grows with
/// the alarms only). What `backlash monitor` and `backlash_fmu.monitor` run.
#[derive(Debug, Clone)]
pub struct Session {
    est: Refined,
    mon: Monitor,
    alarms: Vec<Alarm>,
}

/// The result of a monitored record (`backlash monitor --json`).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub alarms: Vec<Alarm>,
    /// The estimator's play c1 + c2 at the end and its standard error (0 while unknown).
    pub play: f64,
    pub play_se: f64,
    pub samples: u64,
    pub status: Status,
    /// The reference play (after any re-reference) and its standard error; None while learning.
    pub reference_play: Option<f64>,
    pub reference_play_se: Option<f64>,
    /// The noise standard deviation and the threshold (log-likelihood units) the test uses.
    pub sigma: Option<f64>,
    pub threshold: Option<f64>,
    pub wear_ratio: f64,
    pub alarm_period: f64,
    pub learn: u64,
    /// The estimator's final estimate and standard errors.
    pub estimate: crate::identify::mrgia::Estimate,
    pub std_err: Option<crate::identify::oe::StdErr>,
}

impl Session {
    /// The refined estimator with `est` (its warm-up setting) and the monitor with `cfg`.
    pub fn new(
        est: crate::identify::mrgia::MrgiaConfig,
        cfg: MonitorConfig,
    ) -> Result<Self, MonitorError> {
        Ok(Self {
            est: Refined::new(est)?,
            mon: Monitor::new(cfg)?,
            alarms: Vec::new(),
        })
    }

    /// Sample (u, y) at time t; the alarm it raised.
    pub fn push(&mut self, t: f64, u: f64, y: f64) -> Option<Alarm> {
        let (_, a) = self.mon.update(&mut self.est, t, u, y);
        if let Some(a) = a {
            self.alarms.push(a);
        }
        a
    }

    pub fn estimator(&self) -> &Refined {
        &self.est
    }

    pub fn monitor(&self) -> &Monitor {
        &self.mon
    }

    pub fn summary(&self) -> Summary {
        let (play, play_se) = play_of(&self.est);
        let reference = self.mon.reference();
        let c = self.mon.config();
        Summary {
            alarms: self.alarms.clone(),
            play,
            play_se,
            samples: self.est.samples(),
            status: self.mon.status(),
            reference_play: reference.map(|r| r.0),
            reference_play_se: reference.map(|r| r.1),
            sigma: self.mon.sigma(),
            threshold: self.mon.threshold(),
            wear_ratio: c.wear_ratio,
            alarm_period: c.alarm_period,
            learn: c.learn,
            estimate: self.est.estimate(),
            std_err: self.est.std_err(),
        }
    }
}
