//! Simulated test-bench records with one undeclared catalogue effect, with randomised magnitudes.
//!
//! The plant is paper 000's (a = [0.45, 0.55], b0 = 0.8, delay 1, m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1) driven by
//! the paper's input (white, uniform, variance 1.93), and the declared model is always the paper's structure
//! `na = 2, nb = 0, delay = 1`. Each scenario draws its magnitudes from a ChaCha8 generator seeded by the
//! seed and the effect, within these ranges (w0, x0: the clean plant's backlash and linear outputs; SNR is
//! std(noise-free output) / noise std):
//!
//! | effect | magnitude drawn | noise |
//! | --- | --- | --- |
//! | none (clean) | - | SNR 20..50 |
//! | gap-drift | each gap grows by 30..80 % over the record (linear wear) | SNR 20..50 |
//! | curved-borders | at s = 2 std(x0) the s^2 term is 5..15 % and the s^3 term 2..8 % of the linear one, random signs, borders kept increasing over +-3 std(x0) | SNR 20..50 |
//! | extra-delay | true delay 2..4 (declared 1) | SNR 20..50 |
//! | linear-order | either b1 = +-(0.3..0.6) b0, or a3 = +-(0.1..0.25) (stable) | SNR 20..50 |
//! | coloured-noise | AR(1) noise, phi 0.5..0.9 | SNR 10..30 |
//! | saturation | clipped at the 85..95 % and 5..15 % quantiles of w0; at the sensor or an end stop (before the noise), 50/50 | SNR 20..50 |
//! | periodic-disturbance | amplitude 0.5..2 noise std, omega 0.05..3 rad/sample, any phase | SNR 20..50 |
//! | quantization | step 0.1..0.3 std(w0), noise std = step / (6..20) (a coarse sensor: its noise is well below one step) | as said |
//! | direction-dependent | while x falls the linear block's poles are 0.4..0.7 times the rising ones (a_i scaled by s^i), b0 scaled to keep the static gain | SNR 20..50 |
//! | friction | k_e 0.5..2, slip levels 30..70 % of k_e times the half range of w0, each side drawn separately; the series or the contact form (play inside the spring, the plant's gaps as the play), 50/50 | SNR 20..50 |
//!
//! Why these: each is a magnitude a test engineer would want to know about (a gap growing by a third, a
//! border 10 % off straight, a sensor step of a tenth of the signal's spread) and sits well inside what the
//! plant can do (borders monotone, a stable linear block). For quantization, a step below about 3 noise
//! standard deviations is dithered away by the noise and changes no prediction, so no data can show it; the
//! range starts at 6.

use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardUniform};

use super::catalogue::EffectId;
use crate::identify::mrgia::paper_input;
use crate::plant::effects::{
    ColouredNoise, CurvedBorders, DirectionDependent, Effects, Friction, FrictionForm, GapDrift,
    Periodic, Quantization, Saturation, simulate_with_effects,
};
use crate::plant::{Plant, PlantParams};
use crate::stats::{quantile, std_dev};

/// One simulated record.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// The effects switched on (empty: a clean record).
    pub present: Vec<EffectId>,
    pub seed: u64,
    /// The true plant (its delay or orders may exceed the declared ones).
    pub params: PlantParams,
    pub effects: Effects,
    /// Declared structure (na, nb, delay).
    pub declared: (usize, usize, usize),
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    /// Noise-free output.
    pub f: Vec<f64>,
    /// The drawn magnitudes in words.
    pub description: String,
}

struct Draw(ChaCha8Rng);

impl Draw {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let r: f64 = StandardUniform.sample(&mut self.0);
        lo + (hi - lo) * r
    }
    fn sign(&mut self) -> f64 {
        if self.uniform(0.0, 1.0) < 0.5 {
            -1.0
        } else {
            1.0
        }
    }
}

/// Is the linear block with these a's stable (impulse response decays)?
fn stable(a: &[f64]) -> bool {
    let mut h = vec![0.0; 3000];
    h[0] = 1.0;
    for k in 1..h.len() {
        h[k] = -a
            .iter()
            .enumerate()
            .filter(|(i, _)| k > *i)
            .map(|(i, ai)| ai * h[k - 1 - i])
            .sum::<f64>();
    }
    h[2500..].iter().all(|v| v.abs() < 1e-6)
}

