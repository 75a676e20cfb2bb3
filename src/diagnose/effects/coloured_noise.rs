//! `coloured-noise`: the disturbance is not white. An AR(p) noise model on the output error, p = 1..3 by
//! BIC, fitted by least squares on the residual with the deterministic part kept; judged by one-step-ahead
//! prediction (the simulation is unchanged).

use crate::diagnose::effects::figure::{Figure, fmt, outside, pts};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{Effect, EffectId, Fitted, Parameters, Plan, StartContext};
use crate::diagnose::fit::lm::{bic, cost_of};
use crate::diagnose::fit::model::{BaseModel, Element, Elements, Extension, Objective, Scales};
use crate::diagnose::fit::starts::Alternative;
use crate::diagnose::residual::statistics::{ar_filter, ar_ls};
use crate::diagnose::residual::{self, test_names::LJUNG_BOX};
use crate::report::plot::{Axes, PlotError, Series, line_plot};

pub const ID: EffectId = EffectId::declare("coloured-noise");

/// The catalogue entry.
pub struct ColouredNoise;

/// The noise model `e(k) = sum phi_i e(k-i) + white`.
pub fn extension(phi: Vec<f64>) -> Extension {
    Extension::new(&ColouredNoise, vec![], phi)
}

impl Element for ColouredNoise {
    fn id(&self) -> EffectId {
        ID
    }

    /// A noise model has no deterministic part: the simulation is the current model's.
    fn switch_on(&self, _ext: &Extension, _on: &mut Elements) {}

    /// Any coefficients (the prediction refuses non-finite ones).
    fn valid(&self, _ext: &Extension, _base: &BaseModel) -> bool {
        true
    }

    fn typical(&self, ext: &Extension, _s: &Scales) -> Vec<f64> {
        vec![0.5; ext.theta.len()]
    }

    fn noise_model<'a>(&self, ext: &'a Extension) -> Option<&'a [f64]> {
        Some(&ext.theta)
    }
}

impl Effect for ColouredNoise {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "an AR noise model on the output error, fitted on the residual with the deterministic part kept (judged by one-step-ahead prediction; the simulation is unchanged)"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[LJUNG_BOX]
    }

    /// AR order 1..3 by BIC of the least-squares fit on the residual (the fit itself: the engine keeps the
    /// deterministic part).
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let e = cx.residual;
        let mut best: Option<(Vec<f64>, f64)> = None;
        for order in 1..=3 {
            let Some(phi) = ar_ls(e, order) else { continue };
            let b = bic(cost_of(&ar_filter(e, &phi)), e.len(), order);
            if best.as_ref().is_none_or(|x| b < x.1) {
                best = Some((phi, b));
            }
        }
        let (phi, _) = best?;
        let m = cx.current.with(extension(phi));
        Some(Plan {
            objective: Objective::Prediction,
            alternatives: vec![Alternative {
                template: m.clone(),
                starts: vec![m],
            }],
        })
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            Parameters::new()
                .with("ar_order", ext.theta.len())
                .with("phi", &ext.theta)
        })
    }

    /// The plain model's residual's autocorrelation, the fitted AR model's, and that of the one-step
    /// prediction errors of the model with the noise model.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let (Some(ext), Some(pred)) = (fig.model.extension(ID), fig.e1_pred) else {
            return super::figure::generic(fig, ID);
        };
        let (nf, lags) = (fig.n_fit, fig.lags);
        let band = residual::white_band(nf);
        let lagx: Vec<f64> = (1..=lags).map(|l| l as f64).collect();
        let acf0 = residual::autocorrelation(&fig.e0[..nf], lags);
        let acf1 = residual::autocorrelation(&pred[..nf], lags);
        let model = ar_acf(&ext.theta, lags);
        line_plot(
            fig.path,
            "Evidence for coloured-noise: autocorrelation of the output error",
            "lag [samples]",
            "r",
            &[
                Series::points(
                    format!("{}: y - simulation", fig.plain_label),
                    pts(&lagx, &acf0),
                )
                .color(3),
                Series::line("fitted AR noise model", pts(&lagx, &model)).color(1),
                Series::points(
                    format!("{}: y - one-step prediction", fig.after_label),
                    pts(&lagx, &acf1),
                )
                .color(0),
                Series::dashed("95% band", vec![(1.0, band), (lags as f64, band)]).color(7),
                Series::dashed("", vec![(1.0, -band), (lags as f64, -band)]).color(7),
            ],
            Axes::LINEAR,
        )?;
        Ok(format!(
            "Pointing test: {}. The residual is correlated over many lags (red; lag 1: {}) in the way an AR({}) \
             disturbance is (orange; lag 1: {}); the one-step prediction errors of the model with that noise \
             model (blue; lag 1: {}) have {} of {} lags outside the white band +-{}.",
            fig.test,
            fmt(acf0[0]),
            ext.theta.len(),
            fmt(model[0]),
            fmt(acf1[0]),
            outside(&acf1, band),
            lags,
            fmt(band)
        ))
    }

    /// AR(1) noise with phi 0.5..0.9, at an SNR of 10..30.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let phi = d.uniform(0.5, 0.9);
        rig.snr = d.uniform(10.0, 30.0);
        rig.effects.coloured_noise = Some(crate::plant::effects::ColouredNoise { phi });
        format!("AR(1) phi {phi:.2}")
    }

    fn is_noise_model(&self) -> bool {
        true
    }
}

