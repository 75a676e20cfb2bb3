//! The physics: the pseudo-Wiener plant of paper 000 (linear block -> backlash -> sensor).
//!
//! Nothing here knows about FMI. The FMU adapter in `crate::fmus` and the command line both drive [`Plant`].
//!
//! Timing, as in the project's contract: the plant is at sample k with outputs x(k), w(k), y(k), which depend
//! on inputs up to u(k - delay) only; [`Plant::advance`] takes u(k) and moves to sample k + 1. All signals are
//! zero before k = 0, so x(0) = 0 and w(0) = 0.

pub mod backlash;
pub mod continuous;
pub mod effects;
pub mod linear;
pub mod poly;

pub use backlash::{BacklashParams, Mode};
pub use continuous::{ContinuousLinear, TransferFunction};
pub use effects::{Effects, EffectsState};
pub use linear::{Arx, ArxParams, MAX_DELAY, MAX_ORDER};
pub use poly::{PolyBacklash, PolyBacklashParams};

use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// A parameter that is out of its range, with the reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("parameter {name} = {value} is invalid: {reason}")]
pub struct ParamError {
    pub name: String,
    pub value: f64,
    pub reason: &'static str,
}

impl ParamError {
    pub fn new(name: impl Into<String>, value: f64, reason: &'static str) -> Self {
        Self {
            name: name.into(),
            value,
            reason,
        }
    }
}

/// Check helpers shared by the plant and the estimators.
pub(crate) fn check_finite(name: &str, v: f64) -> Result<(), ParamError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ParamError::new(name, v, "must be a finite number"))
    }
}

pub(crate) fn check_positive(name: &str, v: f64) -> Result<(), ParamError> {
    check_finite(name, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(ParamError::new(name, v, "must be positive"))
    }
}

pub(crate) fn check_non_negative(name: &str, v: f64) -> Result<(), ParamError> {
    check_finite(name, v)?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(ParamError::new(name, v, "must not be negative"))
    }
}

// The range messages below spell these bounds out in words; they change together.
const _: () = assert!(MAX_ORDER == 4 && MAX_DELAY == 64);

/// An order (`na`, `nb`, or a degree) between 0 and [`MAX_ORDER`].
pub(crate) fn check_order(name: &str, n: usize) -> Result<(), ParamError> {
    if n <= MAX_ORDER {
        Ok(())
    } else {
        Err(ParamError::new(name, n as f64, "must be between 0 and 4"))
    }
}

/// A delay in samples between 1 and [`MAX_DELAY`].
pub(crate) fn check_delay(delay: usize) -> Result<(), ParamError> {
    if (1..=MAX_DELAY).contains(&delay) {
        Ok(())
    } else {
        Err(ParamError::new(
            "delay",
            delay as f64,
            "must be between 1 and 64 samples",
        ))
    }
}

/// The structure of an ARX block: both orders and the delay in range.
pub(crate) fn check_structure(na: usize, nb: usize, delay: usize) -> Result<(), ParamError> {
    check_order("na", na)?;
    check_order("nb", nb)?;
    check_delay(delay)
}

impl ArxParams {
    /// Orders in range, delay >= 1, finite coefficients.
    pub fn validate(&self) -> Result<(), ParamError> {
        check_structure(self.na, self.nb, self.delay)?;
        for (i, a) in self.a.iter().enumerate() {
            check_finite(&format!("a{}", i + 1), *a)?;
        }
        for (j, b) in self.b.iter().enumerate() {
            check_finite(&format!("b{j}"), *b)?;
        }
        Ok(())
    }
}

impl BacklashParams {
    /// Slopes > 0 and gaps >= 0 (a zero gap is a legal, if degenerate, backlash).
    pub fn validate(&self) -> Result<(), ParamError> {
        check_positive("m1", self.m1)?;
        check_positive("m2", self.m2)?;
        check_non_negative("c1", self.c1)?;
        check_non_negative("c2", self.c2)
    }
}