/// A record of `n` samples with `effect` (or none) under `seed`.
pub fn scenario(effect: Option<EffectId>, seed: u64, n: usize) -> Scenario {
    scenario_with(effect.as_slice(), seed, n)
}

/// A record of `n` samples with every effect of `present` switched on together (none: a clean record),
/// each drawn as for a single-effect record; the magnitudes depend on the seed and on the set.
pub fn scenario_with(present: &[EffectId], seed: u64, n: usize) -> Scenario {
    // One effect keeps the single-effect records' generator (their check seeds stay what they were).
    let tag = present.iter().rev().fold(0u64, |t, e| {
        (t << 8) | (1 + EffectId::ALL.iter().position(|x| x == e).unwrap_or(0) as u64)
    });
    let mut d = Draw(ChaCha8Rng::seed_from_u64(
        seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (tag << 56) ^ ((tag >> 8) << 40),
    ));
    let u = paper_input(n, seed);
    let clean = Plant::simulate(PlantParams::PAPER, &u).expect("the paper plant is valid");
    let mut b = Bench {
        params: PlantParams::PAPER,
        effects: Effects::default(),
        snr: d.uniform(20.0, 50.0),
        fixed_noise: None,
        w0: clean.iter().map(|o| o.w).collect(),
        x0: clean.iter().map(|o| o.x).collect(),
        n,
    };
    let descriptions: Vec<String> = present.iter().map(|&e| b.add(e, &mut d)).collect();
    let description = if present.is_empty() {
        "clean".to_string()
    } else {
        descriptions.join("; ")
    };
    let Bench {
        mut params,
        effects: e,
        snr,
        fixed_noise,
        ..
    } = b;
    // With no noise std the noise is zero whatever its colour.
    params.noise_std = 0.0;
    let noise_free = simulate_with_effects(&params, &e, &u, 0).expect("bench parameters are valid");
    let f: Vec<f64> = noise_free.iter().map(|o| o.f).collect();
    params.noise_std = fixed_noise.unwrap_or(std_dev(&f) / snr);
    params.noise_seed = seed ^ 0x5EED_0000_0000;
    let out = simulate_with_effects(&params, &e, &u, params.noise_seed)
        .expect("bench parameters are valid");
    Scenario {
        present: present.to_vec(),
        seed,
        params,
        effects: e,
        declared: (2, 0, 1),
        y: out.iter().map(|o| o.y).collect(),
        f,
        u,
        description: format!("{description}; noise std {:.4}", params.noise_std),
    }
}

/// The effects of a record in words: "clean", or their names joined by " + ".
pub fn names(present: &[EffectId]) -> String {
    if present.is_empty() {
        "clean".into()
    } else {
        present
            .iter()
            .map(|e| e.as_str())
            .collect::<Vec<_>>()
            .join(" + ")
    }
}

/// A record being set up: the plant, its effects and noise level, and the clean plant's signals.
struct Bench {
    params: PlantParams,
    effects: Effects,
    snr: f64,
    fixed_noise: Option<f64>,
    w0: Vec<f64>,
    x0: Vec<f64>,
    n: usize,
}

