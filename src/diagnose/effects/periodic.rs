//! `periodic-disturbance`: a sinusoid rides on the output, a_s sin(w k) + a_c cos(w k); w from the
//! residual spectrum's peak, a_s and a_c by least squares, then all three refined.

use crate::diagnose::effects::figure::{Figure, fmt, pts};
use crate::diagnose::effects::rig::{Draw, Rig};
use crate::diagnose::effects::{
    Effect, EffectId, Fitted, Parameters, Plan, Screening, StartContext,
};
use crate::diagnose::fit::model::{BaseModel, Element, Elements, Extension, Scales};
use crate::diagnose::residual::statistics::{INPUT_LINE_RATIO, input_line_ratio};
use crate::diagnose::residual::{
    self,
    test_names::{LJUNG_BOX, SPECTRUM_PEAK},
};
use crate::report::plot::{Axes, PlotError, Series, line_plot};
use crate::stats::std_dev;

pub const ID: EffectId = EffectId::declare("periodic-disturbance");

/// The catalogue entry.
pub struct Periodic;

/// The sinusoid `a_sin sin(omega k) + a_cos cos(omega k)`, k from the start of the record.
pub fn extension(omega: f64, a_sin: f64, a_cos: f64) -> Extension {
    Extension::new(&Periodic, vec![], vec![omega, a_sin, a_cos])
}

impl Element for Periodic {
    fn id(&self) -> EffectId {
        ID
    }

    /// a_s sin + a_c cos = A sin(omega k + phase), A = hypot, phase = atan2(a_c, a_s).
    fn switch_on(&self, ext: &Extension, on: &mut Elements) {
        let [omega, a_sin, a_cos] = ext.theta[..] else {
            return;
        };
        on.effects.periodic = Some(crate::plant::effects::Periodic {
            amplitude: a_sin.hypot(a_cos),
            omega,
            phase: a_cos.atan2(a_sin),
        });
    }

    /// Any frequency and amplitudes.
    fn valid(&self, _ext: &Extension, _base: &BaseModel) -> bool {
        true
    }

    fn typical(&self, _ext: &Extension, s: &Scales) -> Vec<f64> {
        vec![1.0 / s.n_fit as f64, 0.1 * s.y, 0.1 * s.y]
    }
}

impl Effect for Periodic {
    fn id(&self) -> EffectId {
        ID
    }