/// Everything that defines a plant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlantParams {
    pub arx: ArxParams,
    pub backlash: BacklashParams,
    /// Standard deviation of the white Gaussian measurement noise added to w to give y.
    pub noise_std: f64,
    /// Seed of the noise generator (ChaCha8); the same seed gives the same noise sequence.
    pub noise_seed: u64,
}

impl PlantParams {
    /// Paper 000, section 4, noise-free.
    pub const PAPER: Self = Self {
        arx: ArxParams::PAPER,
        backlash: BacklashParams::PAPER,
        noise_std: 0.0,
        noise_seed: 0,
    };

    pub fn validate(&self) -> Result<(), ParamError> {
        self.arx.validate()?;
        self.backlash.validate()?;
        check_non_negative("noise_std", self.noise_std)
    }
}

/// The plant's signals at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PlantOutput {
    /// Linear block output.
    pub x: f64,
    /// Backlash output (noise-free); with contact friction ([`effects::FrictionForm::Contact`]) the slider
    /// position, the output of the play operator the slider follows.
    pub w: f64,
    /// Noise-free output after the friction element of the test-bench effects (= w without friction).
    pub f: f64,
    /// Measured output: f plus noise and the enabled sensor effects (without effects: w plus noise).
    pub y: f64,
    /// Regime of the backlash at this sample.
    pub mode: Mode,
}

/// What paper 003 adds to the plant of paper 000: a continuous-time linear block instead of the ARX block,
/// and polynomial borders instead of the straight ones. Kept apart from [`PlantParams`] (which stays the
/// paper 000 parameter set everyone constructs) so that the common case stays a small `Copy` struct.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PlantExtensions {
    /// Backlash bordered by polynomials f_a, f_d; replaces m1, m2, c1, c2 when set.
    pub borders: Option<PolyBacklashParams>,
    /// A strictly proper, stable G(s) sampled with period `ts` (input held between samples); replaces the
    /// ARX block when set. Strictly proper so that x(k) does not depend on u(k): the plant keeps no direct
    /// feedthrough, as the FMU's ModelStructure declares.
    pub continuous: Option<(TransferFunction, f64)>,
    /// The test-bench effects of the diagnosis catalogue ([`effects`]); all off by default. Gap drift,
    /// curved borders and contact friction act on the straight borders m1, m2, c1, c2 and are refused with
    /// polynomial borders; series friction and the sensor effects combine with anything.
    #[serde(default)]
    pub effects: Effects,
}

impl PlantExtensions {
    pub fn validate(&self) -> Result<(), ParamError> {
        if let Some(b) = &self.borders {
            b.validate()?;
        }
        self.effects.validate()?;
        if self.borders.is_some() {
            let e = &self.effects;
            let contact = e
                .friction
                .is_some_and(|f| f.form == effects::FrictionForm::Contact);
            let straight_only = [
                ("gap drift", e.gap_drift.is_some()),
                ("curved borders", e.curved_borders.is_some()),
                ("contact friction", contact),
            ];
            if let Some((name, _)) = straight_only.iter().find(|(_, on)| *on) {
                return Err(ParamError::new(
                    *name,
                    1.0,
                    "acts on the straight borders m1, m2, c1, c2 and cannot be combined with polynomial borders",
                ));
            }
        }
        if self.continuous.is_some() {
            let e = &self.effects;
            let arx_only = [
                (
                    "direction-dependent dynamics",
                    e.direction_dependent.is_some(),
                ),
                ("polynomial feedback", e.polynomial_feedback.is_some()),
            ];
            if let Some((name, _)) = arx_only.iter().find(|(_, on)| *on) {
                return Err(ParamError::new(
                    *name,
                    1.0,
                    "acts on the ARX block's coefficients and cannot be combined with a continuous transfer function",
                ));
            }
        }
        if let Some((tf, ts)) = &self.continuous {
            tf.validate()?;
            check_positive("Ts", *ts)?;
            let deg = |c: &[f64]| c.len() - c.iter().take_while(|v| **v == 0.0).count();
            if deg(&tf.num) >= deg(&tf.den) {
                return Err(ParamError::new(
                    "num",
                    deg(&tf.num) as f64 - 1.0,
                    "the transfer function must be strictly proper (numerator degree below the denominator's)",
                ));
            }
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Serialize, Deserialize)]
enum Linear {
    Arx(Arx),
    Continuous(ContinuousLinear),
}

impl Linear {
    fn peek(&self) -> f64 {
        match self {
            Linear::Arx(a) => a.peek(),
            // Strictly proper: D = 0, so the input at this instant does not enter.
            Linear::Continuous(c) => c.output(0.0),
        }
    }

