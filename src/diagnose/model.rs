//! The models the diagnosis fits: the declared pseudo-Wiener model ([`BaseModel`], m1 = 1) and the
//! catalogue extensions added to it, in the order they were kept ([`Extension`]). The per-sample logic is the test bench's
//! ([`crate::plant::effects`]), so a fitted extension and a simulated rig mean exactly the same thing.

use serde::Serialize;

use super::catalogue::EffectId;
use crate::plant::effects::{
    self, CurvedBorders, DirectionDependent, Effects, Friction, FrictionForm, GapDrift, Periodic,
    Quantization, Saturation,
};
use crate::plant::{BacklashParams, MAX_ORDER, Mode};

/// The declared model: `x(k) = -sum a_i x(k-i) + sum b_j u(k-delay-j)`, backlash with m1 = 1, m2, c1, c2.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BaseModel {
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
    pub a: Vec<f64>,
    pub b: Vec<f64>,
    pub m1: f64,
    pub m2: f64,
    pub c1: f64,
    pub c2: f64,
}

/// The input level before the record's first sample, at which the model is at rest: the linear block's past
/// inputs equal it and its past outputs equal their steady state. `Rest::ZERO` is the plant FMU's
/// convention (everything 0 before the first sample); a record that starts at an operating point far from
/// 0 (positions in encoder counts, temperatures) is simulated from rest at its first input instead, so that
/// a fit does not spend its parameters on a start-up transient the plant never had.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Rest(pub f64);

impl Rest {
    pub const ZERO: Rest = Rest(0.0);
}

impl BaseModel {
    /// Steady-state gain of the linear block, `sum b / (1 + sum a)` (0 when `1 + sum a` is 0: such a block
    /// is not stable and is never simulated).
    pub fn static_gain(&self) -> f64 {
        let den = 1.0 + self.a.iter().sum::<f64>();
        if den == 0.0 {
            0.0
        } else {
            self.b.iter().sum::<f64>() / den
        }
    }

    /// The backlash memory (with `contact`, the slider's position) before the first sample when the linear
    /// block rests at `x_rest`: 0 when that is 0 (the plant's convention); otherwise 0 moved into the band
    /// the backlash holds at `x_rest` (`m1 (x - c1) <= w <= m2 (x + c2)`, the upper border if the band is
    /// inverted), and the contact slider where the spring is unloaded (`x_rest`).
    fn rest_memory(&self, x_rest: f64, contact: bool) -> f64 {
        if x_rest == 0.0 {
            return 0.0;
        }
        if contact {
            return x_rest;
        }
        let lo = self.m1 * (x_rest - self.c1);
        let hi = self.m2 * (x_rest + self.c2);
        if lo <= hi { 0.0f64.clamp(lo, hi) } else { lo }
    }

    /// Zero coefficients, unit slopes, zero gaps.
    pub fn zero(na: usize, nb: usize, delay: usize) -> Self {
        Self {
            na,
            nb,
            delay,
            a: vec![0.0; na],
            b: vec![0.0; nb + 1],
            m1: 1.0,
            m2: 1.0,
            c1: 0.0,
            c2: 0.0,
        }
    }

    pub fn backlash(&self) -> BacklashParams {
        BacklashParams {
            m1: self.m1,
            m2: self.m2,
            c1: self.c1,
            c2: self.c2,
        }
    }

    /// Number of estimated parameters: a, b, m2, c1, c2.
    pub fn n_params(&self) -> usize {
        self.na + self.nb + 4
    }

    /// `[a_1..a_na, b_0..b_nb, m2, c1, c2]`.
    pub fn pack(&self) -> Vec<f64> {
        let mut v = self.a.clone();
        v.extend(&self.b);
        v.extend([self.m2, self.c1, self.c2]);
        v
    }

    /// The same structure with the parameters of `th` (the layout of [`BaseModel::pack`]).
    pub fn unpack(&self, th: &[f64]) -> Self {
        let (na, nb) = (self.na, self.nb);
        Self {
            a: th[..na].to_vec(),
            b: th[na..na + nb + 1].to_vec(),
            m2: th[na + nb + 1],
            c1: th[na + nb + 2],
            c2: th[na + nb + 3],
            ..self.clone()
        }
    }

    /// The same model with other orders and delay: coefficients kept where they exist, new ones zero.
    pub fn with_orders(&self, na: usize, nb: usize, delay: usize) -> Self {
        let mut a = self.a.clone();
        a.resize(na, 0.0);
        let mut b = self.b.clone();
        b.resize(nb + 1, 0.0);
        Self {
            na,
            nb,
            delay,
            a,
            b,
            ..self.clone()
        }
    }

    /// Typical magnitudes of the parameters for finite differences and perturbations, from the data scale
    /// (the gaps get the output's scale: m1 = 1 makes x and y the same units on the upper border).
    pub fn typical(&self, y_scale: f64) -> Vec<f64> {
        let mut t = coefficient_scales(self.na, &self.b, 0.0);
        t.extend([1.0, 0.1 * y_scale, 0.1 * y_scale]);
        t
    }
}

/// Typical magnitudes of a linear block's coefficients `a` (`na` of them) and `b`: 0.5 for each a (poles
/// anywhere in the unit circle), the largest |b| (at least `b_floor` and 1e-6) for each b.
pub(crate) fn coefficient_scales(na: usize, b: &[f64], b_floor: f64) -> Vec<f64> {
    let bmax = b
        .iter()
        .fold(b_floor.abs(), |m, v| m.max(v.abs()))
        .max(1e-6);
    let mut t = vec![0.5; na];
    t.extend(std::iter::repeat_n(bmax, b.len()));
    t
}

