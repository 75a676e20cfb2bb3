//! Optional effects of a test bench: what a real rig adds to the pseudo-Wiener plant of paper 000.
//!
//! Each field of [`Effects`] is one entry of the diagnosis catalogue (`crate::diagnose`), under the
//! contract's stable name; [`Effects::default`] switches every effect off, and then the plant is exactly the
//! contract's plant. The per-sample logic is a set of small pure functions ([`backlash_step`],
//! [`friction_step`], [`noise_step`], [`sensor`]) plus a state bundle ([`EffectsState`]) so that a plant (or
//! an FMU) can call them sample by sample; [`simulate_with_effects`] runs a whole record.
//!
//! Signal path at sample k (x from the ARX block, as in the contract):
//!
//! ```text
//! u(k) -> actuator dead zone                            -> the linear block's input (= u(k) without it)
//! x(k) -> backlash with drifting gaps and curved borders -> w(k)
//!      -> friction element (elasto-plastic Coulomb)     -> f(k)   (= w(k) without friction)
//!      -> sensor: f + periodic disturbance + noise (white or AR(1)), clipped, rounded -> y(k)
//! ```
//!
//! | effect (catalogue id) | field | parameters | where |
//! | --- | --- | --- | --- |
//! | gap-drift | [`GapDrift`] | `c1_rate`, `c2_rate` per sample: `c(k) = c + rate k` | backlash |
//! | curved-borders | [`CurvedBorders`] | quadratic and cubic terms on each border | backlash |
//! | friction | [`Friction`] | `k_e`, `f_plus`, `f_minus`, `form` (series / contact) | with the backlash |
//! | periodic-disturbance | [`Periodic`] | `amplitude`, `omega` (rad/sample), `phase` | sensor |
//! | coloured-noise | [`ColouredNoise`] | `phi`: AR(1) coefficient of the measurement noise | sensor |
//! | saturation | [`Saturation`] | `lo`, `hi`, `before_noise` | sensor (or end stop) |
//! | quantization | [`Quantization`] | `step`, `offset` | sensor (last) |
//! | dead-zone | [`DeadZone`] | `width`: inputs with \|u\| up to it move nothing | actuator (before the linear block) |
//! | direction-dependent | [`DirectionDependent`] | the falling set `a`, `b` of the linear block | linear block |
//! | polynomial-feedback | [`PolynomialFeedback`] | `quadratic`, `cubic`, `lag2`: x(k) gains `phi(x(k-1)) + lag2 phi(x(k-2))`, `phi(x) = quadratic x^2 + cubic x^3` | linear block |
//! | extra-delay | none: `ArxParams::delay` | | linear block |
//! | linear-order | none: `ArxParams::na`, `nb` and coefficients | | linear block |
//!
//! The delay and the orders of the linear block are plant parameters already: a test bench with an
//! "undeclared extra delay" is a plant whose `delay` is larger than the one given to the estimator.
//!
//! [`Plant`](super::Plant) runs the effects when `PlantExtensions::effects` enables any (and the FMU
//! BacklashPlant exposes them as parameters); with every effect off the plant takes its plain path, and
//! effects switched on with neutral values (zero drift, straight curves) reproduce it bit for bit (tested).

use serde::{Deserialize, Serialize};

use super::backlash::{BacklashParams, Mode};
use super::linear::MAX_ORDER;
use super::poly::PolyBacklash;
use super::{ParamError, PlantParams, check_finite, check_non_negative, check_positive};

/// The gaps change linearly over the record (wear): `c1(k) = c1 + c1_rate k`, `c2(k) = c2 + c2_rate k`,
/// k the sample index from the start of the run. The operator is defined for any gap values, so nothing
/// clamps them; a plant that must keep `c >= 0` checks the rates against its run length.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GapDrift {
    pub c1_rate: f64,
    pub c2_rate: f64,
}

impl GapDrift {
    /// The backlash at sample k.
    #[inline]
    pub fn at(&self, bl: &BacklashParams, k: u64) -> BacklashParams {
        let t = k as f64;
        BacklashParams {
            c1: bl.c1 + self.c1_rate * t,
            c2: bl.c2 + self.c2_rate * t,
            ..*bl
        }
    }
}

/// Curved borders: quadratic and cubic terms added to the straight borders, in the distance from the
/// border's zero (so that c1 and c2 keep their meaning as the gaps at zero output):
///
/// ```text
/// upper(x) = m1 s + upper[0] s^2 + upper[1] s^3,   s = x - c1
/// lower(x) = m2 s + lower[0] s^2 + lower[1] s^3,   s = x + c2
/// ```
///
/// The switching rule is the contract's, written with the borders: `w = upper(x)` if `upper(x) > w(k-1)`,
/// else `w = lower(x)` if `lower(x) < w(k-1)`, else `w = w(k-1)`. For straight borders this is exactly
/// `BacklashParams::step` (which is what runs when all four coefficients are zero). Physical borders are
/// increasing over the working range; the rule is still defined (it may jump) where they are not.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct CurvedBorders {
    /// `[s^2, s^3]` coefficients of the upper (driving-up) border.
    pub upper: [f64; 2],
    /// `[s^2, s^3]` coefficients of the lower (driving-down) border.
    pub lower: [f64; 2],
}

