//! The decision rule: when an extension is supported, and which supported extension wins.

use crate::diagnose::effects::EffectId;

/// The smallest relative fall of the held-out RMSE that counts (besides its significance): a change of the
/// model that moves the error by less than 1% is no finding even when it is consistent.
pub const MIN_FALL: f64 = 0.01;

/// The one-sided z threshold of the held-out comparison (5%).
pub const Z_THRESHOLD: f64 = 1.645;

/// The decision rule, as written into every report.
pub const DECISION_RULE: &str = "an extension is supported when its held-out error is at least 1% lower than the \
current model's, the fall is significant (one-sided Diebold-Mariano z above the threshold, 5%), AND its BIC on \
the fit part is lower; among supported deterministic extensions the lowest BIC wins, except that a supported \
extra-delay wins over linear-order when that one's BIC is lower by less than 10 (a longer delay adds no \
coefficient, and one more coefficient with a leading one near zero is that delay); coloured-noise (judged by \
one-step prediction) is chosen only when no deterministic extension is supported; otherwise the answer is null";

/// The BIC difference below which linear-order is no strong evidence against extra-delay (a difference of 10
/// is "very strong" on Kass and Raftery's scale). One more b coefficient whose leading one is near zero is a
/// longer delay; a supported extra-delay then wins, as the model without the extra coefficient.
pub const ALIAS_BIC: f64 = 10.0;

/// The evidence on one candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    /// Held-out RMSE of the current model and of the candidate (of the kind the candidate is judged by).
    pub before: f64,
    pub after: f64,
    /// Diebold-Mariano z of the held-out squared-error reduction.
    pub z: f64,
    pub z_threshold: f64,
    /// BIC of the candidate minus BIC of the current model.
    pub delta_bic: f64,
}

/// A candidate's verdict: supported or not, and the reason in words naming the rule that decided.
#[derive(Debug, Clone, PartialEq)]
pub struct Judgement {
    pub supported: bool,
    pub reason: String,
}

/// Apply the rule to one candidate.
pub fn judge(e: &Evidence) -> Judgement {
    let fall = if e.before > 0.0 {
        1.0 - e.after / e.before
    } else {
        0.0
    };
    let mut failed = Vec::new();
    if fall < MIN_FALL {
        failed.push(if fall <= 0.0 {
            format!(
                "the held-out error does not fall ({} -> {})",
                short(e.before),
                short(e.after)
            )
        } else {
            format!(
                "the held-out error falls by only {:.2}% (at least {:.0}% needed)",
                100.0 * fall,
                100.0 * MIN_FALL
            )
        });
    }
    if e.z <= e.z_threshold {
        failed.push(format!(
            "the fall is not significant (z {:.2}, at most the threshold {:.3})",
            e.z, e.z_threshold
        ));
    }
    if e.delta_bic >= 0.0 {
        failed.push(format!("BIC does not favour it (dBIC {:+.1})", e.delta_bic));
    }
    if failed.is_empty() {
        Judgement {
            supported: true,
            reason: format!(
                "held-out error falls by {:.1}% (z {:.2}) and BIC favours it (dBIC {:+.1})",
                100.0 * fall,
                e.z,
                e.delta_bic
            ),
        }
    } else {
        Judgement {
            supported: false,
            reason: failed.join("; "),
        }
    }
}

fn short(v: f64) -> String {
    format!("{v:.4e}")
}

/// The model-prior term of BIC for effect `id` ([`crate::diagnose::effects::Effect::structure_penalty`]):
/// the log-count of the alternative structures it searched (extra-delay tries 3 delays, linear-order 2
/// orders; the others fit one structure). The extra delay adds no continuous parameter, so without this
/// term it would tie exactly with a longer b polynomial whose leading terms are zero.
pub fn structure_penalty(id: EffectId) -> f64 {
    id.effect().structure_penalty()
}

