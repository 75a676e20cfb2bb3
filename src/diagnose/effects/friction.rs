//! `friction`: an elasto-plastic Coulomb element with the backlash, slip levels F+ and -F-, either
//! *series* (after the backlash output) or *contact* (the play inside the element's spring); both are
//! fitted and the better kept. k_e = 1: the stiffness is carried by b, as m1 = 1 is.

use crate::diagnose::effects::figure::{Figure, effect_against_input};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Element, Elements, Extension, Scales};
use crate::diagnose::fit::starts::Alternative;
use crate::diagnose::residual::test_names::{
    BILLINGS, BY_MODE, DRIFT, EXTREMES, LJUNG_BOX, SINCE_REVERSAL,
};
use crate::plant::effects::FrictionForm;
use crate::report::plot::PlotError;
use crate::stats::quantile;

pub const ID: EffectId = EffectId::declare("friction");

/// The catalogue entry.
pub struct Friction;

/// The element slipping at `f_plus` / `-f_minus` in the arrangement `form`.
pub fn extension(f_plus: f64, f_minus: f64, form: FrictionForm) -> Extension {
    let code = match form {
        FrictionForm::Series => 0.0,
        FrictionForm::Contact => 1.0,
    };
    Extension::new(&Friction, vec![code], vec![f_plus, f_minus])
}

/// Where the play sits in `ext` (kept as its fixed setting: 0 series, 1 contact).
pub fn form(ext: &Extension) -> FrictionForm {
    if ext.fixed[0] == 1.0 {
        FrictionForm::Contact
    } else {
        FrictionForm::Series
    }
}

impl Element for Friction {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.friction = Some(crate::plant::effects::Friction {
            k_e: 1.0,
            f_plus: ext.theta[0],
            f_minus: ext.theta[1],
            form: form(ext),
        });
    }

    /// An empty slip range (also NaN) is not a friction element; with the play inside the spring the play
    /// c1 + c2 must have a width.
    fn valid(&self, ext: &Extension, base: &BaseModel) -> bool {
        let play = base.c1 + base.c2;
        let range = ext.theta[0] + ext.theta[1];
        range > 0.0 && !(form(ext) == FrictionForm::Contact && (play.is_nan() || play < 0.0))
    }

    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![s.y; 2]
    }

    /// The contact element has straight borders: it never goes with curved borders. Neither form goes with
    /// polynomial feedback: the element's spring and slip levels change the gain with the amplitude as a
    /// stiffness that changes with deflection does, and fitted together the two trade the loop between them
    /// while a gap beside them takes what is left (a Coulomb-viscous mass without play fitted as friction,
    /// feedback and a play 11% of its travel wide, `present`). Each is a rival of play on its own. (The plan
    /// checks this rule both ways: friction is not fitted on a model with polynomial feedback.)
    fn blocks(&self, ext: &Extension, other: EffectId) -> bool {
        (form(ext) == FrictionForm::Contact && other == super::curved_borders::ID)
            || other == super::polynomial_feedback::ID
    }
}

impl Effect for Friction {
    fn id(&self) -> EffectId {
        ID
    }

    /// An elasto-plastic element is a play acting on the force: the same loop read another way.
    fn imitates_play(&self) -> bool {
        true
    }

    fn describe(&self) -> &'static str {
        "an elasto-plastic Coulomb element with the backlash, slipping at F+ / -F-: after the backlash output (series, f(k) = clamp(f(k-1) + w(k) - w(k-1), -F-, F+)) or with the play inside its spring (contact: the force unloads, crosses the play at zero, reloads); the better-fitting form is kept"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[
            EXTREMES,
            SINCE_REVERSAL,
            BY_MODE,
            BILLINGS,
            DRIFT,
            LJUNG_BOX,
        ]
    }

    /// A grid for both arrangements of the play (`Grid`), each from templates slipping at the extremes of
    /// the output; an arrangement the current model rules out is not offered.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let grid = Grid::new(cx)?;
        let (mut series, mut contact) = (Vec::new(), Vec::new());
        for scale in gain_scales(steepness_ratio(cx)) {
            grid.series(scale, &mut series);
            grid.contact(scale, &mut contact);
        }
        let (lo, hi) = (
            cx.y.iter().copied().fold(f64::INFINITY, f64::min),
            cx.y.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        Plan::alternatives(
            [
                (FrictionForm::Series, series),
                (FrictionForm::Contact, contact),
            ]
            .into_iter()
            .map(|(form, starts)| Alternative {
                template: cx.current.with(extension(hi, -lo, form)),
                starts,
            })
            .filter(|alt| {
                cx.current
                    .admits(alt.template.exts.last().expect("friction added"))
            })
            .collect(),
        )
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let form = form(ext);
            Parameters::new()
                .with("k_e", 1.0)
                .with("f_plus", ext.theta[0])
                .with("f_minus", ext.theta[1])
                .with("form", form)
                .with(
                    "note",
                    match form {
                        FrictionForm::Series => {
                            "series: f(k) = clamp(f(k-1) + (w(k) - w(k-1)), -f_minus, f_plus) after the backlash; k_e = 1 is the normalisation (the stiffness is carried by b, as m1 = 1 is)"
                        }
                        FrictionForm::Contact => {
                            "contact: the play c1, c2 inside the spring: f = (x - z) - c1 beyond c1, m2 ((x - z) + c2) beyond -c2, 0 between, slider z moves at the slip levels; k_e = 1 is the normalisation"
                        }
                    },
                )
        })
    }

    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        effect_against_input(fig, ID.as_str())?;
        Ok(format!(
            "Pointing test: {}. Output against input: the measured force saturates at the slip levels and, \
             after each reversal, unloads along a steep elastic line; the declared backlash cannot saturate, \
             the friction element does.",
            fig.test
        ))
    }

    /// k_e 0.5..2, slip levels 30..70 % of k_e times the half range of w0, each side drawn separately; the
    /// series or the contact form (the plant's gaps as the play), 50/50.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let w0 = &rig.w0;
        let k_e = d.uniform(0.5, 2.0);
        let half = 0.5 * (quantile(w0, 1.0).unwrap_or(0.0) - quantile(w0, 0.0).unwrap_or(0.0));
        let (fp, fm) = (d.uniform(0.3, 0.7), d.uniform(0.3, 0.7));
        let form = if d.uniform(0.0, 1.0) < 0.5 {
            FrictionForm::Series
        } else {
            FrictionForm::Contact
        };
        rig.effects.friction = Some(crate::plant::effects::Friction {
            k_e,
            f_plus: fp * k_e * half,
            f_minus: fm * k_e * half,
            form,
        });
        format!(
            "{form:?} form, k_e {k_e:.2}, slip at +{:.0}% / -{:.0}% of the elastic range",
            100.0 * fp,
            100.0 * fm
        )
    }
}