/// Coefficients `a`, `b` (at most the plant's orders) padded with zeros to the plant's arrays.
fn padded(a: &[f64], b: &[f64]) -> ([f64; MAX_ORDER], [f64; MAX_ORDER + 1]) {
    let mut pa = [0.0; MAX_ORDER];
    let mut pb = [0.0; MAX_ORDER + 1];
    pa.iter_mut().zip(a).for_each(|(d, s)| *d = *s);
    pb.iter_mut().zip(b).for_each(|(d, s)| *d = *s);
    (pa, pb)
}

/// One catalogue extension with its parameters. `ExtraDelay` and `LinearOrder` change the base model's
/// structure instead (see [`crate::diagnose::catalogue`]); they are `None` here.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Extension {
    None,
    /// `c(k) = c + rate k`, rates per sample.
    GapDrift {
        c1_rate: f64,
        c2_rate: f64,
    },
    /// Quadratic and cubic border terms (see [`CurvedBorders`]).
    CurvedBorders {
        upper: [f64; 2],
        lower: [f64; 2],
    },
    /// The model output clipped to `[lo, hi]`.
    Saturation {
        lo: f64,
        hi: f64,
    },
    /// `a_sin sin(omega k) + a_cos cos(omega k)` added to the output, k from the start of the record.
    Periodic {
        omega: f64,
        a_sin: f64,
        a_cos: f64,
    },
    /// The sensor rounds to `offset + step Z`; the model output is the expected reading with Gaussian noise
    /// of std `sigma` before the rounding ([`effects::expected_reading`]; sigma = 0: plain rounding).
    Quantization {
        step: f64,
        offset: f64,
        sigma: f64,
    },
    /// Elasto-plastic Coulomb element with the backlash, k_e = 1 (absorbed into b, c1, c2, as m1 is);
    /// `form` is where the play sits ([`FrictionForm`]: after it, or inside its spring).
    Friction {
        f_plus: f64,
        f_minus: f64,
        form: FrictionForm,
    },
    /// AR noise model on the output error: `e(k) = sum phi_i e(k-i) + white`.
    ColouredNoise {
        phi: Vec<f64>,
    },
    /// The linear block's coefficients while its output falls ([`DirectionDependent`]): `a` has the base
    /// model's `na` entries, `b` its `nb + 1` ([`EffectModel::rebased`] keeps them so).
    DirectionDependent {
        a: Vec<f64>,
        b: Vec<f64>,
    },
}

impl Extension {
    /// The catalogue entry this extension fits (`None` for [`Extension::None`]; extra-delay and
    /// linear-order change the base model instead).
    pub fn id(&self) -> Option<EffectId> {
        Some(match self {
            Extension::None => return None,
            Extension::GapDrift { .. } => EffectId::GapDrift,
            Extension::CurvedBorders { .. } => EffectId::CurvedBorders,
            Extension::Saturation { .. } => EffectId::Saturation,
            Extension::Periodic { .. } => EffectId::PeriodicDisturbance,
            Extension::Quantization { .. } => EffectId::Quantization,
            Extension::Friction { .. } => EffectId::Friction,
            Extension::ColouredNoise { .. } => EffectId::ColouredNoise,
            Extension::DirectionDependent { .. } => EffectId::DirectionDependent,
        })
    }

    /// Parameters in the fitted vector.
    pub fn n_fitted(&self) -> usize {
        match self {
            Extension::None => 0,
            Extension::Quantization { .. } => 1,
            Extension::GapDrift { .. }
            | Extension::Saturation { .. }
            | Extension::Friction { .. } => 2,
            Extension::CurvedBorders { .. } => 4,
            Extension::Periodic { .. } => 3,
            Extension::ColouredNoise { phi } => phi.len(),
            Extension::DirectionDependent { a, b } => a.len() + b.len(),
        }
    }

    /// Parameters estimated from the data (for the information criterion): quantization's step and offset
    /// are estimated from the measured values (not by the least-squares fit) and count too.
    pub fn n_estimated(&self) -> usize {
        match self {
            Extension::Quantization { .. } => 3,
            e => e.n_fitted(),
        }
    }

    /// The fitted parameters; gap-drift rates are scaled by `time_scale` (total drift over that many samples)
    /// so that they have the gaps' magnitude.
    pub fn pack(&self, time_scale: f64) -> Vec<f64> {
        match self {
            Extension::None => vec![],
            Extension::Quantization { sigma, .. } => vec![*sigma],
            Extension::GapDrift { c1_rate, c2_rate } => {
                vec![c1_rate * time_scale, c2_rate * time_scale]
            }
            Extension::CurvedBorders { upper, lower } => {
                vec![upper[0], upper[1], lower[0], lower[1]]
            }
            Extension::Saturation { lo, hi } => vec![*lo, *hi],
            Extension::Periodic {
                omega,
                a_sin,
                a_cos,
            } => vec![*omega, *a_sin, *a_cos],
            Extension::Friction {
                f_plus, f_minus, ..
            } => vec![*f_plus, *f_minus],
            Extension::ColouredNoise { phi } => phi.clone(),
            Extension::DirectionDependent { a, b } => a.iter().chain(b).copied().collect(),
        }
    }