    fn push(&mut self, u_k: f64, x_k: f64) {
        match self {
            Linear::Arx(a) => a.push(u_k, x_k),
            Linear::Continuous(c) => c.advance(u_k),
        }
    }
}

/// The falling set of a direction-dependent block must be stable on the block's own orders (a block that
/// falls forever is no plant).
fn check_falling_set(d: &effects::DirectionDependent, arx: &ArxParams) -> Result<(), ParamError> {
    if linear::is_stable(&d.a[..arx.na]) {
        Ok(())
    } else {
        Err(ParamError::new(
            "a1_fall",
            d.a[0],
            "the falling set a1_fall..a4_fall of the direction-dependent block must be stable (all roots inside the unit circle)",
        ))
    }
}

/// The plant with its state.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Plant {
    params: PlantParams,
    linear: Linear,
    poly: Option<PolyBacklash>,
    /// The test-bench effects; `None` when all are off, so that the plain plant runs its own short path.
    effects: Option<(Effects, EffectsState)>,
    rng: ChaCha8Rng,
    out: PlantOutput,
    k: u64,
}

impl Plant {
    /// A plant at sample 0 with zero history.
    pub fn new(params: PlantParams) -> Result<Self, ParamError> {
        Self::with_extensions(params, &PlantExtensions::default())
    }

    /// A plant with paper 003's continuous block and/or polynomial borders.
    pub fn with_extensions(params: PlantParams, ext: &PlantExtensions) -> Result<Self, ParamError> {
        params.validate()?;
        ext.validate()?;
        if let Some(d) = &ext.effects.direction_dependent {
            check_falling_set(d, &params.arx)?;
        }
        let linear = match &ext.continuous {
            Some((tf, ts)) => Linear::Continuous(ContinuousLinear::new(tf.clone(), *ts)?),
            None => Linear::Arx(Arx::new(params.arx)),
        };
        let poly = ext.borders.map(PolyBacklash::new).transpose()?;
        let effects =
            (ext.effects != Effects::default()).then(|| (ext.effects, EffectsState::default()));
        let mut p = Self {
            params,
            linear,
            poly,
            effects,
            rng: ChaCha8Rng::seed_from_u64(params.noise_seed),
            out: PlantOutput {
                x: 0.0,
                w: 0.0,
                f: 0.0,
                y: 0.0,
                mode: Mode::Held,
            },
            k: 0,
        };
        p.out = p.compute(0.0);
        Ok(p)
    }

    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// Change the straight-border backlash while running (wear: the gaps grow). The new borders act from the
    /// next sample on; the held output stays where it is. (Polynomial borders, when set, are not affected.)
    pub fn set_backlash(&mut self, backlash: BacklashParams) -> Result<(), ParamError> {
        backlash.validate()?;
        self.params.backlash = backlash;
        Ok(())
    }

