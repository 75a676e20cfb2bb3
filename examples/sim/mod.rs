//! Random plants for the examples that diagnose simulated records (`verdict_confusion`, `play_coverage`):
//! a random stable linear block, a straight backlash of a given gap, the plant run with its effects, and what
//! the truth is read with (the travel of the linear block's output, the reversals of the play's output).

use backlash::diagnose::effects::rig::Draw;
use backlash::plant::PlantParams;
use backlash::plant::backlash::BacklashParams;
use backlash::plant::effects::{Effects, EffectsOutput, simulate_with_effects};
use backlash::plant::linear::ArxParams;
use backlash::stats::quantile;

/// Share of the record the diagnosis fits (`DiagnoseConfig::auto().fit_fraction`), where the truth is counted.
pub const FIT: f64 = 0.7;

/// A random stable linear block: first order (pole 0.3..0.9) or second order (radius 0.5..0.9, angle
/// 0..1 rad), static gain 0.5..2, delay 1..3.
pub fn linear_block(d: &mut Draw) -> ArxParams {
    let (na, a1, a2) = if d.uniform(0.0, 1.0) < 0.5 {
        (1, -d.uniform(0.3, 0.9), 0.0)
    } else {
        let (r, th) = (d.uniform(0.5, 0.9), d.uniform(0.0, 1.0));
        (2, -2.0 * r * th.cos(), r * r)
    };
    let gain = d.uniform(0.5, 2.0);
    ArxParams {
        na,
        nb: 0,
        delay: 1 + (d.uniform(0.0, 3.0) as usize).min(2),
        a: [a1, a2, 0.0, 0.0],
        b: [gain * (1.0 + a1 + a2), 0.0, 0.0, 0.0, 0.0],
    }
}

/// A straight backlash of gap `gap` (split at random) with slopes 0.7..1.5; gap 0 and slope 1: w = x.
pub fn backlash_of(d: &mut Draw, gap: f64) -> BacklashParams {
    if gap == 0.0 {
        return BacklashParams {
            m1: 1.0,
            m2: 1.0,
            c1: 0.0,
            c2: 0.0,
        };
    }
    let split = d.uniform(0.3, 0.7);
    BacklashParams {
        m1: d.uniform(0.7, 1.5),
        m2: d.uniform(0.7, 1.5),
        c1: split * gap,
        c2: (1.0 - split) * gap,
    }
}

/// The plant (noise-free) with its effects.
pub fn run(arx: ArxParams, bl: BacklashParams, e: &Effects, u: &[f64]) -> Vec<EffectsOutput> {
    let params = PlantParams {
        arx,
        backlash: bl,
        noise_std: 0.0,
        noise_seed: 0,
    };
    simulate_with_effects(&params, e, u, 0).expect("the drawn plant is valid")
}

/// The 1st to 99th percentile range of the fit part of `x`.
pub fn travel(x: &[f64]) -> f64 {
    let fit = &x[..(FIT * x.len() as f64) as usize];
    quantile(fit, 0.99).unwrap_or(0.0) - quantile(fit, 0.01).unwrap_or(0.0)
}

/// Reversals of `w` on the fit part: sign changes of its non-zero increments.
pub fn reversals(w: &[f64]) -> usize {
    let fit = &w[..(FIT * w.len() as f64) as usize];
    let mut last = 0.0;
    let mut count = 0;
    for k in 1..fit.len() {
        let dw = fit[k] - fit[k - 1];
        if dw.abs() > 1e-12 {
            let s = dw.signum();
            count += usize::from(last != 0.0 && s != last);
            last = s;
        }
    }
    count
}

/// The effects a diagnosis kept, in order, joined by " + " (empty when none).
pub fn effect_names(d: &backlash::diagnose::engine::Diagnosis) -> String {
    d.steps()
        .iter()
        .map(|c| c.id.to_string())
        .collect::<Vec<_>>()
        .join(" + ")
}
