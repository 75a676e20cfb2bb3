//! The verdict on play: `present`, `absent` (with the play the record rules out) or `undetermined` (with the
//! experiment that would decide), judged on the final model with the evidence for and against in words.
//!
//! - **The model it stands on.** The final model, unless one of the play-free effects that imitate play,
//!   added to it with its gap kept (a rival with play, see `alternatives`), predicts the held-out
//!   part clearly better: then that rival, named in `model`, and its gap is judged against the same effects
//!   without a gap (like with like). Choosing it on the held-out part spends some of that part's evidence,
//!   so its gain must then reach [`FEW_REVERSALS_Z`].
//! - **Present** needs all of: the model with its gap beats, on the held-out part, the same model with
//!   the gap pinned at zero (the same borders as one memoryless curve, paper 003's zero-gap case) and that
//!   zero-gap model with each play-free effect of the catalogue that imitates play added (a curve, friction,
//!   direction-dependent dynamics, a dead zone, clipping), each by at least [`MIN_GAIN`] and significantly;
//!   the play is above zero by [`residual::Z95`] standard errors that hold with coloured residuals (a
//!   sandwich with an autoregressive long-run variance); it is narrower than [`MAX_PLAY_SHARE`] of the travel of the linear block's
//!   output; at least [`MIN_REVERSALS`] reversals of that output cross it on the fit part and
//!   [`MIN_HELDOUT_REVERSALS`] on the held-out part (or [`FEW_REVERSALS`] and [`FEW_HELDOUT_REVERSALS`], a
//!   periodic test of a few periods, with every gain at [`FEW_REVERSALS_Z`]); with a friction element, the
//!   record determines every parameter (else friction and gap read alike); the fit part's halves agree.
//! - **Absent** needs: no gain from the gap, the play not significantly above zero, a model with the gap
//!   not clearly worse than its zero-gap twin on the held-out part, no friction element (itself a play), a bound (the largest
//!   play the record does not rule out at 95%, checked on the play's profile) narrower than
//!   [`MAX_BOUND_SHARE`] of the travel, and at least [`MIN_ABSENT_REVERSALS`] reversals crossing it.
//! - Anything else is **undetermined**, and so is every impossible estimate (a negative gap, a play wider
//!   than the travel), said as what it is.

use serde::Serialize;

pub use super::alternatives::PlayFree;
use super::alternatives::{
    Fitted, best_rival, better_by, clearly_better, fit_errors, heldout_errors, imitators, play_free,
};
use super::fold::Fold;
use crate::diagnose::effects::friction;
use crate::diagnose::fit::lm::long_run_inflation;
use crate::diagnose::fit::model::{EffectModel, Objective, Simulation};
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::record::{POOR_EXCITATION, fairly_excited};
use crate::diagnose::residual::{self, statistics::diebold_mariano};
// A number in a sentence: the rule of the text output and the report, so that the three print it alike.
use crate::report::number as g;
use crate::stats::{quantile, rms};

/// The least relative fall of the held-out error that the gap must bring against every play-free model.
pub const MIN_GAIN: f64 = 0.02;
/// The one-sided z of that fall (Diebold-Mariano, 5%).
pub const MIN_Z: f64 = 1.645;
/// Reversals of the linear block's output that cross the play, on the fit part, for `present` (a few tens:
/// a handful is no evidence).
pub const MIN_REVERSALS: usize = 20;
/// ... and on the held-out part, which judges the gain.
pub const MIN_HELDOUT_REVERSALS: usize = 5;
/// Fewer crossing reversals than [`MIN_REVERSALS`], down to this many on the fit part (four periods of a
/// sine test: a test of seven periods keeps them at every fit fraction from 0.6 to 0.8) ...
pub const FEW_REVERSALS: usize = 8;
/// ... and this many on the held-out part, still allow `present` when the gap's held-out gain over every
/// play-free model is significant at [`FEW_REVERSALS_Z`]: each reversal of a periodic test repeats the
/// same dwell over many samples, but a few events make the test's own error larger than its z assumes.
pub const FEW_HELDOUT_REVERSALS: usize = 2;
/// The one-sided z (0.1%) the held-out gain needs when the reversals are few.
pub const FEW_REVERSALS_Z: f64 = 3.09;
/// What the verdict stands on unless a rival with play predicts better.
const FINAL_MODEL: &str = "the final model";
/// The name of the final model without its friction element, refitted.
const WITHOUT_FRICTION: &str = "the final model without its friction element";
/// The name of the final model refitted from its zero-gap twin's fit.
const REFITTED: &str = "the final model refitted from its zero-gap twin";
/// The name of its zero-gap twin among the play-free models.
const TWIN: &str = "zero-gap";
/// Reversals crossing the bound, on the fit part, for `absent`.
pub const MIN_ABSENT_REVERSALS: usize = 20;
/// The widest play, as a share of the travel (1st to 99th percentile of the linear block's output on the
/// fit part), that a record can show: a wider one is not a play.
pub const MAX_PLAY_SHARE: f64 = 0.5;
/// The narrowest play, as a share of the travel, that `present` claims: a smaller gap is within what a
/// model's other imperfections buy (a spurious gap beside direction-dependent dynamics measured 1.7%).
pub const MIN_PLAY_SHARE: f64 = 0.02;
/// The widest bound, as a share of the travel, that says something.
pub const MAX_BOUND_SHARE: f64 = 0.25;
/// The halves agree when their plays differ by less than their combined 95% error plus this share of the
/// larger (a model that misses something moves a little between halves; a play that is half noise moves a
/// lot).
pub const HALF_TOLERANCE: f64 = 0.25;
/// The most refits of the play's profile a bound takes (each widens it by half: 1.5^10 = 58 times the Wald
/// bound at most).
pub const PROFILE_STEPS: usize = 10;
/// The 95% point of chi-square with one degree of freedom: the profile's threshold.
pub const CHI2_95: f64 = 3.84;
/// How the standard errors are computed, as the answer names it.
pub const SE_METHOD: &str = "sandwich of the fit-part simulation errors (the scores' long-run variance read from \
    an autoregression of order 0 to 12 chosen by BIC, den Haan and Levin's estimate): holds when the residuals are \
    autocorrelated, where the information matrix alone claims too much; plus the noise of the level the play is measured at (the record's first output sample), \
    which moves the play by 1/m1 - 1/m2 per unit where the borders' slopes differ";

/// The three answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Presence {
    Present,
    Absent,
    Undetermined,
}

impl Presence {
    /// The answer's word, as the JSON writes it.
    pub fn word(self) -> &'static str {
        match self {
            Self::Present => "present",
            Self::Absent => "absent",
            Self::Undetermined => "undetermined",
        }
    }
}

/// The verdict at one split of the record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SplitVerdict {
    pub fit_fraction: f64,
    pub presence: Presence,
    /// The play there (`NaN` where the final model could not be refitted on that fit part).
    pub play: f64,
    /// For `undetermined`: what kept it from `present` and from `absent` there.
    pub undecided_by: Vec<String>,
    /// Reversals of the linear block's output that cross the play there (fit part, held-out part).
    pub reversals: [usize; 2],
}

/// The verdict on play with its evidence (the JSON's `backlash`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BacklashSupport {
    pub presence: Presence,
    /// The model the verdict stands on: the final model, or a rival with play that predicts the held-out
    /// part better (the final model with a play-free effect added, its gap kept).
    pub model: String,
    /// True exactly when `presence` is `present`.
    pub supported: bool,
    /// The evidence for and against, in words and numbers.
    pub reasons: Vec<String>,
    /// The final model's play c1 + c2, in the linear block's output units.
    pub play: f64,
    /// Its standard error (see `se_method`); `None` where the record does not determine the gaps.
    pub play_se: Option<f64>,
    /// The standard error the information matrix alone gives (right only for white residuals).
    pub play_se_white: Option<f64>,
    pub se_method: &'static str,
    /// The play the record rules out at 95% (`absent` only).
    pub play_bound: Option<f64>,
    /// The play in the input's units (through the linear block's static gain) and in the output's (times
    /// the borders' mean slope); `None` for an impossible estimate.
    pub play_input_units: Option<f64>,
    pub play_output_units: Option<f64>,
    /// The final model's held-out error and the play-free models'.
    pub heldout_rmse: f64,
    pub play_free: Vec<PlayFree>,
    /// Reversals of the linear block's output that cross the play, or 2% of the travel where the play is
    /// narrower (fit part, held-out part).
    pub reversals: [usize; 2],
    /// The travel of the linear block's output (1st to 99th percentile, fit part).
    pub travel: f64,
    /// The plays of the two halves of the fit part, when they were compared.
    pub halves: Option<[f64; 2]>,
    /// The verdict at the chosen split and its neighbours, for `present` or `absent` before the check
    /// (judged again there: `diagnose::search::stability`); empty where it was not checked.
    pub splits: Vec<SplitVerdict>,
    /// For `undetermined`: what kept it from `present` and from `absent`, in short phrases.
    pub undecided_by: Vec<String>,
    /// For `undetermined`: the experiment that would decide.
    pub experiment: Option<String>,
    /// The answer in one sentence.
    pub verdict: String,
}