    /// Internal consistency of a plant restored from outside (an FMU state): valid parameters, histories of
    /// the right length, finite signals. A forged or corrupted state is refused here rather than failing on
    /// the next step.
    pub fn check(&self) -> Result<(), String> {
        self.params.validate().map_err(|e| e.to_string())?;
        match &self.linear {
            Linear::Arx(a) => {
                a.check()?;
                if a.params != self.params.arx {
                    return Err("the ARX block's parameters differ from the plant's".into());
                }
            }
            Linear::Continuous(c) => {
                c.validate().map_err(|e| e.to_string())?;
                if c.state().iter().any(|v| !v.is_finite()) {
                    return Err("the continuous block's state is not finite".into());
                }
            }
        }
        if let Some(p) = &self.poly {
            p.validate().map_err(|e| e.to_string())?;
        }
        if let Some((e, st)) = &self.effects {
            e.validate().map_err(|e| e.to_string())?;
            if let Some(d) = &e.direction_dependent {
                check_falling_set(d, &self.params.arx).map_err(|e| e.to_string())?;
            }
            if ![st.w, st.f, st.n].iter().all(|v| v.is_finite()) {
                return Err("the effects' state is not finite".into());
            }
            if st.k != self.k + 1 {
                return Err("the effects' sample index differs from the plant's".into());
            }
        }
        let o = &self.out;
        if ![o.x, o.w, o.f, o.y].iter().all(|v| v.is_finite()) {
            return Err("the plant's outputs are not finite".into());
        }
        Ok(())
    }

    /// The outputs at the current sample.
    pub fn output(&self) -> PlantOutput {
        self.out
    }

    /// The current sample index.
    pub fn sample(&self) -> u64 {
        self.k
    }

    /// The linear block's output at this sample: the ARX block's, with the effects that act inside it (the
    /// falling set of a direction-dependent block, polynomial feedback of x(k-1), x(k-2)); the continuous
    /// block's.
    fn linear_output(&self) -> f64 {
        let (Linear::Arx(arx), Some((e, _))) = (&self.linear, &self.effects) else {
            return self.linear.peek();
        };
        let feedback = e
            .polynomial_feedback
            .map_or(0.0, |f| f.term(arx.output_ago(1), arx.output_ago(2)));
        let rise = arx.peek() + feedback;
        match &e.direction_dependent {
            Some(d) => {
                let p = &arx.params;
                let fall = arx.peek_with(&d.a[..p.na], &d.b[..=p.nb]) + d.offset + feedback;
                effects::DirectionDependent::choose(arx.last_output(), rise, fall)
            }
            None => rise,
        }
    }