impl CurvedBorders {
    pub fn is_straight(&self) -> bool {
        self.upper == [0.0; 2] && self.lower == [0.0; 2]
    }

    pub fn upper(&self, bl: &BacklashParams, x: f64) -> f64 {
        let s = x - bl.c1;
        s * (bl.m1 + s * (self.upper[0] + s * self.upper[1]))
    }

    pub fn lower(&self, bl: &BacklashParams, x: f64) -> f64 {
        let s = x + bl.c2;
        s * (bl.m2 + s * (self.lower[0] + s * self.lower[1]))
    }
}

/// An elasto-plastic Coulomb element with the backlash: a spring of stiffness `k_e` and a slider that slips
/// at `+f_plus` / `-f_minus`. The output saturates at the slip levels and unloads elastically after a
/// reversal. Two arrangements of the play ([`FrictionForm`]):
///
/// - `Series` (default): the element after the backlash output w,
///   `f(k) = clamp(f(k-1) + k_e (w(k) - w(k-1)), -f_minus, f_plus)`, f = 0 before k = 0. After a reversal the
///   force holds while x crosses the play, then unloads.
/// - `Contact`: the play inside the elastic element (a linkage with play pushing a friction damper, as in
///   the measured damper of `data/brfd`): with z the slider position and r = x - z the linkage's stretch,
///   `f = k_e m1 (r - c1)` for r > c1, `k_e m2 (r + c2)` for r < -c2, 0 in between, and the slider moves
///   when |f| would pass a slip level. After a reversal the force unloads elastically to zero, stays zero
///   across the play, then loads the other way. See [`contact_step`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Friction {
    pub k_e: f64,
    pub f_plus: f64,
    pub f_minus: f64,
    #[serde(default)]
    pub form: FrictionForm,
}

/// Where the play sits relative to the friction element's spring (see [`Friction`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum FrictionForm {
    #[default]
    Series,
    Contact,
}

/// A sinusoid on the measured output: `amplitude sin(omega k + phase)`, omega in rad/sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Periodic {
    pub amplitude: f64,
    pub omega: f64,
    pub phase: f64,
}

impl Periodic {
    pub fn at(&self, k: u64) -> f64 {
        self.amplitude * (self.omega * k as f64 + self.phase).sin()
    }
}

/// Coloured measurement noise: `n(k) = phi n(k-1) + sqrt(1 - phi^2) noise_std z(k)`, z standard normal, so
/// that `noise_std` stays the noise's (stationary) standard deviation. `n(0) = noise_std z(0)`: the noise
/// starts stationary.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ColouredNoise {
    /// AR(1) coefficient, in (-1, 1).
    pub phi: f64,
}

/// Clipping of the output at `lo` / `hi`. With `before_noise` the clip acts on the noise-free output (a
/// mechanical end stop: the measured value scatters around the stop); otherwise on the measured value (a
/// sensor range: the measured value sits exactly at the limit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Saturation {
    pub lo: f64,
    pub hi: f64,
    #[serde(default)]
    pub before_noise: bool,
}

/// A sensor of resolution `step`: `y = offset + step round((v - offset) / step)`, the last thing that
/// happens to the measured value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quantization {
    pub step: f64,
    #[serde(default)]
    pub offset: f64,
}

/// Direction-dependent dynamics (a motor driven up and coasting down, a valve opening against a spring and
/// closing with it): the linear block has a second set of coefficients, `a`, `b` (same orders and delay),
/// for while its output falls. At sample k the block computes `x_rise(k)` with its own coefficients and
/// `x_fall(k)` with these over the same history; `x(k) = x_rise(k)` if that does not fall below `x(k-1)`,
/// else `x_fall(k)` ([`DirectionDependent::choose`]). With `a`, `b` equal to the block's own and `offset` 0
/// the plant is the plain one. Entries beyond the block's `na` and `nb` are ignored, as in `ArxParams`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DirectionDependent {
    pub a: [f64; MAX_ORDER],
    pub b: [f64; MAX_ORDER + 1],
    /// A constant added to `x_fall(k)`: where the falling set comes to rest against the rising one. With
    /// static gains that differ, the two sets' steady states cross at the input 0 unless it is free, so a
    /// fit about an arbitrary input zero needs it (the plant FMU's block keeps 0: its zero is the physical
    /// one).
    #[serde(default)]
    pub offset: f64,
}

