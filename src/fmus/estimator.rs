//! MrgiaEstimator.fmu: the MRGIA estimator of `crate::identify::mrgia` behind the FMI layer.
//!
//! Timing (the FMI layer's sampled data): the pair (u, y) current at t_k is sample k; when a step reaches
//! t_{k+1} the estimator processes it, so from t_{k+1} on the outputs are the estimate after sample k,
//! y_hat(k), e(k) and Phi(k). One sample per communication step: a step reaching a second instant would
//! feed the pair held over the step as a second sample, so the layer cuts it at the first (fmi2Discard).
//!
//! `refine` selects [`crate::identify::oe::online::Refined`] (MRGIA for a warm-up, then the recursive output-error estimator) instead of
//! plain MRGIA; the `*_se` outputs are its standard errors (0 without refine, during the warm-up and beyond
//! na/nb).
//!
//! `monitor` (which implies `refine`) adds the wear monitor of [`crate::identify::oe::online::monitor`]: it
//! drives the refined estimator sample by sample; sample k has the time k Ts (from the start time). The input
//! `wear_reset`, true at a sample, clears the latched alarm before that sample (an input, not a tunable
//! parameter: inputs are sampled with u and y at the instants, in FMI 2.0 and 3.0 alike, so the reset acts at
//! a known sample).

use super::mrgia_estimator::{self as md, Var};
use crate::fmi::Model;
use crate::fmi::vars::{Value, VarInfo};
use crate::identify::mrgia::{MrgiaConfig, StepResult};
use crate::identify::oe::online::OnlineEstimator as Running;
use crate::identify::oe::online::monitor::{Monitor, MonitorConfig, play_of};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EstimatorFmu {
    ts: f64,
    na: i32,
    nb: i32,
    delay: i32,
    recommended: bool,
    refine: bool,
    /// The settings as set; used when `recommended` is false.
    settings: MrgiaConfig,
    u: f64,
    y: f64,
    est: Option<Running>,
    /// The wear monitor's switch and settings (`wear_reference` 0 is None), and the monitor once running.
    monitor: bool,
    wear: MonitorConfig,
    mon: Option<Monitor>,
    /// The input `wear_reset`: true at a sample clears the latched alarm before the sample.
    wear_reset: bool,
}

impl EstimatorFmu {
    fn config(&self) -> Result<MrgiaConfig, String> {
        let order = |name: &str, v: i32| {
            usize::try_from(v)
                .map_err(|_| format!("parameter {name} = {v} is invalid: must not be negative"))
        };
        let (na, nb, delay) = (
            order("na", self.na)?,
            order("nb", self.nb)?,
            order("delay", self.delay)?,
        );
        // `recommended` replaces the convergence settings; the floor on rho (forgetting, for wear) is a separate
        // choice and always comes from its own parameter.
        let cfg = if self.recommended {
            MrgiaConfig {
                rho_min: self.settings.rho_min,
                ..MrgiaConfig::recommended(na, nb, delay)
            }
        } else {
            MrgiaConfig {
                na,
                nb,
                delay,
                ..self.settings
            }
        };
        cfg.validate().map_err(|e| e.to_string())?;
        Ok(cfg)
    }

    /// The estimator's current estimate as theta-like outputs; before initialisation, theta(0).
    fn estimator(&self) -> Option<std::borrow::Cow<'_, Running>> {
        match &self.est {
            Some(e) => Some(std::borrow::Cow::Borrowed(e)),
            None => self
                .config()
                .ok()
                .and_then(|c| {
                    Running::new(c, self.refines())
                        .map_err(|e| e.to_string())
                        .ok()
                })
                .map(std::borrow::Cow::Owned),
        }
    }
}

impl EstimatorFmu {
    /// A restored monitor matches the parameters (present exactly when `monitor` is on, same settings).
    fn check_monitor(&self) -> Result<(), String> {
        match (&self.mon, self.monitor) {
            (None, false) => Ok(()),
            (Some(m), true) if *m.config() == self.wear => m.check(),
            _ => Err("the wear monitor's state differs from the parameters monitor, wear_*".into()),
        }
    }

