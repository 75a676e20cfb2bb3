//! BacklashPlant.fmu: the plant of `crate::plant` behind the FMI layer.

use super::backlash_plant::{self as md, Var};
use crate::fmi2::Model;
use crate::fmi2::vars::{Value, VarInfo};
use crate::plant::{
    Plant, PlantExtensions, PlantOutput, PlantParams, PolyBacklashParams, TransferFunction,
};
use serde::{Deserialize, Serialize};

/// Parameters as set, the input, and the plant once initialised.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PlantFmu {
    ts: f64,
    /// Orders as set (i32 so that an out-of-range value set by the importer is kept and refused by name).
    na: i32,
    nb: i32,
    delay: i32,
    noise_seed: i32,
    params: PlantParams,
    /// 0: straight borders; 1: polynomial borders `fa`, `fd` (lowest power first).
    border: i32,
    fa: [f64; 4],
    fd: [f64; 4],
    /// 0: ARX block; 1: continuous G(s) with `num`, `den` (coefficient of s^i at index i).
    linear: i32,
    num: [f64; 4],
    den: [f64; 5],
    u: f64,
    plant: Option<Plant>,
}

impl PlantFmu {
    /// Parameters in the plant's types, or the name of the one that is out of range.
    fn plant_params(&self) -> Result<PlantParams, String> {
        let mut p = self.params;
        let order = |name: &str, v: i32| {
            usize::try_from(v)
                .map_err(|_| format!("parameter {name} = {v} is invalid: must be >= 0"))
        };
        p.arx.na = order("na", self.na)?;
        p.arx.nb = order("nb", self.nb)?;
        p.arx.delay = order("delay", self.delay)?;
        p.noise_seed = u64::from(self.noise_seed as u32);
        p.validate().map_err(|e| e.to_string())?;
        Ok(p)
    }

    /// Paper 003's polynomial borders and continuous block, as selected by `border` and `linear`.
    fn extensions(&self) -> Result<PlantExtensions, String> {
        let borders = match self.border {
            0 => None,
            _ => Some(PolyBacklashParams::new(&self.fa, &self.fd).map_err(|e| e.to_string())?),
        };
        let continuous = match self.linear {
            0 => None,
            _ => {
                // The parameters list coefficients of s^0, s^1, ...; TransferFunction wants descending powers.
                let desc = |c: &[f64]| {
                    let top = c.iter().rposition(|v| *v != 0.0).map_or(0, |i| i + 1);
                    c[..top].iter().rev().copied().collect::<Vec<f64>>()
                };
                let tf = TransferFunction::new(&desc(&self.num), &desc(&self.den))
                    .map_err(|e| e.to_string())?;
                Some((tf, self.ts))
            }
        };
        Ok(PlantExtensions {
            borders,
            continuous,
        })
    }

    /// The plant these parameters describe.
    fn build(&self) -> Result<Plant, String> {
        Plant::with_extensions(self.plant_params()?, &self.extensions()?).map_err(|e| e.to_string())
    }

    /// The outputs: those of the running plant, or in initialization mode those it will start with.
    fn output(&self) -> PlantOutput {
        match &self.plant {
            Some(p) => p.output(),
            None => self
                .build()
                .ok()
                .map(|p| p.output())
                .unwrap_or(PlantOutput {
                    x: 0.0,
                    w: 0.0,
                    y: 0.0,
                    mode: crate::plant::Mode::Held,
                }),
        }
    }
}

