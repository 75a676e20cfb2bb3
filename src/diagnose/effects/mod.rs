//! The effect catalogue: one module per effect behind one trait, [`Effect`], registered in one list,
//! [`CATALOGUE`]. The engine, the decision, the report and the JSON output know the trait only.
//!
//! | id | extension fitted | its parameters | pointed to by |
//! | --- | --- | --- | --- |
//! | `gap-drift` | c1(k) = c1 + r1 k, c2(k) = c2 + r2 k | r1, r2 (per sample) | drift, by mode |
//! | `curved-borders` | upper = s + p2 s^2 + p3 s^3 (s = x - c1), lower = m2 s + q2 s^2 + q3 s^3 (s = x + c2) | p2, p3, q2, q3 | against x_hat, Billings, extremes |
//! | `extra-delay` | delay + 1, + 2 or + 3 (each fitted, the best kept) | the delay | cross-correlation |
//! | `linear-order` | na + 1 or nb + 1 (each fitted, the best kept) | the new coefficient | cross-correlation, Ljung-Box |
//! | `coloured-noise` | AR(p) noise model on the output error, p = 1..3 by BIC, least squares on the residual (deterministic part kept) | phi_1..phi_p | Ljung-Box |
//! | `saturation` | model output clipped to [lo, hi] | lo, hi | clipping, extremes, against x_hat, Billings |
//! | `periodic-disturbance` | a_s sin(w k) + a_c cos(w k) on the output; w from the spectrum peak, a_s, a_c by least squares, then all refined | w, amplitude, phase | spectrum peak (not at a frequency the input carries), Ljung-Box |
//! | `quantization` | the sensor rounds to offset + q Z; the model gives the expected reading for Gaussian noise of std sigma (at most 2 q) before the rounding | q and offset (from the value lattice), sigma (fitted) | value lattice |
//! | `friction` | elasto-plastic Coulomb element with the backlash, slip levels F+ and -F-, *series* (after the backlash output) or *contact* (the play inside the element's spring); both fitted, the better kept | F+, F-, form (k_e = 1: the stiffness is carried by b, as m1 = 1) | extremes, since reversal, by mode, Billings, drift, Ljung-Box |
//! | `direction-dependent` | the linear block has a second set of coefficients for while its output falls: x(k) = x_rise(k) unless that falls below x(k-1), then x_fall(k) | a_fall, b_fall (same orders) | by mode, since reversal, Billings, Ljung-Box |
//! | `dead-zone` | the linear block sees 0 while \|u\| <= width, u - width sign(u) beyond | the width | Billings, against x_hat, extremes, cross-correlation, Ljung-Box |
//! | `polynomial-feedback` | x(k) = the linear block's value + phi(x(k-1)) + r phi(x(k-2)), phi(x) = q2 x^2 + q3 x^3 (a cubic spring in feedback, Duffing: a force held over a sample enters through two taps) | q2, q3, r | none: a rival of play only (the verdict on play fits it; the rounds never do) |
//!
//! ## What an effect says about itself
//!
//! [`Effect`]: its id and words, the residual tests that point to it, where its fit starts ([`Plan`]), its
//! JSON parameters, its evidence figure with caption, and how the test bench draws it (its plant element
//! with random magnitudes, [`rig`]). An effect that adds parameters of its own to the model also implements
//! the model's half, [`Element`]: the parameters with their magnitudes and validity, and its element in the
//! simulation (the test bench's effect in `crate::plant::effects`, so that a fitted extension and a
//! simulated rig mean the same thing). Effects that change the declared structure (extra-delay,
//! linear-order) have no element: their plan refits the base model with other orders.
//!
//! ## How to add an effect
//!
//! 1. The plant element: a field of `crate::plant::effects::Effects` with its step, and its FMU parameters
//!    in `modelDescription/BacklashPlant.xml` (handled in `src/fmus/plant.rs`).
//! 2. A module here implementing [`Effect`] (and [`Element`] when it has parameters), with its tests.
//! 3. One line in [`CATALOGUE`].