    /// `refine`, or implied by `monitor`.
    fn refines(&self) -> bool {
        self.refine || self.monitor
    }

    /// play and play_se of the current estimate (0 before initialisation; se 0 without refine).
    fn play(&self) -> (f64, f64) {
        match &self.est {
            Some(Running::Refined(r)) => play_of(r),
            Some(Running::Plain(m)) => {
                // theta ends with c1, c2 (no `estimate()`: it builds vectors, and the layer reads every
                // output after each step).
                let t = m.theta();
                (t[t.len() - 2] + t[t.len() - 1], 0.0)
            }
            None => (0.0, 0.0),
        }
    }

    /// The last sample's prediction, error and update flag; zeros and false before the first step.
    fn last_step(&self) -> StepResult {
        self.est.as_ref().map(Running::last).unwrap_or(StepResult {
            y_hat: 0.0,
            e: 0.0,
            updating: false,
        })
    }

    fn wear_value(&self, var: Var) -> Value {
        let first = self.mon.as_ref().and_then(Monitor::first_alarm);
        match var {
            Var::Monitor => Value::Boolean(self.monitor),
            Var::WearRatio => Value::Real(self.wear.wear_ratio),
            Var::AlarmPeriod => Value::Real(self.wear.alarm_period),
            Var::WearLearn => Value::Integer(i32::try_from(self.wear.learn).unwrap_or(i32::MAX)),
            Var::WearReference => Value::Real(self.wear.reference_play.unwrap_or(0.0)),
            Var::Play => Value::Real(self.play().0),
            Var::PlaySe => Value::Real(self.play().1),
            Var::WearStatistic => Value::Real(self.mon.as_ref().map_or(0.0, Monitor::statistic)),
            Var::WearAlarm => Value::Boolean(first.is_some()),
            Var::WearOnset => Value::Real(first.map_or(0.0, |a| a.onset)),
            Var::WearReset => Value::Boolean(self.wear_reset),
            _ => Value::Real(0.0),
        }
    }

    fn set_wear(&mut self, var: Var, value: Value) {
        let w = &mut self.wear;
        match var {
            Var::Monitor => self.monitor = value.as_bool(),
            Var::WearReset => self.wear_reset = value.as_bool(),
            Var::WearRatio => w.wear_ratio = value.as_real(),
            Var::AlarmPeriod => w.alarm_period = value.as_real(),
            Var::WearLearn => w.learn = value.as_integer().max(0) as u64,
            Var::WearReference => {
                let x = value.as_real();
                w.reference_play = (x != 0.0).then_some(x);
            }
            _ => {}
        }
    }
}