impl DirectionDependent {
    /// The block's output at sample k from its rising-set and falling-set values and x(k-1).
    pub fn choose(x_prev: f64, x_rise: f64, x_fall: f64) -> f64 {
        if x_rise >= x_prev { x_rise } else { x_fall }
    }
}

/// Polynomial feedback in the linear block, the discrete image of a spring whose stiffness grows (or falls)
/// with its deflection (a Duffing oscillator, x'' + 2 zeta w x' + w^2 (x + kappa x^3) = w^2 F). The spring's
/// force `phi(x) = quadratic x^2 + cubic x^3` (beyond the linear part, which is the block's own) acts on the
/// mass as the drive does: held over a sample, a force enters x(k) through two taps, at k-1 and k-2 (a
/// zero-order hold of a second-order block), so the block's output at sample k is its linear value plus
/// [`PolynomialFeedback::term`] = `phi(x(k-1)) + lag2 phi(x(k-2))`. The quadratic term places the spring's
/// centre (a cubic about x0 is a quadratic and a cubic about 0, its linear part the block's own `a`). A
/// negative `cubic` stiffens the spring; a positive one softens it, and far enough out the block runs away as
/// an unstable one does. `quadratic` and `cubic` zero is the plain block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PolynomialFeedback {
    pub quadratic: f64,
    pub cubic: f64,
    /// The second tap's weight (0: the force enters through x(k-1) alone).
    #[serde(default)]
    pub lag2: f64,
}

impl PolynomialFeedback {
    /// The spring's force beyond its linear part at deflection `x`.
    #[inline]
    pub fn force(&self, x: f64) -> f64 {
        x * x * (self.quadratic + self.cubic * x)
    }

    /// What the feedback adds to x(k) after the block's outputs `x1` = x(k-1) and `x2` = x(k-2).
    #[inline]
    pub fn term(&self, x1: f64, x2: f64) -> f64 {
        self.force(x1) + self.lag2 * self.force(x2)
    }
}

/// An actuator or valve dead zone on the input: an input with |u| up to `width` moves nothing; a larger one
/// acts shifted towards zero by the width, `u - width sign(u)` ([`DeadZone::apply`]). Width 0 is the plain
/// input.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeadZone {
    pub width: f64,
}

impl DeadZone {
    /// The input the linear block sees for the commanded input `u`.
    pub fn apply(&self, u: f64) -> f64 {
        if u > self.width {
            u - self.width
        } else if u < -self.width {
            u + self.width
        } else {
            0.0
        }
    }
}

/// The optional effects; `Default` switches all of them off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(default)]
pub struct Effects {
    pub dead_zone: Option<DeadZone>,
    pub direction_dependent: Option<DirectionDependent>,
    pub polynomial_feedback: Option<PolynomialFeedback>,
    pub gap_drift: Option<GapDrift>,
    pub curved_borders: Option<CurvedBorders>,
    pub friction: Option<Friction>,
    pub periodic: Option<Periodic>,
    pub coloured_noise: Option<ColouredNoise>,
    pub saturation: Option<Saturation>,
    pub quantization: Option<Quantization>,
}

impl Effects {
    /// Every enabled effect's parameters in range; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ParamError> {
        if let Some(d) = &self.dead_zone {
            check_non_negative("width", d.width)?;
        }
        if let Some(d) = &self.direction_dependent {
            for (i, v) in d.a.iter().enumerate() {
                check_finite(&format!("a{}_fall", i + 1), *v)?;
            }
            for (j, v) in d.b.iter().enumerate() {
                check_finite(&format!("b{j}_fall"), *v)?;
            }
            check_finite("offset_fall", d.offset)?;
        }
        if let Some(p) = &self.polynomial_feedback {
            check_finite("feedback2", p.quadratic)?;
            check_finite("feedback3", p.cubic)?;
            check_finite("feedback_lag2", p.lag2)?;
        }
        if let Some(g) = &self.gap_drift {
            check_finite("c1_rate", g.c1_rate)?;
            check_finite("c2_rate", g.c2_rate)?;
        }
        if let Some(c) = &self.curved_borders {
            for (i, v) in c.upper.iter().enumerate() {
                check_finite(&format!("upper{}", i + 2), *v)?;
            }
            for (i, v) in c.lower.iter().enumerate() {
                check_finite(&format!("lower{}", i + 2), *v)?;
            }
        }
        if let Some(f) = &self.friction {
            check_positive("k_e", f.k_e)?;
            check_non_negative("f_plus", f.f_plus)?;
            check_non_negative("f_minus", f.f_minus)?;
            // The contact element has the play inside its spring with straight borders.
            if f.form == FrictionForm::Contact
                && self.curved_borders.is_some_and(|c| !c.is_straight())
            {
                return Err(ParamError::new(
                    "friction",
                    2.0,
                    "cannot be the contact form with curved borders (its spring has straight borders): use the series form or straight borders",
                ));
            }
        }
        if let Some(p) = &self.periodic {
            check_finite("amplitude", p.amplitude)?;
            check_finite("omega", p.omega)?;
            check_finite("phase", p.phase)?;
        }
        if let Some(c) = &self.coloured_noise {
            check_finite("phi", c.phi)?;
            if c.phi.abs() >= 1.0 {
                return Err(ParamError::new(
                    "phi",
                    c.phi,
                    "must be strictly between -1 and 1",
                ));
            }
        }
        if let Some(s) = &self.saturation {
            check_finite("lo", s.lo)?;
            check_finite("hi", s.hi)?;
            if s.lo > s.hi {
                return Err(ParamError::new("lo", s.lo, "must not exceed hi"));
            }
        }
        if let Some(q) = &self.quantization {
            check_positive("step", q.step)?;
            check_finite("offset", q.offset)?;
        }
        Ok(())
    }
}