/// The final model's simulation with what the verdict reads off it.
struct Reading {
    name: String,
    chosen: Chosen,
    model: EffectModel,
    sim: Simulation,
    heldout: Vec<f64>,
    play: f64,
    se: Option<f64>,
    se_white: Option<f64>,
    /// Whether the record determines the play's own parameters (m2, c1, c2, a friction element's) but for
    /// the gauge (beside a friction element, a claim needs it).
    identified: bool,
    travel: f64,
}

/// How the model a verdict stands on was chosen: on the fit part alone (the final model, or its refit from
/// the zero-gap twin), or among rivals on the held-out part, which spends some of its evidence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Chosen {
    OnFitPart,
    OnHeldOut,
}

/// How much of the verdict is judged. At the chosen split, all of it. At another split
/// (`diagnose::search::stability`), which asks only whether play would be found there too, the halves (of a
/// fit part that overlaps the chosen one by most of its length) and the bound are not sought again: the
/// answer there is `present` or `undetermined`. Checking a `present` claim, the imitators and the rival with
/// play are not fitted either (judged on the chosen split's held-out part; a neighbour that finds play more
/// easily only lets the claim stand); checking an `absent` claim they are, so that a look-alike the chosen
/// split told from play is not read as play at a neighbour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Depth {
    Full,
    /// Presence against the zero-gap twin and every imitator.
    Rivals,
    /// Presence against the zero-gap twin alone.
    Twin,
}

/// The verdict on play for the final model `last` of a diagnosis on problem `p`.
pub(crate) fn assess(p: &Problem, last: &EffectModel, depth: Depth) -> BacklashSupport {
    (p.progress)("judging the play: the same model without a gap, and its play-free alternatives");
    let Some(first) = read(p, last, FINAL_MODEL, Chosen::OnFitPart) else {
        return unreadable();
    };
    let (r, play_free, mut reasons) = standing(p, first, depth);
    let impossible = impossible(&r, &mut reasons);
    let width = r.crossing_width();
    let reversals = [
        crossing_reversals(&r.sim.x[..p.n_fit], width),
        crossing_reversals(&r.sim.x[p.held_from..], width),
    ];
    let cx = Context {
        p,
        r: &r,
        play_free: &play_free,
        reversals,
        depth,
    };
    let mut out = cx.decide(impossible, &mut reasons);
    if out.presence == Presence::Undetermined
        && depth == Depth::Full
        && let Some(fold) = Fold::of(&r.sim.x[..p.n_fit], &p.y[..p.n_fit])
    {
        // What the record looks like instead, where it is a fold (issue 55: an estimate that cannot be is
        // said as what it is), first among what kept the answer open: no play model fits a fold, whichever
        // of the verdict's conditions failed on it.
        reasons.push(fold.said());
        out.undecided_by.insert(0, FOLD_UNDECIDED.into());
    }
    out.reasons = reasons;
    out
}

/// What kept the answer open where the record is a fold ([`Fold`]).
const FOLD_UNDECIDED: &str = "the record looks like a fold, as a sensor that reads |x|: no play model fits it (see the reasons)";

/// The model the verdict stands on, the play-free models it is judged against and, where it is not the
/// final model `first` (refitted from its zero-gap twin, or a rival), why. The play-free imitators are fitted only where the gap beats its zero-gap twin;
/// a rival with play only for the imitators the final model does not beat; neither at [`Depth::Twin`].
fn standing(p: &Problem, first: Reading, depth: Depth) -> (Reading, Vec<PlayFree>, Vec<String>) {
    let (first, idle) = without_idle_friction(p, first);
    let (first, twin, refitted) = beside_twin(p, first);
    let mut why: Vec<String> = idle.into_iter().chain(refitted).collect();
    let gains = twin.as_ref().is_some_and(|t| beats(&first, t, MIN_Z));
    let mut free: Vec<PlayFree> = twin.into_iter().collect();
    if !gains || depth == Depth::Twin {
        return (first, free, why);
    }
    let last = first.fitted();
    let mut found: Vec<_> = imitators(p, &last, &first.sim, &first.model, TWIN)
        .into_iter()
        .map(|im| (im, "the final model"))
        .collect();
    if !first.model.exts.is_empty() {
        // The look-alikes alone, without the final model's other effects (friction, itself a play, would
        // otherwise stay in every alternative).
        let bare = EffectModel::plain(first.model.base.clone());
        let alone = imitators(p, &last, &first.sim, &bare, "zero-gap, no other effect");
        found.extend(
            alone
                .into_iter()
                .map(|im| (im, "the linear block and play alone")),
        );
    }
    let threats = found
        .iter()
        .filter(|(im, _)| !beats(&first, &im.free, MIN_Z))
        .map(|(im, name)| (im, *name));
    let rival = best_rival(p, &last, threats, MIN_GAIN, MIN_Z);
    free.extend(found.into_iter().map(|(im, _)| im.free));
    let Some(r) = rival.and_then(|f| read(p, &f.model, &f.name, Chosen::OnHeldOut)) else {
        return (first, free, why);
    };
    for t in &mut free {
        t.z = diebold_mariano(&t.errors, &r.heldout);
    }
    why.push(format!(
        "{} predicts the held-out part better than {} ({} against {}, Diebold-Mariano z {:.2}): the \
         verdict stands on that model, whose gap is judged against the same effects without it",
        r.name,
        first.name,
        g(rms(r.heldout.iter().copied())),
        g(rms(first.heldout.iter().copied())),
        diebold_mariano(&first.heldout, &r.heldout)
    ));
    (r, free, why)
}

/// Where the final model `first` has a friction element that earns nothing on the held-out part (the same
/// model without it, refitted from it, predicts the held-out part not clearly worse: 2% and z 1.645), the
/// model without it, with why: an element no held-out error asks for is not evidence (issue 55, item 3),
/// and a friction element is itself a play that would otherwise keep every answer `undetermined`. The
/// choice reads the held-out part, so the model's gains then need z 3.09.
fn without_idle_friction(p: &Problem, first: Reading) -> (Reading, Option<String>) {
    if first.model.effects().friction.is_none() {
        return (first, None);
    }
    let mut bare = EffectModel::plain(first.model.base.clone());
    for e in first.model.exts.iter().filter(|e| e.id() != friction::ID) {
        bare = bare.with(e.clone());
    }
    let fitted = p
        .fit(&bare, std::slice::from_ref(&bare), Objective::Simulation)
        .and_then(|(m, _)| read(p, &m, WITHOUT_FRICTION, Chosen::OnHeldOut));
    let Some(r) = fitted.filter(|r| !clearly_better(&first.heldout, &r.heldout, MIN_GAIN, MIN_Z))
    else {
        return (first, None);
    };
    let why = format!(
        "the final model's friction element earns nothing on the held-out part: without it the held-out \
         error is {} against {} (Diebold-Mariano z {:.2}; 2% and z 1.645 would ask for it), so the verdict \
         stands on the model without it",
        g(rms(r.heldout.iter().copied())),
        g(rms(first.heldout.iter().copied())),
        diebold_mariano(&r.heldout, &first.heldout)
    );
    (r, Some(why))
}

/// `first` and its zero-gap twin fitted. Where the model with the gap predicts the held-out part clearly
/// worse than the twin, a special case of it, its fit stopped in a worse minimum than the twin's (the cost
/// with a gap is not smooth): the same structure is refitted from the twin's fit, the gap free again, and
/// stands instead where its fit-part cost is lower (chosen on the fit part alone, like the final model);
/// with why. A spurious gap that holds a smooth curve's borders away from the twin's is undone so.
fn beside_twin(p: &Problem, first: Reading) -> (Reading, Option<PlayFree>, Option<String>) {
    let Some((twin, twin_model)) = play_free(p, &first.heldout, &first.model, TWIN) else {
        return (first, None, None);
    };
    if !clearly_worse(rms(first.heldout.iter().copied()), &twin) {
        return (first, Some(twin), None);
    }
    let cost = |m: &EffectModel| p.cost(m, Objective::Simulation).unwrap_or(f64::INFINITY);
    let refit = p
        .fit(
            &first.model,
            std::slice::from_ref(&twin_model),
            Objective::Simulation,
        )
        .filter(|(_, c)| *c < cost(&first.model))
        .and_then(|(m, _)| read(p, &m, REFITTED, Chosen::OnFitPart));
    let Some(r) = refit else {
        return (first, Some(twin), None);
    };
    let why = format!(
        "the final model predicts the held-out part clearly worse than its zero-gap twin ({} against {}), \
         though the twin is a special case of it: refitted from the twin's fit it costs less on the fit part \
         and predicts the held-out part with error {}; the verdict stands on that fit",
        g(rms(first.heldout.iter().copied())),
        g(twin.heldout_rmse),
        g(rms(r.heldout.iter().copied()))
    );
    let twin = PlayFree {
        z: diebold_mariano(&twin.errors, &r.heldout),
        ..twin
    };
    (r, Some(twin), Some(why))
}