/// Autocorrelation r(1..=lags) of the AR process e(k) = sum phi_i e(k-i) + v(k) (Yule-Walker, by simulating
/// its impulse response).
fn ar_acf(phi: &[f64], lags: usize) -> Vec<f64> {
    let len = 4000;
    let mut h = vec![0.0; len];
    h[0] = 1.0;
    for k in 1..len {
        h[k] = phi
            .iter()
            .enumerate()
            .filter(|(i, _)| k > *i)
            .map(|(i, p)| p * h[k - 1 - i])
            .sum();
    }
    let r0: f64 = h.iter().map(|v| v * v).sum();
    (1..=lags)
        .map(|l| h.iter().zip(&h[l..]).map(|(a, b)| a * b).sum::<f64>() / r0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// The autocorrelation of AR processes by Yule-Walker: AR(1) with phi 0.5 has r(l) = 0.5^l; AR(2) with
    /// phi (0.5, 0.3) has r(1) = phi1 / (1 - phi2) = 5/7 and r(2) = phi1 r(1) + phi2 = 23/35.
    #[test]
    fn ar_autocorrelation_by_yule_walker() {
        let r = ar_acf(&[0.5], 3);
        for (l, v) in r.iter().enumerate() {
            assert!((v - 0.5f64.powi(l as i32 + 1)).abs() < 1e-12, "{r:?}");
        }
        let r = ar_acf(&[0.5, 0.3], 2);
        assert!(
            (r[0] - 5.0 / 7.0).abs() < 1e-12 && (r[1] - 23.0 / 35.0).abs() < 1e-12,
            "{r:?}"
        );
    }

    /// The reported parameters are the fitted noise model's order and coefficients; a model without one
    /// reports none.
    #[test]
    fn parameters_are_the_fitted_ar_model() {
        let plain = paper();
        let m = plain.with(extension(vec![0.5, -0.25]));
        let fitted = |model| Fitted::on(model, &plain);
        let p = ColouredNoise.parameters(&fitted(&m));
        assert_eq!(
            serde_json::to_string(&p).unwrap(),
            r#"{"ar_order":2,"phi":[0.5,-0.25]}"#
        );
        assert_eq!(ColouredNoise.parameters(&fitted(&plain)), Parameters::new());
    }

    /// An AR(1) residual e(k) = 0.6 e(k-1) + v(k), v(k) = sin(1.7 k^1.3) + 0.5 cos(0.9 k), k < 60: by
    /// NumPy least squares (conditional, as `ar_ls`) and BIC n ln(rss / n) + p ln n over orders 1..3, the
    /// order 2 wins (-40.33 against -30.90 and -37.83) with phi = [1.00544, -0.43992].
    #[test]
    fn starts_at_the_bic_best_ar_fit() {
        let m = paper();
        let mut e = vec![0.0; 60];
        for k in 0..60 {
            let kf = f64::from(k as u32);
            let v = (1.7 * kf.powf(1.3)).sin() + 0.5 * (0.9 * kf).cos();
            e[k] = if k > 0 { 0.6 * e[k - 1] } else { 0.0 } + v;
        }
        let p = ColouredNoise.plan(&context(&m, &e, &e, &e)).unwrap();
        assert_eq!(p.objective, Objective::Prediction);
        let phi = &p.alternatives[0].starts[0].exts[0].theta;
        assert_eq!(phi.len(), 2);
        assert!((phi[0] - 1.0054404372362657).abs() < 1e-9, "{phi:?}");
        assert!((phi[1] + 0.4399247944902299).abs() < 1e-9, "{phi:?}");
        // A zero residual has no AR fit: no plan.
        let zero = vec![0.0; 60];
        assert!(
            ColouredNoise
                .plan(&context(&m, &zero, &zero, &zero))
                .is_none()
        );
    }
}