impl Effects {
    /// The input the linear block sees for the commanded input `u`: the actuator's effects (the dead zone)
    /// act on it; without them it is `u`.
    pub fn actuator(&self, u: f64) -> f64 {
        match &self.dead_zone {
            Some(d) => d.apply(u),
            None => u,
        }
    }

    /// Whether an actuator effect changes the input ([`Effects::actuator`] is not the identity).
    pub fn acts_on_input(&self) -> bool {
        self.dead_zone.is_some()
    }
}

/// One backlash step with the structural effects: the backlash `b` at this sample (the gaps drifted: see
/// [`drifted`]) and its curved borders; the new output for input `x` after output `w_prev`, and the regime.
/// Without curved borders this is `b.step(x, w_prev)`.
#[inline]
pub fn backlash_step(
    b: &BacklashParams,
    curve: Option<&CurvedBorders>,
    x: f64,
    w_prev: f64,
) -> (f64, Mode) {
    match curve {
        Some(c) if !c.is_straight() => {
            let up = c.upper(b, x);
            if up > w_prev {
                return (up, Mode::Up);
            }
            let down = c.lower(b, x);
            if down < w_prev {
                (down, Mode::Down)
            } else {
                (w_prev, Mode::Held)
            }
        }
        _ => b.step(x, w_prev),
    }
}

/// The backlash at sample k with its gaps' drift.
#[inline]
pub fn drifted(bl: &BacklashParams, drift: Option<&GapDrift>, k: u64) -> BacklashParams {
    match drift {
        Some(d) => d.at(bl, k),
        None => *bl,
    }
}

/// Whether the memory zone of [`backlash_step`] with the backlash `b` (at this sample: see [`drifted`]) is
/// inverted at input `x`: the upper border's output above the lower one's there (beyond the borders'
/// crossing, or everywhere with a negative play). There the step, which checks the upper border first,
/// flips between the borders as x holds or falls.
#[inline]
pub fn zone_inverted(b: &BacklashParams, curve: Option<&CurvedBorders>, x: f64) -> bool {
    match curve {
        Some(c) if !c.is_straight() => c.upper(b, x) > c.lower(b, x),
        _ => b.upper(x) > b.lower(x),
    }
}

/// One step of the friction element: `clamp(f_prev + k_e dw, -f_minus, f_plus)`. Never panics: with
/// `-f_minus > f_plus` (not a valid element) the upper level wins.
pub fn friction_step(fr: &Friction, f_prev: f64, dw: f64) -> f64 {
    (f_prev + fr.k_e * dw).max(-fr.f_minus).min(fr.f_plus)
}

/// One step of the contact friction element ([`FrictionForm::Contact`]) at input x from slider position
/// `z_prev`, with the play and slopes of `bl`: returns the force, the new slider position and the regime
/// (`Up` / `Down` while slipping, `Held` while the slider sticks). The slider is the output of a play
/// operator on x, so it is the backlash output of this arrangement.
pub fn contact_step(fr: &Friction, bl: &BacklashParams, x: f64, z_prev: f64) -> (f64, f64, Mode) {
    let r = x - z_prev;
    let (k_up, k_dn) = (fr.k_e * bl.m1, fr.k_e * bl.m2);
    let f = if r > bl.c1 {
        k_up * (r - bl.c1)
    } else if r < -bl.c2 {
        k_dn * (r + bl.c2)
    } else {
        0.0
    };
    if f > fr.f_plus {
        (fr.f_plus, x - bl.c1 - fr.f_plus / k_up, Mode::Up)
    } else if f < -fr.f_minus {
        (-fr.f_minus, x + bl.c2 + fr.f_minus / k_dn, Mode::Down)
    } else {
        (f, z_prev, Mode::Held)
    }
}