    /// The inverse of [`Extension::pack`] for this variant.
    pub fn unpack(&self, th: &[f64], time_scale: f64) -> Self {
        match self {
            Extension::None => self.clone(),
            // Noise of more than two steps hides the rounding (the expected reading is then the value
            // itself), so sigma is bounded there: the fit cannot wander off to an unbounded parameter.
            Extension::Quantization { step, offset, .. } => Extension::Quantization {
                step: *step,
                offset: *offset,
                sigma: th[0].abs().min(2.0 * step),
            },
            Extension::GapDrift { .. } => Extension::GapDrift {
                c1_rate: th[0] / time_scale,
                c2_rate: th[1] / time_scale,
            },
            Extension::CurvedBorders { .. } => Extension::CurvedBorders {
                upper: [th[0], th[1]],
                lower: [th[2], th[3]],
            },
            Extension::Saturation { .. } => Extension::Saturation {
                lo: th[0],
                hi: th[1],
            },
            Extension::Periodic { .. } => Extension::Periodic {
                omega: th[0],
                a_sin: th[1],
                a_cos: th[2],
            },
            Extension::Friction { form, .. } => Extension::Friction {
                f_plus: th[0],
                f_minus: th[1],
                form: *form,
            },
            Extension::ColouredNoise { .. } => Extension::ColouredNoise { phi: th.to_vec() },
            Extension::DirectionDependent { a, .. } => Extension::DirectionDependent {
                a: th[..a.len()].to_vec(),
                b: th[a.len()..].to_vec(),
            },
        }
    }

    /// This extension on a base model of other orders: a falling set ([`Extension::DirectionDependent`])
    /// takes the base's length, a new coefficient starting at the base's own (no direction dependence in it);
    /// every other extension is unchanged.
    fn fitted_to(&self, base: &BaseModel) -> Self {
        match self {
            Extension::DirectionDependent { a, b } => {
                let resize = |fall: &[f64], own: &[f64]| -> Vec<f64> {
                    (0..own.len())
                        .map(|i| fall.get(i).copied().unwrap_or(own[i]))
                        .collect()
                };
                Extension::DirectionDependent {
                    a: resize(a, &base.a),
                    b: resize(b, &base.b),
                }
            }
            e => e.clone(),
        }
    }

    /// The deterministic part as test-bench effects (the noise model has none).
    pub fn effects(&self) -> Effects {
        let mut e = Effects::default();
        self.add_to(&mut e);
        e
    }

    /// Switch this extension's deterministic part on in `e`.
    fn add_to(&self, e: &mut Effects) {
        match self {
            Extension::None | Extension::ColouredNoise { .. } => {}
            Extension::GapDrift { c1_rate, c2_rate } => {
                e.gap_drift = Some(GapDrift {
                    c1_rate: *c1_rate,
                    c2_rate: *c2_rate,
                })
            }
            Extension::CurvedBorders { upper, lower } => {
                e.curved_borders = Some(CurvedBorders {
                    upper: *upper,
                    lower: *lower,
                })
            }
            Extension::Saturation { lo, hi } => {
                e.saturation = Some(Saturation {
                    lo: *lo,
                    hi: *hi,
                    before_noise: true,
                })
            }
            Extension::Periodic {
                omega,
                a_sin,
                a_cos,
            } => {
                // a_s sin + a_c cos = A sin(omega k + phase), A = hypot, phase = atan2(a_c, a_s).
                e.periodic = Some(Periodic {
                    amplitude: a_sin.hypot(*a_cos),
                    omega: *omega,
                    phase: a_cos.atan2(*a_sin),
                })
            }
            Extension::Quantization { step, offset, .. } => {
                e.quantization = Some(Quantization {
                    step: *step,
                    offset: *offset,
                })
            }
            Extension::DirectionDependent { a, b } => {
                let (a, b) = padded(a, b);
                e.direction_dependent = Some(DirectionDependent { a, b });
            }
            Extension::Friction {
                f_plus,
                f_minus,
                form,
            } => {
                e.friction = Some(Friction {
                    k_e: 1.0,
                    f_plus: *f_plus,
                    f_minus: *f_minus,
                    form: *form,
                })
            }
        }
    }
}

/// What a fit minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Objective {
    /// Output error: y - simulation.
    Simulation,
    /// One-step prediction error of the model with its noise model.
    Prediction,
}

/// A base model with the extensions kept so far, in the order they were kept (each catalogue entry at most
/// once; see [`EffectModel::can_add`] for the ones that do not combine).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectModel {
    pub base: BaseModel,
    pub exts: Vec<Extension>,
}

/// The model's signals over a record.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Simulation {
    /// Linear block output.
    pub x: Vec<f64>,
    /// Backlash output.
    pub w: Vec<f64>,
    /// Model output (simulation, noise-free).
    pub y: Vec<f64>,
    pub mode: Vec<Mode>,
}

impl EffectModel {
    pub fn plain(base: BaseModel) -> Self {
        Self {
            base,
            exts: Vec::new(),
        }
    }

    /// This model with `ext` added last.
    pub fn with(&self, ext: Extension) -> Self {
        let mut m = self.clone();
        m.exts.push(ext);
        m
    }

    /// This model's extensions on another base model (a falling set resized to its orders).
    pub fn rebased(&self, base: BaseModel) -> Self {
        Self {
            exts: self.exts.iter().map(|e| e.fitted_to(&base)).collect(),
            base,
        }
    }

    /// The linear block's falling set, if the model has one.
    fn falling_set(&self) -> Option<(&[f64], &[f64])> {
        self.exts.iter().find_map(|e| match e {
            Extension::DirectionDependent { a, b } => Some((a.as_slice(), b.as_slice())),
            _ => None,
        })
    }

    /// The extension fitting catalogue entry `id`, if the model has it.
    pub fn extension(&self, id: EffectId) -> Option<&Extension> {
        self.exts.iter().find(|e| e.id() == Some(id))
    }

    /// The noise model's AR coefficients, if the model has one.
    pub fn noise(&self) -> Option<&[f64]> {
        self.exts.iter().find_map(|e| match e {
            Extension::ColouredNoise { phi } => Some(phi.as_slice()),
            _ => None,
        })
    }

