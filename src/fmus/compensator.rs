//! BacklashCompensator.fmu: the backlash inverse of `crate::compensate::inverse` behind the FMI layer.
//!
//! Timing: `v` depends directly on the inputs (the ModelStructure says so). After the inputs r, m1, m2, c1,
//! c2 are set at t_k, a get returns v(k) computed from them and the memory of samples 0..k-1; the step
//! reaching t_{k+1} commits sample k with the inputs current at t_k (the backlash output of v(k) becomes the
//! memory). Between instants a get answers for the inputs as they are then. A step reaching several instants
//! commits the held inputs at each (for a held r and estimate, the same v), so any step size is accepted.
//!
//! Degenerate inputs (m1 or m2 not positive, a negative gap, crossing borders) are answered with the
//! inverse's documented fallback; the get or step that meets them answers Warning with a log line under
//! logStatusWarning, and the output `degenerate` is true.

use super::backlash_compensator::{self as md, Var};
use crate::compensate::{Answer, BacklashInverse};
use crate::fmi::Model;
use crate::fmi::vars::{Value, VarInfo};
use crate::plant::BacklashParams;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CompensatorFmu {
    ts: f64,
    smoothing: f64,
    r: f64,
    estimate: BacklashParams,
    /// The inverse once initialised (before: an inverse at rest with the smoothing as set).
    inverse: Option<BacklashInverse>,
    /// Samples committed since initialization mode was left.
    #[serde(default)]
    committed: u64,
}

impl CompensatorFmu {
    /// The answer for the inputs as set, without committing.
    fn answer(&self) -> Answer {
        match &self.inverse {
            Some(inv) => inv.evaluate(self.r, &self.estimate),
            None => BacklashInverse::new(self.smoothing)
                .unwrap_or_else(|_| BacklashInverse::exact())
                .evaluate(self.r, &self.estimate),
        }
    }
}

