//! The effect catalogue: the contract's stable ids, what each means, and which residual tests point to it.
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

use serde::{Deserialize, Serialize};

/// Names of the residual tests (the `name` of their [`crate::diagnose::residual::Verdict`]).
pub mod test_names {
    pub const LJUNG_BOX: &str = "ljung-box";
    pub const CROSS_CORRELATION: &str = "residual-input cross-correlation";
    pub const BILLINGS: &str = "billings higher-order correlations";
    pub const BY_MODE: &str = "residual by backlash mode";
    pub const SINCE_REVERSAL: &str = "residual by time since reversal";
    pub const AGAINST_X: &str = "residual against x_hat on the borders";
    pub const DRIFT: &str = "drift (CUSUM by mode)";
    pub const SPECTRUM_PEAK: &str = "residual spectrum peak";
    pub const LATTICE: &str = "value lattice (quantization)";
    pub const CLIPPING: &str = "clipping at the extremes";
    pub const EXTREMES: &str = "incremental gain at the output extremes";
}

/// One entry of the catalogue, serialised under the contract's stable name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EffectId {
    GapDrift,
    CurvedBorders,
    ExtraDelay,
    LinearOrder,
    ColouredNoise,
    Saturation,
    PeriodicDisturbance,
    Quantization,
    Friction,
    DirectionDependent,
}

impl EffectId {
    /// The whole catalogue, in the contract's order.
    pub const ALL: [EffectId; 10] = [
        EffectId::GapDrift,
        EffectId::CurvedBorders,
        EffectId::ExtraDelay,
        EffectId::LinearOrder,
        EffectId::ColouredNoise,
        EffectId::Saturation,
        EffectId::PeriodicDisturbance,
        EffectId::Quantization,
        EffectId::Friction,
        EffectId::DirectionDependent,
    ];

    /// The contract's stable name.
    pub fn as_str(self) -> &'static str {
        match self {
            EffectId::GapDrift => "gap-drift",
            EffectId::CurvedBorders => "curved-borders",
            EffectId::ExtraDelay => "extra-delay",
            EffectId::LinearOrder => "linear-order",
            EffectId::ColouredNoise => "coloured-noise",
            EffectId::Saturation => "saturation",
            EffectId::PeriodicDisturbance => "periodic-disturbance",
            EffectId::Quantization => "quantization",
            EffectId::Friction => "friction",
            EffectId::DirectionDependent => "direction-dependent",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.as_str() == s)
    }

    /// What the extension adds to the declared model.
    pub fn describe(self) -> &'static str {
        match self {
            EffectId::GapDrift => {
                "gaps linear in time: c1(k) = c1 + r1 k, c2(k) = c2 + r2 k (wear)"
            }
            EffectId::CurvedBorders => {
                "quadratic and cubic terms on both borders: upper = s + p2 s^2 + p3 s^3 (s = x - c1), lower likewise"
            }
            EffectId::ExtraDelay => "a longer delay: delay + 1, + 2 or + 3 samples",
            EffectId::LinearOrder => "one more a or b coefficient in the linear block",
            EffectId::ColouredNoise => {
                "an AR noise model on the output error, fitted on the residual with the deterministic part kept (judged by one-step-ahead prediction; the simulation is unchanged)"
            }
            EffectId::Saturation => "the output clipped at fitted levels lo and hi",
            EffectId::PeriodicDisturbance => {
                "a sinusoid on the output, frequency, amplitude and phase fitted"
            }
            EffectId::Quantization => {
                "the sensor rounds to a step q (from the value lattice) with an offset; the model gives the expected reading for a fitted noise level before the rounding"
            }
            EffectId::Friction => {
                "an elasto-plastic Coulomb element with the backlash, slipping at F+ / -F-: after the backlash output (series, f(k) = clamp(f(k-1) + w(k) - w(k-1), -F-, F+)) or with the play inside its spring (contact: the force unloads, crosses the play at zero, reloads); the better-fitting form is kept"
            }
            EffectId::DirectionDependent => {
                "direction-dependent dynamics: the linear block has a second set of coefficients (same orders) for while its output falls, as a motor driven up and coasting down"
            }
        }
    }

    /// The residual tests whose rejection makes this effect a candidate, most specific first.
    pub fn pointing_tests(self) -> &'static [&'static str] {
        use test_names::*;
        match self {
            EffectId::GapDrift => &[DRIFT, BY_MODE],
            EffectId::CurvedBorders => &[AGAINST_X, BILLINGS, EXTREMES],
            EffectId::ExtraDelay => &[CROSS_CORRELATION],
            EffectId::LinearOrder => &[CROSS_CORRELATION, LJUNG_BOX],
            EffectId::ColouredNoise => &[LJUNG_BOX],
            EffectId::Saturation => &[CLIPPING, EXTREMES, AGAINST_X, BILLINGS],
            EffectId::PeriodicDisturbance => &[SPECTRUM_PEAK, LJUNG_BOX],
            EffectId::Quantization => &[LATTICE],
            EffectId::DirectionDependent => &[BY_MODE, SINCE_REVERSAL, BILLINGS, LJUNG_BOX],
            EffectId::Friction => &[
                EXTREMES,
                SINCE_REVERSAL,
                BY_MODE,
                BILLINGS,
                DRIFT,
                LJUNG_BOX,
            ],
        }
    }

    /// The effects a test points to (the inverse of [`EffectId::pointing_tests`]).
    pub fn pointed_by(test: &str) -> Vec<EffectId> {
        Self::ALL
            .into_iter()
            .filter(|e| e.pointing_tests().contains(&test))
            .collect()
    }
}

impl std::fmt::Display for EffectId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod unit {
    use super::*;

    #[test]
    fn names_are_the_contract_ones_and_round_trip() {
        let names: Vec<&str> = EffectId::ALL.iter().map(|e| e.as_str()).collect();
        assert_eq!(
            names,
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
                "direction-dependent"
            ]
        );
        for e in EffectId::ALL {
            assert_eq!(EffectId::parse(e.as_str()), Some(e));
            assert_eq!(
                serde_json::to_string(&e).unwrap(),
                format!("\"{}\"", e.as_str())
            );
            assert!(!e.pointing_tests().is_empty());
        }
    }
}