    /// Whether the extension of `id` can be added: each entry once; nothing after a noise model (it
    /// describes what the deterministic part leaves, so it ends the search); curved borders and friction
    /// with the play inside its spring never together (that element has straight borders, as the test
    /// bench's). Extra-delay and linear-order change the base model and combine with everything.
    pub fn can_add(&self, id: EffectId) -> bool {
        let has = |i: EffectId| self.extension(i).is_some();
        !has(id) && self.noise().is_none() && !(id == EffectId::CurvedBorders && self.has_contact())
    }

    /// Whether `ext` can be added ([`EffectModel::can_add`] for its entry, and no friction with the play inside
    /// its spring on curved borders).
    pub fn admits(&self, ext: &Extension) -> bool {
        let contact = matches!(
            ext,
            Extension::Friction {
                form: FrictionForm::Contact,
                ..
            }
        );
        ext.id().is_some_and(|id| self.can_add(id))
            && !(contact && self.extension(EffectId::CurvedBorders).is_some())
    }

    /// Whether the model has friction with the play inside its spring.
    pub fn has_contact(&self) -> bool {
        self.exts.iter().any(|e| {
            matches!(
                e,
                Extension::Friction {
                    form: FrictionForm::Contact,
                    ..
                }
            )
        })
    }

    /// The fitted parameter vector: base, then each extension's in order.
    pub fn pack(&self, time_scale: f64) -> Vec<f64> {
        let mut v = self.base.pack();
        for e in &self.exts {
            v.extend(e.pack(time_scale));
        }
        v
    }

    pub fn unpack(&self, th: &[f64], time_scale: f64) -> Self {
        let mut at = self.base.n_params();
        let base = self.base.unpack(&th[..at]);
        let exts = self
            .exts
            .iter()
            .map(|e| {
                let n = e.n_fitted();
                at += n;
                e.unpack(&th[at - n..at], time_scale)
            })
            .collect();
        Self { base, exts }
    }

    /// Parameters counted by the information criterion.
    pub fn n_estimated(&self) -> usize {
        self.base.n_params() + self.exts.iter().map(Extension::n_estimated).sum::<usize>()
    }

    /// The deterministic part of every extension as test-bench effects.
    pub fn effects(&self) -> Effects {
        let mut e = Effects::default();
        for x in &self.exts {
            x.add_to(&mut e);
        }
        e
    }

    /// Whether the extensions' own parameters describe a valid element: a non-empty friction slip range
    /// (and a play of some width inside the spring), saturation levels in order, a positive rounding step.
    fn extensions_valid(&self) -> bool {
        let play = self.base.c1 + self.base.c2;
        self.exts.iter().all(|e| match e {
            Extension::Friction {
                f_plus,
                f_minus,
                form,
            } => {
                // An empty slip range (also NaN) is not a friction element; with the play inside the spring
                // the play must have a width.
                let range = f_plus + f_minus;
                range > 0.0 && !(*form == FrictionForm::Contact && (play.is_nan() || play < 0.0))
            }
            Extension::Saturation { lo, hi } => lo <= hi,
            Extension::Quantization { step, .. } => *step > 0.0 && step.is_finite(),
            Extension::DirectionDependent { a, b } => {
                is_stable(a) && a.iter().chain(b).all(|v| v.is_finite())
            }
            _ => true,
        })
    }

    /// The quantizer and its noise level before the rounding, if the model has one.
    fn reading(&self) -> Option<(Quantization, f64)> {
        self.exts.iter().find_map(|e| match e {
            Extension::Quantization {
                step,
                offset,
                sigma,
            } => Some((
                Quantization {
                    step: *step,
                    offset: *offset,
                },
                *sigma,
            )),
            _ => None,
        })
    }

    /// Simulate samples `0..n` of the model output into `sim` (reusing its buffers), as a fit sees it, from
    /// rest at the input level `rest` (see [`Rest`]).
    /// Returns `false` if the model is not valid: m2 <= 0 or non-finite parameters, an unstable linear block,
    /// `|x| > limit`, an empty friction slip range, or a backlash that visits an inverted memory zone on
    /// these samples (see the chatter check in the loop).
    pub fn simulate_into(
        &self,
        u: &[f64],
        rest: Rest,
        n: usize,
        limit: f64,
        sim: &mut Simulation,
    ) -> bool {
        self.run(u, rest, n, limit, true, sim)
    }