pub mod coloured_noise;
pub mod curved_borders;
pub mod dead_zone;
pub mod direction_dependent;
pub mod extra_delay;
pub mod figure;
pub mod friction;
pub mod gap_drift;
pub mod linear_order;
pub mod periodic;
pub mod polynomial_feedback;
pub mod quantization;
pub mod rig;
pub mod saturation;

use serde::ser::{Serialize, SerializeMap, Serializer};

pub use crate::diagnose::fit::model::{Element, Extension, Scales};
pub use crate::diagnose::fit::starts::{Plan, StartContext};
pub use crate::diagnose::id::EffectId;
use crate::report::plot::PlotError;
use figure::Figure;
use rig::{Draw, Rig};

/// Every effect of the catalogue, in the contract's order. Adding an effect is a module and a line here.
pub static CATALOGUE: [&dyn Effect; 12] = [
    &gap_drift::GapDrift,
    &curved_borders::CurvedBorders,
    &extra_delay::ExtraDelay,
    &linear_order::LinearOrder,
    &coloured_noise::ColouredNoise,
    &saturation::Saturation,
    &periodic::Periodic,
    &quantization::Quantization,
    &friction::Friction,
    &direction_dependent::DirectionDependent,
    &dead_zone::DeadZone,
    &polynomial_feedback::PolynomialFeedback,
];

/// One entry of the catalogue. Everything the diagnosis does with an effect goes through this trait.
pub trait Effect: Sync {
    /// The contract's stable name.
    fn id(&self) -> EffectId;

    /// What the extension adds to the declared model, in words.
    fn describe(&self) -> &'static str;

    /// The residual tests whose rejection makes this effect a candidate, most specific first; none for a
    /// rival of play that the rounds never fit (its `imitates_play` is true).
    fn pointing_tests(&self) -> &'static [&'static str];

    /// The fits a candidate needs: its structures and their starts, or `None` when the data give it no
    /// start (no lattice for quantization, no room for a longer delay or order).
    fn plan(&self, cx: &StartContext) -> Option<Plan>;

    /// The fitted effect's parameters in the report's units (the JSON object's `parameters`).
    fn parameters(&self, fitted: &Fitted) -> Parameters;

    /// Draw the evidence figure for this effect, chosen in `fig`; returns its caption.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError>;

    /// Switch the effect on in a test-bench record being set up, with magnitudes drawn from `d`; returns
    /// them in words.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String;

    /// The log-count of the alternative structures the candidate searches (a uniform prior over them, the
    /// model-prior term of BIC); 0 for an effect that fits one structure.
    fn structure_penalty(&self) -> f64 {
        0.0
    }

    /// A noise model describes what the deterministic part leaves: it is chosen only when no deterministic
    /// extension is supported, and it ends the loop.
    fn is_noise_model(&self) -> bool {
        false
    }

    /// An effect this one aliases: when both are supported and the other's BIC is within
    /// [`crate::diagnose::search::decision::ALIAS_BIC`] of this one's, the other is chosen (a longer b
    /// polynomial whose leading terms are zero is a longer delay).
    fn yields_to(&self) -> Option<EffectId> {
        None
    }

    /// Whether this effect, without a gap, explains records that a model with play also fits (a smooth
    /// curve, friction, direction-dependent dynamics, a dead zone, clipping, a stiffening spring): the verdict on play tries the
    /// zero-gap model with it added, and play is present only where the model with a gap beats that too.
    fn imitates_play(&self) -> bool {
        false
    }

    /// Why this effect is not a candidate in spite of a rejecting test (evidence that belongs to the
    /// input), if so.
    fn set_aside(&self, _screen: &Screening) -> Option<String> {
        None
    }
}

/// A fitted candidate as its parameters are reported: its model, the model it extended, the record's length
/// and its sample period (when known: per-second forms of per-sample parameters).
pub struct Fitted<'a> {
    pub model: &'a crate::diagnose::fit::model::EffectModel,
    pub current: &'a crate::diagnose::fit::model::EffectModel,
    pub n: usize,
    pub ts: Option<f64>,
    /// The output level the fits worked about: levels in the output's units (saturation limits, a
    /// lattice's offset) are reported with it added back, where the record puts them.
    pub output_level: f64,
}

