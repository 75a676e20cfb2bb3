//! MrgiaEstimator.fmu: the MRGIA estimator of `crate::identify::mrgia` behind the FMI layer.
//!
//! Timing (the FMI layer's sampled data): the pair (u, y) current at t_k is sample k; when a step reaches
//! t_{k+1} the estimator processes it, so from t_{k+1} on the outputs are the estimate after sample k,
//! y_hat(k), e(k) and Phi(k). One sample per communication step: a step reaching a second instant would
//! feed the pair held over the step as a second sample, so the layer cuts it at the first (fmi2Discard).

use super::mrgia_estimator::{self as md, Var};
use crate::fmi2::Model;
use crate::fmi2::vars::{Value, VarInfo};
use crate::identify::mrgia::{Mrgia, MrgiaConfig, StepResult};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct EstimatorFmu {
    ts: f64,
    na: i32,
    nb: i32,
    delay: i32,
    recommended: bool,
    /// The settings as set; used when `recommended` is false.
    settings: MrgiaConfig,
    u: f64,
    y: f64,
    est: Option<Mrgia>,
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
    fn estimator(&self) -> Option<std::borrow::Cow<'_, Mrgia>> {
        match &self.est {
            Some(e) => Some(std::borrow::Cow::Borrowed(e)),
            None => self
                .config()
                .ok()
                .and_then(|c| Mrgia::new(c).ok())
                .map(std::borrow::Cow::Owned),
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
            settings: MrgiaConfig::paper(2, 0, 1),
            u: 0.0,
            y: 0.0,
            est: None,
        }
    }

    fn get(&self, var: Var) -> Value {
        let s = &self.settings;
        let r = Value::Real;
        // Estimates straight from theta = [a1..a_na, b0..b_nb, m2 - 1, c1, c2] (no allocation per get: the
        // layer reads every output after each step).
        let est = self.estimator();
        let theta = |i: Option<usize>| -> f64 {
            match (&est, i) {
                (Some(e), Some(i)) => e.theta()[i],
                _ => 0.0,
            }
        };
        let (na, nb) = (self.na.max(0) as usize, self.nb.max(0) as usize);
        let a = |i: usize| r(theta((i < na).then_some(i)));
        let b = |j: usize| r(theta((j <= nb).then_some(na + j)));
        let tail = |off: usize| theta(Some(na + nb + 1 + off));
        let last = || {
            self.est.as_ref().map(Mrgia::last).unwrap_or(StepResult {
                y_hat: 0.0,
                e: 0.0,
                updating: false,
            })
        };
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
            Var::M2 => r(if est.is_some() { 1.0 + tail(0) } else { 0.0 }),
            Var::C1 => r(tail(1)),
            Var::C2 => r(tail(2)),
            Var::YHat => r(last().y_hat),
            Var::E => r(last().e),
            Var::Updating => Value::Boolean(last().updating),
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
            Var::P0 => s.p0 = x,
            Var::RhoExp => s.rho_exp = x,
            Var::RhoMin => s.rho_min = x,
            Var::Eps => s.eps = x,
            Var::Sigma0 => s.sigma0 = x,
            Var::CInit => s.c_init = x,
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
            | Var::Updating => {}
        }
    }

    fn exit_initialization(&mut self) -> Result<(), String> {
        let cfg = self.config()?;
        self.est = Some(Mrgia::new(cfg).map_err(|e| e.to_string())?);
        Ok(())
    }

    fn sample_period(&self) -> f64 {
        self.ts
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
                Ok(())
            }
        }
    }

    fn step(&mut self, n: u64) -> Result<(), String> {
        let est = self.est.as_mut().ok_or(
            "the estimator is not initialised (fmi2ExitInitializationMode was not called)",
        )?;
        for _ in 0..n {
            est.update(self.u, self.y);
        }
        Ok(())
    }
}
