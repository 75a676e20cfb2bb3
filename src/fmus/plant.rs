//! BacklashPlant.fmu: the plant of `crate::plant` behind the FMI layer.

use super::backlash_plant::{self as md, Var};
use crate::fmi::Model;
use crate::fmi::vars::{Value, VarInfo};
use crate::plant::effects::{
    ColouredNoise, CurvedBorders, DeadZone, DirectionDependent, Effects, Friction, FrictionForm,
    GapDrift, Periodic, PolynomialFeedback, Quantization, Saturation,
};
use crate::plant::{
    MAX_ORDER, Plant, PlantExtensions, PlantOutput, PlantParams, PolyBacklashParams,
    TransferFunction,
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
    /// The test-bench effects as set (`crate::plant::effects`), in the FMU's units (per second, rad/s).
    bench: Bench,
    u: f64,
    plant: Option<Plant>,
}

/// The test-bench parameters of the FMU. Each effect is off at its default: zero rates, straight curves,
/// `friction = 0`, zero amplitude, `noise_phi = 0`, `saturation = 0`, `quant_step = 0`,
/// `dead_zone = 0`, `feedback2 = feedback3 = 0` (`feedback_lag2` alone switches nothing on).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct Bench {
    c_rate: [f64; 2],
    /// curve_up2, curve_up3, curve_down2, curve_down3.
    curve: [f64; 4],
    friction: i32,
    k_e: f64,
    f_plus: f64,
    f_minus: f64,
    dist: [f64; 3],
    noise_phi: f64,
    saturation: i32,
    sat: [f64; 2],
    quant: [f64; 2],
    direction_dependent: i32,
    /// a1_fall..a4_fall.
    fall_a: [f64; MAX_ORDER],
    /// b0_fall..b4_fall.
    fall_b: [f64; MAX_ORDER + 1],
    /// Width of the input dead zone (0: off).
    #[serde(default)]
    dead_zone: f64,
    /// feedback2, feedback3, feedback_lag2: polynomial feedback of x(k-1) and x(k-2) in the ARX block
    /// (feedback2 and feedback3 both 0: off).
    #[serde(default)]
    feedback: [f64; 3],
}

impl Bench {
    const OFF: Self = Self {
        c_rate: [0.0; 2],
        curve: [0.0; 4],
        friction: 0,
        k_e: 1.0,
        f_plus: 1.0,
        f_minus: 1.0,
        dist: [0.0; 3],
        noise_phi: 0.0,
        saturation: 0,
        sat: [-1.0, 1.0],
        quant: [0.0; 2],
        direction_dependent: 0,
        fall_a: [0.0; MAX_ORDER],
        fall_b: [0.0; MAX_ORDER + 1],
        dead_zone: 0.0,
        feedback: [0.0; 3],
    };

    /// The library's effects, with rates and frequencies per sample of period `ts`. The layer has checked
    /// each value against the XML's min/max (which hold k_e > 0 and |noise_phi| < 1) and refused NaN, so
    /// plain comparisons suffice; what the XML cannot say (sat_lo <= sat_hi) is checked here, with the FMU's
    /// names.
    fn effects(&self, ts: f64) -> Result<Effects, String> {
        let e = Effects {
            direction_dependent: self.direction_dependent_effect()?,
            polynomial_feedback: (self.feedback[..2] != [0.0; 2]).then_some(PolynomialFeedback {
                quadratic: self.feedback[0],
                cubic: self.feedback[1],
                lag2: self.feedback[2],
            }),
            gap_drift: (self.c_rate != [0.0; 2]).then(|| GapDrift {
                c1_rate: self.c_rate[0] * ts,
                c2_rate: self.c_rate[1] * ts,
            }),
            curved_borders: (self.curve != [0.0; 4]).then(|| CurvedBorders {
                upper: [self.curve[0], self.curve[1]],
                lower: [self.curve[2], self.curve[3]],
            }),
            friction: self.friction_effect()?,
            periodic: (self.dist[0] != 0.0).then(|| Periodic {
                amplitude: self.dist[0],
                omega: self.dist[1] * ts,
                phase: self.dist[2],
            }),
            coloured_noise: (self.noise_phi != 0.0).then_some(ColouredNoise {
                phi: self.noise_phi,
            }),
            saturation: self.saturation_effect()?,
            dead_zone: (self.dead_zone != 0.0).then_some(DeadZone {
                width: self.dead_zone,
            }),
            quantization: (self.quant[0] != 0.0).then(|| Quantization {
                step: self.quant[0],
                offset: self.quant[1],
            }),
        };
        e.validate().map_err(|err| err.to_string())?;
        Ok(e)
    }