#[cfg(test)]
impl<'a> Fitted<'a> {
    /// `model` fitted on top of `current` over 100 samples of unknown period, about the output level 0
    /// (tests set the rest by struct update).
    pub fn on(
        model: &'a crate::diagnose::fit::model::EffectModel,
        current: &'a crate::diagnose::fit::model::EffectModel,
    ) -> Self {
        Self {
            model,
            current,
            n: 100,
            ts: None,
            output_level: 0.0,
        }
    }
}

impl Fitted<'_> {
    /// The fitted model's extension of `id` (an effect reads its own).
    pub fn extension(&self, id: EffectId) -> Option<&Extension> {
        self.model.extension(id)
    }

    /// The parameters `of` the fitted model's extension of `id`; none when it has none.
    pub fn own(&self, id: EffectId, of: impl FnOnce(&Extension) -> Parameters) -> Parameters {
        self.extension(id).map_or_else(Parameters::new, of)
    }
}

/// What a round's residual tests found, as a candidacy sees it.
pub struct Screening<'a> {
    /// The input on the fit part.
    pub u: &'a [f64],
    /// The residual spectrum's peak [rad/sample].
    pub omega: f64,
    /// The names of the tests that rejected.
    pub rejected: &'a [&'static str],
}

/// An effect's parameters: named values in the order the effect gives them, serialised as a JSON object
/// (absent values are left out).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Parameters(Vec<(&'static str, serde_json::Value)>);

impl Parameters {
    pub fn new() -> Self {
        Self::default()
    }

    /// This set with `name` = `value` added last.
    pub fn with(mut self, name: &'static str, value: impl Serialize) -> Self {
        let v = serde_json::to_value(value).unwrap_or(serde_json::Value::Null);
        self.0.push((name, v));
        self
    }

    /// This set with `name` = `value` added last when there is a value.
    pub fn with_some(self, name: &'static str, value: Option<impl Serialize>) -> Self {
        match value {
            Some(v) => self.with(name, v),
            None => self,
        }
    }

    /// The value of `name`, if set.
    pub fn get(&self, name: &str) -> Option<&serde_json::Value> {
        self.0.iter().find(|(k, _)| *k == name).map(|(_, v)| v)
    }
}

impl Serialize for Parameters {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in &self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

impl EffectId {
    /// The catalogue's effect of this id. Every id is made by its effect's module and that effect is in
    /// [`CATALOGUE`] (tested), so the lookup cannot fail for an id the library made.
    pub fn effect(self) -> &'static dyn Effect {
        CATALOGUE
            .iter()
            .copied()
            .find(|e| e.id() == self)
            .expect("every effect id is registered in the catalogue")
    }

    /// The whole catalogue's ids, in the contract's order.
    pub fn all() -> impl Iterator<Item = EffectId> {
        CATALOGUE.iter().map(|e| e.id())
    }

    /// The effect of the stable name `s`, if the catalogue has one.
    pub fn parse(s: &str) -> Option<Self> {
        Self::all().find(|e| e.as_str() == s)
    }

    /// What the extension adds to the declared model.
    pub fn describe(self) -> &'static str {
        self.effect().describe()
    }

    /// The residual tests whose rejection makes this effect a candidate, most specific first.
    pub fn pointing_tests(self) -> &'static [&'static str] {
        self.effect().pointing_tests()
    }

    /// The effects a test points to (the inverse of [`EffectId::pointing_tests`]).
    pub fn pointed_by(test: &str) -> Vec<EffectId> {
        Self::all()
            .filter(|e| e.pointing_tests().contains(&test))
            .collect()
    }

    /// The position in the catalogue (the contract's order).
    fn position(self) -> usize {
        CATALOGUE
            .iter()
            .position(|e| e.id() == self)
            .unwrap_or(CATALOGUE.len())
    }
}

impl PartialOrd for EffectId {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// The catalogue's order.
impl Ord for EffectId {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.position().cmp(&other.position())
    }
}

#[cfg(test)]
mod unit {
    use super::*;