/// A model's deterministic part simulated, its play and the play's standard errors; named `name`.
fn read(p: &Problem, last: &EffectModel, name: &str, chosen: Chosen) -> Option<Reading> {
    let model = last.deterministic();
    let sim = model.simulate(p.u, p.rest, p.u.len(), p.limit)?;
    let heldout = heldout_errors(p, &sim);
    let var = p.play_variance(&model);
    let x_fit = &sim.x[..p.n_fit];
    let travel = quantile(x_fit, 0.99).unwrap_or(0.0) - quantile(x_fit, 0.01).unwrap_or(0.0);
    Some(Reading {
        name: name.into(),
        chosen,
        play: model.play(),
        se: var.as_ref().map(|v| v.sandwich.sqrt()),
        se_white: var.as_ref().map(|v| v.classical.sqrt()),
        identified: var.is_some_and(|v| v.determines(&model.play_entries())),
        model,
        sim,
        heldout,
        travel,
    })
}

impl Reading {
    /// The width whose crossings are counted: the play, or [`MIN_PLAY_SHARE`] of the travel where the play
    /// is narrower (the narrowest play claimed; every turn would cross a gap of zero).
    fn crossing_width(&self) -> f64 {
        self.play.abs().max(MIN_PLAY_SHARE * self.travel)
    }

    /// The model and its held-out errors, for the comparisons.
    fn fitted(&self) -> Fitted {
        Fitted {
            name: self.name.clone(),
            model: self.model.clone(),
            heldout: self.heldout.clone(),
        }
    }
}

fn unreadable() -> BacklashSupport {
    BacklashSupport::undetermined(
        "the final model cannot be simulated over the record, so nothing can be said about play",
    )
}

impl BacklashSupport {
    /// The verdict with its size and interval in one line: the first thing the text output, the report and
    /// a user read.
    pub fn headline(&self) -> String {
        let interval = |p: f64, se: f64| {
            format!(
                "{} +/- {} in the linear block's units (95% interval {} to {})",
                g(p),
                g(se),
                g(p - residual::Z95 * se),
                g(p + residual::Z95 * se)
            )
        };
        let input = self.play_input_units.map_or(String::new(), |v| {
            format!(", about {} in the input's units", g(v))
        });
        match (self.presence, self.play_se) {
            (Presence::Present, Some(se)) => {
                format!("play: present, {}{input}", interval(self.play, se))
            }
            (Presence::Absent, _) => format!(
                "play: absent, none above {} in the linear block's units (95%)",
                g(self.play_bound.unwrap_or(f64::NAN))
            ),
            _ => {
                let se = self.play_se.map_or("unknown".into(), g);
                let size = if self.play > 0.0 {
                    format!("{} +/- {se} in the linear block's units", g(self.play))
                } else {
                    // A negative or zero gap is not a play: said as the fit's gap, not as a size.
                    format!(
                        "the fitted gap c1 + c2 is {} +/- {se}, which is no play",
                        g(self.play)
                    )
                };
                let why = if self.undecided_by.is_empty() {
                    "no evidence either way".into()
                } else {
                    self.undecided_by.join("; ")
                };
                format!("play: undetermined, {size}: {why}")
            }
        }
    }

    /// `undetermined` for the reason `why`, with no numbers.
    pub(crate) fn undetermined(why: &str) -> Self {
        Self {
            presence: Presence::Undetermined,
            model: FINAL_MODEL.into(),
            supported: false,
            reasons: vec![why.into()],
            play: f64::NAN,
            play_se: None,
            play_se_white: None,
            se_method: SE_METHOD,
            play_bound: None,
            play_input_units: None,
            play_output_units: None,
            heldout_rmse: f64::NAN,
            play_free: Vec::new(),
            reversals: [0, 0],
            travel: 0.0,
            halves: None,
            splits: Vec::new(),
            undecided_by: vec![why.into()],
            experiment: None,
            verdict: why.into(),
        }
    }
}

/// Estimates that cannot be a play, said as what they are; true when there is one.
fn impossible(r: &Reading, reasons: &mut Vec<String>) -> bool {
    let mut found = false;
    if let Some(se) = r.se
        && r.play < -residual::Z95 * se
    {
        reasons.push(format!(
            "the fitted gap is negative ({} +/- {}, {:.1} standard errors below zero): after a reversal the \
             output turns at once or leads instead of holding, which no play does; the model class is wrong \
             for this record (a lead, a fold or a drift looks like this)",
            g(r.play),
            g(se),
            -r.play / se
        ));
        found = true;
    }
    if r.play > MAX_PLAY_SHARE * r.travel {
        reasons.push(format!(
            "the fitted play {} is wider than half the travel of the linear block's output ({}): a play that \
             wide would hold the output for most of the record; the model uses the gap for something else",
            g(r.play),
            g(r.travel)
        ));
        found = true;
    }
    let (m1, m2) = (r.model.base.m1, r.model.base.m2);
    if !(m2 > 0.2 * m1 && m2 < 5.0 * m1) {
        reasons.push(format!(
            "the borders' slopes differ by more than five times (m1 = {}, m2 = {}): no mechanical play has \
             such borders",
            g(m1),
            g(m2)
        ));
        found = true;
    }
    found
}

/// Whether the model with the gap beats the play-free model `t` on the held-out part, by [`MIN_GAIN`] with
/// a Diebold-Mariano z of at least `z`.
fn beats(r: &Reading, t: &PlayFree, z: f64) -> bool {
    gap_beats(rms(r.heldout.iter().copied()), t, z)
}

/// [`beats`] for a model with the gap whose held-out RMSE is `rmse`.
fn gap_beats(rmse: f64, t: &PlayFree, z: f64) -> bool {
    better_by(rmse, t.heldout_rmse, t.z, MIN_GAIN, z)
}

/// The play-free model of `play_free` with the lowest held-out error among those a model with the gap
/// (held-out RMSE `rmse`) does not beat at `z`: the other explanation of the record.
fn best_unbeaten(rmse: f64, play_free: &[PlayFree], z: f64) -> Option<&PlayFree> {
    play_free
        .iter()
        .filter(|t| !gap_beats(rmse, t, z))
        .min_by(|a, b| a.heldout_rmse.total_cmp(&b.heldout_rmse))
}

/// Whether a play `play` with standard error `se` is above zero by 1.96 of them and its model (held-out RMSE
/// `rmse`) predicts better than every play-free model of `play_free` at z [`MIN_Z`] or more, however little.
fn unclaimed_play_helps(play: f64, se: Option<f64>, rmse: f64, play_free: &[PlayFree]) -> bool {
    let above = se.is_some_and(|se| play > residual::Z95 * se);
    above
        && !play_free.is_empty()
        && play_free
            .iter()
            .all(|t| better_by(rmse, t.heldout_rmse, t.z, 0.0, MIN_Z))
}

/// Whether the model with the gap, held-out RMSE `with_gap`, predicts clearly worse than the play-free
/// model `t`: `t` beats it by the rule every gain passes ([`MIN_GAIN`], [`MIN_Z`]).
fn clearly_worse(with_gap: f64, t: &PlayFree) -> bool {
    better_by(t.heldout_rmse, with_gap, -t.z, MIN_GAIN, MIN_Z)
}

/// Reversals of `x` whose excursion afterwards exceeds `h` (see [`reversal_turns`]).
pub fn crossing_reversals(x: &[f64], h: f64) -> usize {
    reversal_turns(x, h).len()
}

/// The samples where `x` turns and then moves at least `h` back: the turning points of the zigzag with
/// threshold `h` (a turn is counted once `x` has moved `h` from its extreme). `h` of 0 or less, or NaN,
/// gives none.
pub fn reversal_turns(x: &[f64], h: f64) -> Vec<usize> {
    let mut turns = Vec::new();
    if h.is_nan() || h <= 0.0 || x.is_empty() {
        return turns;
    }
    let (mut lo, mut hi) = ((x[0], 0), (x[0], 0));
    let mut dir = 0i8;
    for (k, &v) in x.iter().enumerate() {
        match dir {
            1 if v > hi.0 => hi = (v, k),
            1 if hi.0 - v >= h => {
                turns.push(hi.1);
                (dir, lo) = (-1, (v, k));
            }
            -1 if v < lo.0 => lo = (v, k),
            -1 if v - lo.0 >= h => {
                turns.push(lo.1);
                (dir, hi) = (1, (v, k));
            }
            0 => {
                if v < lo.0 {
                    lo = (v, k);
                }
                if v > hi.0 {
                    hi = (v, k);
                }
                if v - lo.0 >= h {
                    (dir, hi) = (1, (v, k));
                } else if hi.0 - v >= h {
                    (dir, lo) = (-1, (v, k));
                }
            }
            _ => {}
        }
    }
    turns
}

/// The bisections that narrow a bound between the last play the profile allows and the first it rules out.
pub const PROFILE_HALVINGS: usize = 3;

