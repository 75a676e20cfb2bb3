//! The verdict on play judged again at the neighbouring splits of the record. A claim (`present` or
//! `absent`) that a user can move by choosing another fit fraction is not a claim the record makes: the
//! final model is refitted from where it ended on the fit parts of the splits [`SPLIT_STEP`] before and
//! after the chosen one, and judged there on whether play is present (the gap against its zero-gap twin on
//! that split's held-out part, and against the play-free imitators where the claim is `absent`, its
//! significance, the reversals that cross it, friction told from it; the halves and the bound are the
//! chosen split's: `Depth`). Where a neighbour
//! contradicts the claim (`present` needs `present` at every split, `absent` no `present` at any) the answer
//! is `undetermined`, with every split's verdict in the reasons. An `undetermined` answer claims nothing and
//! is not re-judged.

use rayon::prelude::*;

use super::diagnosis::FIT_FRACTIONS;
use super::presence::{
    self, BacklashSupport, Depth, FEW_HELDOUT_REVERSALS, FEW_REVERSALS, Presence, SplitVerdict,
};
use crate::diagnose::fit::model::{EffectModel, Objective};
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::fit::structure::fit_len;
use crate::report::number as g;

/// How far the other splits judged lie from the chosen one, as a fraction of the record.
pub const SPLIT_STEP: f64 = 0.1;

/// The fit fractions [`SPLIT_STEP`] before and after `fraction` that lie in [`FIT_FRACTIONS`]: the splits
/// next to the one the user chose (the default 0.7 is judged at 0.6 and 0.8; a user who moved the split to
/// where the input excites both parts alike is judged near there, not where the held-out part is quiet).
pub fn neighbours(fraction: f64) -> Vec<f64> {
    [fraction - SPLIT_STEP, fraction + SPLIT_STEP]
        .into_iter()
        // Rounded to the hundredth, so that 0.7 - 0.1 is 0.6 and not 0.6000000000000001 in the answer.
        .map(|f| (f * 100.0).round() / 100.0)
        .filter(|f| FIT_FRACTIONS.contains(f))
        .collect()
}

/// `first`, the verdict on `p`'s split (the fit fraction `fraction`) for the final model `last`, checked
/// at the neighbouring splits ([`neighbours`]): unchanged where they agree, `undetermined` where any differs.
pub(crate) fn over_splits(
    p: &Problem,
    last: &EffectModel,
    fraction: f64,
    first: BacklashSupport,
) -> BacklashSupport {
    if first.presence == Presence::Undetermined {
        return first;
    }
    let depth = match first.presence {
        Presence::Absent => Depth::Rivals,
        _ => Depth::Twin,
    };
    let others: Vec<SplitVerdict> = neighbours(fraction)
        .par_iter()
        .map(|&f| at_split(p, last, f, depth))
        .collect();
    let own = SplitVerdict {
        fit_fraction: fraction,
        presence: first.presence,
        play: first.play,
        undecided_by: Vec::new(),
        reversals: first.reversals,
    };
    let mut splits = vec![own];
    splits.extend(others);
    splits.sort_by(|a, b| a.fit_fraction.total_cmp(&b.fit_fraction));
    judged(first, splits)
}

/// The verdict at the fit fraction `f`: the final model refitted from where it ended on that split's fit
/// part (its parameters keep their meaning: the time scale of drifts is the original split's), judged.
fn at_split(p: &Problem, last: &EffectModel, f: f64, depth: Depth) -> SplitVerdict {
    (p.progress)(&format!("judging the play again at fit fraction {f:.2}"));
    let q = p.resplit(fit_len(p.u.len(), f));
    let start = last.deterministic();
    // On a long record's window (`Problem::verdict_window`) a later split keeps the same fit part, where the
    // final model is fitted already: only the held-out part moves.
    let refit = if q.n_fit == p.n_fit {
        Some((start, f64::NAN))
    } else {
        q.fit(&start, std::slice::from_ref(&start), Objective::Simulation)
    };
    let Some((m, _)) = refit else {
        return SplitVerdict {
            fit_fraction: f,
            presence: Presence::Undetermined,
            play: f64::NAN,
            undecided_by: vec!["the final model could not be refitted on this fit part".into()],
            reversals: [0, 0],
        };
    };
    let s = presence::assess(&q, &m, depth);
    SplitVerdict {
        fit_fraction: f,
        presence: s.presence,
        play: s.play,
        undecided_by: s.undecided_by,
        reversals: s.reversals,
    }
}