    /// The contract's names come first, in its order, and never change; the catalogue may grow after them.
    #[test]
    fn names_are_the_contract_ones_and_round_trip() {
        let names: Vec<&str> = EffectId::all().map(|e| e.as_str()).collect();
        assert_eq!(
            names[..10],
            [
                "gap-drift",
                "curved-borders",
                "extra-delay",
                "linear-order",
                "coloured-noise",
                "saturation",
                "periodic-disturbance",
                "quantization",
                "friction",
                "direction-dependent",
            ]
        );
        for e in EffectId::all() {
            assert_eq!(EffectId::parse(e.as_str()), Some(e));
            assert_eq!(e.effect().id(), e);
            assert_eq!(
                serde_json::to_string(&e).unwrap(),
                format!("\"{}\"", e.as_str())
            );
            // Only a rival of play may have no test pointing to it.
            assert!(!e.pointing_tests().is_empty() || e.effect().imitates_play());
            assert!(!e.describe().is_empty());
        }
        assert_eq!(EffectId::parse("offset"), None);
    }

    /// Each effect's words (the report's `describe`) name what it adds, each in its own words.
    #[test]
    fn descriptions_name_their_element() {
        let words = [
            ("gap-drift", "gaps linear in time"),
            ("curved-borders", "both borders"),
            ("extra-delay", "longer delay"),
            ("linear-order", "coefficient in the linear block"),
            ("coloured-noise", "AR noise model"),
            ("saturation", "clipped"),
            ("periodic-disturbance", "sinusoid"),
            ("quantization", "rounds to a step"),
            ("friction", "Coulomb"),
            ("direction-dependent", "while its output falls"),
            ("dead-zone", "dead zone"),
            ("polynomial-feedback", "q3 x^3"),
        ];
        assert_eq!(words.len(), CATALOGUE.len());
        for (name, said) in words {
            let d = EffectId::parse(name).unwrap().describe();
            assert!(d.contains(said), "{name}: {d}");
        }
    }

    /// Each residual test points to the effects the catalogue's table lists for it, in the catalogue's
    /// order; a name that is no test points nowhere.
    #[test]
    fn tests_point_to_the_effects_of_the_table() {
        use crate::diagnose::residual::test_names::{
            BILLINGS, CLIPPING, CROSS_CORRELATION, DRIFT, LATTICE, LJUNG_BOX, SPECTRUM_PEAK,
        };
        let pointed = |test: &str| -> Vec<&str> {
            EffectId::pointed_by(test)
                .into_iter()
                .map(EffectId::as_str)
                .collect()
        };
        assert_eq!(pointed(LATTICE), ["quantization"]);
        assert_eq!(pointed(SPECTRUM_PEAK), ["periodic-disturbance"]);
        assert_eq!(pointed(CLIPPING), ["saturation"]);
        assert_eq!(
            pointed(BILLINGS),
            [
                "curved-borders",
                "saturation",
                "friction",
                "direction-dependent",
                "dead-zone"
            ]
        );
        assert!(
            EffectId::parse("polynomial-feedback").is_some_and(|e| e.pointing_tests().is_empty())
        );
        assert_eq!(pointed(DRIFT), ["gap-drift", "friction"]);
        assert_eq!(
            pointed(CROSS_CORRELATION),
            ["extra-delay", "linear-order", "dead-zone"]
        );
        assert_eq!(
            pointed(LJUNG_BOX),
            [
                "linear-order",
                "coloured-noise",
                "periodic-disturbance",
                "friction",
                "direction-dependent",
                "dead-zone"
            ]
        );
        assert!(pointed("offset").is_empty());
    }

    /// The ids order as the catalogue lists them, and each is listed once.
    #[test]
    fn ids_order_as_the_catalogue_and_are_unique() {
        let ids: Vec<EffectId> = EffectId::all().collect();
        let mut sorted = ids.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted, ids);
    }

    /// Parameters keep their order and leave absent values out.
    #[test]
    fn parameters_keep_their_order() {
        let p = Parameters::new()
            .with("b", 1.5)
            .with_some("skipped", None::<f64>)
            .with("a", "text");
        assert_eq!(
            serde_json::to_string(&p).unwrap(),
            r#"{"b":1.5,"a":"text"}"#
        );
        assert_eq!(p.get("a"), Some(&serde_json::json!("text")));
        assert_eq!(serde_json::to_string(&Parameters::new()).unwrap(), "{}");
    }
}
#[cfg(test)]
mod tests;