/// The next measurement-noise value from the previous one and a standard normal draw `z`: white
/// `noise_std z`, or AR(1) with stationary std `noise_std` ([`ColouredNoise`]). `first` marks sample 0.
pub fn noise_step(
    coloured: Option<&ColouredNoise>,
    noise_std: f64,
    n_prev: f64,
    z: f64,
    first: bool,
) -> f64 {
    match coloured {
        Some(c) if !first => c.phi * n_prev + (1.0 - c.phi * c.phi).sqrt() * noise_std * z,
        _ => noise_std * z,
    }
}

/// The sensor at sample k: the noise-free output `f` plus the periodic disturbance and the noise `n`,
/// clipped and rounded as the effects say (never panics: with lo > hi, not a valid range, hi wins).
pub fn sensor(e: &Effects, f: f64, n: f64, k: u64) -> f64 {
    let mut v = f;
    if let Some(s) = e.saturation.as_ref().filter(|s| s.before_noise) {
        v = v.max(s.lo).min(s.hi);
    }
    if let Some(p) = &e.periodic {
        v += p.at(k);
    }
    v += n;
    if let Some(s) = e.saturation.as_ref().filter(|s| !s.before_noise) {
        v = v.max(s.lo).min(s.hi);
    }
    if let Some(q) = &e.quantization {
        v = quantize(q, v);
    }
    v
}

/// `offset + step round((v - offset) / step)`.
pub fn quantize(q: &Quantization, v: f64) -> f64 {
    q.offset + q.step * ((v - q.offset) / q.step).round()
}

/// The expected reading of the sensor when Gaussian noise of standard deviation `sigma` is added before the
/// rounding: `E[quantize(v + sigma z)]`, z standard normal. `sigma = 0` is [`quantize`]; as sigma grows
/// past about step/2 the noise dithers the staircase away and the expected reading tends to v.
pub fn expected_reading(q: &Quantization, v: f64, sigma: f64) -> f64 {
    let z = (v - q.offset) / q.step;
    let s = sigma.abs() / q.step;
    if s < 1e-9 {
        return quantize(q, v);
    }
    // Noise of more than two steps hides the rounding: the expected reading differs from v by the Fourier
    // series sum_k (-1)^k sin(2 pi k z) exp(-2 pi^2 k^2 s^2) / (pi k), below 1e-34 relative for s >= 2. This
    // also bounds the loop below to 35 terms whatever sigma is.
    if s >= 2.0 || !s.is_finite() {
        return v;
    }
    // More than 2^52 steps from the offset, neighbouring lattice points are not distinct floats (the step is
    // below the value's resolution): the reading is the value. (There `m + 1 == m`, and a loop stepping m by
    // one never ended: a fit whose step shrank towards zero hung.)
    if z.abs() >= 2f64.powi(f64::MANTISSA_DIGITS as i32 - 1) {
        return v;
    }
    // round(X) = m_lo + #{m in (m_lo, m_hi] : X > m - 1/2} when X is in (m_lo - 1/2, m_hi + 1/2), which
    // holds to 1e-15 for a window of 8.5 standard deviations on either side (at most 35 terms for s < 2).
    let m_lo = (z - 8.5 * s).round();
    let terms = ((z + 8.5 * s).round() - m_lo) as usize;
    let e = m_lo
        + (1..=terms)
            .map(|i| {
                // P(z + s N > m - 1/2) = erfc((m - 1/2 - z) / (s sqrt 2)) / 2.
                let m = m_lo + i as f64;
                0.5 * statrs::function::erf::erfc((m - 0.5 - z) / (s * std::f64::consts::SQRT_2))
            })
            .sum::<f64>();
    q.offset + q.step * e
}

/// The signals of a plant with effects at one sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EffectsOutput {
    /// Linear block output.
    pub x: f64,
    /// Backlash output (noise-free, with drift and curvature); with contact friction, the slider
    /// position (the output of the play operator the slider follows).
    pub w: f64,
    /// Noise-free output after the friction element (= w without friction).
    pub f: f64,
    /// Measured output.
    pub y: f64,
    /// Regime of the backlash.
    pub mode: Mode,
}

/// The state the effects keep between samples: previous backlash output, friction force, noise value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct EffectsState {
    pub w: f64,
    pub f: f64,
    pub n: f64,
    pub k: u64,
}