impl Bench {
    /// Switch `effect` on with magnitudes drawn from `d`; returns them in words.
    fn add(&mut self, effect: EffectId, d: &mut Draw) -> String {
        let (w0, n) = (&self.w0, self.n);
        let (std_w, std_x) = (std_dev(w0), std_dev(&self.x0));
        let bl = self.params.backlash;
        let params = &mut self.params;
        let e = &mut self.effects;
        match effect {
            EffectId::DirectionDependent => {
                let s = d.uniform(0.4, 0.7);
                let arx = &params.arx;
                let mut fall = DirectionDependent { a: arx.a, b: arx.b };
                let mut scale = 1.0;
                for a in fall.a.iter_mut().take(arx.na) {
                    scale *= s;
                    *a *= scale;
                }
                let gain = (1.0 + fall.a.iter().sum::<f64>()) / (1.0 + arx.a.iter().sum::<f64>());
                fall.b.iter_mut().for_each(|b| *b *= gain);
                e.direction_dependent = Some(fall);
                format!("falling poles {s:.2} times the rising ones, same static gain")
            }
            EffectId::GapDrift => {
                let (g1, g2) = (d.uniform(0.3, 0.8), d.uniform(0.3, 0.8));
                let span = (n - 1) as f64;
                e.gap_drift = Some(GapDrift {
                    c1_rate: bl.c1 * g1 / span,
                    c2_rate: bl.c2 * g2 / span,
                });
                format!(
                    "c1 +{:.0}%, c2 +{:.0}% over the record",
                    100.0 * g1,
                    100.0 * g2
                )
            }
            EffectId::CurvedBorders => {
                let s_ref = 2.0 * std_x;
                let mut c = CurvedBorders::default();
                for _ in 0..100 {
                    let (m1, m2) = (bl.m1, bl.m2);
                    c = CurvedBorders {
                        upper: [
                            d.sign() * d.uniform(0.05, 0.15) * m1 / s_ref,
                            d.sign() * d.uniform(0.02, 0.08) * m1 / (s_ref * s_ref),
                        ],
                        lower: [
                            d.sign() * d.uniform(0.05, 0.15) * m2 / s_ref,
                            d.sign() * d.uniform(0.02, 0.08) * m2 / (s_ref * s_ref),
                        ],
                    };
                    let increasing = (-30..=30).all(|i| {
                        let s = i as f64 / 10.0 * std_x;
                        m1 + 2.0 * c.upper[0] * s + 3.0 * c.upper[1] * s * s > 0.2 * m1
                            && m2 + 2.0 * c.lower[0] * s + 3.0 * c.lower[1] * s * s > 0.2 * m2
                    });
                    if increasing {
                        break;
                    }
                }
                e.curved_borders = Some(c);
                format!(
                    "upper [{:.3}, {:.4}], lower [{:.3}, {:.4}]",
                    c.upper[0], c.upper[1], c.lower[0], c.lower[1]
                )
            }
            EffectId::ExtraDelay => {
                let extra = 1 + (d.uniform(0.0, 3.0) as usize).min(2);
                params.arx.delay += extra;
                format!("true delay {}", params.arx.delay)
            }
            EffectId::LinearOrder => {
                if d.uniform(0.0, 1.0) < 0.5 {
                    params.arx.nb = 1;
                    params.arx.b[1] = d.sign() * d.uniform(0.3, 0.6) * params.arx.b[0];
                    format!("b1 = {:.3}", params.arx.b[1])
                } else {
                    params.arx.na = 3;
                    let mut a3 = d.sign() * d.uniform(0.1, 0.25);
                    if !stable(&[params.arx.a[0], params.arx.a[1], a3]) {
                        a3 = -a3;
                    }
                    params.arx.a[2] = a3;
                    format!("a3 = {a3:.3}")
                }
            }
            EffectId::ColouredNoise => {
                let phi = d.uniform(0.5, 0.9);
                self.snr = d.uniform(10.0, 30.0);
                e.coloured_noise = Some(ColouredNoise { phi });
                format!("AR(1) phi {phi:.2}")
            }
            EffectId::Saturation => {
                let (qh, ql) = (d.uniform(0.85, 0.95), d.uniform(0.05, 0.15));
                let before = d.uniform(0.0, 1.0) < 0.5;
                e.saturation = Some(Saturation {
                    lo: quantile(w0, ql).unwrap_or(0.0),
                    hi: quantile(w0, qh).unwrap_or(0.0),
                    before_noise: before,
                });
                format!(
                    "clipped at the {:.0}% / {:.0}% quantiles, {}",
                    100.0 * ql,
                    100.0 * qh,
                    if before {
                        "end stop (before the noise)"
                    } else {
                        "sensor range"
                    }
                )
            }
            EffectId::PeriodicDisturbance => {
                let rel = d.uniform(0.5, 2.0);
                let omega = d.uniform(0.05, 3.0);
                let phase = d.uniform(0.0, 2.0 * std::f64::consts::PI);
                let noise = std_w / self.snr;
                e.periodic = Some(Periodic {
                    amplitude: rel * noise,
                    omega,
                    phase,
                });
                format!("amplitude {rel:.2} noise std, omega {omega:.3} rad/sample")
            }
            EffectId::Quantization => {
                let step = d.uniform(0.1, 0.3) * std_w;
                let ratio = d.uniform(6.0, 20.0);
                let offset = d.uniform(0.0, step);
                self.fixed_noise = Some(step / ratio);
                e.quantization = Some(Quantization { step, offset });
                format!("step {:.3} std(w), noise step/{ratio:.1}", step / std_w)
            }
            EffectId::Friction => {
                let k_e = d.uniform(0.5, 2.0);
                let half =
                    0.5 * (quantile(w0, 1.0).unwrap_or(0.0) - quantile(w0, 0.0).unwrap_or(0.0));
                let (fp, fm) = (d.uniform(0.3, 0.7), d.uniform(0.3, 0.7));
                let form = if d.uniform(0.0, 1.0) < 0.5 {
                    FrictionForm::Series
                } else {
                    FrictionForm::Contact
                };
                e.friction = Some(Friction {
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};
    use std::time::Instant;

    /// A drawn sign is negative exactly when the uniform draw in its place is below one half.
    #[test]
    fn signs_are_negative_below_one_half() {
        let mut uniform = Draw(ChaCha8Rng::seed_from_u64(7));
        let mut sign = Draw(ChaCha8Rng::seed_from_u64(7));
        for _ in 0..50 {
            let r = uniform.uniform(0.0, 1.0);
            assert_eq!(sign.sign(), if r < 0.5 { -1.0 } else { 1.0 }, "{r}");
        }
    }

    fn run(s: &Scenario) -> Diagnosis {
        let (na, nb, d) = s.declared;
        diagnose(&s.u, &s.y, &DiagnoseConfig::new(na, nb, d)).expect("diagnosis runs")
    }

    fn line(s: &Scenario, d: &Diagnosis, secs: f64) -> String {
        let cands: Vec<String> = d
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "{}{}(z {:.1}, dBIC {:.0})",
                    if c.supported { "+" } else { "-" },
                    c.id,
                    c.heldout_z,
                    c.delta_bic
                )
            })
            .collect();
        format!(
            "{:>22} seed {:>5}: -> {:>22} before {:.4} after {:.4} [{:.2}s, rounds {}] {} | {}",
            names(&s.present),
            s.seed,
            d.effect_id().map_or("null".into(), |e| e.to_string()),
            d.base_heldout_rmse,
            d.after_rmse(),
            secs,
            d.base_rounds,
            s.description,
            cands.join(" ")
        )
    }

    /// Write the report of `d` on the record `s` (time 0.01 per sample) into a fresh temporary folder named
    /// after `tag`; returns the folder and the Markdown text.
    fn report_of(s: &Scenario, d: &Diagnosis, tag: &str) -> (std::path::PathBuf, String) {
        let dir = std::env::temp_dir().join(format!("backlash-{tag}-{}", std::process::id()));
        let t: Vec<f64> = (0..s.u.len()).map(|k| k as f64 * 0.01).collect();
        let input = crate::diagnose::report::ReportInput {
            columns: ["time", "u", "y"],
            file: "bench",
            t: &t,
            u: &s.u,
            y: &s.y,
            decimate: 1,
            command: None,
            validations: &[],
        };
        let md = crate::diagnose::report::write_report(&dir, d, &input).unwrap();
        let text = std::fs::read_to_string(&md).unwrap();
        (dir, text)
    }

    /// Seeds of the held-out check set: never used while the diagnosis was developed (development used
    /// seeds 0..60 for every effect and 0..300 for clean records), so the magnitudes drawn from them are
    /// new too.
    const CHECK_SEEDS: std::ops::Range<u64> = 10_000..10_010;
    const CLEAN_CHECK_SEEDS: std::ops::Range<u64> = 20_000..20_020;
    const CHECK_N: usize = 3000;

    /// The done-when of the issue for one effect: named in at least 9 of 10 check records, and the held-out
    /// error falls in each of those.
    fn check_effect(effect: EffectId) {
        let mut named = 0;
        let mut lines = Vec::new();
        let mut reported = false;
        for seed in CHECK_SEEDS {
            let s = scenario(Some(effect), seed, CHECK_N);
            let t = Instant::now();
            let d = run(&s);
            assert_pointed_by_rejections(&d);
            if !reported && d.effect_id() == Some(effect) {
                assert_evidence_of(&s, &d, effect_evidence(effect));
                reported = true;
            }
            // The held-out error the effect is judged by falls: the free-run simulation error, or for a
            // noise model its one-step prediction error (its simulation error is the plain model's, as the
            // noise model adds no deterministic part).
            let falls = d.effect().is_some_and(|c| match c.one_step {
                Some(o) => o.after < o.before,
                None => c.heldout_rmse < d.base_heldout_rmse,
            });
            let ok = d.effect_id() == Some(effect) && falls;
            named += usize::from(ok);
            lines.push(line(&s, &d, t.elapsed().as_secs_f64()));
        }
        assert!(
            named >= 9,
            "{effect}: named in {named} of 10\n{}",
            lines.join("\n")
        );
    }

    /// Every candidate of the first round was pointed to by tests, each of which rejected.
    fn assert_pointed_by_rejections(d: &Diagnosis) {
        for c in &d.candidates {
            assert!(!c.pointed_by.is_empty(), "{}", c.id);
            for name in &c.pointed_by {
                assert!(
                    d.tests
                        .iter()
                        .any(|t| t.verdict.name == *name && t.verdict.rejects),
                    "{} pointed to by {name}, which did not reject",
                    c.id
                );
            }
        }
    }

    /// A phrase of the caption of the evidence figure the report draws for `effect`.
    fn effect_evidence(effect: EffectId) -> &'static str {
        match effect {
            EffectId::GapDrift => "with fixed gaps both would stay at zero",
            EffectId::CurvedBorders => "straight borders leave no trend",
            EffectId::ExtraDelay | EffectId::LinearOrder => {
                "the linear block misses a term or a delay"
            }
            EffectId::ColouredNoise => "disturbance is (orange)",
            EffectId::Saturation => "the clipped model does not",
            EffectId::PeriodicDisturbance => "stands far above the noise floor",
            EffectId::Quantization => "sit on a grid of step",
            EffectId::Friction => "the friction element does",
            EffectId::DirectionDependent => "rises and falls at different speeds",
        }
    }