/// Whether the verdict `other` at another split leaves the claim `own` standing: `present` needs `present`
/// there too; `absent` only needs no `present` there (no bound is sought at a neighbour: one that a shorter
/// held-out or fit part cannot establish contradicts nothing, and required, it lost 64 of 238 play-free
/// records, none of them a play). A split the final model could not be refitted on says nothing either way
/// (see [`silent`]).
fn agrees(own: Presence, other: &SplitVerdict) -> bool {
    silent(other)
        || match own {
            Presence::Absent => other.presence != Presence::Present,
            _ => other.presence == own,
        }
}

/// Whether a split says nothing about play: the final model could not be refitted there (it has no play
/// there), or fewer than [`FEW_HELDOUT_REVERSALS`] reversals cross the play on its held-out part or fewer
/// than [`FEW_REVERSALS`] on its fit part, so that no verdict there could be `present` whatever the record
/// holds. None is evidence: the fits' strict simulation refuses, as a start, a model it accepted on the
/// chosen fit part where inverted samples make a larger share of a shorter one, or where the added samples
/// of a longer one move it against x (8 of the 108 countable play records of the confusion table found
/// `present` have a neighbour that refused the final model so, beside one that agrees); a later split of a
/// slow sine leaves its held-out part one reversal (the damper's 0.25 Hz test at 0.8), an earlier one its
/// fit part seven (the same test at 0.5).
fn silent(s: &SplitVerdict) -> bool {
    !s.play.is_finite() || s.reversals[1] < FEW_HELDOUT_REVERSALS || s.reversals[0] < FEW_REVERSALS
}

/// How a split's play reads in the reasons.
fn said_play(s: &SplitVerdict) -> String {
    if !s.play.is_finite() {
        "not refitted".into()
    } else if silent(s) {
        format!(
            "{}, {} reversal(s) cross it on the fit part and {} held out: too few to judge",
            g(s.play),
            s.reversals[0],
            s.reversals[1]
        )
    } else if s.presence == Presence::Undetermined && !s.undecided_by.is_empty() {
        format!(
            "{}: {}",
            g(s.play),
            s.undecided_by.join("; ").replace(" (see the reasons)", "")
        )
    } else {
        g(s.play)
    }
}