/// The play between `allowed` (not ruled out) and `ruled_out` (ruled out) where `ruled` turns, to within
/// `(ruled_out - allowed) / 2^PROFILE_HALVINGS`: the narrowest play found ruled out.
fn narrowed(mut allowed: f64, mut ruled_out: f64, ruled: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..PROFILE_HALVINGS {
        let mid = 0.5 * (allowed + ruled_out);
        if ruled(mid) {
            ruled_out = mid;
        } else {
            allowed = mid;
        }
    }
    ruled_out
}

/// The conditions [`Context::decide`] checked, each true where it holds.
struct Conditions {
    /// The held-out part is excited like the fit part.
    fair: bool,
    impossible: bool,
    /// The gap beats every play-free model on the held-out part.
    gains: bool,
    significant: bool,
    crossed: bool,
    /// The record tells the friction element from the gap, and a slider slips.
    identified: bool,
    /// A friction element in the model reads as a play.
    friction: bool,
    /// The model with the gap predicts clearly worse than its zero-gap twin.
    worse: bool,
    /// A play too narrow to claim still predicts better than every play-free model.
    narrow: bool,
    /// Nothing spoke against `absent` (a bound was sought).
    open: bool,
}

/// Everything the decision reads.
struct Context<'a, 'p> {
    p: &'a Problem<'p>,
    r: &'a Reading,
    play_free: &'a [PlayFree],
    reversals: [usize; 2],
    depth: Depth,
}

impl Context<'_, '_> {
    /// The three answers' conditions; every condition checked says why in `reasons` (the halves are
    /// refitted only where everything else says present).
    fn decide(&self, impossible: bool, reasons: &mut Vec<String>) -> BacklashSupport {
        let r = self.r;
        self.say_gain(reasons);
        let gains = !self.play_free.is_empty()
            && self.play_free.iter().all(|t| beats(r, t, self.needed_z()));
        let significant = self.significant(reasons);
        let crossed = self.crossed(reasons);
        // Both said, whichever fails.
        let (told_apart, slips) = (self.identified(reasons), self.slider_slips(reasons));
        let identified = told_apart && slips;
        let fair = self.fair_test(reasons);
        let mut halves = None;
        let present = fair && !impossible && significant && gains && crossed && identified && {
            self.depth != Depth::Full || {
                halves = self.halves();
                self.halves_agree(halves, reasons)
            }
        };
        if present {
            return self.answer(Presence::Present, None, halves);
        }
        let friction = self.friction_reads_as_play(reasons);
        let worse = self.worse_than_its_twin(reasons);
        let narrow = !gains && !significant && self.narrow_play_helps(reasons);
        // Nothing speaks against `absent`: a bound is sought (at the chosen split only).
        let open = self.depth == Depth::Full
            && fair
            && !(impossible || gains || significant || friction || worse || narrow);
        if let Some(b) = open.then(|| self.bound(reasons)).flatten() {
            return self.answer(Presence::Absent, Some(b), halves);
        }
        let mut out = self.answer(Presence::Undetermined, None, halves);
        out.undecided_by = self.undecided_by(&Conditions {
            fair,
            impossible,
            gains,
            significant,
            crossed,
            identified,
            friction,
            worse,
            narrow,
            open,
        });
        out
    }

    /// What kept an `undetermined` answer from `present` and from `absent`, in short phrases: each failed
    /// condition of `c` that the answer's reasons explain (the claim's later conditions only where its
    /// earlier ones held).
    fn undecided_by(&self, c: &Conditions) -> Vec<String> {
        let [fit, held] = self.reversals;
        let claim = c.fair && c.significant && c.gains && !c.impossible;
        [
            (
                !c.fair,
                "the input barely moves on the held-out part, which so tests no claim (see the reasons)"
                    .to_string(),
            ),
            (c.impossible, "the estimate is impossible for a play (see the reasons)".into()),
            (
                c.gains && !c.significant,
                "the gap helps on the held-out part but is not significantly above zero".into(),
            ),
            (!c.gains && c.significant, self.two_explanations()),
            (
                c.narrow,
                "a play too narrow to claim predicts the held-out part better than every play-free model".into(),
            ),
            (
                c.open,
                "no bound on the play could be established (see the reasons)".into(),
            ),
            (
                c.worse,
                "the model with the gap predicts worse than without it: no bound is read from its fit".into(),
            ),
            (
                c.friction,
                "the friction element reads as a play: the record cannot tell them apart".into(),
            ),
            (
                claim && !c.crossed,
                format!(
                    "too few reversals cross the play ({fit} on the fit part, {held} held out; \
                     {MIN_REVERSALS} and {MIN_HELDOUT_REVERSALS}, or {FEW_REVERSALS} and \
                     {FEW_HELDOUT_REVERSALS} with a stronger gain, needed)"
                ),
            ),
            (
                claim && c.crossed && !c.identified,
                "the record does not tell the friction element from the gap, or its gap from a dead zone \
                 (see the reasons)"
                    .into(),
            ),
            (
                claim && c.crossed && c.identified,
                "the two halves of the fit part do not confirm the play (see the reasons)".into(),
            ),
        ]
        .into_iter()
        .filter_map(|(on, why)| on.then_some(why))
        .collect()
    }

    /// Where the gap is significant on the fit part but does not beat every play-free model held out: the
    /// two explanations, the model with the play and the best play-free model it does not beat, with their
    /// held-out errors (issue 56: which of two explanations a user gets is not a coin tossed for them).
    fn two_explanations(&self) -> String {
        let r = self.r;
        let rmse = rms(r.heldout.iter().copied());
        let Some(t) = best_unbeaten(rmse, self.play_free, self.needed_z()) else {
            return "the gap is significant on the fit part but no play-free model could be fitted to judge it \
                    against on the held-out part"
                .into();
        };
        format!(
            "two explanations: the model with a play of {} (held-out error {}) and the {} model without one \
             ({}, Diebold-Mariano z {:.2}), which predicts the held-out part as well or better",
            g(r.play),
            g(rmse),
            t.model,
            g(t.heldout_rmse),
            t.z
        )
    }

    /// Whether the held-out part excites the record as the fit part does: its input's standard deviation
    /// and range at least [`POOR_EXCITATION`] of the fit part's (the rule of the diagnosis's warning); in
    /// words where they are not, or where the fit part's input is constant (no ratio).
    fn fair_test(&self, reasons: &mut Vec<String>) -> bool {
        let (s, r) = self.p.held_out_excitation();
        let fair = fairly_excited((s, r));
        if !(s.is_finite() && r.is_finite()) {
            // `excitation`'s NaN: the fit part's input is constant.
            reasons.push(
                "the input does not move on the fit part, so no held-out comparison tests a play or its \
                 absence"
                    .into(),
            );
        } else if !fair {
            reasons.push(format!(
                "the input's standard deviation on the held-out part is {:.1}% and its range {:.1}% of the fit \
                 part's (at least {:.0}% each is needed): the models' held-out errors are compared where \
                 almost nothing moves, so neither a play nor its absence is tested there (see the warnings \
                 for a fairer split)",
                100.0 * s,
                100.0 * r,
                100.0 * POOR_EXCITATION
            ));
        }
        fair
    }

    /// Whether the model with the gap predicts the held-out part clearly worse than its zero-gap twin (a
    /// special case of it), by the rule every gain passes turned round: its fit went wrong or spent the gap
    /// on the fit part's noise, and a bound read from it would rule out a play the record does not rule out;
    /// in words. (A significant loss of a few tenths of a percent is the gap's own noise: the two models'
    /// errors are so alike that the test sees it.)
    fn worse_than_its_twin(&self, reasons: &mut Vec<String>) -> bool {
        let Some(twin) = self.play_free.iter().find(|t| t.model == TWIN) else {
            return false;
        };
        let with_gap = rms(self.r.heldout.iter().copied());
        let worse = clearly_worse(with_gap, twin);
        if worse {
            reasons.push(format!(
                "the model with the gap predicts the held-out part clearly worse than the same model without \
                 it ({} against {}, Diebold-Mariano z {:.2}; at least {:.0}% and z {MIN_Z} make it clear), \
                 though the gap-free model is a special case of it: its fit is no basis for a bound on the play",
                g(with_gap),
                g(twin.heldout_rmse),
                twin.z,
                100.0 * MIN_GAIN
            ));
        }
        worse
    }

    /// Whether a play that is not claimed (too narrow, or a gain below [`MIN_GAIN`]) is still evidence
    /// against `absent`: above zero by 1.96 standard errors, and the model with it predicts the held-out
    /// part better than every play-free model with a Diebold-Mariano z of at least [`MIN_Z`], however
    /// little. A play of 1.4% of the travel whose gain over a polynomial feedback was 1.8% at z 3.06 read as
    /// `absent` with a bound above it; no play-free record of the confusion table meets both. In words.
    fn narrow_play_helps(&self, reasons: &mut Vec<String>) -> bool {
        let r = self.r;
        let rmse = rms(r.heldout.iter().copied());
        let narrow = unclaimed_play_helps(r.play, r.se, rmse, self.play_free);
        if narrow {
            reasons.push(format!(
                "the play {} is above zero by more than 1.96 standard errors and the model with it predicts \
                 the held-out part better than every play-free model (each at z {MIN_Z} or more), though not \
                 enough to claim it: the record does not say there is no play",
                g(r.play)
            ));
        }
        narrow
    }