    fn describe(&self) -> &'static str {
        "a sinusoid on the output, frequency, amplitude and phase fitted"
    }

    fn pointing_tests(&self) -> &'static [&'static str] {
        &[SPECTRUM_PEAK, LJUNG_BOX]
    }

    /// The residual's least-squares sinusoid at the spectrum's peak.
    fn plan(&self, cx: &StartContext) -> Option<Plan> {
        let w = cx.omega;
        let (mut ss, mut cc, mut sc, mut se, mut ce) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (k, v) in cx.residual.iter().enumerate() {
            let (s, c) = (w * k as f64).sin_cos();
            ss += s * s;
            cc += c * c;
            sc += s * c;
            se += s * v;
            ce += c * v;
        }
        let (a_sin, a_cos) = solve_symmetric_2x2([ss, sc, cc], [se, ce]);
        Some(Plan::at(cx.current.with(extension(w, a_sin, a_cos))))
    }

    fn parameters(&self, f: &Fitted) -> Parameters {
        f.own(ID, |ext| {
            let [omega, a_sin, a_cos] = ext.theta[..] else {
                return Parameters::new();
            };
            let two_pi = 2.0 * std::f64::consts::PI;
            Parameters::new()
                .with("omega", omega)
                .with("omega_unit", "rad/sample")
                .with(
                    "period_samples",
                    two_pi / omega.abs().max(f64::MIN_POSITIVE),
                )
                .with("amplitude", a_sin.hypot(a_cos))
                .with("phase", a_cos.atan2(a_sin))
                .with_some("frequency_hz", f.ts.map(|t| omega.abs() / (two_pi * t)))
        })
    }

    /// The periodogram of the plain model's residual with the fitted frequency.
    fn evidence(&self, fig: &Figure) -> Result<String, PlotError> {
        let Some(ext) = fig.model.extension(ID) else {
            return super::figure::generic(fig, ID);
        };
        let omega = ext.theta[0];
        let (w, p) = residual::periodogram(&fig.e0[..fig.n_fit], false);
        let pmax = p.iter().cloned().fold(0.0, f64::max);
        let pmin = p
            .iter()
            .cloned()
            .filter(|v| *v > 0.0)
            .fold(f64::INFINITY, f64::min);
        line_plot(
            fig.path,
            "Evidence for periodic-disturbance: periodogram of the residual (fit part)",
            "omega, rad/sample",
            "power",
            &[
                Series::line(format!("{}: residual", fig.plain_label), pts(&w, &p)).color(3),
                Series::dashed("fitted frequency", vec![(omega, pmin), (omega, pmax)]).color(0),
            ],
            Axes::LOG_LOG,
        )?;
        Ok(format!(
            "Pointing test: {}. A line in the residual's spectrum stands far above the noise floor; dashed: \
             the frequency the fit settled on ({} rad/sample).",
            fig.test,
            fmt(omega)
        ))
    }

    /// Amplitude 0.5..2 noise std, omega 0.05..3 rad/sample, any phase.
    fn draw(&self, rig: &mut Rig, d: &mut Draw) -> String {
        let rel = d.uniform(0.5, 2.0);
        let omega = d.uniform(0.05, 3.0);
        let phase = d.uniform(0.0, 2.0 * std::f64::consts::PI);
        let noise = std_dev(&rig.w0) / rig.snr;
        rig.effects.periodic = Some(crate::plant::effects::Periodic {
            amplitude: rel * noise,
            omega,
            phase,
        });
        format!("amplitude {rel:.2} noise std, omega {omega:.3} rad/sample")
    }

    /// A residual spectrum peak at a frequency the input carries ([`input_line_ratio`] above
    /// [`INPUT_LINE_RATIO`]) is model error driven by the input, not a disturbance.
    fn set_aside(&self, screen: &Screening) -> Option<String> {
        if !screen.rejected.contains(&SPECTRUM_PEAK) {
            return None;
        }
        let ratio = input_line_ratio(screen.u, screen.omega);
        (ratio > INPUT_LINE_RATIO).then(|| {
            format!(
                "periodic-disturbance: the residual's spectrum peak at {:.4} rad/sample is a frequency the input \
                 carries (its periodogram there is {:.0} times its median): model error driven by the input, not \
                 a disturbance",
                screen.omega, ratio
            )
        })
    }
}