    fn run(
        &self,
        u: &[f64],
        rest: Rest,
        n: usize,
        limit: f64,
        strict: bool,
        sim: &mut Simulation,
    ) -> bool {
        let b = &self.base;
        if !(b.m2 > 0.0 && b.m2.is_finite() && b.c1.is_finite() && b.c2.is_finite()) {
            return false;
        }
        if !is_stable(&b.a) || !self.extensions_valid() {
            return false;
        }
        let contact = self.has_contact();
        let n = n.min(u.len());
        let bl = b.backlash();
        // The rounding is the expected reading (below), not the bench's plain rounding.
        let expected = self.reading();
        let eff = Effects {
            quantization: None,
            ..self.effects()
        };
        let drift = eff.gap_drift.as_ref();
        let curve = eff.curved_borders.as_ref();
        let friction = eff.friction.as_ref();
        let slack = 1e-12 * limit
            + match drift {
                Some(d) => (d.c1_rate.abs() + d.c2_rate.abs()) * 1.000_001,
                None => 0.0,
            };
        let sensor_needed = eff.periodic.is_some() || eff.saturation.is_some();
        let output = |f: f64, k: usize| {
            let v = if sensor_needed {
                effects::sensor(&eff, f, 0.0, k as u64)
            } else {
                f
            };
            match &expected {
                Some((q, sigma)) => effects::expected_reading(q, v, *sigma),
                None => v,
            }
        };
        sim.x.clear();
        sim.w.clear();
        sim.y.clear();
        sim.mode.clear();
        let u_rest = rest.0;
        let x_rest = b.static_gain() * u_rest;
        let (mut w_prev, mut f_prev) = (b.rest_memory(x_rest, contact), 0.0);
        let d = b.delay;
        let fall = self.falling_set();
        let linear = |a: &[f64], bb: &[f64], k: usize, xs: &[f64]| {
            let mut x = 0.0;
            for (i, ai) in a.iter().enumerate() {
                x -= ai * if k > i { xs[k - 1 - i] } else { x_rest };
            }
            for (j, bj) in bb.iter().enumerate() {
                x += bj * if k >= d + j { u[k - d - j] } else { u_rest };
            }
            x
        };
        for k in 0..n {
            let rise = linear(&b.a, &b.b, k, &sim.x);
            let x = match fall {
                Some((fa, fb)) => {
                    let prev = if k > 0 { sim.x[k - 1] } else { x_rest };
                    DirectionDependent::choose(prev, rise, linear(fa, fb, k, &sim.x))
                }
                None => rise,
            };
            if x.is_nan() || x.abs() > limit {
                return false;
            }
            if let (true, Some(fr)) = (contact, friction) {
                let blk = drift.map_or(bl, |d| d.at(&bl, k as u64));
                let (f, z, mode) = effects::contact_step(fr, &blk, x, w_prev);
                sim.x.push(x);
                sim.w.push(z);
                sim.y.push(output(f, k));
                sim.mode.push(mode);
                w_prev = z;
                f_prev = f;
                continue;
            }
            let (w, mode) = effects::backlash_step(&bl, drift, curve, x, w_prev, k as u64);
            if strict && k > 0 {
                // A backlash whose memory zone is not inverted moves onto the upper border only while x rises
                // and onto the lower one only while x falls (up to the borders' own drift). Where the zone is
                // inverted (upper border left of the lower one) the rule flips between the borders every
                // sample: a chatter no plant shows and a fit would exploit, so such parameters are refused.
                let dx = x - sim.x[k - 1];
                let ok = match mode {
                    Mode::Up => dx >= -slack,
                    Mode::Down => dx <= slack,
                    Mode::Held => true,
                };
                if !ok {
                    return false;
                }
            }
            let f = match friction {
                Some(fr) => effects::friction_step(fr, f_prev, w - w_prev),
                None => w,
            };
            sim.x.push(x);
            sim.w.push(w);
            sim.y.push(output(f, k));
            sim.mode.push(mode);
            w_prev = w;
            f_prev = f;
        }
        sim.y.iter().all(|v| v.is_finite())
    }

    /// Simulate a fitted model over a record (held-out part, another record): the same as
    /// [`EffectModel::simulate_into`] except that a visit to an inverted memory zone is simulated by the contract's
    /// rule rather than refused (a model fitted where its zone was valid must still give a prediction).
    pub fn simulate(&self, u: &[f64], rest: Rest, n: usize, limit: f64) -> Option<Simulation> {
        let mut s = Simulation::default();
        self.run(u, rest, n, limit, false, &mut s).then_some(s)
    }

    /// One-step-ahead prediction of y(k) from y up to k-1: the simulation plus, with a noise model,
    /// `sum phi_i (y(k-i) - s(k-i))` (s the simulation). Without a noise model the predictor of an
    /// output-error model is its simulation.
    pub fn predict_from(&self, sim: &[f64], y: &[f64]) -> Vec<f64> {
        match self.noise() {
            Some(phi) => (0..sim.len())
                .map(|k| {
                    let mut p = sim[k];
                    for (i, f) in phi.iter().enumerate() {
                        if k > i {
                            p += f * (y[k - 1 - i] - sim[k - 1 - i]);
                        }
                    }
                    p
                })
                .collect(),
            None => sim.to_vec(),
        }
    }
}