/// The friction grid's settings from the data: slip levels at fractions of the output's 1% / 99%
/// quantiles, gap offsets and widths, the plays of the contact form.
struct Grid<'a> {
    cx: &'a StartContext<'a>,
    q01: f64,
    q99: f64,
    u_range: f64,
    small_gap: f64,
    /// An eighth of the output's 1%..99% range: the series form's gap offsets.
    spread: f64,
}

impl<'a> Grid<'a> {
    fn new(cx: &'a StartContext<'a>) -> Option<Self> {
        let (q01, q99) = (quantile(cx.y, 0.01)?, quantile(cx.y, 0.99)?);
        Some(Self {
            cx,
            q01,
            q99,
            u_range: quantile(cx.u, 0.99)? - quantile(cx.u, 0.01)?,
            small_gap: 0.01 * cx.y_scale,
            spread: (q99 - q01) / 8.0,
        })
    }

    /// The current model with the linear block's gain `scale` times its own and equal slopes (with a small
    /// gap, unequal ones invert the memory zone within the range; the element carries the asymmetry in its
    /// two slip levels).
    fn scaled(&self, scale: f64) -> BaseModel {
        let mut b = self.cx.current.base.clone();
        b.b.iter_mut().for_each(|v| *v *= scale);
        b.m2 = 1.0;
        b
    }

    fn model(&self, b: &BaseModel, c1: f64, c2: f64, frac: f64, form: FrictionForm) -> EffectModel {
        self.cx
            .current
            .rebased(BaseModel {
                c1,
                c2,
                ..b.clone()
            })
            .with(extension(frac * self.q99, -frac * self.q01, form))
    }

    /// Series form: the offset of the gaps sets the element's first output (w(0) jumps onto a border when
    /// a gap is negative): the current one scaled, none, and +-1/8 of the output's range.
    fn series(&self, scale: f64, out: &mut Vec<EffectModel>) {
        let bb = &self.cx.current.base;
        let b = self.scaled(scale);
        let gap = ((bb.c1 + bb.c2) / 2.0 * scale).max(self.small_gap);
        for offset in [
            (bb.c2 - bb.c1) / 2.0 * scale,
            0.0,
            self.spread,
            -self.spread,
        ] {
            for frac in [1.0, 0.9, 0.8, 0.7] {
                for g in [gap, self.small_gap] {
                    out.push(self.model(&b, g - offset, g + offset, frac, FrictionForm::Series));
                }
            }
        }
    }

    /// Contact form: the play, a few percent of the stroke of x, placed around the start.
    fn contact(&self, scale: f64, out: &mut Vec<EffectModel>) {
        let b = self.scaled(scale);
        let x_range = scale * self.cx.current.base.static_gain().abs() * self.u_range;
        for play in [0.02, 0.05, 0.1] {
            let g = play * x_range;
            for offset in [0.0, 0.5 * g, -0.5 * g] {
                for frac in [1.0, 0.9, 0.8] {
                    out.push(self.model(&b, g - offset, g + offset, frac, FrictionForm::Contact));
                }
            }
        }
    }
}

/// Gains of the friction grid: from the current one up past twice the steepest slope, by factors of sqrt 2
/// (at most 40).
pub fn gain_scales(r: f64) -> Vec<f64> {
    let mut scales = vec![1.0];
    while scales.len() < 40 && *scales.last().unwrap() < 2.0 * r.max(4.0) {
        let next = scales.last().unwrap() * std::f64::consts::SQRT_2;
        scales.push(next);
    }
    scales
}

/// The steepest part of the output against the input (the 90th percentile of |dy / du| over moves of u
/// above its median) over the current model's static gain; 1 when either is unknown.
fn steepness_ratio(cx: &StartContext) -> f64 {
    let gain = cx.current.base.static_gain();
    let (u, y) = (cx.u, cx.y);
    let du: Vec<f64> = u.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let du_med = quantile(&du, 0.5).unwrap_or(0.0);
    let slopes: Vec<f64> = (1..u.len())
        .filter(|&k| du_med > 0.0 && (u[k] - u[k - 1]).abs() > du_med)
        .map(|k| ((y[k] - y[k - 1]) / (u[k] - u[k - 1])).abs())
        .collect();
    let steep = quantile(&slopes, 0.9).unwrap_or(0.0);
    if gain.abs() > 0.0 && steep.is_finite() && steep > 0.0 {
        steep / gain.abs()
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests;