/// The solution of the 2x2 normal equations `[[g0, g1], [g1, g2]] x = r` by Cramer's rule; (0, 0) when the
/// determinant's magnitude is at most 1e-12 (a sinusoid at frequency 0 or pi, or too few samples: no start).
fn solve_symmetric_2x2(g: [f64; 3], r: [f64; 2]) -> (f64, f64) {
    let det = g[0] * g[2] - g[1] * g[1];
    if det.abs() > 1e-12 {
        (
            (r[0] * g[2] - r[1] * g[1]) / det,
            (r[1] * g[0] - r[0] * g[1]) / det,
        )
    } else {
        (0.0, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::fit::model::Objective;
    use crate::diagnose::fit::starts::tests::{context, paper};

    /// The reported parameters by hand: omega 0.25 rad/sample is a period of 2 pi / 0.25 = 25.13 samples and,
    /// at 0.01 s a sample, 0.25 / (2 pi 0.01) = 3.979 Hz; amplitude and phase of 0.3 sin + 0.4 cos are 0.5
    /// and atan2(0.4, 0.3); no frequency without a sample time.
    #[test]
    fn parameters_by_hand() {
        let plain = paper();
        let m = plain.with(extension(0.25, 0.3, 0.4));
        let at = |ts| {
            let p = Periodic.parameters(&Fitted {
                ts,
                ..Fitted::on(&m, &plain)
            });
            serde_json::to_value(&p).expect("it serialises")
        };
        let two_pi = 2.0 * std::f64::consts::PI;
        let v = at(Some(0.01));
        let close = |key: &str, want: f64| {
            let got = v[key].as_f64().expect("a number");
            assert!(
                (got - want).abs() < 1e-12 * want.abs(),
                "{key}: {got} {want}"
            );
        };
        close("period_samples", two_pi / 0.25);
        close("frequency_hz", 0.25 / (two_pi * 0.01));
        close("amplitude", 0.5);
        close("phase", 0.4f64.atan2(0.3));
        assert!(at(None).get("frequency_hz").is_none());
    }

    /// Cramer's rule on a symmetric 2x2 system, and no solution at or below the singularity bound.
    #[test]
    fn symmetric_2x2_by_hand() {
        // [[2, 1], [1, 3]] x = [3, 5]: x = (4/5, 7/5).
        let (x0, x1) = solve_symmetric_2x2([2.0, 1.0, 3.0], [3.0, 5.0]);
        assert!(
            (x0 - 0.8).abs() < 1e-15 && (x1 - 1.4).abs() < 1e-15,
            "{x0} {x1}"
        );
        // Determinant exactly 1e-12: singular; just above it: solved.
        assert_eq!(
            solve_symmetric_2x2([1.0, 0.0, 1e-12], [1.0, 1.0]),
            (0.0, 0.0)
        );
        let (y0, y1) = solve_symmetric_2x2([1.0, 0.0, 2e-12], [1.0, 1.0]);
        assert_eq!(y0, 1.0);
        assert!((y1 - 5e11).abs() < 1.0);
        assert_eq!(solve_symmetric_2x2([0.0, 0.0, 5.0], [1.0, 1.0]), (0.0, 0.0));
    }

    /// A residual spectrum peak at a frequency the input carries is set aside (model error driven by the
    /// input); at a frequency it does not carry, or when the spectrum-peak test did not reject, it is not.
    #[test]
    fn a_peak_the_input_carries_is_set_aside() {
        let u: Vec<f64> = (0..400)
            .map(f64::from)
            .map(|k| (0.5 * k).sin() + 0.2 * (1.7 * k.powf(1.3)).sin())
            .collect();
        let screen = |omega, rejected| Screening {
            u: &u,
            omega,
            rejected,
        };
        let peak: &[&str] = &[SPECTRUM_PEAK, LJUNG_BOX];
        let why = Periodic.set_aside(&screen(0.5, peak)).expect("set aside");
        assert!(why.contains("a frequency the input carries"), "{why}");
        assert_eq!(Periodic.set_aside(&screen(2.0, peak)), None);
        assert_eq!(Periodic.set_aside(&screen(0.5, &[LJUNG_BOX])), None);
    }

    /// The residual 0.7 sin(0.4 k) - 0.3 cos(0.4 k) + 0.05 sin(2.3 k), k < 60: its least-squares sinusoid
    /// at 0.4 rad/sample by NumPy (`lstsq` on [sin, cos]).
    #[test]
    fn starts_at_the_least_squares_sinusoid() {
        let m = paper();
        let r: Vec<f64> = (0..60)
            .map(f64::from)
            .map(|k| 0.7 * (0.4 * k).sin() - 0.3 * (0.4 * k).cos() + 0.05 * (2.3 * k).sin())
            .collect();
        let p = Periodic.plan(&context(&m, &r, &r, &r)).unwrap();
        assert_eq!(p.objective, Objective::Simulation);
        let [omega, a_sin, a_cos] = p.alternatives[0].starts[0].exts[0].theta[..] else {
            panic!("three parameters")
        };
        assert_eq!(omega, 0.4);
        assert!((a_sin - 0.7001429053851362).abs() < 1e-12, "{a_sin}");
        assert!((a_cos + 0.2997369530916549).abs() < 1e-12, "{a_cos}");
        // At omega = 0 the sine column vanishes: no fit, zero amplitudes.
        let cx = StartContext {
            omega: 0.0,
            ..context(&m, &r, &r, &r)
        };
        let start = &Periodic.plan(&cx).unwrap().alternatives[0].starts[0];
        assert_eq!(start.exts[0].theta[1..], [0.0, 0.0]);
    }
}