impl EffectsState {
    /// The outputs at sample `k = self.k` for the linear block output `x` and a standard normal draw `z`;
    /// then moves on to k + 1. With `poly` (paper 003's polynomial borders, which keep their own state) the
    /// backlash output comes from it; gap drift, curved borders and contact friction need the straight
    /// borders (`PlantExtensions::validate` refuses the combination) and are ignored with `poly`.
    pub fn step(
        &mut self,
        p: &PlantParams,
        e: &Effects,
        poly: Option<&mut PolyBacklash>,
        x: f64,
        z: f64,
    ) -> EffectsOutput {
        let k = self.k;
        let (w, mode, f) = match (&e.friction, poly) {
            (_, Some(poly)) => {
                let w = poly.step(x);
                let f = match &e.friction {
                    Some(fr) => friction_step(fr, self.f, w - self.w),
                    None => w,
                };
                (w, poly.mode(), f)
            }
            (Some(fr), None) if fr.form == FrictionForm::Contact => {
                let bl = drifted(&p.backlash, e.gap_drift.as_ref(), k);
                let (f, z, mode) = contact_step(fr, &bl, x, self.w);
                (z, mode, f)
            }
            (fr, None) => {
                let b = drifted(&p.backlash, e.gap_drift.as_ref(), k);
                let (w, mode) = backlash_step(&b, e.curved_borders.as_ref(), x, self.w);
                let f = match fr {
                    Some(fr) => friction_step(fr, self.f, w - self.w),
                    None => w,
                };
                (w, mode, f)
            }
        };
        let n = noise_step(e.coloured_noise.as_ref(), p.noise_std, self.n, z, k == 0);
        let y = sensor(e, f, n, k);
        *self = Self { w, f, n, k: k + 1 };
        EffectsOutput { x, w, f, y, mode }
    }
}