    fn compute(&mut self, w_prev: f64) -> PlantOutput {
        let x = self.linear_output();
        if let Some((e, st)) = &mut self.effects {
            // One standard normal draw per sample when there is noise, as on the plain path, so that the same
            // seed gives the same noise sequence with and without effects.
            let z = if self.params.noise_std > 0.0 {
                StandardNormal.sample(&mut self.rng)
            } else {
                0.0
            };
            let o = st.step(&self.params, e, self.poly.as_mut(), x, z);
            return PlantOutput {
                x,
                w: o.w,
                f: o.f,
                y: o.y,
                mode: o.mode,
            };
        }
        let (w, mode) = match &mut self.poly {
            Some(poly) => {
                let w = poly.step(x);
                (w, poly.mode())
            }
            None => self.params.backlash.step(x, w_prev),
        };
        let noise = if self.params.noise_std > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            self.params.noise_std * z
        } else {
            0.0
        };
        PlantOutput {
            x,
            w,
            f: w,
            y: w + noise,
            mode,
        }
    }

    /// Take u(k) and move to sample k + 1.
    pub fn advance(&mut self, u_k: f64) {
        // The actuator's effects (a dead zone) act on the input before the linear block.
        let u_k = match &self.effects {
            Some((e, _)) => e.actuator(u_k),
            None => u_k,
        };
        self.linear.push(u_k, self.out.x);
        self.k += 1;
        self.out = self.compute(self.out.w);
    }

    /// Outputs at samples 0..u.len() for the input sequence u (output k is the plant's state before it reads u(k)).
    pub fn simulate(params: PlantParams, u: &[f64]) -> Result<Vec<PlantOutput>, ParamError> {
        let mut p = Self::new(params)?;
        Ok(u.iter()
            .map(|&uk| {
                let o = p.output();
                p.advance(uk);
                o
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn starts_at_zero_and_responds_after_the_delay() {
        let mut p = Plant::new(PlantParams::PAPER).unwrap();
        assert_eq!(p.output().y, 0.0);
        p.advance(2.0);
        // x(1) = 0.8 * 2 = 1.6 > 0 + 0.5: engaged up, w = 1.1.
        let o = p.output();
        assert!((o.x - 1.6).abs() < 1e-15);
        assert!((o.w - 1.1).abs() < 1e-15);
        assert_eq!(o.mode, Mode::Up);
    }

    #[test]
    fn simulate_matches_stepping_and_noise_is_seeded() {
        let mut params = PlantParams::PAPER;
        params.noise_std = 0.1;
        params.noise_seed = 7;
        let u: Vec<f64> = (0..500).map(|k| (k as f64 * 0.37).sin() * 2.0).collect();
        let a = Plant::simulate(params, &u).unwrap();
        let b = Plant::simulate(params, &u).unwrap();
        assert_eq!(a, b);
        params.noise_seed = 8;
        let c = Plant::simulate(params, &u).unwrap();
        assert!(a.iter().zip(&c).any(|(a, c)| a.y != c.y));
        // The noise is y - w: zero mean, the requested std (500 samples: within 4 standard errors).
        let e: Vec<f64> = a.iter().map(|o| o.y - o.w).collect();
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let std = (e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
        assert!(mean.abs() < 4.0 * 0.1 / (500f64).sqrt(), "mean {mean}");
        assert!(
            (std - 0.1).abs() < 4.0 * 0.1 / (1000f64).sqrt(),
            "std {std}"
        );
    }

    #[test]
    fn straight_polynomial_borders_and_a_first_order_block_reproduce_the_discrete_plant() {
        // G(s) = b / (s + a) sampled with ZOH at Ts is x(k) = e^{-a Ts} x(k-1) + (b/a)(1 - e^{-a Ts}) u(k-1):
        // the ARX block with a1 = -e^{-a Ts}, b0 = (b/a)(1 - e^{-a Ts}), delay 1. Straight polynomial borders
        // equal to m1 (x - c1), m2 (x + c2) must then give the paper-000 plant's output.
        let (a, b, ts): (f64, f64, f64) = (0.7, 1.3, 0.5);
        let phi = (-a * ts).exp();
        let mut p = PlantParams::PAPER;
        p.arx = ArxParams {
            na: 1,
            nb: 0,
            delay: 1,
            a: [-phi, 0.0, 0.0, 0.0],
            b: [b / a * (1.0 - phi), 0.0, 0.0, 0.0, 0.0],
        };
        let bl = p.backlash;
        let ext = PlantExtensions {
            borders: Some(PolyBacklashParams::from_straight(&bl)),
            continuous: Some((TransferFunction::new(&[b], &[1.0, a]).unwrap(), ts)),
            effects: Effects::default(),
        };
        // |x| stays below 4, the crossing point of the paper's straight borders: beyond it paper 000's rule
        // and paper 003's differ (plant::poly documents why).
        let u: Vec<f64> = (0..400).map(|k| 1.8 * (0.05 * k as f64).sin()).collect();
        let want = Plant::simulate(p, &u).unwrap();
        let mut plant = Plant::with_extensions(p, &ext).unwrap();
        for (k, w) in want.iter().enumerate() {
            let o = plant.output();
            assert!((o.x - w.x).abs() < 1e-12, "x at {k}: {} vs {}", o.x, w.x);
            assert!((o.w - w.w).abs() < 1e-12, "w at {k}: {} vs {}", o.w, w.w);
            plant.advance(u[k]);
        }
    }

    #[test]
    fn a_proper_transfer_function_is_refused() {
        let ext = PlantExtensions {
            borders: None,
            continuous: Some((
                TransferFunction::new(&[1.0, 0.0], &[1.0, 1.0]).unwrap(),
                0.1,
            )),
            effects: Effects::default(),
        };
        let e = Plant::with_extensions(PlantParams::PAPER, &ext).unwrap_err();
        assert!(e.reason.contains("strictly proper"), "{e}");
    }

    #[test]
    fn effects_combine_with_polynomial_borders_where_they_can() {
        use effects::{Friction, FrictionForm, GapDrift, Quantization};
        let bl = PlantParams::PAPER.backlash;
        let series = Friction {
            k_e: 1.0,
            f_plus: 0.4,
            f_minus: 0.4,
            form: FrictionForm::Series,
        };
        let mut ext = PlantExtensions {
            borders: Some(PolyBacklashParams::from_straight(&bl)),
            continuous: None,
            effects: Effects {
                friction: Some(series),
                quantization: Some(Quantization {
                    step: 0.1,
                    offset: 0.0,
                }),
                ..Effects::default()
            },
        };
        // Straight polynomial borders with series friction and a quantized sensor: w is the plain plant's
        // (below the borders' crossing point), f the friction element's output, y its quantized value.
        let u: Vec<f64> = (0..400).map(|k| 4.0 * (0.07 * k as f64).sin()).collect();
        let want = Plant::simulate(PlantParams::PAPER, &u).unwrap();
        let mut plant = Plant::with_extensions(PlantParams::PAPER, &ext).unwrap();
        let (mut f_prev, mut w_prev, mut slipping) = (0.0, 0.0, 0);
        for (k, w) in want.iter().enumerate() {
            let o = plant.output();
            assert!((o.w - w.w).abs() < 1e-12, "w at {k}");
            let f = (f_prev + (o.w - w_prev)).clamp(-0.4, 0.4);
            assert!((o.f - f).abs() < 1e-12, "f at {k}");
            assert!(
                ((o.y / 0.1).round() - o.y / 0.1).abs() < 1e-9 && (o.y - o.f).abs() <= 0.05 + 1e-12
            );
            slipping += usize::from(o.f.abs() == 0.4);
            (f_prev, w_prev) = (o.f, o.w);
            plant.advance(u[k]);
        }
        assert!(
            slipping > 20,
            "the friction element slips ({slipping} samples)"
        );
        // Gap drift needs the straight borders.
        ext.effects.gap_drift = Some(GapDrift {
            c1_rate: 1e-3,
            c2_rate: 0.0,
        });
        let e = Plant::with_extensions(PlantParams::PAPER, &ext).unwrap_err();
        assert_eq!(e.name, "gap drift");
        assert!(e.reason.contains("polynomial borders"), "{e}");
    }

    /// x(k) = 0.5 x(k-1) + u(k-1) rising, 0.9 x(k-1) + 0.1 u(k-1) falling, u = 1, 1, 0, 0, 0:
    /// x1 = 1 (rise 1 >= 0), x2 = 1.5, x3: rise 0.75 < 1.5 so fall 0.9 * 1.5 = 1.35, x4 = 0.9 * 1.35 = 1.215.
    /// With the falling set equal to the block's own the plant is the plain one, bit for bit.
    #[test]
    fn direction_dependent_block_by_hand() {
        use effects::DirectionDependent;
        let mut p = PlantParams::PAPER;
        p.arx = ArxParams {
            na: 1,
            nb: 0,
            delay: 1,
            a: [-0.5, 0.0, 0.0, 0.0],
            b: [1.0, 0.0, 0.0, 0.0, 0.0],
        };
        let with_offset =
            |a: [f64; MAX_ORDER], b: [f64; MAX_ORDER + 1], offset: f64| PlantExtensions {
                effects: Effects {
                    direction_dependent: Some(DirectionDependent { a, b, offset }),
                    ..Effects::default()
                },
                ..PlantExtensions::default()
            };
        let with = |a, b| with_offset(a, b, 0.0);
        let u = [1.0, 1.0, 0.0, 0.0, 0.0];
        let run = |ext: &PlantExtensions| block_outputs(p, ext, &u);
        let xs = run(&with([-0.9, 0.0, 0.0, 0.0], [0.1, 0.0, 0.0, 0.0, 0.0]));
        let want = [0.0, 1.0, 1.5, 1.35, 1.215];
        for (x, w) in xs.iter().zip(want) {
            assert!((x - w).abs() < 1e-12, "{xs:?}");
        }
        let plain: Vec<f64> = Plant::simulate(p, &u)
            .unwrap()
            .iter()
            .map(|o| o.x)
            .collect();
        assert_eq!(run(&with(p.arx.a, p.arx.b)), plain);
        // The falling set's offset moves only the falling samples: x3 = 1.35 + 0.25, x4 = 0.9 x3 + 0.25.
        let xs = run(&with_offset(
            [-0.9, 0.0, 0.0, 0.0],
            [0.1, 0.0, 0.0, 0.0, 0.0],
            0.25,
        ));
        let want = [0.0, 1.0, 1.5, 1.6, 0.9 * 1.6 + 0.25];
        for (x, w) in xs.iter().zip(want) {
            assert!((x - w).abs() < 1e-12, "{xs:?}");
        }
        // An unstable falling set, and the effect on a continuous block, are refused by name.
        let err = Plant::with_extensions(p, &with([-1.5, 0.0, 0.0, 0.0], p.arx.b)).unwrap_err();
        assert_eq!(err.name, "a1_fall");
        let cont = on_a_continuous_block(with(p.arx.a, p.arx.b));
        let err = Plant::with_extensions(p, &cont).unwrap_err();
        assert!(err.reason.contains("continuous"), "{err}");
    }

    /// The linear block's output before each input of `u` is applied, the plant built with `ext` (its
    /// state checked at the end).
    fn block_outputs(p: PlantParams, ext: &PlantExtensions, u: &[f64]) -> Vec<f64> {
        let mut plant = Plant::with_extensions(p, ext).unwrap();
        let xs = u
            .iter()
            .map(|&uk| {
                let x = plant.output().x;
                plant.advance(uk);
                x
            })
            .collect();
        assert!(plant.check().is_ok());
        xs
    }

    /// `ext` with the linear block replaced by a continuous one, 1 / (s + 1) sampled at 0.1.
    fn on_a_continuous_block(mut ext: PlantExtensions) -> PlantExtensions {
        ext.continuous = Some((
            TransferFunction {
                num: vec![1.0],
                den: vec![1.0, 1.0],
            },
            0.1,
        ));
        ext
    }

    /// x(k) = 0.5 x(k-1) + u(k-1) + phi(x(k-1)) + 0.5 phi(x(k-2)), phi(x) = 0.2 x^2 - 0.1 x^3, u = 1, 1, 0:
    /// x1 = 1, x2 = 0.5 + 1 + phi(1) = 1.6, x3 = 0.8 + phi(1.6) + 0.5 phi(1) = 0.8 + 0.1024 + 0.05 = 0.9524.
    /// Zero terms are the plain plant, bit for bit; the feedback on a continuous block is refused by name.
    #[test]
    fn polynomial_feedback_by_hand() {
        use effects::PolynomialFeedback;
        let mut p = PlantParams::PAPER;
        p.arx = ArxParams {
            na: 1,
            nb: 0,
            delay: 1,
            a: [-0.5, 0.0, 0.0, 0.0],
            b: [1.0, 0.0, 0.0, 0.0, 0.0],
        };
        let with = |quadratic: f64, cubic: f64| PlantExtensions {
            effects: Effects {
                polynomial_feedback: Some(PolynomialFeedback {
                    quadratic,
                    cubic,
                    lag2: 0.5,
                }),
                ..Effects::default()
            },
            ..PlantExtensions::default()
        };
        let u = [1.0, 1.0, 0.0, 0.0];
        let run = |ext: &PlantExtensions| block_outputs(p, ext, &u);
        let xs = run(&with(0.2, -0.1));
        for (x, w) in xs.iter().zip([0.0, 1.0, 1.6, 0.9524]) {
            assert!((x - w).abs() < 1e-12, "{xs:?}");
        }
        let plain: Vec<f64> = Plant::simulate(p, &u)
            .unwrap()
            .iter()
            .map(|o| o.x)
            .collect();
        assert_eq!(run(&with(0.0, 0.0)), plain);
        let cont = on_a_continuous_block(with(0.0, -0.1));
        let err = Plant::with_extensions(p, &cont).unwrap_err();
        assert_eq!(err.name, "polynomial feedback");
        let bad = with(f64::NAN, 0.0);
        assert_eq!(
            Plant::with_extensions(p, &bad).unwrap_err().name,
            "feedback2"
        );
    }

    #[test]
    fn wear_set_while_running_adds_to_the_gap_drift() {
        use effects::GapDrift;
        let ext = PlantExtensions {
            effects: Effects {
                gap_drift: Some(GapDrift {
                    c1_rate: 0.01,
                    c2_rate: 0.0,
                }),
                ..Effects::default()
            },
            ..PlantExtensions::default()
        };
        let mut plant = Plant::with_extensions(PlantParams::PAPER, &ext).unwrap();
        for _ in 0..100 {
            plant.advance(0.0);
        }
        let mut bl = PlantParams::PAPER.backlash;
        bl.c1 = 1.0;
        plant.set_backlash(bl).unwrap();
        // At sample 101 the gap is 1.0 + 0.01 * 101: engaging up from w = 0 needs x > 2.01.
        plant.advance(2.0 / 0.8);
        assert_eq!(plant.output().w, 0.0);
        plant.advance(0.0);
        plant.advance(4.0 / 0.8);
        let o = plant.output();
        let c1 = 1.0 + 0.01 * 103.0;
        assert!((o.w - (o.x - c1)).abs() < 1e-12, "{o:?}");
        assert!(plant.check().is_ok());
    }

    #[test]
    fn a_forged_effects_state_is_refused() {
        let ext = PlantExtensions {
            effects: Effects {
                coloured_noise: Some(effects::ColouredNoise { phi: 0.5 }),
                ..Effects::default()
            },
            ..PlantExtensions::default()
        };
        let plant = Plant::with_extensions(PlantParams::PAPER, &ext).unwrap();
        assert!(plant.check().is_ok());
        let mut j = serde_json::to_value(&plant).unwrap();
        j["effects"][1]["k"] = serde_json::json!(7);
        let forged: Plant = serde_json::from_value(j).unwrap();
        assert!(forged.check().unwrap_err().contains("sample index"));
        let mut j = serde_json::to_value(&plant).unwrap();
        j["effects"][0]["coloured_noise"]["phi"] = serde_json::json!(1.5);
        let forged: Plant = serde_json::from_value(j).unwrap();
        assert!(forged.check().unwrap_err().contains("phi"));
    }

    #[test]
    fn bad_parameters_are_refused_with_their_name() {
        let mut p = PlantParams::PAPER;
        p.backlash.m2 = 0.0;
        assert_eq!(Plant::new(p).unwrap_err().name, "m2");
        let mut p = PlantParams::PAPER;
        p.backlash.c1 = -0.1;
        assert_eq!(Plant::new(p).unwrap_err().name, "c1");
        let mut p = PlantParams::PAPER;
        p.arx.delay = 0;
        assert_eq!(Plant::new(p).unwrap_err().name, "delay");
        let mut p = PlantParams::PAPER;
        p.arx.na = 5;
        assert_eq!(Plant::new(p).unwrap_err().name, "na");
        let mut p = PlantParams::PAPER;
        p.arx.a[2] = f64::NAN;
        assert_eq!(Plant::new(p).unwrap_err().name, "a3");
        let mut p = PlantParams::PAPER;
        p.noise_std = f64::INFINITY;
        assert_eq!(Plant::new(p).unwrap_err().name, "noise_std");
    }
}