/// The stability test of the linear block (shared with the recursive estimator).
pub use crate::plant::linear::is_stable;

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::plant::effects::simulate_with_effects;
    use crate::plant::{ArxParams, PlantParams};

    /// A falling slope m2 that is not positive and finite is no backlash: the model does not run.
    #[test]
    fn a_slope_that_is_not_positive_and_finite_does_not_run() {
        let u = input(50);
        for m2 in [-1.0, 0.0, f64::INFINITY, f64::NAN] {
            let m = EffectModel::plain(BaseModel { m2, ..paper_base() });
            assert!(m.simulate(&u, Rest::ZERO, 50, 1e6).is_none(), "m2 = {m2}");
        }
    }

    /// The paper's linear block (static gain 0.8 / 2 = 0.4) and backlash, for the diagnose modules' tests.
    pub(crate) fn paper_base() -> BaseModel {
        BaseModel {
            na: 2,
            nb: 0,
            delay: 1,
            a: vec![0.45, 0.55],
            b: vec![0.8],
            m1: 1.0,
            m2: 1.5,
            c1: 0.5,
            c2: 1.0,
        }
    }

    /// Two tones, 2 sin(0.37 k) + cos(0.05 k): the diagnose modules' test input.
    pub(crate) fn input(n: usize) -> Vec<f64> {
        (0..n)
            .map(|k| 2.0 * (k as f64 * 0.37).sin() + (k as f64 * 0.05).cos())
            .collect()
    }

    /// [`input`] and the paper model's simulation of it from rest at 0.
    pub(crate) fn paper_record(n: usize) -> (Vec<f64>, Simulation) {
        let u = input(n);
        let sim = EffectModel::plain(paper_base())
            .simulate(&u, Rest::ZERO, n, 1e6)
            .expect("the paper model runs");
        (u, sim)
    }

    #[test]
    fn plain_model_is_the_plant_and_extensions_are_the_bench() {
        let u = input(600);
        let p = PlantParams::PAPER;
        let exts = [
            Extension::None,
            Extension::GapDrift {
                c1_rate: 1e-3,
                c2_rate: 5e-4,
            },
            Extension::CurvedBorders {
                upper: [0.1, -0.02],
                lower: [0.05, 0.01],
            },
            Extension::Saturation { lo: -1.0, hi: 1.2 },
            Extension::Periodic {
                omega: 0.3,
                a_sin: 0.2,
                a_cos: -0.1,
            },
            Extension::Quantization {
                step: 0.1,
                offset: 0.02,
                sigma: 0.0,
            },
            Extension::Friction {
                f_plus: 0.8,
                f_minus: 1.1,
                form: FrictionForm::Series,
            },
            Extension::Friction {
                f_plus: 0.8,
                f_minus: 1.1,
                form: FrictionForm::Contact,
            },
            Extension::DirectionDependent {
                a: vec![0.2, 0.15],
                b: vec![0.5],
            },
        ];
        // Each alone, and every pair that combines (in both orders of adding them).
        let mut models: Vec<EffectModel> = exts
            .iter()
            .map(|e| EffectModel::plain(paper_base()).with(e.clone()))
            .collect();
        for a in &exts[1..] {
            for b in &exts[1..] {
                let m = EffectModel::plain(paper_base()).with(a.clone());
                if m.admits(b) {
                    models.push(m.with(b.clone()));
                }
            }
        }
        assert!(models.len() > 50, "{}", models.len());
        for m in models {
            let s = m.simulate(&u, Rest::ZERO, u.len(), 1e9).unwrap();
            let bench = simulate_with_effects(&p, &m.effects(), &u, 0).unwrap();
            let ext = &m.exts;
            for (k, o) in bench.iter().enumerate() {
                assert!(
                    (s.y[k] - o.y).abs() < 1e-12,
                    "{ext:?} at {k}: {} vs {}",
                    s.y[k],
                    o.y
                );
                assert!((s.x[k] - o.x).abs() < 1e-12);
            }
        }
    }

    /// A falling set packs as a then b, follows the base model's orders when rebased (a new coefficient
    /// starts at the base's own), and an unstable one is not a valid model.
    #[test]
    fn falling_set_packs_rebases_and_must_be_stable() {
        let fall = Extension::DirectionDependent {
            a: vec![0.2, 0.15],
            b: vec![0.5],
        };
        let m = EffectModel::plain(paper_base()).with(fall.clone());
        let th = m.pack(1.0);
        assert_eq!(th[6..], [0.2, 0.15, 0.5]);
        assert_eq!(m.unpack(&th, 1.0), m);
        let wider = m.rebased(paper_base().with_orders(3, 1, 1));
        assert_eq!(
            wider.exts[0],
            Extension::DirectionDependent {
                a: vec![0.2, 0.15, 0.0],
                b: vec![0.5, 0.0],
            }
        );
        let narrower = m.rebased(paper_base().with_orders(1, 0, 1));
        assert_eq!(
            narrower.exts[0],
            Extension::DirectionDependent {
                a: vec![0.2],
                b: vec![0.5],
            }
        );
        let u = input(50);
        assert!(m.simulate(&u, Rest::ZERO, 50, 1e9).is_some());
        let unstable = EffectModel::plain(paper_base()).with(Extension::DirectionDependent {
            a: vec![-1.5, 0.0],
            b: vec![0.5],
        });
        assert!(unstable.simulate(&u, Rest::ZERO, 50, 1e9).is_none());
    }

    #[test]
    fn pack_unpack_round_trip() {
        let m = EffectModel::plain(paper_base())
            .with(Extension::GapDrift {
                c1_rate: 1e-4,
                c2_rate: -2e-4,
            })
            .with(Extension::Saturation { lo: -1.0, hi: 2.0 });
        let th = m.pack(1000.0);
        assert_eq!(th.len(), 10);
        assert_eq!(m.n_estimated(), 10);
        let back = m.unpack(&th, 1000.0);
        assert_eq!(back.base, m.base);
        match back.exts[..] {
            [
                Extension::GapDrift { c1_rate, c2_rate },
                Extension::Saturation { lo, hi },
            ] => {
                assert!((c1_rate - 1e-4).abs() < 1e-18 && (c2_rate + 2e-4).abs() < 1e-18);
                assert_eq!((lo, hi), (-1.0, 2.0));
            }
            _ => panic!("{back:?}"),
        }
    }

    #[test]
    fn unstable_model_is_refused_and_prediction_uses_the_noise_model() {
        let mut b = paper_base();
        b.a = vec![-2.5, 0.0];
        assert!(
            EffectModel::plain(b)
                .simulate(&input(500), Rest::ZERO, 500, 1e6)
                .is_none()
        );
        let m = EffectModel::plain(paper_base()).with(Extension::ColouredNoise { phi: vec![0.5] });
        assert!(
            !m.can_add(EffectId::GapDrift),
            "nothing after a noise model"
        );
        let sim = vec![1.0, 2.0, 3.0];
        let y = vec![1.5, 2.0, 2.0];
        assert_eq!(m.predict_from(&sim, &y), vec![1.0, 2.25, 3.0]);
        let _ = ArxParams::PAPER;
    }

    #[test]
    fn stability_test() {
        assert!(is_stable(&[]));
        assert!(is_stable(&[0.45, 0.55]));
        assert!(is_stable(&[-0.9]));
        assert!(!is_stable(&[1.03]));
        assert!(!is_stable(&[-1.0]));
        // (1 - 0.5 z^-1)(1 - 1.2 z^-1) = 1 - 1.7 z^-1 + 0.6 z^-2: a root at 1.2.
        assert!(!is_stable(&[-1.7, 0.6]));
        // (1 - 0.5 z^-1)(1 + 0.8 z^-1)(1 - 0.9 z^-1)
        let (p, q, r) = (-0.5, 0.8, -0.9);
        assert!(is_stable(&[p + q + r, p * q + p * r + q * r, p * q * r]));
        assert!(!is_stable(&[0.0, 0.0, 1.01]));
    }

    /// By hand on the paper's backlash (m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1): at x = 2 the band is
    /// [1 (2 - 0.5), 1.5 (2 + 1)] = [1.5, 4.5], so 0 moves up to 1.5; at x = -3 it is [-3.5, -3], so 0 moves
    /// down to -3; at 0 it stays 0; with the slider inside the spring it rests at x. Gaps c1 = 5, c2 = -4
    /// invert the band at x = 1 ([-4, -4.5]): the upper border, -4.
    #[test]
    fn rest_memory_by_hand() {
        let b = paper_base();
        assert_eq!(b.rest_memory(2.0, false), 1.5);
        assert_eq!(b.rest_memory(-3.0, false), -3.0);
        assert_eq!(b.rest_memory(0.0, false), 0.0);
        assert_eq!(b.rest_memory(0.0, true), 0.0);
        assert_eq!(b.rest_memory(-3.0, true), -3.0);
        let inverted = BaseModel {
            c1: 5.0,
            c2: -4.0,
            ..paper_base()
        };
        assert_eq!(inverted.rest_memory(1.0, false), -4.0);
    }

    /// The chatter check allows x to fall a little on the upper border while both gaps narrow: each sample
    /// the border moves by up to |c1_rate| + |c2_rate|. Here x = u(k-1) rises onto the upper border, then
    /// falls 0.002 per sample while c1 shrinks 0.005 per sample, so w still rises (mode up, x falling less
    /// than the drift): a valid drifting backlash, simulated.
    #[test]
    fn narrowing_gaps_let_x_fall_on_the_upper_border() {
        let base = BaseModel {
            na: 0,
            nb: 0,
            delay: 1,
            a: vec![],
            b: vec![1.0],
            m1: 1.0,
            m2: 1.0,
            c1: 0.5,
            c2: 0.5,
        };
        let mut u: Vec<f64> = (0..30).map(|k| 0.1 * k as f64).collect();
        u.extend((1..=40).map(|k| 2.9 - 0.002 * k as f64));
        let m = EffectModel::plain(base).with(Extension::GapDrift {
            c1_rate: -0.005,
            c2_rate: -0.005,
        });
        let mut sim = Simulation::default();
        assert!(m.simulate_into(&u, Rest::ZERO, u.len(), 1e9, &mut sim));
        let last = sim.mode.len() - 1;
        assert_eq!(sim.mode[last], Mode::Up);
        assert!(sim.x[last] < sim.x[last - 1]);
    }

    /// Coefficient magnitudes: 0.5 per a, the largest |b| per b (raised to the floor, never below 1e-6);
    /// padding fills the plant's arrays with zeros after the given coefficients.
    #[test]
    fn coefficient_scales_and_padding_by_hand() {
        assert_eq!(
            coefficient_scales(2, &[0.3, -0.8], 0.0),
            vec![0.5, 0.5, 0.8, 0.8]
        );
        assert_eq!(coefficient_scales(0, &[0.3], -2.0), vec![2.0]);
        assert_eq!(coefficient_scales(1, &[0.0], 0.0), vec![0.5, 1e-6]);
        let (a, b) = padded(&[0.1, 0.2], &[0.3]);
        assert_eq!(a[..2], [0.1, 0.2]);
        assert!(a[2..].iter().chain(&b[1..]).all(|v| *v == 0.0));
        assert_eq!(b[0], 0.3);
    }

    /// From rest at a constant input u0 the model stays at rest: x = gain u0 (gain 0.8 / (1 + 0.45 + 0.55) =
    /// 0.4), w at the rest memory above: u0 = 5 gives x = 2, y = 1.5; u0 = -7.5 gives x = -3, y = -3.
    #[test]
    fn a_model_at_rest_stays_there() {
        let b = paper_base();
        assert!((b.static_gain() - 0.4).abs() < 1e-15);
        for (u0, x, y) in [(5.0, 2.0, 1.5), (-7.5, -3.0, -3.0)] {
            let u = vec![u0; 20];
            let s = EffectModel::plain(b.clone())
                .simulate(&u, Rest(u0), 20, 1e9)
                .unwrap();
            for k in 0..20 {
                assert!((s.x[k] - x).abs() < 1e-12, "{u0} at {k}: {}", s.x[k]);
                assert!((s.y[k] - y).abs() < 1e-12, "{u0} at {k}: {}", s.y[k]);
            }
        }
        // A block with 1 + sum a = 0 has no static gain: 0 by convention.
        let marginal = BaseModel {
            a: vec![-0.5, -0.5],
            ..paper_base()
        };
        assert_eq!(marginal.static_gain(), 0.0);
    }

    #[test]
    fn typical_magnitudes_and_orders_by_hand() {
        let b = BaseModel {
            nb: 1,
            b: vec![0.8, -1.2],
            ..paper_base()
        };
        // a: 0.5 each; b: the largest |b| for each; m2: 1; the gaps a tenth of the output's scale.
        assert_eq!(b.typical(10.0), vec![0.5, 0.5, 1.2, 1.2, 1.0, 1.0, 1.0]);
        assert_eq!(
            BaseModel::zero(1, 0, 1).typical(1.0),
            vec![0.5, 1e-6, 1.0, 0.1, 0.1]
        );
        let w = b.with_orders(3, 0, 2);
        assert_eq!((w.na, w.nb, w.delay), (3, 0, 2));
        assert_eq!(w.a, vec![0.45, 0.55, 0.0]);
        assert_eq!(w.b, vec![0.8]);
        assert_eq!(b.n_params(), 7);
        assert_eq!(b.pack(), vec![0.45, 0.55, 0.8, -1.2, 1.5, 0.5, 1.0]);
        assert_eq!(b.unpack(&b.pack()), b);
    }

    /// The model's output with a quantizer is the expected reading of the sensor's value, rounded once: a
    /// saturation that never clips (which sends the output through the sensor) changes nothing, also with
    /// noise before the rounding (sigma > 0, readings off the grid).
    #[test]
    fn the_sensor_does_not_round_before_the_expected_reading() {
        let u = input(80);
        let q = Extension::Quantization {
            step: 0.5,
            offset: 0.1,
            sigma: 0.2,
        };
        let wide = Extension::Saturation { lo: -1e9, hi: 1e9 };
        let plain = EffectModel::plain(paper_base()).with(q.clone());
        let sensed = EffectModel::plain(paper_base()).with(wide).with(q);
        let a = plain.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y;
        let b = sensed.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y;
        assert_eq!(a, b);
        // Readings off the grid: the expectation over the noise, not a rounded value.
        assert!(
            a.iter()
                .any(|v| ((v - 0.1) / 0.5 - ((v - 0.1) / 0.5).round()).abs() > 1e-3)
        );
    }

    /// The extensions' own validity: a positive finite rounding step, saturation levels in order, a
    /// non-empty slip range, and a play of non-negative width for the contact form.
    #[test]
    fn extension_parameters_are_checked() {
        let with = |e: Extension| EffectModel::plain(paper_base()).with(e);
        let q = |step: f64| Extension::Quantization {
            step,
            offset: 0.0,
            sigma: 0.0,
        };
        assert!(with(q(0.1)).extensions_valid());
        assert!(!with(q(-0.1)).extensions_valid());
        assert!(!with(q(0.0)).extensions_valid());
        assert!(!with(q(f64::INFINITY)).extensions_valid());
        assert!(with(Extension::Saturation { lo: 1.0, hi: 1.0 }).extensions_valid());
        assert!(!with(Extension::Saturation { lo: 1.0, hi: 0.5 }).extensions_valid());
        let fr = |f_plus: f64, f_minus: f64, form: FrictionForm| Extension::Friction {
            f_plus,
            f_minus,
            form,
        };
        assert!(with(fr(0.5, -0.2, FrictionForm::Series)).extensions_valid());
        assert!(!with(fr(0.5, -0.5, FrictionForm::Series)).extensions_valid());
        assert!(!with(fr(f64::NAN, 1.0, FrictionForm::Series)).extensions_valid());
        assert!(with(fr(0.5, 0.5, FrictionForm::Contact)).extensions_valid());
        let mut narrow = EffectModel::plain(BaseModel {
            c1: 0.5,
            c2: -0.6,
            ..paper_base()
        });
        assert!(
            narrow
                .with(fr(0.5, 0.5, FrictionForm::Series))
                .extensions_valid()
        );
        narrow = narrow.with(fr(0.5, 0.5, FrictionForm::Contact));
        assert!(!narrow.extensions_valid());
        // The play is the sum c1 + c2: both negative is no play, one negative with a larger other is.
        let contact = |c1: f64, c2: f64| {
            EffectModel::plain(BaseModel {
                c1,
                c2,
                ..paper_base()
            })
            .with(fr(0.5, 0.5, FrictionForm::Contact))
            .extensions_valid()
        };
        assert!(!contact(-0.5, -0.6));
        assert!(contact(-0.2, 0.6));
        // A model with an invalid extension is not simulated.
        assert!(
            with(q(-0.1))
                .simulate(&input(50), Rest::ZERO, 50, 1e9)
                .is_none()
        );
    }

    /// Each entry once; curved borders never with contact friction (and the reverse); anything else
    /// combines.
    #[test]
    fn which_extensions_combine() {
        let plain = EffectModel::plain(paper_base());
        assert!(EffectId::ALL.iter().all(|&id| plain.can_add(id)));
        let drift = plain.with(Extension::GapDrift {
            c1_rate: 0.0,
            c2_rate: 0.0,
        });
        assert!(!drift.can_add(EffectId::GapDrift));
        assert!(drift.can_add(EffectId::Saturation));
        let contact = Extension::Friction {
            f_plus: 1.0,
            f_minus: 1.0,
            form: FrictionForm::Contact,
        };
        let with_contact = plain.with(contact.clone());
        assert!(with_contact.has_contact());
        assert!(!with_contact.can_add(EffectId::CurvedBorders));
        assert!(with_contact.can_add(EffectId::Saturation));
        let curved = plain.with(Extension::CurvedBorders {
            upper: [0.0; 2],
            lower: [0.0; 2],
        });
        assert!(!curved.has_contact());
        assert!(!curved.admits(&contact));
        assert!(curved.admits(&Extension::Friction {
            f_plus: 1.0,
            f_minus: 1.0,
            form: FrictionForm::Series,
        }));
        assert!(!plain.admits(&Extension::None));
    }

    /// The size limit is on |x| itself: an input block whose output reaches the limit exactly is
    /// valid, one that passes it is not.
    #[test]
    fn limit_admits_equality_and_refuses_beyond() {
        let mut base = paper_base().with_orders(0, 0, 1);
        base.b[0] = 1.0;
        let m = EffectModel::plain(base);
        let u = vec![2.0; 20];
        assert!(m.simulate(&u, Rest(2.0), 20, 2.0).is_some());
        assert!(m.simulate(&u, Rest(2.0), 20, 1.999).is_none());
        let mut beyond = u.clone();
        beyond[10] = -2.5;
        assert!(m.simulate(&beyond, Rest(2.0), 20, 2.0).is_none());
    }
}