/// The plant with effects over the input sequence `u` (output k is the state before it reads u(k), as in
/// `Plant::simulate`): [`Plant`](super::Plant) with these effects, its noise (std `params.noise_std`) drawn
/// from ChaCha8 seeded with `seed` instead of `params.noise_seed`.
pub fn simulate_with_effects(
    params: &PlantParams,
    effects: &Effects,
    u: &[f64],
    seed: u64,
) -> Result<Vec<EffectsOutput>, ParamError> {
    let ext = super::PlantExtensions {
        effects: *effects,
        ..Default::default()
    };
    let params = PlantParams {
        noise_seed: seed,
        ..*params
    };
    let mut plant = super::Plant::with_extensions(params, &ext)?;
    Ok(u.iter()
        .map(|&uk| {
            let o = plant.output();
            plant.advance(uk);
            EffectsOutput {
                x: o.x,
                w: o.w,
                f: o.f,
                y: o.y,
                mode: o.mode,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::Plant;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;

    /// By hand on the paper's backlash, whose borders cross at x = -4: at x = -5 the upper border gives
    /// -5.5 and the lower -6 (inverted), at -3 they give -3.5 and -3 (not), at -4 both -4.5 (not: equal). A
    /// gap drift closing both gaps by 0.005 per sample inverts the zone at x = 0 once -c1 > 1.5 c2, after
    /// sample 160: not at 150 (0.25 against 0.375), at 170 (0.35 against 0.225). A quadratic term on the upper
    /// border (s + 0.1 s^2, s = x - c1) leaves x = 6 valid (8.525 against 10.5) and inverts x = 20 (57.525
    /// against 31.5), where the straight borders are not (19.5 against 31.5).
    #[test]
    fn inverted_zone_by_hand() {
        let bl = BacklashParams::PAPER;
        let inv = |x: f64| zone_inverted(&bl, None, x);
        assert!(inv(-5.0) && !inv(-3.0) && !inv(-4.0));
        let closing = GapDrift {
            c1_rate: -0.005,
            c2_rate: -0.005,
        };
        let at = |k| drifted(&bl, Some(&closing), k);
        assert!(!zone_inverted(&at(150), None, 0.0));
        assert!(zone_inverted(&at(170), None, 0.0));
        let bent = CurvedBorders {
            upper: [0.1, 0.0],
            lower: [0.0, 0.0],
        };
        assert!(!zone_inverted(&bl, Some(&bent), 6.0));
        assert!(zone_inverted(&bl, Some(&bent), 20.0));
        assert!(!inv(20.0));
    }

    #[test]
    fn contact_friction_on_curved_borders_is_refused_series_is_not() {
        let friction = |form| Friction {
            k_e: 1.0,
            f_plus: 0.5,
            f_minus: 0.5,
            form,
        };
        let curved = CurvedBorders {
            upper: [0.1, 0.0],
            lower: [0.0, 0.0],
        };
        let e = Effects {
            friction: Some(friction(FrictionForm::Contact)),
            curved_borders: Some(curved),
            ..Effects::default()
        };
        let err = e.validate().unwrap_err();
        assert!(err.reason.contains("series form"), "{err}");
        let series = Effects {
            friction: Some(friction(FrictionForm::Series)),
            ..e
        };
        assert!(series.validate().is_ok());
        let straight = Effects {
            curved_borders: Some(CurvedBorders::default()),
            ..e
        };
        assert!(straight.validate().is_ok());
    }
    use rand_distr::{Distribution, StandardNormal};

    fn input(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| 2.0 * (k as f64 * 0.13).sin() + (k as f64 * 0.031).cos())
            .collect()
    }

    #[test]
    fn no_effects_is_the_plant() {
        let mut p = PlantParams::PAPER;
        p.noise_std = 0.05;
        p.noise_seed = 11;
        let u = input(800);
        let a = Plant::simulate(p, &u).unwrap();
        let b = simulate_with_effects(&p, &Effects::default(), &u, 11).unwrap();
        for (a, b) in a.iter().zip(&b) {
            assert_eq!((a.x, a.w, a.y, a.mode), (b.x, b.w, b.y, b.mode));
            assert_eq!(b.f, b.w);
        }
    }

    #[test]
    fn straight_curve_and_zero_drift_change_nothing() {
        // The effects path (taken when any effect is set) with neutral effects against the plant's plain
        // path, noise included: same draws in the same order.
        let mut p = PlantParams::PAPER;
        p.noise_std = 0.05;
        let u = input(500);
        let e = Effects {
            gap_drift: Some(GapDrift {
                c1_rate: 0.0,
                c2_rate: 0.0,
            }),
            curved_borders: Some(CurvedBorders::default()),
            ..Effects::default()
        };
        let a = simulate_with_effects(&p, &Effects::default(), &u, 0).unwrap();
        let b = simulate_with_effects(&p, &e, &u, 0).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn curved_rule_with_tiny_curvature_matches_straight_rule() {
        let bl = BacklashParams::PAPER;
        let c = CurvedBorders {
            upper: [1e-300, 0.0],
            lower: [0.0, 0.0],
        };
        let mut w1 = 0.0;
        let mut w2 = 0.0;
        for x in input(300) {
            let a = bl.step(x, w1);
            let b = backlash_step(&bl, Some(&c), x, w2);
            assert_eq!(a.1, b.1);
            assert!((a.0 - b.0).abs() < 1e-12);
            (w1, w2) = (a.0, b.0);
        }
    }

    #[test]
    fn gap_drift_moves_the_borders() {
        let bl = BacklashParams::PAPER;
        let g = GapDrift {
            c1_rate: 0.001,
            c2_rate: -0.0005,
        };
        let b = g.at(&bl, 1000);
        assert!((b.c1 - 1.5).abs() < 1e-12 && (b.c2 - 0.5).abs() < 1e-12);
        // Engaging up at x = 2 from w = 0: w = x - c1(k).
        assert!(
            (backlash_step(&drifted(&bl, Some(&g), 1000), None, 2.0, 0.0).0 - 0.5).abs() < 1e-12
        );
    }

    #[test]
    fn friction_element_saturates_and_unloads_elastically() {
        let fr = Friction {
            k_e: 2.0,
            f_plus: 1.0,
            f_minus: 0.5,
            form: FrictionForm::Series,
        };
        let mut f = 0.0;
        let mut fs = Vec::new();
        for dw in [0.2, 0.2, 0.2, 0.2, -0.1, -0.1, -0.1, -0.1, 0.1] {
            f = friction_step(&fr, f, dw);
            fs.push(f);
        }
        let want = [0.4, 0.8, 1.0, 1.0, 0.8, 0.6, 0.4, 0.2, 0.4];
        for (a, b) in fs.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{fs:?}");
        }
        assert_eq!(friction_step(&fr, -0.4, -1.0), -0.5);
    }

    #[test]
    fn sensor_effects() {
        let q = Quantization {
            step: 0.25,
            offset: 0.1,
        };
        assert!((quantize(&q, 0.2) - 0.1).abs() < 1e-15);
        assert!((quantize(&q, 0.3) - 0.35).abs() < 1e-15);
        // Expected reading: exact rounding without noise, the identity once the noise dithers it away,
        // and the mean of many noisy readings in between.
        assert_eq!(expected_reading(&q, 0.3, 0.0), quantize(&q, 0.3));
        assert!((expected_reading(&q, 0.3, 1.0) - 0.3).abs() < 1e-6);
        // Just below the cut-off the series is already the identity (as at sigma = 1 above, to the accuracy
        // of its erfc terms); above it (and for a huge or non-finite sigma, which used to loop for ever) the
        // value itself.
        assert!((expected_reading(&q, 0.3, 0.499) - 0.3).abs() < 1e-6);
        assert_eq!(expected_reading(&q, 0.3, 0.5), 0.3);
        assert_eq!(expected_reading(&q, 0.3, 1e300), 0.3);
        assert_eq!(expected_reading(&q, 0.3, f64::INFINITY), 0.3);
        // A step below the value's resolution (2^60 steps from the offset) reads the value, at once.
        let fine = Quantization {
            step: 2f64.powi(-60),
            offset: 0.0,
        };
        assert_eq!(expected_reading(&fine, 1.0, 2f64.powi(-61)), 1.0);
        let mut r = ChaCha8Rng::seed_from_u64(5);
        let m: f64 = (0..200_000)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut r);
                quantize(&q, 0.3 + 0.05 * z)
            })
            .sum::<f64>()
            / 200_000.0;
        assert!((expected_reading(&q, 0.3, 0.05) - m).abs() < 2e-3, "{m}");
        let e = Effects {
            saturation: Some(Saturation {
                lo: -1.0,
                hi: 1.0,
                before_noise: false,
            }),
            ..Effects::default()
        };
        assert_eq!(sensor(&e, 3.0, 0.1, 0), 1.0);
        let e = Effects {
            saturation: Some(Saturation {
                lo: -1.0,
                hi: 1.0,
                before_noise: true,
            }),
            ..Effects::default()
        };
        assert_eq!(sensor(&e, 3.0, 0.1, 0), 1.1);
        let e = Effects {
            periodic: Some(Periodic {
                amplitude: 2.0,
                omega: 0.5,
                phase: 0.0,
            }),
            ..Effects::default()
        };
        assert!((sensor(&e, 1.0, 0.0, 3) - (1.0 + 2.0 * 1.5f64.sin())).abs() < 1e-15);
    }

    #[test]
    fn coloured_noise_has_the_std_and_the_correlation() {
        let mut p = PlantParams::PAPER;
        p.noise_std = 0.2;
        let e = Effects {
            coloured_noise: Some(ColouredNoise { phi: 0.8 }),
            ..Effects::default()
        };
        let u = vec![0.0; 20000];
        let o = simulate_with_effects(&p, &e, &u, 3).unwrap();
        let n: Vec<f64> = o.iter().map(|o| o.y - o.f).collect();
        let m = n.iter().sum::<f64>() / n.len() as f64;
        let var = n.iter().map(|v| (v - m).powi(2)).sum::<f64>() / n.len() as f64;
        let r1 =
            n.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / (n.len() as f64 * var);
        assert!((var.sqrt() - 0.2).abs() < 0.02, "std {}", var.sqrt());
        assert!((r1 - 0.8).abs() < 0.03, "r1 {r1}");
    }

    #[test]
    fn bad_effect_parameters_are_named() {
        let e = Effects {
            coloured_noise: Some(ColouredNoise { phi: 1.0 }),
            ..Effects::default()
        };
        assert_eq!(e.validate().unwrap_err().name, "phi");
        let e = Effects {
            quantization: Some(Quantization {
                step: 0.0,
                offset: 0.0,
            }),
            ..Effects::default()
        };
        assert_eq!(e.validate().unwrap_err().name, "step");
        let e = Effects {
            saturation: Some(Saturation {
                lo: 1.0,
                hi: 0.0,
                before_noise: false,
            }),
            ..Effects::default()
        };
        assert_eq!(e.validate().unwrap_err().name, "lo");
    }

    #[test]
    fn contact_friction_unloads_crosses_the_play_at_zero_and_reloads() {
        let fr = Friction {
            k_e: 1.0,
            f_plus: 1.0,
            f_minus: 1.0,
            form: FrictionForm::Contact,
        };
        let bl = BacklashParams {
            m1: 1.0,
            m2: 1.0,
            c1: 0.5,
            c2: 0.5,
        };
        // x up to 3 (slipping at f = 1 once x - z > 1.5), then down to -3.
        let xs: Vec<f64> = (0..=30)
            .map(|i| i as f64 * 0.1)
            .chain((1..=60).map(|i| 3.0 - i as f64 * 0.1))
            .collect();
        let mut z = 0.0;
        let mut fs = Vec::new();
        for &x in &xs {
            let (f, zn, _) = contact_step(&fr, &bl, x, z);
            z = zn;
            fs.push(f);
        }
        let near = |i: usize, v: f64| (fs[i] - v).abs() < 1e-9;
        assert!(near(5, 0.0), "x = 0.5: in the play");
        assert!(near(10, 0.5), "x = 1: elastic");
        assert!(near(30, 1.0), "x = 3: slipping, z = 1.5");
        // Reversal at x = 3 (index 30): unloads to zero at x = 2, zero across the play down to x = 1, then
        // loads the other way and slips at -1 from x = 0 on.
        assert!(near(35, 0.5), "x = 2.5");
        assert!(
            near(40, 0.0) && near(45, 0.0) && near(50, 0.0),
            "x = 2 .. 1: play"
        );
        assert!(near(55, -0.5), "x = 0.5");
        assert!(near(60, -1.0) && near(70, -1.0), "x = 0, -1: slipping");
    }
}