impl Model for PlantFmu {
    type Var = Var;
    const MODEL_IDENTIFIER: &'static str = md::MODEL_IDENTIFIER;
    const GUID: &'static str = md::GUID;
    const LOG_CATEGORIES: &'static [&'static str] = md::LOG_CATEGORIES;
    const VARIABLES: &'static [VarInfo] = &md::VARIABLES;
    /// 1e8 samples (seconds of work at the plant's rate): a longer step, e.g. Ts = 1e-9 s with a step of
    /// 1000 s, would hold the importer's thread for hours inside one fmi2DoStep.
    const MAX_SAMPLES_PER_STEP: Option<u64> = Some(100_000_000);

    fn var(index: usize) -> Var {
        Var::ALL[index]
    }

    fn new() -> Self {
        Self {
            ts: 1.0,
            na: 0,
            nb: 0,
            delay: 1,
            noise_seed: 0,
            params: PlantParams::PAPER,
            border: 0,
            fa: [0.0; 4],
            fd: [0.0; 4],
            linear: 0,
            num: [0.0; 4],
            den: [0.0; 5],
            u: 0.0,
            plant: None,
        }
    }

    fn get(&self, var: Var) -> Value {
        let p = &self.params;
        let r = Value::Real;
        match var {
            Var::Ts => r(self.ts),
            Var::U => r(self.u),
            Var::Y => r(self.output().y),
            Var::W => r(self.output().w),
            Var::X => r(self.output().x),
            Var::Na => Value::Integer(self.na),
            Var::Nb => Value::Integer(self.nb),
            Var::Delay => Value::Integer(self.delay),
            Var::NoiseSeed => Value::Integer(self.noise_seed),
            Var::A1 => r(p.arx.a[0]),
            Var::A2 => r(p.arx.a[1]),
            Var::A3 => r(p.arx.a[2]),
            Var::A4 => r(p.arx.a[3]),
            Var::B0 => r(p.arx.b[0]),
            Var::B1 => r(p.arx.b[1]),
            Var::B2 => r(p.arx.b[2]),
            Var::B3 => r(p.arx.b[3]),
            Var::B4 => r(p.arx.b[4]),
            Var::M1 => r(p.backlash.m1),
            Var::M2 => r(p.backlash.m2),
            Var::C1 => r(p.backlash.c1),
            Var::C2 => r(p.backlash.c2),
            Var::NoiseStd => r(p.noise_std),
            Var::Border => Value::Integer(self.border),
            Var::Fa0 => r(self.fa[0]),
            Var::Fa1 => r(self.fa[1]),
            Var::Fa2 => r(self.fa[2]),
            Var::Fa3 => r(self.fa[3]),
            Var::Fd0 => r(self.fd[0]),
            Var::Fd1 => r(self.fd[1]),
            Var::Fd2 => r(self.fd[2]),
            Var::Fd3 => r(self.fd[3]),
            Var::Linear => Value::Integer(self.linear),
            Var::Num0 => r(self.num[0]),
            Var::Num1 => r(self.num[1]),
            Var::Num2 => r(self.num[2]),
            Var::Num3 => r(self.num[3]),
            Var::Den0 => r(self.den[0]),
            Var::Den1 => r(self.den[1]),
            Var::Den2 => r(self.den[2]),
            Var::Den3 => r(self.den[3]),
            Var::Den4 => r(self.den[4]),
        }
    }

    fn set(&mut self, var: Var, value: Value) {
        let x = value.as_real();
        let p = &mut self.params;
        match var {
            Var::Ts => self.ts = x,
            Var::U => self.u = x,
            Var::Na => self.na = value.as_integer(),
            Var::Nb => self.nb = value.as_integer(),
            Var::Delay => self.delay = value.as_integer(),
            Var::NoiseSeed => self.noise_seed = value.as_integer(),
            Var::A1 => p.arx.a[0] = x,
            Var::A2 => p.arx.a[1] = x,
            Var::A3 => p.arx.a[2] = x,
            Var::A4 => p.arx.a[3] = x,
            Var::B0 => p.arx.b[0] = x,
            Var::B1 => p.arx.b[1] = x,
            Var::B2 => p.arx.b[2] = x,
            Var::B3 => p.arx.b[3] = x,
            Var::B4 => p.arx.b[4] = x,
            Var::M1 => p.backlash.m1 = x,
            Var::M2 => p.backlash.m2 = x,
            Var::C1 | Var::C2 => {
                if var == Var::C1 {
                    p.backlash.c1 = x;
                } else {
                    p.backlash.c2 = x;
                }
                // Tunable: a running plant takes the new gap from its next sample on. The layer has checked
                // the value (finite, >= 0), so the plant cannot refuse it.
                if let Some(plant) = &mut self.plant {
                    let accepted = plant.set_backlash(p.backlash);
                    debug_assert!(accepted.is_ok());
                }
            }
            Var::NoiseStd => p.noise_std = x,
            Var::Border => self.border = value.as_integer(),
            Var::Fa0 => self.fa[0] = x,
            Var::Fa1 => self.fa[1] = x,
            Var::Fa2 => self.fa[2] = x,
            Var::Fa3 => self.fa[3] = x,
            Var::Fd0 => self.fd[0] = x,
            Var::Fd1 => self.fd[1] = x,
            Var::Fd2 => self.fd[2] = x,
            Var::Fd3 => self.fd[3] = x,
            Var::Linear => self.linear = value.as_integer(),
            Var::Num0 => self.num[0] = x,
            Var::Num1 => self.num[1] = x,
            Var::Num2 => self.num[2] = x,
            Var::Num3 => self.num[3] = x,
            Var::Den0 => self.den[0] = x,
            Var::Den1 => self.den[1] = x,
            Var::Den2 => self.den[2] = x,
            Var::Den3 => self.den[3] = x,
            Var::Den4 => self.den[4] = x,
            // Outputs: the layer refuses to set them before calling here.
            Var::Y | Var::W | Var::X => {}
        }
    }

    fn exit_initialization(&mut self) -> Result<(), String> {
        self.plant = Some(self.build()?);
        Ok(())
    }

    fn sample_period(&self) -> f64 {
        self.ts
    }

    fn check_restored(&self) -> Result<(), String> {
        let ts_ok = self.ts.is_finite() && self.ts > 0.0;
        if !ts_ok || !self.u.is_finite() {
            return Err("Ts or u is not valid".into());
        }
        match &self.plant {
            // Not initialised yet: parameters are checked at fmi2ExitInitializationMode.
            None => Ok(()),
            Some(p) => p.check(),
        }
    }

    fn step(&mut self, n: u64) -> Result<(), String> {
        let plant = self
            .plant
            .as_mut()
            .ok_or("the plant is not initialised (fmi2ExitInitializationMode was not called)")?;
        for _ in 0..n {
            plant.advance(self.u);
        }
        Ok(())
    }
}