/// `first` with the splits' verdicts kept and said; `undetermined` where one contradicts it (see
/// [`agrees`]).
fn judged(mut first: BacklashSupport, splits: Vec<SplitVerdict>) -> BacklashSupport {
    let said = splits
        .iter()
        .map(|s| {
            format!(
                "{} at {:.2} (play {})",
                s.presence.word(),
                s.fit_fraction,
                said_play(s)
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    let same = splits.iter().all(|s| s.presence == first.presence);
    // `present` needs at least one other split judged (the chosen one is always there); `absent` needs
    // only that none finds play.
    let judged_elsewhere =
        first.presence == Presence::Absent || splits.iter().filter(|s| !silent(s)).count() > 1;
    let stable = judged_elsewhere && splits.iter().all(|s| agrees(first.presence, s));
    first.splits = splits;
    if stable {
        first.reasons.push(if same {
            format!("the verdict holds at every split of the record judged: {said}")
        } else {
            format!("no split of the record judged finds play: {said}")
        });
        return first;
    }
    let why = if judged_elsewhere {
        format!(
            "the verdict moves with the split of the record ({said}): the final model refitted on another \
             fit part is judged otherwise, so the record does not settle it"
        )
    } else {
        format!(
            "the verdict could not be judged at any other split of the record ({said}): the final model \
             could not be refitted there or its held-out part is too short to judge, so nothing says the \
             record settles it"
        )
    };
    first.reasons.push(why.clone());
    first.presence = Presence::Undetermined;
    first.supported = false;
    first.play_bound = None;
    first.undecided_by = vec![if judged_elsewhere {
        "the verdict moves with the split of the record (see the reasons)".into()
    } else {
        "no other split of the record could judge the verdict (see the reasons)".into()
    }];
    first.verdict = format!("play is undetermined: {why}");
    first.experiment = Some(
        "a longer record excited alike throughout (the same amplitudes and rates in every part), so that \
         every split of it sees the same play"
            .into(),
    );
    first
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::lm::LmOptions;
    use crate::diagnose::fit::model::BaseModel;
    use crate::diagnose::fit::model::tests::{input, paper_base, with_noise};

    /// The paper plant with the gaps `c1`, `c2` on the two-tone input, with noise, as a problem split at
    /// 70%, and the true model.
    fn judged_record(c1: f64, c2: f64, m2: f64) -> (Vec<f64>, Vec<f64>, EffectModel) {
        let m = EffectModel::plain(BaseModel {
            c1,
            c2,
            m2,
            ..paper_base()
        });
        let u = input(2000);
        let sim = m.simulate(&u, crate::diagnose::fit::model::Rest::ZERO, 2000, 1e6);
        let y = with_noise(&sim.expect("the paper plant runs").y, 0.02, 7);
        (u, y, m)
    }

    /// At a neighbouring split only presence is judged: the twin alone is fitted, no halves, no bound.
    #[test]
    fn a_neighbour_judges_presence_only() {
        let (u, y, m) = judged_record(0.2, 0.3, 1.5);
        let p = Problem::new(&u, &y, 1400, LmOptions::default());
        let full = presence::assess(&p, &m, Depth::Full);
        let near = presence::assess(&p, &m, Depth::Twin);
        let rivals = presence::assess(&p, &m, Depth::Rivals);
        assert_eq!(full.presence, Presence::Present, "{:?}", full.reasons);
        assert_eq!(near.presence, Presence::Present, "{:?}", near.reasons);
        assert_eq!(rivals.presence, Presence::Present, "{:?}", rivals.reasons);
        assert!(full.halves.is_some() && near.halves.is_none() && rivals.halves.is_none());
        assert!(near.play_free.len() == 1);
        assert_eq!(rivals.play_free.len(), full.play_free.len());
        assert!(full.play_free.len() > 1);
        let (u, y, m) = judged_record(0.0, 0.0, 1.0);
        let p = Problem::new(&u, &y, 1400, LmOptions::default());
        let full = presence::assess(&p, &m, Depth::Full);
        let near = presence::assess(&p, &m, Depth::Rivals);
        assert_eq!(full.presence, Presence::Absent, "{:?}", full.reasons);
        assert_eq!(near.presence, Presence::Undetermined, "{:?}", near.reasons);
        assert!(near.play_bound.is_none());
    }

    /// The whole check on a record with play: present at 0.7 and at both neighbours, listed in order.
    #[test]
    fn a_play_is_judged_present_at_every_neighbour() {
        let (u, y, m) = judged_record(0.2, 0.3, 1.5);
        let p = Problem::new(&u, &y, fit_len(u.len(), 0.7), LmOptions::default());
        let first = presence::assess(&p, &m, Depth::Full);
        let s = over_splits(&p, &m, 0.7, first);
        assert_eq!(s.presence, Presence::Present, "{:?}", s.reasons);
        let at: Vec<_> = s
            .splits
            .iter()
            .map(|v| (v.fit_fraction, v.presence))
            .collect();
        assert_eq!(
            at,
            [
                (0.6, Presence::Present),
                (0.7, Presence::Present),
                (0.8, Presence::Present)
            ]
        );
        assert!(
            s.splits.iter().all(|v| (v.play - 0.5).abs() < 0.05),
            "{:?}",
            s.splits
        );
    }

    #[test]
    fn the_neighbouring_splits_stay_among_the_accepted_fractions() {
        assert_eq!(neighbours(0.7), vec![0.6, 0.8]);
        assert_eq!(neighbours(0.35), vec![0.45]);
        assert_eq!(neighbours(0.9), vec![0.8]);
        assert_eq!(neighbours(0.3), vec![0.4]);
    }

    fn claim(presence: Presence) -> BacklashSupport {
        let mut s = BacklashSupport::undetermined("for the test");
        (s.presence, s.supported, s.play) = (presence, presence == Presence::Present, 1.5);
        s.play_bound = (presence == Presence::Absent).then_some(0.2);
        s
    }

    fn at(fit_fraction: f64, presence: Presence) -> SplitVerdict {
        SplitVerdict {
            fit_fraction,
            presence,
            play: 1.5,
            undecided_by: Vec::new(),
            reversals: [40, 12],
        }
    }

    #[test]
    fn a_verdict_that_moves_with_the_split_is_undetermined() {
        use Presence::*;
        for (own, other) in [
            (Present, Undetermined),
            (Absent, Present),
            (Present, Absent),
        ] {
            let s = judged(claim(own), vec![at(0.6, own), at(0.7, own), at(0.8, other)]);
            assert_eq!(s.presence, Undetermined, "{own:?} beside {other:?}");
            assert!(!s.supported && s.play_bound.is_none() && s.experiment.is_some());
            assert!(s.verdict.contains("moves with the split"), "{}", s.verdict);
            assert!(s.verdict.contains(&format!("{} at 0.80", other.word())));
            assert_eq!(s.splits.len(), 3);
        }
    }

    /// A neighbour that is undetermined says why in the split's reasons, without pointing at reasons the
    /// answer does not carry (the neighbour's own).
    #[test]
    fn an_undetermined_neighbour_says_why() {
        let mut other = at(0.8, Presence::Undetermined);
        other.undecided_by =
            vec!["two explanations: the model with a play (see the reasons)".into()];
        let s = judged(
            claim(Presence::Present),
            vec![
                at(0.6, Presence::Present),
                at(0.7, Presence::Present),
                other,
            ],
        );
        assert!(
            s.verdict.contains(
                "undetermined at 0.80 (play 1.5000: two explanations: the model with a play)"
            ),
            "{}",
            s.verdict
        );
    }

    #[test]
    fn a_verdict_that_holds_at_every_split_stands() {
        for own in [Presence::Present, Presence::Absent] {
            let s = judged(claim(own), vec![at(0.6, own), at(0.7, own), at(0.8, own)]);
            assert_eq!(s.presence, own);
            assert_eq!(s.supported, own == Presence::Present);
            assert_eq!(s.play_bound.is_some(), own == Presence::Absent);
            assert!(s.reasons.last().unwrap().contains("holds at every split"));
        }
    }

    #[test]
    fn an_absent_play_stands_beside_a_split_without_a_bound() {
        let s = judged(
            claim(Presence::Absent),
            vec![at(0.6, Presence::Undetermined), at(0.7, Presence::Absent)],
        );
        assert_eq!(s.presence, Presence::Absent);
        assert_eq!(s.play_bound, Some(0.2));
        assert!(
            s.reasons
                .last()
                .unwrap()
                .contains("no split of the record judged")
        );
    }

    /// A split the final model cannot be refitted on is silent: beside one that agrees the claim stands;
    /// with no other split judged `present` does not, and the answer says why, while `absent` (which only
    /// needs no split to find play) does.
    #[test]
    fn a_model_that_cannot_be_refitted_elsewhere_is_said_so() {
        let mut silent = at(0.8, Presence::Undetermined);
        silent.play = f64::NAN;
        for own in [Presence::Present, Presence::Absent] {
            let s = judged(claim(own), vec![at(0.6, own), at(0.7, own), silent.clone()]);
            assert_eq!(s.presence, own);
            assert!(
                s.reasons
                    .last()
                    .unwrap()
                    .contains("undetermined at 0.80 (play not refitted)")
            );
        }
        let alone = |own| judged(claim(own), vec![at(0.7, own), silent.clone()]);
        assert_eq!(alone(Presence::Absent).presence, Presence::Absent);
        let s = alone(Presence::Present);
        assert_eq!(s.presence, Presence::Undetermined);
        assert!(
            s.verdict.contains("could not be judged at any other split"),
            "{}",
            s.verdict
        );
        assert_eq!(
            s.undecided_by,
            ["no other split of the record could judge the verdict (see the reasons)"]
        );
        let s = judged(
            claim(Presence::Present),
            vec![
                at(0.6, Presence::Absent),
                at(0.7, Presence::Present),
                silent,
            ],
        );
        assert_eq!(s.presence, Presence::Undetermined);
    }

    /// A split whose held-out part one reversal crosses (fewer than two) cannot find play whatever the
    /// record holds: it is silent, as a split that could not be refitted is; two reversals can judge.
    #[test]
    fn a_split_with_too_short_a_held_out_part_says_nothing() {
        let short = |held: usize| {
            let mut s = at(0.8, Presence::Undetermined);
            s.reversals = [30, held];
            judged(
                claim(Presence::Present),
                vec![at(0.6, Presence::Present), at(0.7, Presence::Present), s],
            )
        };
        let s = short(1);
        assert_eq!(s.presence, Presence::Present);
        assert!(
            s.reasons.last().unwrap().contains(
                "30 reversal(s) cross it on the fit part and 1 held out: too few to judge"
            ),
            "{:?}",
            s.reasons
        );
        assert_eq!(short(2).presence, Presence::Undetermined);
    }

    /// A split whose fit part fewer than 8 reversals cross cannot find play either (a slow sine's earlier
    /// split): silent; 8 can judge.
    #[test]
    fn a_split_with_too_short_a_fit_part_says_nothing() {
        let early = |fit: usize| {
            let mut s = at(0.6, Presence::Undetermined);
            s.reversals = [fit, 12];
            judged(
                claim(Presence::Present),
                vec![s, at(0.7, Presence::Present), at(0.8, Presence::Present)],
            )
        };
        let s = early(7);
        assert_eq!(s.presence, Presence::Present, "{:?}", s.reasons);
        assert!(
            s.reasons.last().unwrap().contains(
                "7 reversal(s) cross it on the fit part and 12 held out: too few to judge"
            ),
            "{:?}",
            s.reasons
        );
        assert_eq!(early(8).presence, Presence::Undetermined);
    }
}
