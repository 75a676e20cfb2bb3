//! `gap-drift`: the gaps change linearly over the record, as with wear: c1(k) = c1 + r1 k, c2(k) = c2 + r2 k.

use crate::diagnose::effects::figure::{Figure, fmt};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::model::{BaseModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::test_names::{BY_MODE, DRIFT};
use crate::plant::Mode;
use crate::report::plot::{Axes, PlotError, Series, line_plot};

pub const ID: EffectId = EffectId::declare("gap-drift");

/// The catalogue entry.
pub struct GapDrift;

/// The extension with rates `c1_rate`, `c2_rate` per sample.
pub fn extension(c1_rate: f64, c2_rate: f64) -> Extension {
    Extension::new(&GapDrift, vec![], vec![c1_rate, c2_rate])
}

impl Element for GapDrift {
    fn id(&self) -> EffectId {
        ID
    }

    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        on.effects.gap_drift = Some(crate::plant::effects::GapDrift {
            c1_rate: ext.theta[0],
            c2_rate: ext.theta[1],
        });
    }

    /// Any rates: the operator is defined for any gap values.
    fn valid(&self, _ext: &Extension, _base: &BaseModel) -> bool {
        true
    }

    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![0.1 * s.y; 2]
    }

    /// Without a gap the gaps drift oppositely (c2's rate is minus c1's): the one curve's level drifts, as
    /// a slowly moving operating point does, and the gap stays zero.
    fn zero_gap_ties(&self, _ext: &Extension) -> Option<crate::diagnose::fit::model::Ties> {
        Some(vec![(1, 0, -1.0)])
    }

    /// The rates scaled by `time_scale` (the total drift over that many samples), so that they have the
    /// gaps' magnitude.
    fn pack(&self, ext: &Extension, time_scale: f64) -> Vec<f64> {
        ext.theta.iter().map(|r| r * time_scale).collect()
    }

    fn unpack(&self, _ext: &Extension, th: &[f64], time_scale: f64) -> Vec<f64> {
        th.iter().map(|v| v / time_scale).collect()
    }
}

impl Effect for GapDrift {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "gaps linear in time: c1(k) = c1 + r1 k, c2(k) = c2 + r2 k (wear)"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[DRIFT, BY_MODE]
    }

    /// The rates start at zero: the current model.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        Some(Plan::at(cx.current.with(extension(0.0, 0.0))))
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let (b, r1, r2) = (&f.model.base, ext.theta[0], ext.theta[1]);
            let end = f.n.saturating_sub(1) as f64;
            Parameters::new()
                .with("c1_rate", r1)
                .with("c2_rate", r2)
                .with("c1_start", b.c1)
                .with("c2_start", b.c2)
                .with("c1_end", b.c1 + r1 * end)
                .with("c2_end", b.c2 + r2 * end)
                .with("rate_unit", "per sample")
                .with_some("c1_rate_per_s", f.ts.map(|t| r1 / t))
                .with_some("c2_rate_per_s", f.ts.map(|t| r2 / t))
        })
    }

    /// Running means of the plain model's residual on each border, and the drift the fit found.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let Some(ext) = fig.model.extension(ID) else {
            return super::figure::generic(fig, ID);
        };
        let (c1_rate, c2_rate) = (ext.theta[0], ext.theta[1]);
        let n = fig.n;
        let t = &fig.t[..n];
        let win = (n / 25).max(5);
        let running = |mode: Mode| -> Vec<(f64, f64)> {
            let idx: Vec<usize> = (0..n).filter(|&k| fig.declared.mode[k] == mode).collect();
            running_means(t, fig.e0, &idx, win)
        };
        let [up_line, dn_line] = border_drift_lines(t, c1_rate, c2_rate, fig.model.base.m2);
        let (ru, rd) = (running(Mode::Up), running(Mode::Down));
        let (lu, ld) = (centred_on(up_line, &ru), centred_on(dn_line, &rd));
        line_plot(
            fig.path,
            "Evidence for gap-drift: residual of the plain model on each border",
            fig.columns[0],
            "running mean of the residual",
            &[
                Series::line("upper border (driving up)", ru).color(1),
                Series::line("lower border (driving down)", rd).color(2),
                Series::dashed("fitted drift, upper", lu).color(1),
                Series::dashed("fitted drift, lower", ld).color(2),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. Running mean ({win} samples) of the {}'s residual on the upper and lower \
             borders; with fixed gaps both would stay at zero. Dashed: the change the fitted drift \
             predicts (c1 rate {}, c2 rate {} per sample).",
            fig.test,
            fig.plain_label,
            fmt(c1_rate),
            fmt(c2_rate)
        ))
    }

    /// Each gap grows by 30..80 % over the record.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let bl = rig.params.backlash;
        let (g1, g2) = (d.uniform(0.3, 0.8), d.uniform(0.3, 0.8));
        let span = (rig.n - 1) as f64;
        rig.effects.gap_drift = Some(crate::plant::effects::GapDrift {
            c1_rate: bl.c1 * g1 / span,
            c2_rate: bl.c2 * g2 / span,
        });
        format!(
            "c1 +{:.0}%, c2 +{:.0}% over the record",
            100.0 * g1,
            100.0 * g2
        )
    }
}

/// The change of each border a fitted gap drift predicts against the declared fit: the upper border
/// `y = m1 (x - c1(k))` (m1 = 1) falls by `c1_rate k`, the lower `y = m2 (x + c2(k))` rises by
/// `m2 c2_rate k`.
fn border_drift_lines(t: &[f64], c1_rate: f64, c2_rate: f64, m2: f64) -> [Vec<(f64, f64)>; 2] {
    [drift_line(t, -c1_rate), drift_line(t, m2 * c2_rate)]
}

/// `line` moved up or down so that its mean equals the mean of `data`'s y (the declared fit absorbed the
/// average gap, so only the change over time is the drift's).
fn centred_on(line: Vec<(f64, f64)>, data: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let ml = line.iter().map(|p| p.1).sum::<f64>() / line.len().max(1) as f64;
    let md = data.iter().map(|p| p.1).sum::<f64>() / data.len().max(1) as f64;
    line.into_iter().map(|(a, b)| (a, b - ml + md)).collect()
}

/// The line `slope k` (k the sample index) at about 200 of the times `t`.
fn drift_line(t: &[f64], slope: f64) -> Vec<(f64, f64)> {
    (0..t.len())
        .step_by((t.len() / 200).max(1))
        .map(|k| (t[k], slope * k as f64))
        .collect()
}

/// Means of `e` over windows of `win` consecutive samples of `idx` (every `win / 4`-th window), each at the
/// time `t` of its middle sample.
fn running_means(t: &[f64], e: &[f64], idx: &[usize], win: usize) -> Vec<(f64, f64)> {
    idx.windows(win)
        .step_by((win / 4).max(1))
        .map(|w| {
            (
                t[w[w.len() / 2]],
                w.iter().map(|&k| e[k]).sum::<f64>() / w.len() as f64,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests;