    /// A friction element in the final model is itself a play acting on the force (an elasto-plastic
    /// element F = k (p - z) holds z within a play of width (F+ + F-) / k of p): the record cannot rule out
    /// play then, whatever the gap says; in words (where the element never slips, it holds no loop and its
    /// gap is a dead zone: said so, and still no ground for `absent`).
    fn friction_reads_as_play(&self, reasons: &mut Vec<String>) -> bool {
        let Some(f) = self.r.model.effects().friction else {
            return false;
        };
        reasons.push(if self.slider_stuck().is_some() {
            // A contact element that never slips holds no loop: its gap is a dead zone (see
            // `slider_slips`), and a play with memory beside it is neither seen nor ruled out.
            "the final model's friction element never slips on the fit part: its gap is a dead zone inside \
             its spring, and whether a play with memory is there too the record does not say, so no play is \
             not an answer here"
                .to_string()
        } else {
            format!(
                "the final model's friction element is itself a play acting on the output (slip levels {} and \
                 {}: a loop of width {} in its spring's units): the record cannot tell that friction from \
                 play, so no play is not an answer here",
                g(f.f_plus),
                g(-f.f_minus),
                g((f.f_plus + f.f_minus) / f.k_e)
            )
        });
        true
    }

    /// Whether the friction element and the gap are told apart: false where the model has a friction
    /// element and the record leaves one of the play's own parameters (m2, c1, c2, the element's slip
    /// levels: `EffectModel::play_entries`) undetermined beyond the direction the element hides by
    /// construction (`EffectModel::gauge_weights`: the gap's centre, which a slipping slider absorbs, or
    /// the level a series element does not see): a slip level never reached, or a spring traded against
    /// the gap, so the loop is read as friction and as play alike; in words. A parameter elsewhere that
    /// the record does not determine (a saturation limit never reached) says nothing about the play.
    /// Without friction an undetermined centre is a constant traded against the gap (direction-dependent
    /// dynamics' falling constant) and the play stands.
    fn identified(&self, reasons: &mut Vec<String>) -> bool {
        let r = self.r;
        let told_apart = r.identified || r.model.effects().friction.is_none();
        if r.se.is_some() && !told_apart {
            reasons.push(
                "the record does not determine the gap's and the friction element's parameters (the \
                 information matrix is singular along them beyond where the gap sits, which the element \
                 hides by construction: a slip level never reached, or the spring traded against the gap): \
                 the play c1 + c2 is determined, but the loop reads as friction and as play alike, so it is \
                 not claimed"
                    .into(),
            );
        }
        told_apart
    }

    /// Whether the gap inside a friction element's spring (contact form) moves: its slider slips, on the
    /// fit part, by more than the play. A slider that never slips holds the gap where it started, a band
    /// of zero force at a fixed place: a dead zone inside the spring, which has no memory (a Coulomb-viscous
    /// mass driven by a force and measured by its velocity fits so: its velocity stays zero while the force
    /// lies within +-Fc, wherever it came from), so it is not a play; in words. True for every other model.
    fn slider_slips(&self, reasons: &mut Vec<String>) -> bool {
        let Some(travel) = self.slider_stuck() else {
            return true;
        };
        reasons.push(format!(
            "the friction element's slider moves by {} on the fit part, less than the play {}: the gap stays \
             where it started, a band of zero force at a fixed place, which is a dead zone inside the spring \
             (no memory), not a play",
            g(travel),
            g(self.r.play)
        ));
        false
    }

    /// How far the slider of a friction element with the play inside its spring moves on the fit part
    /// (max - min of its position), where that is no more than the play (the slider never slips past it);
    /// `None` where it moves further, and for every other model.
    fn slider_stuck(&self) -> Option<f64> {
        let r = self.r;
        if !r.model.has_contact() {
            return None;
        }
        // In the contact form the backlash output is the slider's position.
        let z = &r.sim.w[..self.p.n_fit];
        let lo = z.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = z.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Some(hi - lo).filter(|travel| *travel <= r.play)
    }

    /// The z the held-out gain needs against every play-free model: [`MIN_Z`], or [`FEW_REVERSALS_Z`] when
    /// the verdict stands on a rival chosen on the held-out part (the choice spends some of its evidence).
    fn needed_z(&self) -> f64 {
        if self.r.chosen == Chosen::OnFitPart {
            MIN_Z
        } else {
            FEW_REVERSALS_Z
        }
    }

    /// Whether the play is significantly above zero and at least [`MIN_PLAY_SHARE`] of the travel, in
    /// words.
    fn significant(&self, reasons: &mut Vec<String>) -> bool {
        let r = self.r;
        let Some(se) = r.se else {
            reasons.push("the record does not determine the gaps (no standard error)".into());
            return false;
        };
        if r.play > 0.0 && r.play < MIN_PLAY_SHARE * r.travel {
            reasons.push(format!(
                "the play {} is below {:.0}% of the travel {}: too narrow to tell from what the model's other \
                 imperfections buy",
                g(r.play),
                100.0 * MIN_PLAY_SHARE,
                g(r.travel)
            ));
            return false;
        }
        let yes = r.play > residual::Z95 * se;
        reasons.push(format!(
            "the play {} +/- {} is {}significantly above zero ({:.1} standard errors; the standard error \
             assuming white residuals would be {})",
            g(r.play),
            g(se),
            if yes { "" } else { "not " },
            r.play / se,
            r.se_white.map_or("unknown".into(), g)
        ));
        yes
    }

    /// The held-out comparison with every play-free model, in words.
    fn say_gain(&self, reasons: &mut Vec<String>) {
        let rmse = rms(self.r.heldout.iter().copied());
        for t in self.play_free {
            let verb = if beats(self.r, t, self.needed_z()) {
                "beats"
            } else {
                "does not beat"
            };
            reasons.push(format!(
                "with the gap the held-out error is {} and {verb} the {} model's {} ({:+.1}%, \
                 Diebold-Mariano z {:.2}; at least {:.0}% and z {} are needed)",
                g(rmse),
                t.model,
                g(t.heldout_rmse),
                100.0 * (rmse / t.heldout_rmse - 1.0),
                t.z,
                100.0 * MIN_GAIN,
                self.needed_z()
            ));
        }
        if self.play_free.is_empty() {
            reasons.push(
                "the zero-gap model could not be fitted, so the gap was compared with nothing"
                    .into(),
            );
        }
    }

    /// Enough reversals cross the play, on both parts: [`MIN_REVERSALS`] and [`MIN_HELDOUT_REVERSALS`], or
    /// [`FEW_REVERSALS`] and [`FEW_HELDOUT_REVERSALS`] with a held-out gain significant at
    /// [`FEW_REVERSALS_Z`] against every play-free model.
    fn crossed(&self, reasons: &mut Vec<String>) -> bool {
        let [fit, held] = self.reversals;
        let enough = fit >= MIN_REVERSALS && held >= MIN_HELDOUT_REVERSALS;
        let few = fit >= FEW_REVERSALS && held >= FEW_HELDOUT_REVERSALS;
        let weakest = self
            .play_free
            .iter()
            .map(|t| t.z)
            .fold(f64::INFINITY, f64::min);
        let strong = !self.play_free.is_empty() && weakest >= FEW_REVERSALS_Z;
        let width = if self.r.play.abs() < self.r.crossing_width() {
            format!(
                "{:.0}% of the travel, {} (the play is narrower)",
                100.0 * MIN_PLAY_SHARE,
                g(self.r.crossing_width())
            )
        } else {
            "the play".into()
        };
        let mut why = format!(
            "{fit} reversals of the linear block's output cross {width} on the fit part and {held} on the \
             held-out part ({MIN_REVERSALS} and {MIN_HELDOUT_REVERSALS} are enough"
        );
        if !enough && few {
            why += &format!(
                "; with {FEW_REVERSALS} to {MIN_REVERSALS} and {FEW_HELDOUT_REVERSALS} to \
                 {MIN_HELDOUT_REVERSALS} the gain must reach z {FEW_REVERSALS_Z} against every play-free \
                 model: the weakest is {weakest:.2}"
            );
        } else if !enough {
            why += &format!(
                "; at least {FEW_REVERSALS} and {FEW_HELDOUT_REVERSALS} with a stronger gain"
            );
        }
        reasons.push(why + ")");
        enough || (few && strong)
    }

    /// The plays of the fit part's two halves, each refitted from the final model to its own samples of a
    /// simulation of the fit part (`Problem::range_play`: the linear block held, the second half starting in
    /// the state the first left), with their standard errors (infinite where a half does not determine them).
    fn halves(&self) -> Option<[(f64, f64); 2]> {
        let p = self.p;
        let h = p.n_fit / 2;
        let m = &self.r.model;
        Some([p.range_play(m, 0..h)?, p.range_play(m, h..p.n_fit)?])
    }