    /// The report of `d` draws its evidence figure and captions it with `phrase`.
    fn assert_evidence_of(s: &Scenario, d: &Diagnosis, phrase: &str) {
        let effect = d.effect_id().map_or("null".to_string(), |e| e.to_string());
        let (dir, text) = report_of(s, d, &format!("evidence-{effect}-{}", s.seed));
        assert!(text.contains(phrase), "{phrase}: {text}");
        assert!(dir.join("evidence.png").metadata().unwrap().len() > 1000);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn check_gap_drift() {
        check_effect(EffectId::GapDrift);
    }
    #[test]
    fn check_curved_borders() {
        check_effect(EffectId::CurvedBorders);
    }
    #[test]
    fn check_extra_delay() {
        check_effect(EffectId::ExtraDelay);
    }
    #[test]
    fn check_linear_order() {
        check_effect(EffectId::LinearOrder);
    }
    #[test]
    fn check_coloured_noise() {
        check_effect(EffectId::ColouredNoise);
    }
    #[test]
    fn check_saturation() {
        check_effect(EffectId::Saturation);
    }
    #[test]
    fn check_periodic_disturbance() {
        check_effect(EffectId::PeriodicDisturbance);
    }
    #[test]
    fn check_quantization() {
        check_effect(EffectId::Quantization);
    }
    #[test]
    fn check_friction() {
        check_effect(EffectId::Friction);
    }
    #[test]
    fn check_direction_dependent() {
        check_effect(EffectId::DirectionDependent);
    }

    /// Clean records: null in at least 19 of 20.
    #[test]
    fn check_clean_records_give_null() {
        let mut false_positives = Vec::new();
        for seed in CLEAN_CHECK_SEEDS {
            let s = scenario(None, seed, CHECK_N);
            let d = run(&s);
            assert_pointed_by_rejections(&d);
            if d.effect_id().is_some() {
                false_positives.push(line(&s, &d, 0.0));
            } else if seed == CLEAN_CHECK_SEEDS.start {
                assert_evidence_of(&s, &d, "No extension passed both criteria");
            }
            // The paper plant's play (c1 + c2 = 1.5) is plain in every clean record.
            assert!(d.backlash.supported, "{}", d.backlash.verdict);
            let se = d.backlash.play_se.expect("the gaps are determined");
            assert!(
                (d.backlash.play - 1.5).abs() < 4.0 * se,
                "{seed}: play {} +/- {se}",
                d.backlash.play
            );
            assert_eq!(
                d.effect_id().is_none(),
                (d.after_rmse() - d.base_heldout_rmse).abs() == 0.0,
                "after equals before exactly when null"
            );
        }
        assert!(false_positives.len() <= 1, "{}", false_positives.join("\n"));
    }

    /// A constant output offset is no effect: the declared model absorbs it into the gaps
    /// (m1 (x - c1) + d = m1 (x - (c1 - d / m1))), so the diagnosis stays null and the gaps move by d.
    #[test]
    fn constant_offset_is_absorbed_into_the_gaps() {
        let s = scenario(None, 20_100, CHECK_N);
        let offset = 0.7;
        let y: Vec<f64> = s.y.iter().map(|v| v + offset).collect();
        let d = diagnose(&s.u, &y, &DiagnoseConfig::new(2, 0, 1)).unwrap();
        assert_eq!(d.effect_id(), None);
        let b = &d.base.base;
        let (c1, c2, m2) = (
            s.params.backlash.c1,
            s.params.backlash.c2,
            s.params.backlash.m2,
        );
        assert!(
            (b.c1 - (c1 - offset)).abs() < 0.02,
            "c1 {} vs {}",
            b.c1,
            c1 - offset
        );
        assert!(
            (b.c2 - (c2 + offset / m2)).abs() < 0.02,
            "c2 {} vs {}",
            b.c2,
            c2 + offset / m2
        );
    }

    /// Degenerate records do not break the diagnosis: a constant record, pure noise (no relation between u
    /// and y), and refusals with a reason for bad input.
    #[test]
    fn degenerate_records() {
        let zeros = vec![0.0; 1000];
        let d = diagnose(&zeros, &zeros, &DiagnoseConfig::new(1, 0, 1)).unwrap();
        assert_eq!(d.effect_id(), None);
        let u = paper_input(2000, 3);
        let y = paper_input(2000, 4);
        let d = diagnose(&u, &y, &DiagnoseConfig::new(2, 2, 1)).unwrap();
        assert!(d.base_heldout_rmse.is_finite());
        use crate::diagnose::engine::DiagnoseError;
        let mut bad = y.clone();
        bad[17] = f64::NAN;
        assert_eq!(
            diagnose(&u, &bad, &DiagnoseConfig::new(1, 0, 1)).unwrap_err(),
            DiagnoseError::NonFinite(17)
        );
        assert!(matches!(
            diagnose(&u[..50], &y[..50], &DiagnoseConfig::new(1, 0, 1)),
            Err(DiagnoseError::TooShort { .. })
        ));
        assert!(matches!(
            diagnose(&u, &y, &DiagnoseConfig::new(5, 0, 1)),
            Err(DiagnoseError::Structure(_))
        ));
    }

    /// The JSON object has the contract's keys, and a report can be written.
    #[test]
    fn json_shape_and_report() {
        let s = scenario(Some(EffectId::Saturation), 20_200, 1500);
        let d = run(&s);
        let j = d.to_json(Some(0.01));
        assert!(j["before"]["rmse"].as_f64().unwrap() > 0.0);
        assert!(j["after"]["rmse"].as_f64().unwrap() > 0.0);
        assert_eq!(j["effect"]["id"], "saturation");
        assert!(j["effect"]["pointed_by"].is_string());
        assert!(j["effect"]["parameters"]["hi"].is_number());
        assert!(j["tests"].as_array().unwrap().len() >= 10);
        assert!(j["tests"][0]["points_to"].is_array());
        let cands = j["candidates"].as_array().unwrap();
        assert!(
            cands
                .iter()
                .any(|c| c["id"] == "saturation" && c["supported"] == true)
        );
        for c in cands {
            for key in ["heldout_rmse", "bic", "delta_bic", "heldout_z", "fit_rmse"] {
                assert!(c[key].is_number(), "{key} in {c}");
            }
        }
        let (dir, text) = report_of(&s, &d, "diag");
        assert!(text.contains("**Effect: `saturation`**"));
        assert!(!text.contains("Effects found"), "one effect: {text}");
        for f in [
            "heldout.png",
            "residual.png",
            "correlations.png",
            "evidence.png",
        ] {
            assert!(dir.join(f).metadata().unwrap().len() > 1000, "{f}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A record with two effects: the loop names both (in order of their BIC gain), each step lowers the
    /// held-out error, the JSON lists the steps, the rounds and why the loop stopped, and the report shows
    /// the loop; with `max_effects = 1` only the first is named.
    #[test]
    fn the_loop_names_both_effects_of_a_two_effect_record() {
        let s = scenario_with(&[EffectId::GapDrift, EffectId::Quantization], 30_100, 3000);
        let d = run(&s);
        let named: Vec<EffectId> = d.steps().iter().map(|c| c.id).collect();
        let mut sorted = named.clone();
        sorted.sort();
        assert_eq!(
            sorted,
            [EffectId::GapDrift, EffectId::Quantization],
            "{}",
            d.stopped
        );
        let j = d.to_json(None);
        let steps = j["effects"].as_array().unwrap();
        assert_eq!(steps.len(), 2);
        assert_eq!(j["effect"]["id"], steps[0]["id"]);
        assert_eq!(steps[0]["before_rmse"], j["before"]["rmse"]);
        assert_eq!(steps[1]["before_rmse"], steps[0]["after_rmse"]);
        assert_eq!(j["after"]["rmse"], steps[1]["after_rmse"]);
        let (e0, e1, e2) = (
            d.base_heldout_rmse,
            steps[0]["after_rmse"].as_f64().unwrap(),
            steps[1]["after_rmse"].as_f64().unwrap(),
        );
        assert!(e2 < e1 && e1 < e0, "{e0} -> {e1} -> {e2}");
        // Round 2 extended the first effect and chose the second; round 3 found nothing more.
        let rounds = j["rounds"].as_array().unwrap();
        assert_eq!(rounds.len(), 2, "{rounds:?}");
        assert_eq!(rounds[0]["extends"], serde_json::json!([named[0]]));
        assert_eq!(rounds[0]["chosen"], serde_json::json!(named[1]));
        assert!(rounds[1]["chosen"].is_null());
        assert!(j["stopped"].as_str().unwrap().contains("no further effect"));
        // The final model carries both extensions, fitted jointly.
        let fin = d.final_model();
        assert!(fin.extension(EffectId::GapDrift).is_some());
        assert!(fin.extension(EffectId::Quantization).is_some());

        let (dir, text) = report_of(&s, &d, "loop");
        assert!(text.contains("## The loop"), "{text}");
        let found = format!(
            "**Effects found, in order: `{}`, then `{}`.**",
            named[0], named[1]
        );
        assert!(text.contains(&found), "{text}");
        assert!(text.contains(&format!("| 2 | `{}` |", named[1])), "{text}");
        assert!(dir.join("steps.png").metadata().unwrap().len() > 1000);
        // The evidence figure is the first named effect's own.
        let caption = match named[0] {
            EffectId::GapDrift => {
                "on the upper and lower borders; with fixed gaps both would stay at zero"
            }
            _ => "sit on a grid of step",
        };
        assert!(text.contains(caption), "{text}");
        std::fs::remove_dir_all(&dir).unwrap();

        let (na, nb, delay) = s.declared;
        let one = diagnose(
            &s.u,
            &s.y,
            &DiagnoseConfig {
                max_effects: 1,
                ..DiagnoseConfig::new(na, nb, delay)
            },
        )
        .unwrap();
        assert_eq!(one.steps().len(), 1);
        assert_eq!(one.effect_id(), Some(named[0]));
        assert!(one.stopped.contains("--max-effects"), "{}", one.stopped);
        let bad = DiagnoseConfig {
            max_effects: 0,
            ..DiagnoseConfig::new(na, nb, delay)
        };
        let err = diagnose(&s.u, &s.y, &bad).unwrap_err().to_string();
        assert!(err.contains("between 1 and 10"), "{err}");
    }

    /// `stable` by hand: 1 + 0.45 z^-1 + 0.55 z^-2 (the paper's a) has poles of modulus sqrt(0.55) < 1;
    /// a = [0.5] gives h(k) = (-0.5)^k, which decays; a = [-1] gives h(k) = 1 for ever; a = [0, 0, 1.2] has
    /// poles of modulus 1.2^(1/3) > 1.
    #[test]
    fn stable_tells_decaying_impulse_responses() {
        assert!(stable(&[0.45, 0.55]));
        assert!(stable(&[0.5]));
        assert!(!stable(&[-1.0]));
        assert!(!stable(&[0.0, 0.0, 1.2]));
    }

    /// The curved-borders draws keep to the documented ranges: at s = 2 std(x0) the s^2 term is 5..15 % and
    /// the s^3 term 2..8 % of the linear one m s, with random signs, and the border's slope
    /// m + 2 c2 s + 3 c3 s^2 stays above 0.2 m over +-3 std(x0).
    #[test]
    fn curved_border_draws_keep_to_their_ranges() {
        let n = 300;
        // Negative draws of [upper s^2, upper s^3, lower s^2, lower s^3].
        let mut negative = [0; 4];
        for seed in 0..40 {
            let s = scenario(Some(EffectId::CurvedBorders), seed, n);
            let x0: Vec<f64> = Plant::simulate(PlantParams::PAPER, &s.u)
                .unwrap()
                .iter()
                .map(|o| o.x)
                .collect();
            let std_x = std_dev(&x0);
            let s_ref = 2.0 * std_x;
            let c = s.effects.curved_borders.unwrap();
            let bl = PlantParams::PAPER.backlash;
            for (side, (m, [c2, c3])) in
                [(bl.m1, c.upper), (bl.m2, c.lower)].into_iter().enumerate()
            {
                let square = (c2 * s_ref * s_ref) / (m * s_ref);
                let cube = (c3 * s_ref.powi(3)) / (m * s_ref);
                assert!((0.05..=0.15).contains(&square.abs()), "{seed}: {square}");
                assert!((0.02..=0.08).contains(&cube.abs()), "{seed}: {cube}");
                negative[2 * side] += usize::from(square < 0.0);
                negative[2 * side + 1] += usize::from(cube < 0.0);
                for i in -30..=30 {
                    let x = f64::from(i) / 10.0 * std_x;
                    assert!(m + 2.0 * c2 * x + 3.0 * c3 * x * x > 0.2 * m, "{seed}: {x}");
                }
            }
        }
        // Random signs on each term of each border: both signs among 40 draws (the resampling of borders
        // that would not stay increasing drops some negative s^3 terms, not most of them).
        for count in negative {
            assert!((4..=36).contains(&count), "{negative:?} of 40 negative");
        }
    }

    /// Each set of effects has its own generator: a single-effect record does not draw from the clean
    /// record's stream (its SNR, the first draw, differs for the same seed). The SNR is recovered as the
    /// noise-free output's standard deviation over the noise's.
    #[test]
    fn each_set_of_effects_draws_from_its_own_stream() {
        let snr = |s: &Scenario| std_dev(&s.f) / s.params.noise_std;
        let clean = scenario_with(&[], 4, 400);
        let drift = scenario_with(&[EffectId::GapDrift], 4, 400);
        let friction = scenario_with(&[EffectId::Friction], 4, 400);
        assert!(
            (snr(&clean) - snr(&drift)).abs() > 1e-6,
            "{} {}",
            snr(&clean),
            snr(&drift)
        );
        assert!((snr(&drift) - snr(&friction)).abs() > 1e-6);
        // The same set and seed give the same record.
        assert_eq!(scenario_with(&[EffectId::GapDrift], 4, 400).y, drift.y);
    }

    /// The drawn drift widens each gap by the fraction in the description over the record, reached at its
    /// last sample: c_rate * (n - 1) = c * g. A 10-sample record makes an off-by-two span visible through the
    /// description's whole percents (9 / 11 of the fraction).
    #[test]
    fn gap_drift_reaches_the_described_widening_at_the_last_sample() {
        let n = 10;
        for seed in 0..5 {
            let s = scenario(Some(EffectId::GapDrift), seed, n);
            let drift = s.effects.gap_drift.as_ref().expect("gap drift drawn");
            let percent = |name: &str| -> f64 {
                let rest = &s.description
                    [s.description.find(&format!("{name} +")).unwrap() + name.len() + 2..];
                rest[..rest.find('%').unwrap()].parse().unwrap()
            };
            let bl = s.params.backlash;
            let got = [
                100.0 * drift.c1_rate * (n - 1) as f64 / bl.c1,
                100.0 * drift.c2_rate * (n - 1) as f64 / bl.c2,
            ];
            for (g, want) in got.iter().zip([percent("c1"), percent("c2")]) {
                assert!(
                    (g - want).abs() <= 0.5 + 1e-9,
                    "{got:?} vs {}",
                    s.description
                );
            }
        }
    }
}

#[cfg(test)]
mod draw_tests;