/// The winner among judged candidates `(id, supported, bic)`: the supported deterministic extension with the
/// lowest BIC, else a supported noise model, else none. A winner that yields to another supported effect
/// ([`crate::diagnose::effects::Effect::yields_to`]: linear-order to extra-delay) gives way to it unless its
/// BIC is lower by at least [`ALIAS_BIC`]. Returns its index.
pub fn choose(candidates: &[(EffectId, bool, f64)]) -> Option<usize> {
    let best_of = |deterministic: bool| {
        candidates
            .iter()
            .enumerate()
            .filter(|(_, (id, ok, _))| *ok && id.effect().is_noise_model() != deterministic)
            .min_by(|a, b| a.1.2.total_cmp(&b.1.2))
            .map(|(i, _)| i)
    };
    let Some(b) = best_of(true) else {
        return best_of(false);
    };
    let alias = candidates[b].0.effect().yields_to().and_then(|other| {
        candidates
            .iter()
            .position(|(id, ok, _)| *id == other && *ok)
    });
    Some(match alias {
        Some(d) if candidates[d].2 < candidates[b].2 + ALIAS_BIC => d,
        _ => b,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::effects::{
        coloured_noise::ID as ColouredNoise, extra_delay::ID as ExtraDelay,
        friction::ID as Friction, gap_drift::ID as GapDrift, linear_order::ID as LinearOrder,
        saturation::ID as Saturation,
    };

    fn ev(after: f64, z: f64, delta_bic: f64) -> Evidence {
        Evidence {
            before: 1.0,
            after,
            z,
            z_threshold: Z_THRESHOLD,
            delta_bic,
        }
    }

    #[test]
    fn every_rule_must_hold_and_the_reason_names_the_one_that_failed() {
        assert!(judge(&ev(0.9, 3.0, -5.0)).supported);
        // Each rule alone fails the candidate and is named.
        let small = judge(&ev(0.995, 3.0, -5.0));
        assert!(!small.supported);
        assert!(small.reason.contains("only 0.50%"), "{}", small.reason);
        assert!(!small.reason.contains("significant"));
        let rise = judge(&ev(1.2, 3.0, -5.0));
        assert!(!rise.supported && rise.reason.contains("does not fall"));
        let weak = judge(&ev(0.9, 1.645, -5.0));
        assert!(!weak.supported);
        assert!(weak.reason.contains("not significant"), "{}", weak.reason);
        assert!(!weak.reason.contains("BIC"));
        let bic = judge(&ev(0.9, 3.0, 0.0));
        assert!(!bic.supported && bic.reason.contains("BIC does not favour"));
        assert!(!bic.reason.contains("significant"));
        // Boundaries: exactly 1% falls count, z just above the threshold counts.
        assert!(judge(&ev(0.99, 1.6451, -0.1)).supported);
        assert!(!judge(&ev(0.9901, 1.6451, -0.1)).supported);
        // A zero "before" error cannot fall.
        let zero = judge(&Evidence {
            before: 0.0,
            ..ev(0.0, 10.0, -1.0)
        });
        assert!(!zero.supported);
    }

    #[test]
    fn the_fall_is_relative_to_the_error_before_and_the_reason_quotes_both() {
        // 2.0 -> 1.9 is a 5% fall: supported, and said so.
        let e = Evidence {
            before: 2.0,
            ..ev(1.9, 3.0, -5.0)
        };
        let j = judge(&e);
        assert!(j.supported, "{}", j.reason);
        assert!(j.reason.contains("falls by 5.0%"), "{}", j.reason);
        // 2.0 -> 1.99 is 0.5%: too small, whatever the scale.
        let small = judge(&Evidence {
            before: 2.0,
            ..ev(1.99, 3.0, -5.0)
        });
        assert!(
            !small.supported && small.reason.contains("only 0.50%"),
            "{}",
            small.reason
        );
        // A rise quotes both errors.
        let rise = judge(&ev(1.2, 3.0, -5.0));
        assert!(
            rise.reason.contains("(1.0000e0 -> 1.2000e0)"),
            "{}",
            rise.reason
        );
    }

    #[test]
    fn penalties_are_the_log_counts() {
        assert_eq!(structure_penalty(ExtraDelay), 3f64.ln());
        assert_eq!(structure_penalty(LinearOrder), 2f64.ln());
        assert_eq!(structure_penalty(Friction), 0.0);
    }

    #[test]
    fn deterministic_before_noise_and_lowest_bic_wins() {
        assert_eq!(choose(&[]), None);
        assert_eq!(choose(&[(GapDrift, false, -10.0)]), None);
        assert_eq!(
            choose(&[(ColouredNoise, true, -100.0), (GapDrift, true, -1.0)]),
            Some(1)
        );
        assert_eq!(
            choose(&[(ColouredNoise, true, -100.0), (GapDrift, false, -1.0)]),
            Some(0)
        );
        assert_eq!(
            choose(&[
                (Saturation, true, -3.0),
                (Friction, true, -7.0),
                (GapDrift, true, -5.0)
            ]),
            Some(1)
        );
    }

    #[test]
    fn extra_delay_wins_over_a_linear_order_that_is_not_strongly_better() {
        let c = |lo: f64, de: f64, de_ok: bool| {
            choose(&[
                (LinearOrder, true, lo),
                (ExtraDelay, de_ok, de),
                (Saturation, true, -50.0),
            ])
        };
        // Linear-order better by less than 10: the delay.
        assert_eq!(c(-104.5, -100.0, true), Some(1));
        assert_eq!(c(-109.9, -100.0, true), Some(1));
        // By 10 or more, or the delay not supported: linear-order.
        assert_eq!(c(-110.0, -100.0, true), Some(0));
        assert_eq!(c(-104.5, -100.0, false), Some(0));
        // The rule only arbitrates between those two: a better third candidate still wins.
        assert_eq!(c(-40.0, -30.0, true), Some(2));
        // The delay better anyway.
        assert_eq!(c(-100.0, -104.5, true), Some(1));
    }
}