    /// Whether the halves' plays agree (see [`HALF_TOLERANCE`]), in words.
    fn halves_agree(&self, halves: Option<[(f64, f64); 2]>, reasons: &mut Vec<String>) -> bool {
        let Some([(a, sa), (b, sb)]) = halves else {
            reasons.push("the halves of the fit part could not be refitted on their own".into());
            return false;
        };
        if !(sa.is_finite() && sb.is_finite()) {
            reasons.push(format!(
                "the halves of the fit part give plays {} and {} that neither half determines (no standard \
                 error): their agreement says nothing",
                g(a),
                g(b)
            ));
            return false;
        }
        let allowed = residual::Z95 * sa.hypot(sb) + HALF_TOLERANCE * a.abs().max(b.abs());
        let agree = (a - b).abs() <= allowed;
        reasons.push(format!(
            "the two halves of the fit part give plays {} +/- {} and {} +/- {}: they {} (a difference up to {} \
             is allowed)",
            g(a),
            g(sa),
            g(b),
            g(sb),
            if agree { "agree" } else { "disagree" },
            g(allowed)
        ));
        agree
    }

    /// The play the record rules out at 95%: the Wald bound `max(play, 0) + 1.96 se`, checked on the profile
    /// (the model refitted with the play held there must cost at least [`CHI2_95`] more, in units of the
    /// residual variance times the sandwich's inflation), widened by half at a time where it is not, until
    /// it holds or passes [`MAX_BOUND_SHARE`] of the travel (at most [`PROFILE_STEPS`] refits: a model whose
    /// other elements take over part of the loop, curved borders beside a friction, has a flat profile near
    /// zero and a Wald bound well inside it); `None` (with the reason) when no bound holds, is too wide or is
    /// crossed too rarely.
    fn bound(&self, reasons: &mut Vec<String>) -> Option<f64> {
        let (p, r) = (self.p, self.r);
        let (start, inflation) = self.profile_start(reasons)?;
        let best = p.cost(&r.model, Objective::Simulation)?;
        let unit = best / p.n_fit as f64 * inflation;
        let Some(bound) = self.ruled_out(start, best, unit) else {
            reasons
                .push("no play the record rules out could be found on the play's profile".into());
            return None;
        };
        let crossing = crossing_reversals(&r.sim.x[..p.n_fit], bound);
        let narrow = bound <= MAX_BOUND_SHARE * r.travel;
        reasons.push(format!(
            "the record rules out a play above {} at 95% (profile checked), {}% of the travel {}; {crossing} \
             reversals cross that width (at least {MIN_ABSENT_REVERSALS} and at most {:.0}% of the travel are \
             needed to say no play)",
            g(bound),
            (100.0 * bound / r.travel).round(),
            g(r.travel),
            100.0 * MAX_BOUND_SHARE
        ));
        (narrow && crossing >= MIN_ABSENT_REVERSALS).then_some(bound)
    }

    /// The first play, from `start` up by half at a time ([`PROFILE_STEPS`] at most, and not beyond
    /// [`MAX_BOUND_SHARE`] of the travel once past `start`), whose profile (the final model refitted with its
    /// play pinned there) costs at least [`CHI2_95`] units `unit` more than the fit's `best`; past `start`,
    /// narrowed between it and the last play that costs less by [`PROFILE_HALVINGS`] bisections (the bound is
    /// where the profile crosses the threshold, not the step of the search that passed it: up to a third
    /// narrower).
    fn ruled_out(&self, start: f64, best: f64, unit: f64) -> Option<f64> {
        let (p, r) = (self.p, self.r);
        let ruled = |b: f64| {
            let pins = r.model.play_pins(b, p.time_scale);
            let mut s = r.model.clone();
            s.base.c2 = b - s.base.c1;
            p.fit_pinned(&r.model, &pins, &[s])
                .is_some_and(|(_, c)| (c - best) / unit >= CHI2_95)
        };
        let widest = MAX_BOUND_SHARE * r.travel;
        let mut bound = start;
        for step in 0..PROFILE_STEPS {
            if step > 0 && bound > widest {
                return None;
            }
            if ruled(bound) {
                let allowed = (step > 0).then_some(bound / 1.5);
                return Some(allowed.map_or(bound, |a| narrowed(a, bound, ruled)));
            }
            bound *= 1.5;
        }
        None
    }

    /// Where [`Context::bound`]'s profile starts, and the factor by which the residuals' autocorrelation
    /// inflates its unit: the Wald bound and the sandwich's inflation `(se / se_white)^2` where the play has
    /// standard errors; where it has none (the gap sits at zero, the lower bound of its fit, where no
    /// information is read across the bound, or the record does not determine the gaps) and the gap is
    /// narrower than [`MIN_PLAY_SHARE`] of the travel, the narrowest play ever claimed, that share (above the
    /// estimate, so the profile rises from the fit) and the residuals' own inflation
    /// ([`long_run_inflation`]), said in words; `None` otherwise (a wider gap with no standard error: where
    /// the profile should start is not known).
    fn profile_start(&self, reasons: &mut Vec<String>) -> Option<(f64, f64)> {
        let r = self.r;
        if let (Some(se), Some(white)) = (r.se, r.se_white.filter(|w| *w > 0.0)) {
            return Some((
                r.play.max(0.0) + residual::Z95 * se,
                (se / white).powi(2).max(1.0),
            ));
        }
        let start = MIN_PLAY_SHARE * r.travel;
        if r.play.abs() >= start {
            return None;
        }
        let inflation = long_run_inflation(&fit_errors(self.p, &r.sim));
        reasons.push(format!(
            "the gap {} is within {:.0}% of the travel of zero, narrower than any play claimed, and the record \
             gives it no standard error: the bound is read on the profile alone, from {:.0}% of the travel up, \
             with the residual variance inflated {:.2} times for the residuals' autocorrelation",
            g(r.play),
            100.0 * MIN_PLAY_SHARE,
            100.0 * MIN_PLAY_SHARE,
            inflation
        ));
        Some((start, inflation))
    }

    /// The answer with its numbers, its sentence and, for `undetermined`, the experiment.
    fn answer(
        &self,
        presence: Presence,
        bound: Option<f64>,
        halves: Option<[(f64, f64); 2]>,
    ) -> BacklashSupport {
        let r = self.r;
        let possible = r.play >= 0.0 && r.play <= MAX_PLAY_SHARE * r.travel;
        let gain = r.model.base.static_gain().abs();
        let slope = 0.5 * (r.model.base.m1 + r.model.base.m2);
        let play_input_units = (possible && gain > 0.0).then(|| r.play / gain);
        let experiment = (presence == Presence::Undetermined).then(|| self.experiment(gain));
        BacklashSupport {
            presence,
            model: r.name.clone(),
            supported: presence == Presence::Present,
            reasons: Vec::new(),
            play: r.play,
            play_se: r.se,
            play_se_white: r.se_white,
            se_method: SE_METHOD,
            play_bound: bound,
            play_input_units,
            play_output_units: possible.then_some(r.play * slope),
            heldout_rmse: rms(r.heldout.iter().copied()),
            play_free: self.play_free.to_vec(),
            reversals: self.reversals,
            travel: r.travel,
            halves: halves.map(|[a, b]| [a.0, b.0]),
            splits: Vec::new(),
            undecided_by: Vec::new(),
            verdict: self.sentence(presence, bound, play_input_units),
            experiment,
        }
    }

    /// The answer in one sentence.
    fn sentence(&self, presence: Presence, bound: Option<f64>, input: Option<f64>) -> String {
        let r = self.r;
        let se = r.se.map_or(String::new(), |s| format!(" +/- {}", g(s)));
        let in_input = input.map_or(String::new(), |v| {
            format!(" (about {} in the input's units)", g(v))
        });
        match presence {
            Presence::Present => format!(
                "play is present: {}{se} in the linear block's units{in_input}; the model with the gap beats \
                 every play-free model on the held-out part",
                g(r.play)
            ),
            Presence::Absent => format!(
                "no play: the record rules out a play above {} (95%) in the linear block's units, and the gap \
                 brings nothing on the held-out part",
                g(bound.unwrap_or(f64::NAN))
            ),
            Presence::Undetermined => {
                "the record cannot tell whether there is play (the reasons say why and what would decide)".into()
            }
        }
    }