    /// The switch `direction_dependent` (0 off, 1 on with the falling block `fall_a`, `fall_b`).
    fn direction_dependent_effect(&self) -> Result<Option<DirectionDependent>, String> {
        match self.direction_dependent {
            0 => Ok(None),
            1 => Ok(Some(DirectionDependent {
                a: self.fall_a,
                b: self.fall_b,
                offset: 0.0,
            })),
            v => Err(invalid(
                "direction_dependent",
                v as f64,
                "must be 0 (off) or 1 (on)",
            )),
        }
    }

    /// The switch `friction` (0 off, 1 series, 2 contact) with its parameters.
    fn friction_effect(&self) -> Result<Option<Friction>, String> {
        let form = match self.friction {
            0 => return Ok(None),
            1 => FrictionForm::Series,
            2 => FrictionForm::Contact,
            v => {
                return Err(invalid(
                    "friction",
                    v as f64,
                    "must be 0 (off), 1 (series) or 2 (contact)",
                ));
            }
        };
        Ok(Some(Friction {
            k_e: self.k_e,
            f_plus: self.f_plus,
            f_minus: self.f_minus,
            form,
        }))
    }

    /// The switch `saturation` (0 off, 1 sensor range, 2 end stop) with its limits `sat_lo <= sat_hi`.
    fn saturation_effect(&self) -> Result<Option<Saturation>, String> {
        let before_noise = match self.saturation {
            0 => return Ok(None),
            1 => false,
            2 => true,
            v => {
                return Err(invalid(
                    "saturation",
                    v as f64,
                    "must be 0 (off), 1 (sensor range) or 2 (end stop)",
                ));
            }
        };
        if self.sat[0] > self.sat[1] {
            return Err(invalid("sat_lo", self.sat[0], "must not exceed sat_hi"));
        }
        Ok(Some(Saturation {
            lo: self.sat[0],
            hi: self.sat[1],
            before_noise,
        }))
    }
}

/// The message for a parameter the XML's bounds let through but the plant refuses.
fn invalid(name: &str, v: f64, why: &str) -> String {
    format!("parameter {name} = {v} is invalid: {why}")
}

impl PlantFmu {
    /// The plant, once initialised: what `backlash::api::PlantSpec` simulates (the FMU's parameters by name).
    pub fn plant(&self) -> Option<&Plant> {
        self.plant.as_ref()
    }