impl Model for EstimatorFmu {
    type Var = Var;
    const MODEL_IDENTIFIER: &'static str = md::MODEL_IDENTIFIER;
    const GUID: &'static str = md::GUID;
    const LOG_CATEGORIES: &'static [&'static str] = md::LOG_CATEGORIES;
    const VARIABLES: &'static [VarInfo] = &md::VARIABLES;
    const MAX_SAMPLES_PER_STEP: u64 = 1;

    fn var(index: usize) -> Var {
        Var::ALL[index]
    }

    fn new() -> Self {
        Self {
            ts: 1.0,
            na: 2,
            nb: 0,
            delay: 1,
            recommended: false,
            refine: false,
            settings: MrgiaConfig::paper(2, 0, 1),
            u: 0.0,
            y: 0.0,
            est: None,
            monitor: false,
            wear: MonitorConfig::default(),
            mon: None,
            wear_reset: false,
        }
    }

    fn get(&self, var: Var) -> Value {
        let s = &self.settings;
        let r = Value::Real;
        // Estimates straight from the estimator's vectors (no allocation per get: the layer reads every
        // output after each step).
        let est = self.estimator();
        let (na, nb) = (self.na.max(0) as usize, self.nb.max(0) as usize);
        let at = |f: fn(&Running, usize) -> f64, i: Option<usize>| -> f64 {
            match (&est, i) {
                (Some(e), Some(i)) => f(e, i),
                _ => 0.0,
            }
        };
        let a = |i: usize| r(at(Running::value, (i < na).then_some(i)));
        let b = |j: usize| r(at(Running::value, (j <= nb).then_some(na + j)));
        let tail = |off: usize| r(at(Running::value, Some(na + nb + 1 + off)));
        let a_se = |i: usize| r(at(Running::std_err_at, (i < na).then_some(i)));
        let b_se = |j: usize| r(at(Running::std_err_at, (j <= nb).then_some(na + j)));
        let tail_se = |off: usize| r(at(Running::std_err_at, Some(na + nb + 1 + off)));
        match var {
            Var::Ts => r(self.ts),
            Var::U => r(self.u),
            Var::Y => r(self.y),
            Var::Na => Value::Integer(self.na),
            Var::Nb => Value::Integer(self.nb),
            Var::Delay => Value::Integer(self.delay),
            Var::Recommended => Value::Boolean(self.recommended),
            Var::P0 => r(s.p0),
            Var::RhoExp => r(s.rho_exp),
            Var::RhoMin => r(s.rho_min),
            Var::Eps => r(s.eps),
            Var::Sigma0 => r(s.sigma0),
            Var::CInit => r(s.c_init),
            Var::A1 => a(0),
            Var::A2 => a(1),
            Var::A3 => a(2),
            Var::A4 => a(3),
            Var::B0 => b(0),
            Var::B1 => b(1),
            Var::B2 => b(2),
            Var::B3 => b(3),
            Var::B4 => b(4),
            Var::M2 => tail(0),
            Var::C1 => tail(1),
            Var::C2 => tail(2),
            Var::Refine => Value::Boolean(self.refine),
            Var::A1Se => a_se(0),
            Var::A2Se => a_se(1),
            Var::A3Se => a_se(2),
            Var::A4Se => a_se(3),
            Var::B0Se => b_se(0),
            Var::B1Se => b_se(1),
            Var::B2Se => b_se(2),
            Var::B3Se => b_se(3),
            Var::B4Se => b_se(4),
            Var::M2Se => tail_se(0),
            Var::C1Se => tail_se(1),
            Var::C2Se => tail_se(2),
            Var::YHat => r(self.last_step().y_hat),
            Var::E => r(self.last_step().e),
            Var::Updating => Value::Boolean(self.last_step().updating),
            Var::Monitor
            | Var::WearRatio
            | Var::AlarmPeriod
            | Var::WearLearn
            | Var::WearReference
            | Var::Play
            | Var::PlaySe
            | Var::WearStatistic
            | Var::WearAlarm
            | Var::WearOnset
            | Var::WearReset => self.wear_value(var),
        }
    }

    fn set(&mut self, var: Var, value: Value) {
        let x = value.as_real();
        let s = &mut self.settings;
        match var {
            Var::Ts => self.ts = x,
            Var::U => self.u = x,
            Var::Y => self.y = x,
            Var::Na => self.na = value.as_integer(),
            Var::Nb => self.nb = value.as_integer(),
            Var::Delay => self.delay = value.as_integer(),
            Var::Recommended => self.recommended = value.as_bool(),
            Var::Refine => self.refine = value.as_bool(),
            Var::P0 => s.p0 = x,
            Var::RhoExp => s.rho_exp = x,
            Var::RhoMin => s.rho_min = x,
            Var::Eps => s.eps = x,
            Var::Sigma0 => s.sigma0 = x,
            Var::CInit => s.c_init = x,
            Var::Monitor
            | Var::WearRatio
            | Var::AlarmPeriod
            | Var::WearLearn
            | Var::WearReference
            | Var::WearReset => self.set_wear(var, value),
            // Outputs: the layer refuses to set them before calling here.
            Var::A1
            | Var::A2
            | Var::A3
            | Var::A4
            | Var::B0
            | Var::B1
            | Var::B2
            | Var::B3
            | Var::B4
            | Var::M2
            | Var::C1
            | Var::C2
            | Var::YHat
            | Var::E
            | Var::Updating
            | Var::A1Se
            | Var::A2Se
            | Var::A3Se
            | Var::A4Se
            | Var::B0Se
            | Var::B1Se
            | Var::B2Se
            | Var::B3Se
            | Var::B4Se
            | Var::M2Se
            | Var::C1Se
            | Var::C2Se
            | Var::Play
            | Var::PlaySe
            | Var::WearStatistic
            | Var::WearAlarm
            | Var::WearOnset => {}
        }
    }

    fn exit_initialization(&mut self) -> Result<(), String> {
        let cfg = self.config()?;
        self.est = Some(Running::new(cfg, self.refines()).map_err(|e| e.to_string())?);
        self.mon = if self.monitor {
            Some(Monitor::new(self.wear).map_err(|e| e.to_string())?)
        } else {
            None
        };
        Ok(())
    }

    fn sample_period(&self) -> f64 {
        self.ts
    }

    fn samples(&self) -> Option<u64> {
        self.est.as_ref().map(Running::samples)
    }

    fn check_restored(&self) -> Result<(), String> {
        let ts_ok = self.ts.is_finite() && self.ts > 0.0;
        if !ts_ok || !self.u.is_finite() || !self.y.is_finite() {
            return Err("Ts, u or y is not valid".into());
        }
        // Mrgia checks its own consistency when deserialised; its settings must also be valid.
        match &self.est {
            None => Ok(()),
            Some(e) => {
                e.check()?;
                if e.refining_kind() != self.refines() {
                    return Err("the estimator's kind differs from the parameter refine".into());
                }
                self.check_monitor()?;
                let c = e.config();
                c.validate().map_err(|e| e.to_string())?;
                if (c.na, c.nb, c.delay)
                    != (self.na as usize, self.nb as usize, self.delay as usize)
                    || self.na < 0
                    || self.nb < 0
                {
                    return Err(
                        "the estimator's orders differ from the parameters na, nb, delay".into(),
                    );
                }
                // The running estimator's settings are those its parameters give (none is tunable).
                if *c != self.config()? {
                    return Err(
                        "the estimator's settings (c_init, p0, sigma0, ...) differ from the \
                         FMU's parameters"
                            .into(),
                    );
                }
                Ok(())
            }
        }
    }

    fn step(&mut self, n: u64) -> Result<(), String> {
        let est = self.est.as_mut().ok_or(
            "the estimator is not initialised (fmi2ExitInitializationMode was not called)",
        )?;
        for _ in 0..n {
            match (&mut self.mon, &mut *est) {
                (Some(m), Running::Refined(r)) => {
                    if self.wear_reset {
                        m.reset_alarm();
                    }
                    let t = r.samples() as f64 * self.ts;
                    m.update(r, t, self.u, self.y);
                }
                _ => {
                    est.update(self.u, self.y);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::oe::online::monitor::study::{Change, Scenario, noise_std};
    use crate::plant::PlantParams;

    /// `n` samples of the paper's plant: the backlash output plus `noise` times a fixed pseudo-random
    /// sequence in [-0.5, 0.5) (none for 0).
    fn paper_samples(n: usize, noise: f64) -> (Vec<f64>, Vec<f64>) {
        let u = crate::identify::mrgia::paper_input(n, 3);
        let y = crate::plant::Plant::simulate(PlantParams::PAPER, &u)
            .unwrap()
            .iter()
            .enumerate()
            .map(|(k, o)| o.w + noise * ((k * 7919 % 1000) as f64 / 1000.0 - 0.5))
            .collect();
        (u, y)
    }

    /// `fmu` initialised and stepped once per sample of `u`, `y`.
    fn feed(fmu: &mut EstimatorFmu, u: &[f64], y: &[f64]) {
        fmu.exit_initialization().unwrap();
        for (uk, yk) in u.iter().zip(y) {
            fmu.set(Var::U, Value::Real(*uk));
            fmu.set(Var::Y, Value::Real(*yk));
            fmu.step(1).unwrap();
        }
    }

    /// The library's MRGIA with `cfg` on `u`, `y`: its theta.
    fn library_theta(cfg: MrgiaConfig, u: &[f64], y: &[f64]) -> Vec<f64> {
        let (_, lib) = crate::identify::mrgia::identify(cfg, u, y).unwrap();
        lib.theta().to_vec()
    }

    /// The estimates as read: a_i for i < na and b_j for j <= nb (0 beyond the orders), c1, c2 and the
    /// play c1 + c2, the numbers of the library's MRGIA run on the same samples with the same settings.
    #[test]
    fn outputs_are_the_estimate_within_the_orders() {
        let (u, y) = paper_samples(400, 0.0);
        let mut fmu = EstimatorFmu::new();
        feed(&mut fmu, &u, &y);
        let t = library_theta(MrgiaConfig::paper(2, 0, 1), &u, &y);
        assert!(t.iter().all(|v| *v != 0.0), "{t:?}");
        let expected = [
            (Var::A1, t[0]),
            (Var::A2, t[1]),
            (Var::A3, 0.0),
            (Var::A4, 0.0),
            (Var::B0, t[2]),
            (Var::B1, 0.0),
            (Var::C1, t[4]),
            (Var::C2, t[5]),
            (Var::Play, t[4] + t[5]),
        ];
        for (var, value) in expected {
            assert_eq!(fmu.get(var), Value::Real(value), "{var:?}");
        }
    }

    /// With `refine`, past the warm-up, on the paper's plant with a little noise: the last sample's
    /// prediction, error and update flag and the standard error of every entry (na = 2, nb = 1) are the
    /// library's refined estimator's on the same samples.
    #[test]
    fn refined_outputs_are_the_library_estimators() {
        // Noise gives the fit a residual, so standard errors.
        let (u, y) = paper_samples(3 * crate::identify::oe::online::WARMUP, 0.02);
        let mut fmu = EstimatorFmu::new();
        fmu.set(Var::Refine, Value::Boolean(true));
        fmu.set(Var::Nb, Value::Integer(1));
        feed(&mut fmu, &u, &y);
        let mut lib = Running::new(MrgiaConfig::paper(2, 1, 1), true).unwrap();
        for (uk, yk) in u.iter().zip(&y) {
            lib.update(*uk, *yk);
        }
        let last = lib.last();
        assert_eq!(fmu.get(Var::YHat), Value::Real(last.y_hat));
        assert_eq!(fmu.get(Var::E), Value::Real(last.e));
        assert_eq!(fmu.get(Var::Updating), Value::Boolean(last.updating));
        assert!(last.y_hat != 0.0);
        // The estimate's entries [a1, a2, b0, b1, m2, c1, c2], each with its own standard error.
        let se_vars = [
            Var::A1Se,
            Var::A2Se,
            Var::B0Se,
            Var::B1Se,
            Var::M2Se,
            Var::C1Se,
            Var::C2Se,
        ];
        let se: Vec<f64> = (0..se_vars.len()).map(|i| lib.std_err_at(i)).collect();
        assert!(se.iter().all(|v| *v > 0.0), "{se:?}");
        assert!((1..se.len()).all(|i| !se[..i].contains(&se[i])), "{se:?}");
        for (var, value) in se_vars.into_iter().zip(se) {
            assert_eq!(fmu.get(var), Value::Real(value), "{var:?}");
        }
    }

    /// The orders, the delay and the floor on rho set as parameters are the running estimator's, also with
    /// `recommended` (which replaces the convergence settings but keeps rho_min): its estimates are the
    /// library's with those settings. rho_min = 0.3 binds from sample 123 with the paper's exponent and
    /// from sample 4 with the recommended one.
    #[test]
    fn parameters_reach_the_running_estimator() {
        let (u, y) = paper_samples(400, 0.0);
        for recommended in [false, true] {
            let mut fmu = EstimatorFmu::new();
            fmu.set(Var::Na, Value::Integer(1));
            fmu.set(Var::Nb, Value::Integer(1));
            fmu.set(Var::Delay, Value::Integer(2));
            fmu.set(Var::RhoMin, Value::Real(0.3));
            fmu.set(Var::Recommended, Value::Boolean(recommended));
            feed(&mut fmu, &u, &y);
            let base = if recommended {
                MrgiaConfig::recommended(1, 1, 2)
            } else {
                MrgiaConfig::paper(1, 1, 2)
            };
            let t = library_theta(
                MrgiaConfig {
                    rho_min: 0.3,
                    ..base
                },
                &u,
                &y,
            );
            let expected = [
                (Var::A1, t[0]),
                (Var::A2, 0.0),
                (Var::B0, t[1]),
                (Var::B1, t[2]),
                (Var::B2, 0.0),
                (Var::C1, t[4]),
                (Var::C2, t[5]),
            ];
            for (var, value) in expected {
                assert_eq!(fmu.get(var), Value::Real(value), "{recommended} {var:?}");
            }
        }
    }

    /// `wear_reset` true for one sample clears the latched alarm and onset; a growth that goes on alarms again.
    /// With Ts 0.01 the onset is read in seconds (samples times Ts).
    #[test]
    fn wear_reset_clears_the_latched_alarm() {
        let plant = PlantParams::PAPER;
        let change = Change::PlayStep {
            at: 5000,
            ratio: 0.5,
        };
        let mut sc = Scenario::new(plant, noise_std(plant, 20.0), 1, change);
        let mut fmu = EstimatorFmu::new();
        let ts = 0.01;
        fmu.set(Var::Ts, Value::Real(ts));
        fmu.set(Var::Monitor, Value::Boolean(true));
        fmu.set(Var::Recommended, Value::Boolean(true));
        fmu.exit_initialization().unwrap();
        let alarm = |f: &EstimatorFmu| f.get(Var::WearAlarm) == Value::Boolean(true);
        let mut sample = |f: &mut EstimatorFmu| {
            let (u, y) = sc.next_sample();
            f.set(Var::U, Value::Real(u));
            f.set(Var::Y, Value::Real(y));
            f.step(1).unwrap();
        };
        let mut k = 0;
        while !alarm(&fmu) && k < 8000 {
            sample(&mut fmu);
            k += 1;
        }
        assert!(
            alarm(&fmu) && k > 5000,
            "no alarm after the step ({k} samples)"
        );
        // The onset is a time, sample k at k Ts: between the start and the alarm, in seconds.
        let onset = fmu.get(Var::WearOnset).as_real();
        assert!(onset > 0.0 && onset <= k as f64 * ts, "{onset} {k}");
        fmu.set(Var::WearReset, Value::Boolean(true));
        sample(&mut fmu);
        assert!(!alarm(&fmu));
        assert_eq!(fmu.get(Var::WearOnset), Value::Real(0.0));
        fmu.set(Var::WearReset, Value::Boolean(false));
        sample(&mut fmu);
        assert_eq!(fmu.get(Var::WearReset), Value::Boolean(false));
    }

    /// A restored state is checked: an initialised estimator's own state passes, with the wear monitor off and
    /// on; a non-finite u or y (each alone), or a running monitor whose settings are not the parameters
    /// wear_*, is refused by what is wrong.
    #[test]
    fn a_restored_state_is_refused_by_what_is_wrong() {
        let initialised = |monitor: bool| {
            let mut fmu = EstimatorFmu::new();
            fmu.set(Var::Monitor, Value::Boolean(monitor));
            fmu.exit_initialization().unwrap();
            fmu
        };
        for monitor in [false, true] {
            assert_eq!(initialised(monitor).check_restored(), Ok(()), "{monitor}");
        }
        for (var, bad) in [(Var::U, f64::NAN), (Var::Y, f64::INFINITY)] {
            let mut forged = initialised(false);
            forged.set(var, Value::Real(bad));
            let e = forged.check_restored().unwrap_err();
            assert!(e.contains("u or y is not valid"), "{var:?} = {bad}: {e}");
        }
        let mut forged = initialised(true);
        forged.set(Var::WearRatio, Value::Real(forged.wear.wear_ratio * 2.0));
        let e = forged.check_restored().unwrap_err();
        assert!(e.contains("wear monitor's state differs"), "{e}");
    }
}