    /// The experiment that would decide, in the input's units where the static gain allows.
    fn experiment(&self, gain: f64) -> String {
        let r = self.r;
        let suspected = r.play.abs().max(r.se.unwrap_or(0.0)).max(0.02 * r.travel);
        let excursion = 5.0 * suspected;
        let in_input = if gain > 0.0 {
            format!(" (about {} of the input)", g(excursion / gain))
        } else {
            String::new()
        };
        format!(
            "a slow triangle or sine of the input at two amplitudes, each with at least {MIN_ABSENT_REVERSALS} \
             reversals whose excursion in the linear block's output exceeds {}{in_input}, slow enough for the \
             linear block to settle between reversals: a play holds the output over the same width at both \
             amplitudes and rates, a dynamic lag does not",
            g(excursion)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gap inside a friction element's spring is a play only where the slider slips: the paper's linear
    /// block with equal slopes and a gap of 0.6 inside the spring, at noise 0.02. With slip levels the
    /// force never reaches, the gap stays where it started (a dead zone inside the spring, no memory) and
    /// the verdict says so; with slip levels it reaches, it does not.
    #[test]
    fn a_gap_whose_slider_never_slips_is_a_dead_zone() {
        use crate::diagnose::effects::friction::extension;
        use crate::diagnose::fit::lm::LmOptions;
        use crate::diagnose::fit::model::tests::{input, paper_base, with_noise};
        use crate::diagnose::fit::model::{BaseModel, Rest};
        use crate::plant::effects::FrictionForm;
        let n = 2000;
        let u = input(n);
        let said = |slip: f64| {
            let base = BaseModel {
                c1: 0.3,
                c2: 0.3,
                m2: 1.0,
                ..paper_base()
            };
            let m = EffectModel::plain(base).with(extension(slip, slip, FrictionForm::Contact));
            let sim = m.simulate(&u, Rest::ZERO, n, 1e6).expect("the model runs");
            let y = with_noise(&sim.y, 0.02, 5);
            let p = Problem::new(&u, &y, 1400, LmOptions::default());
            assess(&p, &m, Depth::Twin).reasons.join(" | ")
        };
        let never = said(100.0);
        assert!(never.contains("a dead zone inside the spring"), "{never}");
        assert!(!never.contains("is itself a play"), "{never}");
        let slips = said(0.5);
        assert!(!slips.contains("a dead zone inside the spring"), "{slips}");
    }

    /// Samples of [`paper_gap_record`], and where its fit part ends.
    const RECORD: (usize, usize) = (2000, 1400);

    /// A record of the paper's linear block with equal slopes and a gap of `c` each side (noise 0.02 drawn
    /// with `seed`), its input scaled by `held_scale` on the held-out part: the input, the output and the
    /// true model.
    fn paper_gap_record(c: f64, seed: u64, held_scale: f64) -> (Vec<f64>, Vec<f64>, EffectModel) {
        use crate::diagnose::fit::model::BaseModel;
        use crate::diagnose::fit::model::Rest;
        use crate::diagnose::fit::model::tests::{input, paper_base, with_noise};
        let (n, n_fit) = RECORD;
        let mut u = input(n);
        u[n_fit..].iter_mut().for_each(|v| *v *= held_scale);
        let truth = EffectModel::plain(BaseModel {
            c1: c,
            c2: c,
            m2: 1.0,
            ..paper_base()
        });
        let sim = truth
            .simulate(&u, Rest::ZERO, n, 1e6)
            .expect("the model runs");
        (u, with_noise(&sim.y, 0.02, seed), truth)
    }

    /// A fit that stopped with a spurious gap is not the basis of the verdict: on a record of the paper's
    /// linear block with no gap (noise 0.02), a "final model" with a gap of 1.0 left open predicts the held-out
    /// part clearly worse than its zero-gap twin; the verdict stands on the structure refitted from the
    /// twin's fit, which costs less on the fit part and predicts better, and says so. The true model is
    /// kept as it is.
    #[test]
    fn a_gap_model_worse_than_its_twin_is_refitted_from_the_twin() {
        use crate::diagnose::fit::lm::LmOptions;
        let (u, y, truth) = paper_gap_record(0.0, 7, 1.0);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let mut stuck = truth.clone();
        (stuck.base.c1, stuck.base.c2) = (0.5, 0.5);
        let first = read(&p, &stuck, FINAL_MODEL, Chosen::OnFitPart).expect("it runs");
        let before = rms(first.heldout.iter().copied());
        let (r, twin, why) = beside_twin(&p, first);
        let twin = twin.expect("the twin is fitted");
        assert!(
            twin.heldout_rmse < 0.9 * before,
            "{} {before}",
            twin.heldout_rmse
        );
        assert_eq!(r.name, REFITTED);
        assert!(rms(r.heldout.iter().copied()) < 0.9 * before);
        // The twin is judged against the model the verdict stands on, not the one it replaced.
        assert_eq!(twin.z, diebold_mariano(&twin.errors, &r.heldout));
        let cost = |m: &EffectModel| p.cost(m, Objective::Simulation).expect("it runs");
        assert!(cost(&r.model) < cost(&stuck));
        assert!(why.is_some_and(|w| w.contains("refitted from the twin's fit")));
        let kept = read(&p, &truth, FINAL_MODEL, Chosen::OnFitPart).expect("it runs");
        let (r, _, why) = beside_twin(&p, kept);
        assert_eq!(r.name, FINAL_MODEL);
        assert!(why.is_none());
    }

    /// A held-out part where the input barely moves tests no claim: the paper's model with a play of 1.0
    /// (noise 0.02), its input cut to 1% on the held-out part, is `undetermined` and says why; the same
    /// record with the input kept is `present`.
    #[test]
    fn a_quiet_held_out_part_tests_no_claim() {
        use crate::diagnose::fit::lm::LmOptions;
        let verdict = |quiet: f64| {
            let (u, y, truth) = paper_gap_record(0.5, 3, quiet);
            let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
            assess(&p, &truth, Depth::Full)
        };
        let quiet = verdict(0.01);
        assert_eq!(quiet.presence, Presence::Undetermined);
        assert!(
            quiet.undecided_by[0].contains("barely moves"),
            "{:?}",
            quiet.undecided_by
        );
        assert!(
            !quiet.undecided_by.iter().any(|w| w.contains("halves")),
            "{:?}",
            quiet.undecided_by
        );
        let said = quiet.reasons.join(" | ");
        assert!(said.contains("range 1.0% of the fit part's"), "{said}");
        assert_eq!(verdict(1.0).presence, Presence::Present);
    }

    /// A record that is a fold says so first: the paper's linear block read through |x| (noise 0.02),
    /// judged on the linear model (the gap at zero), is `undetermined` with the fold first among what kept it
    /// open and described in the reasons; the record with the play and no fold does not mention one.
    #[test]
    fn a_fold_is_said_first_among_what_kept_the_answer_open() {
        use crate::diagnose::fit::lm::LmOptions;
        use crate::diagnose::fit::model::Rest;
        let (u, _, truth) = paper_gap_record(0.0, 5, 1.0);
        let sim = truth
            .simulate(&u, Rest::ZERO, u.len(), 1e6)
            .expect("the model runs");
        let folded: Vec<f64> = sim.x.iter().map(|x| x.abs()).collect();
        let y = crate::diagnose::fit::model::tests::with_noise(&folded, 0.02, 5);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let out = assess(&p, &truth, Depth::Full);
        assert_eq!(out.presence, Presence::Undetermined);
        assert_eq!(
            out.undecided_by[0], FOLD_UNDECIDED,
            "{:?}",
            out.undecided_by
        );
        assert!(
            out.reasons
                .iter()
                .any(|r| r.contains("looks like a fold instead")),
            "{:?}",
            out.reasons
        );
        let (u, y, truth) = paper_gap_record(0.5, 5, 1.0);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let plain = assess(&p, &truth, Depth::Full);
        assert!(!plain.undecided_by.iter().any(|w| w.contains("fold")));
        assert!(!plain.reasons.iter().any(|r| r.contains("fold instead")));
    }

    /// The bound of `m` on `p` read on the profile alone (no standard error), its reasons joined, and the
    /// travel.
    fn bound_without_se(p: &Problem, m: &EffectModel) -> (Option<f64>, String, f64) {
        let mut r = read(p, m, FINAL_MODEL, Chosen::OnFitPart).expect("it runs");
        (r.se, r.se_white) = (None, None);
        let cx = Context {
            p,
            r: &r,
            play_free: &[],
            reversals: [0, 0],
            depth: Depth::Full,
        };
        let mut reasons = Vec::new();
        (cx.bound(&mut reasons), reasons.join(" | "), r.travel)
    }

    /// The bisection keeps the narrowest play found ruled out: where the profile turns at 1.3 between 1 and
    /// 1.5, within 0.5 / 8 above it; a profile that rules out everything tried keeps the lower end's half step.
    #[test]
    fn a_bound_is_narrowed_to_where_the_profile_turns() {
        let b = narrowed(1.0, 1.5, |p| p >= 1.3);
        assert!((1.3..=1.3 + 0.5 / 8.0).contains(&b), "{b}");
        assert_eq!(narrowed(1.0, 1.5, |_| true), 1.0 + 0.5 / 8.0);
        assert_eq!(narrowed(1.0, 1.5, |_| false), 1.5);
    }

    /// A gap that sits at zero, the lower bound of its fit, has no standard error, and the record still
    /// rules out a play: on the paper's linear block with no play (noise 0.02), the bound is read on the
    /// profile from 2% of the travel up and holds within a quarter of the travel; so it is for a gap near
    /// zero but off it (1% of the travel: the record does not determine it, as where a saturation takes
    /// part of it over), from the same start; a gap of 2% of the travel or wider with no standard error
    /// gives no bound (where its profile would start is not known).
    #[test]
    fn a_gap_at_zero_is_bounded_on_its_profile_alone() {
        use crate::diagnose::fit::lm::LmOptions;
        let (u, y, truth) = paper_gap_record(0.0, 11, 1.0);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let bound_of = |m: &EffectModel| bound_without_se(&p, m);
        let (bound, said, travel) = bound_of(&truth);
        let bound = bound.unwrap_or_else(|| panic!("no bound: {said}"));
        assert!(
            bound >= MIN_PLAY_SHARE * travel && bound <= MAX_BOUND_SHARE * travel,
            "{bound} {said}"
        );
        assert!(said.contains("within 2% of the travel of zero"), "{said}");
        let gapped = |play: f64| {
            let mut m = truth.clone();
            (m.base.c1, m.base.c2) = (play / 2.0, play / 2.0);
            bound_of(&m)
        };
        let (near, said, _) = gapped(0.01 * travel);
        let near = near.unwrap_or_else(|| panic!("no bound near zero: {said}"));
        assert!(
            near >= MIN_PLAY_SHARE * travel && near <= MAX_BOUND_SHARE * travel,
            "{near} {said}"
        );
        for play in [MIN_PLAY_SHARE * travel, 0.5] {
            let (bound, said, _) = gapped(play);
            assert!(bound.is_none(), "{play}: {said}");
        }
    }

    /// A friction element no held-out error asks for is dropped before the verdict: on a record of the
    /// paper's model with a play and no friction, a final model with an element whose slip levels the
    /// force never reaches stands without it, and says so; on a record whose element slips (the play inside
    /// its spring, slip levels 0.5), the element is kept.
    #[test]
    fn an_idle_friction_element_is_dropped_before_the_verdict() {
        use crate::diagnose::effects::friction::extension;
        use crate::diagnose::fit::lm::LmOptions;
        use crate::diagnose::fit::model::Rest;
        use crate::diagnose::fit::model::tests::with_noise;
        use crate::plant::effects::FrictionForm;
        let (u, y, truth) = paper_gap_record(0.3, 5, 1.0);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let idle = truth.with(extension(100.0, 100.0, FrictionForm::Series));
        let first = read(&p, &idle, FINAL_MODEL, Chosen::OnFitPart).expect("it runs");
        let (r, why) = without_idle_friction(&p, first);
        assert_eq!(r.name, WITHOUT_FRICTION);
        assert!(r.model.effects().friction.is_none());
        assert!(why.is_some_and(|w| w.contains("earns nothing")));
        let slipping = truth.with(extension(0.5, 0.5, FrictionForm::Contact));
        let sim = slipping
            .simulate(&u, Rest::ZERO, u.len(), 1e6)
            .expect("the model runs");
        let y = with_noise(&sim.y, 0.02, 5);
        let p = Problem::new(&u, &y, RECORD.1, LmOptions::default());
        let first = read(&p, &slipping, FINAL_MODEL, Chosen::OnFitPart).expect("it runs");
        let (r, why) = without_idle_friction(&p, first);
        assert_eq!(r.name, FINAL_MODEL);
        assert!(why.is_none());
    }

    /// The first line never prints a gap of zero or less as a play's size; a claim is headlined as one, an
    /// absence with its bound.
    #[test]
    fn a_negative_gap_is_not_headlined_as_a_play() {
        let mut s = BacklashSupport::undetermined("for the test");
        (s.play, s.play_se) = (-0.16, Some(0.9));
        let h = s.headline();
        assert!(
            h.contains("the fitted gap c1 + c2 is -0.16") && h.contains("which is no play"),
            "{h}"
        );
        s.play = 0.0;
        assert!(
            s.headline().contains("which is no play"),
            "{}",
            s.headline()
        );
        s.play = 0.5;
        let h = s.headline();
        assert!(h.starts_with("play: undetermined, 0.5"), "{h}");
        assert!(!h.contains("no play"), "{h}");
        (s.presence, s.play_input_units) = (Presence::Present, Some(0.25));
        let h = s.headline();
        assert!(h.starts_with("play: present, 0.5000 +/- 0.9000"), "{h}");
        assert!(h.contains("about 0.2500 in the input's units"), "{h}");
        (s.presence, s.play_bound) = (Presence::Absent, Some(0.8));
        let h = s.headline();
        assert!(h.starts_with("play: absent, none above 0.8000"), "{h}");
    }

    /// A play-free model for the comparisons, named `model`, with its held-out error and the gap's z against it.
    fn free(model: &str, heldout_rmse: f64, z: f64) -> PlayFree {
        PlayFree {
            model: model.into(),
            heldout_rmse,
            z,
            errors: Vec::new(),
        }
    }

    /// The other explanation is the best play-free model the gap does not beat: of a beaten one (the gap 10%
    /// better at z 4), a close one and a better one, the better one; none where every one is beaten.
    #[test]
    fn the_other_explanation_is_the_best_unbeaten_play_free_model() {
        let all = [
            free("zero-gap", 1.1, 4.0),
            free("zero-gap + friction", 1.01, 0.5),
            free("zero-gap + saturation", 0.95, -1.0),
        ];
        let best = best_unbeaten(1.0, &all, MIN_Z).map(|t| t.model.as_str());
        assert_eq!(best, Some("zero-gap + saturation"));
        let best = best_unbeaten(1.0, &all[..2], MIN_Z).map(|t| t.model.as_str());
        assert_eq!(best, Some("zero-gap + friction"));
        assert!(best_unbeaten(1.0, &all[..1], MIN_Z).is_none());
    }

    /// A triangle of amplitude 1: every turn moves 2 back, so a threshold below 2 counts each turn after the
    /// first rise, one of 2.5 none; noise of 0.1 on a constant counts nothing at 0.5.
    #[test]
    fn reversals_are_counted_by_the_excursion_after_them() {
        let tri: Vec<f64> = (0..400)
            .map(|k| {
                let p = (k % 40) as f64 / 10.0;
                if p < 2.0 { p - 1.0 } else { 3.0 - p }
            })
            .collect();
        assert_eq!(crossing_reversals(&tri, 1.5), 19);
        assert_eq!(crossing_reversals(&tri, 2.5), 0);
        let turns = reversal_turns(&tri, 1.5);
        assert!(turns.iter().all(|&k| tri[k].abs() > 0.9), "{turns:?}");
        let flat: Vec<f64> = (0..100)
            .map(|k| if k % 2 == 0 { 0.05 } else { -0.05 })
            .collect();
        assert_eq!(crossing_reversals(&flat, 0.5), 0);
        assert_eq!(crossing_reversals(&flat, 0.0), 0);
        assert_eq!(crossing_reversals(&[], 1.0), 0);
    }

    /// Worse means clearly worse: a saturated record's gap model 0.2% behind its zero-gap twin at z -2.40
    /// (the two models' errors so alike that the test sees a tenth of a percent) is not; the Imperial Valley
    /// damper record's at fit fraction 0.8, 15% behind at z -4.23, is; 15% behind at z -1.2 is not.
    #[test]
    fn a_gap_model_is_worse_than_its_twin_only_clearly() {
        let twin = |heldout_rmse: f64, z: f64| PlayFree {
            model: TWIN.into(),
            heldout_rmse,
            z,
            errors: Vec::new(),
        };
        assert!(!clearly_worse(8.057e-3, &twin(8.041e-3, -2.40)));
        assert!(clearly_worse(1.15, &twin(1.0, -4.23)));
        assert!(!clearly_worse(1.15, &twin(1.0, -1.2)));
    }

    /// A play record's numbers (play 1.4% of its travel): 0.104 +/- 0.0121, held-out 0.1658 against the
    /// zero-gap model's 0.1695 (z 3.70) and the zero-gap model with polynomial feedback's 0.1688 (z 3.06):
    /// the unclaimed play helps. Not where one comparison is not significant (z 1.2), where the play is
    /// within 1.96 standard errors, where it has none, or with nothing to compare.
    #[test]
    fn an_unclaimed_play_helps_only_against_every_rival_and_above_its_error() {
        let rivals = [
            free(TWIN, 0.1695, 3.70),
            free("zero-gap + polynomial-feedback", 0.1688, 3.06),
        ];
        assert!(unclaimed_play_helps(0.104, Some(0.0121), 0.1658, &rivals));
        let weak = [rivals[0].clone(), free("zero-gap + x", 0.1688, 1.2)];
        assert!(!unclaimed_play_helps(0.104, Some(0.0121), 0.1658, &weak));
        assert!(!unclaimed_play_helps(0.02, Some(0.0121), 0.1658, &rivals));
        assert!(!unclaimed_play_helps(0.104, None, 0.1658, &rivals));
        assert!(!unclaimed_play_helps(0.104, Some(0.0121), 0.1658, &[]));
        assert!(!unclaimed_play_helps(0.104, Some(0.0121), 0.17, &rivals));
    }
}