    /// Parameters in the plant's types, or the name of the one that is out of range.
    fn plant_params(&self) -> Result<PlantParams, String> {
        let mut p = self.params;
        let order = |name: &str, v: i32| {
            usize::try_from(v)
                .map_err(|_| format!("parameter {name} = {v} is invalid: must not be negative"))
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
        if self.border != 0 {
            let b = &self.bench;
            let straight_only = [
                ("c1_rate, c2_rate (gap drift)", b.c_rate != [0.0; 2]),
                (
                    "curve_up2 .. curve_down3 (curved borders)",
                    b.curve != [0.0; 4],
                ),
                ("friction = 2 (contact friction)", b.friction == 2),
            ];
            if let Some((what, _)) = straight_only.iter().find(|(_, on)| *on) {
                return Err(format!(
                    "parameters {what} act on the straight borders m1, m2, c1, c2 and cannot be used with \
                     border = 1 (polynomial borders)"
                ));
            }
        }
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
            effects: self.bench.effects(self.ts)?,
        })
    }

    /// The plant these parameters describe.
    fn build(&self) -> Result<Plant, String> {
        Plant::with_extensions(self.plant_params()?, &self.extensions()?).map_err(|e| e.to_string())
    }

    /// The outputs: those of the running plant, or in initialization mode those it will start with.
    /// A gap (`var` c1 or c2), tunable: a running plant takes it from its next sample on. The layer has checked
    /// the value (finite, >= 0), so the plant cannot refuse it.
    fn set_gap(&mut self, var: Var, x: f64) {
        let gaps = &mut self.params.backlash;
        if var == Var::C1 {
            gaps.c1 = x;
        } else {
            gaps.c2 = x;
        }
        if let Some(plant) = &mut self.plant {
            let accepted = plant.set_backlash(self.params.backlash);
            debug_assert!(accepted.is_ok());
        }
    }

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
                    f: 0.0,
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
    /// 1e6 samples (milliseconds of work): a longer step, e.g. Ts = 1e-9 s with a step of 1000 s, would hold
    /// the importer's thread for hours inside one fmi2DoStep; the layer cuts it there with fmi2Discard.
    const MAX_SAMPLES_PER_STEP: u64 = 1_000_000;

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
            bench: Bench::OFF,
            u: 0.0,
            plant: None,
        }
    }

    fn get(&self, var: Var) -> Value {
        let p = &self.params;
        let b = &self.bench;
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
            Var::F => r(self.output().f),
            Var::C1Rate => r(b.c_rate[0]),
            Var::C2Rate => r(b.c_rate[1]),
            Var::CurveUp2 => r(b.curve[0]),
            Var::CurveUp3 => r(b.curve[1]),
            Var::CurveDown2 => r(b.curve[2]),
            Var::CurveDown3 => r(b.curve[3]),
            Var::Friction => Value::Integer(b.friction),
            Var::KE => r(b.k_e),
            Var::FPlus => r(b.f_plus),
            Var::FMinus => r(b.f_minus),
            Var::DistAmplitude => r(b.dist[0]),
            Var::DistOmega => r(b.dist[1]),
            Var::DistPhase => r(b.dist[2]),
            Var::NoisePhi => r(b.noise_phi),
            Var::Saturation => Value::Integer(b.saturation),
            Var::SatLo => r(b.sat[0]),
            Var::SatHi => r(b.sat[1]),
            Var::QuantStep => r(b.quant[0]),
            Var::QuantOffset => r(b.quant[1]),
            Var::DirectionDependent => Value::Integer(b.direction_dependent),
            Var::A1Fall => r(b.fall_a[0]),
            Var::A2Fall => r(b.fall_a[1]),
            Var::A3Fall => r(b.fall_a[2]),
            Var::A4Fall => r(b.fall_a[3]),
            Var::B0Fall => r(b.fall_b[0]),
            Var::B1Fall => r(b.fall_b[1]),
            Var::B2Fall => r(b.fall_b[2]),
            Var::B3Fall => r(b.fall_b[3]),
            Var::B4Fall => r(b.fall_b[4]),
            Var::DeadZone => r(b.dead_zone),
            Var::Feedback2 => r(b.feedback[0]),
            Var::Feedback3 => r(b.feedback[1]),
            Var::FeedbackLag2 => r(b.feedback[2]),
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
            Var::C1 | Var::C2 => self.set_gap(var, x),
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
            Var::C1Rate => self.bench.c_rate[0] = x,
            Var::C2Rate => self.bench.c_rate[1] = x,
            Var::CurveUp2 => self.bench.curve[0] = x,
            Var::CurveUp3 => self.bench.curve[1] = x,
            Var::CurveDown2 => self.bench.curve[2] = x,
            Var::CurveDown3 => self.bench.curve[3] = x,
            Var::Friction => self.bench.friction = value.as_integer(),
            Var::KE => self.bench.k_e = x,
            Var::FPlus => self.bench.f_plus = x,
            Var::FMinus => self.bench.f_minus = x,
            Var::DistAmplitude => self.bench.dist[0] = x,
            Var::DistOmega => self.bench.dist[1] = x,
            Var::DistPhase => self.bench.dist[2] = x,
            Var::NoisePhi => self.bench.noise_phi = x,
            Var::Saturation => self.bench.saturation = value.as_integer(),
            Var::SatLo => self.bench.sat[0] = x,
            Var::SatHi => self.bench.sat[1] = x,
            Var::QuantStep => self.bench.quant[0] = x,
            Var::QuantOffset => self.bench.quant[1] = x,
            Var::DirectionDependent => self.bench.direction_dependent = value.as_integer(),
            Var::A1Fall => self.bench.fall_a[0] = x,
            Var::A2Fall => self.bench.fall_a[1] = x,
            Var::A3Fall => self.bench.fall_a[2] = x,
            Var::A4Fall => self.bench.fall_a[3] = x,
            Var::B0Fall => self.bench.fall_b[0] = x,
            Var::B1Fall => self.bench.fall_b[1] = x,
            Var::B2Fall => self.bench.fall_b[2] = x,
            Var::B3Fall => self.bench.fall_b[3] = x,
            Var::B4Fall => self.bench.fall_b[4] = x,
            Var::DeadZone => self.bench.dead_zone = x,
            Var::Feedback2 => self.bench.feedback[0] = x,
            Var::Feedback3 => self.bench.feedback[1] = x,
            Var::FeedbackLag2 => self.bench.feedback[2] = x,
            // Outputs: the layer refuses to set them before calling here.
            Var::Y | Var::W | Var::X | Var::F => {}
        }
    }

    fn exit_initialization(&mut self) -> Result<(), String> {
        self.plant = Some(self.build()?);
        Ok(())
    }

    fn sample_period(&self) -> f64 {
        self.ts
    }

    fn samples(&self) -> Option<u64> {
        self.plant.as_ref().map(Plant::sample)
    }

    fn check_restored(&self) -> Result<(), String> {
        let ts_ok = self.ts.is_finite() && self.ts > 0.0;
        if !ts_ok || !self.u.is_finite() {
            return Err("Ts or u is not valid".into());
        }
        match &self.plant {
            // Not initialised yet: parameters are checked at fmi2ExitInitializationMode.
            None => Ok(()),
            Some(p) => {
                p.check()?;
                // The running plant's parameters are those its FMU's parameters build (set_gap keeps the
                // tunable gaps in step), or the getters would report another plant than the one running.
                if self.build()?.params() != p.params() {
                    return Err(
                        "the plant's parameters (the gaps c1, c2, the ARX block, m, the noise) \
                         differ from the FMU's parameters"
                            .into(),
                    );
                }
                Ok(())
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// feedback2 and feedback3 switch the polynomial feedback on (either non-zero) with their values and
    /// feedback_lag2's, as the FMU reads them back; feedback_lag2 alone switches nothing on; on the
    /// continuous block the feedback is refused by name at initialisation.
    #[test]
    fn polynomial_feedback_parameters_reach_the_plant() {
        let mut fmu = PlantFmu::new();
        fmu.set(Var::FeedbackLag2, Value::Real(0.8));
        assert_eq!(fmu.get(Var::FeedbackLag2), Value::Real(0.8));
        assert_eq!(fmu.bench.effects(1.0).unwrap().polynomial_feedback, None);
        fmu.set(Var::Feedback3, Value::Real(-0.05));
        assert_eq!(fmu.get(Var::Feedback3), Value::Real(-0.05));
        assert_eq!(
            fmu.bench.effects(1.0).unwrap().polynomial_feedback,
            Some(PolynomialFeedback {
                quadratic: 0.0,
                cubic: -0.05,
                lag2: 0.8
            })
        );
        fmu.set(Var::Feedback2, Value::Real(0.01));
        assert_eq!(fmu.get(Var::Feedback2), Value::Real(0.01));
        assert_eq!(fmu.exit_initialization(), Ok(()));
        let mut cont = PlantFmu::new();
        cont.set(Var::Feedback3, Value::Real(-0.05));
        cont.set(Var::Linear, Value::Integer(1));
        cont.set(Var::Num0, Value::Real(1.0));
        cont.set(Var::Den0, Value::Real(1.0));
        cont.set(Var::Den1, Value::Real(1.0));
        let err = cont.exit_initialization().unwrap_err();
        assert!(err.contains("polynomial feedback"), "{err}");
    }

    /// The saturation's limits may meet (a constant output) but not cross: sat_lo above sat_hi is refused
    /// at initialisation by name, with either switch on; off, the limits are not looked at.
    #[test]
    fn saturation_limits_may_meet_but_not_cross() {
        let init = |switch: i32, lo: f64, hi: f64| {
            let mut fmu = PlantFmu::new();
            fmu.set(Var::Saturation, Value::Integer(switch));
            fmu.set(Var::SatLo, Value::Real(lo));
            fmu.set(Var::SatHi, Value::Real(hi));
            fmu.exit_initialization()
        };
        for switch in [1, 2] {
            assert_eq!(init(switch, 0.5, 0.5), Ok(()));
            assert_eq!(init(switch, -1.0, 1.0), Ok(()));
            let err = init(switch, 0.6, 0.5).unwrap_err();
            assert!(
                err.contains("sat_lo") && err.contains("must not exceed sat_hi"),
                "{err}"
            );
        }
        assert_eq!(init(0, 0.6, 0.5), Ok(()));
    }
}