impl Model for CompensatorFmu {
    type Var = Var;
    const MODEL_IDENTIFIER: &'static str = md::MODEL_IDENTIFIER;
    const GUID: &'static str = md::GUID;
    const LOG_CATEGORIES: &'static [&'static str] = md::LOG_CATEGORIES;
    const VARIABLES: &'static [VarInfo] = &md::VARIABLES;
    /// A sample is a few comparisons; the plant's bound on the work one step may hold the importer for.
    const MAX_SAMPLES_PER_STEP: u64 = 1_000_000;

    fn var(index: usize) -> Var {
        Var::ALL[index]
    }

    fn new() -> Self {
        Self {
            ts: 1.0,
            smoothing: 0.0,
            r: 0.0,
            estimate: BacklashParams {
                m1: 1.0,
                m2: 1.0,
                c1: 0.0,
                c2: 0.0,
            },
            inverse: None,
            committed: 0,
        }
    }

    fn get(&self, var: Var) -> Value {
        let e = &self.estimate;
        match var {
            Var::Ts => Value::Real(self.ts),
            Var::R => Value::Real(self.r),
            Var::M1 => Value::Real(e.m1),
            Var::M2 => Value::Real(e.m2),
            Var::C1 => Value::Real(e.c1),
            Var::C2 => Value::Real(e.c2),
            Var::Smoothing => Value::Real(self.smoothing),
            Var::V => Value::Real(self.answer().v),
            Var::W => Value::Real(self.answer().w),
            Var::Degenerate => Value::Boolean(self.answer().degenerate.is_some()),
        }
    }

    fn set(&mut self, var: Var, value: Value) {
        let e = &mut self.estimate;
        match var {
            Var::Ts => self.ts = value.as_real(),
            Var::R => self.r = value.as_real(),
            Var::M1 => e.m1 = value.as_real(),
            Var::M2 => e.m2 = value.as_real(),
            Var::C1 => e.c1 = value.as_real(),
            Var::C2 => e.c2 = value.as_real(),
            Var::Smoothing => self.smoothing = value.as_real(),
            // Outputs: the layer refuses to set them before calling here.
            Var::V | Var::W | Var::Degenerate => {}
        }
    }

    fn exit_initialization(&mut self) -> Result<(), String> {
        let inv = BacklashInverse::new(self.smoothing).map_err(|e| e.to_string())?;
        self.inverse = Some(inv);
        Ok(())
    }

    fn sample_period(&self) -> f64 {
        self.ts
    }

    fn step(&mut self, n: u64) -> Result<(), String> {
        let inv = self.inverse.as_mut().ok_or(
            "the compensator is not initialised (fmi2ExitInitializationMode was not called)",
        )?;
        for _ in 0..n {
            inv.commit(self.r, &self.estimate);
        }
        self.committed += n;
        Ok(())
    }

    fn samples(&self) -> Option<u64> {
        self.inverse.as_ref().map(|_| self.committed)
    }

    fn warning(&self) -> Option<String> {
        self.answer().degenerate.map(|d| d.to_string())
    }

    fn check_restored(&self) -> Result<(), String> {
        let e = &self.estimate;
        let ts_ok = self.ts.is_finite() && self.ts > 0.0;
        let finite = [self.r, e.m1, e.m2, e.c1, e.c2, self.smoothing]
            .iter()
            .all(|x| x.is_finite());
        if !ts_ok || !finite {
            return Err("Ts, smoothing or an input is not valid".into());
        }
        match &self.inverse {
            None => Ok(()),
            Some(inv) if inv.smoothing() != self.smoothing => {
                Err("the compensator's smoothing differs from the parameter smoothing".into())
            }
            Some(inv) => inv.check(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::fmu_state;
    use crate::fmi::state::State;
    use crate::fmi::timing::LayerState;
    use crate::fmi::vars::input_indices;

    fn at(r: f64, fmu: &mut CompensatorFmu) -> f64 {
        fmu.set(Var::R, Value::Real(r));
        let v = fmu.get(Var::V).as_real();
        fmu.step(1).unwrap();
        v
    }

    /// v depends directly on r; the step commits the direction memory (paper borders: up v = r + 0.5).
    #[test]
    fn v_follows_the_inputs_and_the_step_commits() {
        let mut fmu = CompensatorFmu::new();
        let p = BacklashParams::PAPER;
        for (var, x) in [(Var::M2, p.m2), (Var::C1, p.c1), (Var::C2, p.c2)] {
            fmu.set(var, Value::Real(x));
        }
        fmu.exit_initialization().unwrap();
        assert_eq!(at(1.0, &mut fmu), 1.5);
        // Held reference: v holds.
        assert_eq!(at(1.0, &mut fmu), 1.5);
        assert!((at(0.3, &mut fmu) - (0.3 / 1.5 - 1.0)).abs() < 1e-12);
        assert_eq!(fmu.warning(), None);
        fmu.set(Var::M2, Value::Real(-1.0));
        assert_eq!(fmu.get(Var::Degenerate), Value::Boolean(true));
        let w = fmu.warning().unwrap();
        assert!(w.contains("m2 = -1 is not a positive number"), "{w}");
        assert!(fmu.get(Var::V).as_real().is_finite());
    }

    /// A restored state is checked: an initialised compensator's own state passes; a sample time of zero or
    /// below, or a non-finite one, is refused.
    #[test]
    fn a_restored_state_needs_a_positive_sample_time() {
        let mut fmu = CompensatorFmu::new();
        fmu.exit_initialization().unwrap();
        assert_eq!(fmu.check_restored(), Ok(()));
        for ts in [0.0, -0.01, f64::NAN, f64::INFINITY] {
            let mut forged = CompensatorFmu::new();
            forged.exit_initialization().unwrap();
            forged.ts = ts;
            let e = forged.check_restored().unwrap_err();
            assert!(e.contains("Ts"), "{ts}: {e}");
        }
    }

    /// A restored initialised compensator whose inverse's smoothing is not the parameter smoothing (as no run
    /// leaves it: the parameter is fixed once the inverse is built) is refused.
    #[test]
    fn a_restored_inverse_must_have_the_parameter_smoothing() {
        let mut fmu = CompensatorFmu::new();
        fmu.exit_initialization().unwrap();
        fmu.smoothing = 0.5;
        let e = fmu.check_restored().unwrap_err();
        assert!(e.contains("smoothing differs"), "{e}");
    }

    /// The committed count is the model's sample count an FMU state is checked against: a compensator's
    /// state saves and restores before initialisation (no count) and after three samples (count 3, the
    /// layer at t_3), and the count survives the round trip.
    #[test]
    fn a_state_restores_with_its_sample_count() {
        let restored = |fmu: &CompensatorFmu, layer: &LayerState| {
            let bytes = fmu_state::save(fmu, layer).unwrap();
            fmu_state::parse::<CompensatorFmu>(&bytes)
                .unwrap()
                .1
                .samples()
        };
        let mut fmu = CompensatorFmu::new();
        let mut layer = LayerState::new(input_indices(&md::VARIABLES).len());
        assert_eq!(fmu.samples(), None);
        assert_eq!(restored(&fmu, &layer), None);
        fmu.exit_initialization().unwrap();
        fmu.step(3).unwrap();
        (layer.state, layer.samples, layer.time) = (State::StepComplete, 3, 3.0);
        assert_eq!(restored(&fmu, &layer), Some(3));
    }

    #[test]
    fn a_negative_smoothing_is_refused_at_initialisation() {
        let mut fmu = CompensatorFmu::new();
        fmu.smoothing = -1.0;
        let e = fmu.exit_initialization().unwrap_err();
        assert!(e.contains("smoothing width -1"), "{e}");
    }
}
