//! Tests across the catalogue: every effect's element simulates as the test bench's plant, the extensions
//! pack, rebase and refuse invalid parameters as their elements say, and which ones combine.

use super::*;
use crate::diagnose::effects::{
    coloured_noise, curved_borders, dead_zone, direction_dependent, friction, gap_drift, periodic,
    polynomial_feedback, quantization, saturation,
};
use crate::diagnose::fit::model::tests::{input, paper_base};
use crate::diagnose::fit::model::{BaseModel, EffectModel, Rest, Simulation};
use crate::plant::effects::{FrictionForm, simulate_with_effects};
use crate::plant::{Mode, PlantParams};

/// One extension of every effect that has an element (friction in both forms).
fn one_of_each() -> Vec<Extension> {
    vec![
        gap_drift::extension(1e-3, 5e-4),
        curved_borders::extension([0.1, -0.02], [0.05, 0.01]),
        saturation::extension(-1.0, 1.2),
        periodic::extension(0.3, 0.2, -0.1),
        quantization::extension(0.1, 0.02, 0.0),
        friction::extension(0.8, 1.1, FrictionForm::Series),
        friction::extension(0.8, 1.1, FrictionForm::Contact),
        direction_dependent::extension(&[0.2, 0.15], &[0.5]),
    ]
}

#[test]
fn plain_model_is_the_plant_and_extensions_are_the_bench() {
    let u = input(600);
    let p = PlantParams::PAPER;
    let exts = one_of_each();
    // The plain model, each alone, and every pair that combines (in both orders of adding them).
    let mut models: Vec<EffectModel> = vec![EffectModel::plain(paper_base())];
    models.extend(
        exts.iter()
            .map(|e| EffectModel::plain(paper_base()).with(e.clone())),
    );
    for a in &exts {
        for b in &exts {
            let m = EffectModel::plain(paper_base()).with(a.clone());
            if m.admits(b) {
                models.push(m.with(b.clone()));
            }
        }
    }
    assert!(models.len() > 50, "{}", models.len());
    for m in models {
        let s = m.simulate(&u, Rest::ZERO, u.len(), 1e9).unwrap();
        let bench = simulate_with_effects(&p, &m.effects(), &u, 0).unwrap();
        let ext = &m.exts;
        for (k, o) in bench.iter().enumerate() {
            assert!(
                (s.y[k] - o.y).abs() < 1e-12,
                "{ext:?} at {k}: {} vs {}",
                s.y[k],
                o.y
            );
            assert!((s.x[k] - o.x).abs() < 1e-12);
        }
    }
}

/// A falling set packs as a then b, follows the base model's orders when rebased (a new coefficient
/// starts at the base's own), and an unstable one is not a valid model.
#[test]
fn falling_set_packs_rebases_and_must_be_stable() {
    let fall = direction_dependent::extension(&[0.2, 0.15], &[0.5]);
    let m = EffectModel::plain(paper_base()).with(fall);
    let th = m.pack(1.0);
    assert_eq!(th[6..], [0.2, 0.15, 0.5, 0.0]);
    assert_eq!(m.unpack(&th, 1.0), m);
    let wider = m.rebased(paper_base().with_orders(3, 1, 1));
    assert_eq!(
        wider.exts[0],
        direction_dependent::extension(&[0.2, 0.15, 0.0], &[0.5, 0.0])
    );
    let narrower = m.rebased(paper_base().with_orders(1, 0, 1));
    assert_eq!(
        narrower.exts[0],
        direction_dependent::extension(&[0.2], &[0.5])
    );
    let u = input(50);
    assert!(m.simulate(&u, Rest::ZERO, 50, 1e9).is_some());
    let unstable =
        EffectModel::plain(paper_base()).with(direction_dependent::extension(&[-1.5, 0.0], &[0.5]));
    assert!(unstable.simulate(&u, Rest::ZERO, 50, 1e9).is_none());
}

#[test]
fn pack_unpack_round_trip() {
    let m = EffectModel::plain(paper_base())
        .with(gap_drift::extension(1e-4, -2e-4))
        .with(saturation::extension(-1.0, 2.0));
    let th = m.pack(1000.0);
    assert_eq!(th.len(), 10);
    assert_eq!(m.n_estimated(), 10);
    let back = m.unpack(&th, 1000.0);
    assert_eq!(back.base, m.base);
    let (drift, sat) = (&back.exts[0].theta, &back.exts[1].theta);
    assert!((drift[0] - 1e-4).abs() < 1e-18 && (drift[1] + 2e-4).abs() < 1e-18);
    assert_eq!(sat[..], [-1.0, 2.0]);
    assert_eq!(back.exts[0].id(), gap_drift::ID);
}

#[test]
fn unstable_model_is_refused_and_prediction_uses_the_noise_model() {
    let mut b = paper_base();
    b.a = vec![-2.5, 0.0];
    assert!(
        EffectModel::plain(b)
            .simulate(&input(500), Rest::ZERO, 500, 1e6)
            .is_none()
    );
    let m = EffectModel::plain(paper_base()).with(coloured_noise::extension(vec![0.5]));
    assert!(!m.can_add(gap_drift::ID), "nothing after a noise model");
    let sim = vec![1.0, 2.0, 3.0];
    let y = vec![1.5, 2.0, 2.0];
    assert_eq!(m.predict_from(&sim, &y), vec![1.0, 2.25, 3.0]);
}

/// The chatter check allows x to fall a little on the upper border while both gaps narrow: each sample
/// the border moves by up to |c1_rate| + |c2_rate|. Here x = u(k-1) rises onto the upper border, then
/// falls 0.002 per sample while c1 shrinks 0.005 per sample, so w still rises (mode up, x falling less
/// than the drift): a valid drifting backlash, simulated.
#[test]
fn narrowing_gaps_let_x_fall_on_the_upper_border() {
    let base = BaseModel {
        na: 0,
        nb: 0,
        delay: 1,
        a: vec![],
        b: vec![1.0],
        m1: 1.0,
        m2: 1.0,
        c1: 0.5,
        c2: 0.5,
    };
    let mut u: Vec<f64> = (0..30).map(|k| 0.1 * k as f64).collect();
    u.extend((1..=40).map(|k| 2.9 - 0.002 * k as f64));
    let m = EffectModel::plain(base).with(gap_drift::extension(-0.005, -0.005));
    let mut sim = Simulation::default();
    assert!(m.simulate_into(&u, Rest::ZERO, u.len(), 1e9, &mut sim));
    let last = sim.mode.len() - 1;
    assert_eq!(sim.mode[last], Mode::Up);
    assert!(sim.x[last] < sim.x[last - 1]);
}

/// The model's output with a quantizer is the expected reading of the sensor's value, rounded once: a
/// saturation that never clips (which sends the output through the sensor) changes nothing, also with
/// noise before the rounding (sigma > 0, readings off the grid).
#[test]
fn the_sensor_does_not_round_before_the_expected_reading() {
    let u = input(80);
    let q = quantization::extension(0.5, 0.1, 0.2);
    let wide = saturation::extension(-1e9, 1e9);
    let plain = EffectModel::plain(paper_base()).with(q.clone());
    let sensed = EffectModel::plain(paper_base()).with(wide).with(q);
    let a = plain.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y;
    let b = sensed.simulate(&u, Rest::ZERO, 80, 1e9).unwrap().y;
    assert_eq!(a, b);
    // Readings off the grid: the expectation over the noise, not a rounded value.
    assert!(
        a.iter()
            .any(|v| ((v - 0.1) / 0.5 - ((v - 0.1) / 0.5).round()).abs() > 1e-3)
    );
}

/// The extensions' own validity: a positive finite rounding step, saturation levels in order, a
/// non-empty slip range, and a play of non-negative width for the contact form.
#[test]
fn extension_parameters_are_checked() {
    let with = |e: Extension| EffectModel::plain(paper_base()).with(e);
    let q = |step: f64| quantization::extension(step, 0.0, 0.0);
    assert!(with(q(0.1)).runnable());
    assert!(!with(q(-0.1)).runnable());
    assert!(!with(q(0.0)).runnable());
    assert!(!with(q(f64::INFINITY)).runnable());
    assert!(with(saturation::extension(1.0, 1.0)).runnable());
    assert!(!with(saturation::extension(1.0, 0.5)).runnable());
    let fr = friction::extension;
    assert!(with(fr(0.5, -0.2, FrictionForm::Series)).runnable());
    assert!(!with(fr(0.5, -0.5, FrictionForm::Series)).runnable());
    assert!(!with(fr(f64::NAN, 1.0, FrictionForm::Series)).runnable());
    assert!(with(fr(0.5, 0.5, FrictionForm::Contact)).runnable());
    let mut narrow = EffectModel::plain(BaseModel {
        c1: 0.5,
        c2: -0.6,
        ..paper_base()
    });
    assert!(narrow.with(fr(0.5, 0.5, FrictionForm::Series)).runnable());
    narrow = narrow.with(fr(0.5, 0.5, FrictionForm::Contact));
    assert!(!narrow.runnable());
    // The play is the sum c1 + c2: both negative is no play, one negative with a larger other is.
    let contact = |c1: f64, c2: f64| {
        EffectModel::plain(BaseModel {
            c1,
            c2,
            ..paper_base()
        })
        .with(fr(0.5, 0.5, FrictionForm::Contact))
        .runnable()
    };
    assert!(!contact(-0.5, -0.6));
    assert!(contact(-0.2, 0.6));
    // A model with an invalid extension is not simulated.
    assert!(
        with(q(-0.1))
            .simulate(&input(50), Rest::ZERO, 50, 1e9)
            .is_none()
    );
}

/// Each entry once; curved borders never with contact friction (and the reverse); polynomial feedback never
/// with friction of either form (and the reverse: friction's plan has nothing to fit on a model with the
/// feedback); anything else combines.
#[test]
fn which_extensions_combine() {
    let plain = EffectModel::plain(paper_base());
    assert!(EffectId::all().all(|id| plain.can_add(id)));
    let drift = plain.with(gap_drift::extension(0.0, 0.0));
    assert!(!drift.can_add(gap_drift::ID));
    assert!(drift.can_add(saturation::ID));
    let contact = friction::extension(1.0, 1.0, FrictionForm::Contact);
    let with_contact = plain.with(contact.clone());
    assert!(with_contact.has_contact());
    assert!(!with_contact.can_add(curved_borders::ID));
    assert!(with_contact.can_add(saturation::ID));
    let curved = plain.with(curved_borders::extension([0.0; 2], [0.0; 2]));
    assert!(!curved.has_contact());
    assert!(!curved.admits(&contact));
    assert!(curved.admits(&friction::extension(1.0, 1.0, FrictionForm::Series)));
    let series = plain.with(friction::extension(1.0, 1.0, FrictionForm::Series));
    assert!(!series.can_add(polynomial_feedback::ID));
    assert!(!with_contact.can_add(polynomial_feedback::ID));
    let spring = plain.with(polynomial_feedback::extension(0.0, -0.01, 1.0));
    assert!(!spring.admits(&friction::extension(1.0, 1.0, FrictionForm::Series)));
    let y = input(50);
    let cx = crate::diagnose::fit::starts::tests::context(&spring, &y, &y, &y);
    assert!(friction::Friction.plan(&cx).is_none());
    assert!(spring.can_add(saturation::ID));
}

/// Every effect of the catalogue describes itself, answers a plan or none on a plain context, and every
/// element's typical magnitudes match its packed parameters.
#[test]
fn every_element_has_a_magnitude_per_parameter() {
    let scales = Scales {
        y: 1.0,
        x: 1.0,
        u: 1.0,
        n_fit: 100,
    };
    // The elements the bench does not simulate too: a noise model of order 3 (its magnitudes must follow
    // the order, not the first order's one), a dead zone, the cubic spring.
    let mut all = one_of_each();
    all.extend([
        coloured_noise::extension(vec![0.5, -0.2, 0.1]),
        dead_zone::extension(0.1),
        polynomial_feedback::extension(0.1, 0.01, 0.2),
    ]);
    for e in all {
        assert_eq!(
            e.element.typical(&e, &scales).len(),
            e.pack(10.0).len(),
            "{e:?}"
        );
        assert_eq!(e.unpack(&e.pack(1.0), 1.0), e, "{e:?}");
    }
}

/// The zero-gap model (the play-free alternative the verdict on play fits): m2 = m1, the gaps about their
/// middle with c2 = -c1, the curved borders' lower terms held at the upper's (one curve), the gaps' drift
/// rates opposite (the curve's level drifts, the gap stays zero), and the noise model left out.
#[test]
fn the_zero_gap_model_ties_each_element() {
    let m = EffectModel::plain(paper_base())
        .with(gap_drift::extension(1e-3, 5e-4))
        .with(curved_borders::extension([0.1, -0.02], [0.05, 0.01]))
        .with(coloured_noise::extension(vec![0.5]));
    let (moved, pins) = m.zero_gap(1.0);
    let expected = EffectModel::plain(BaseModel {
        m2: 1.0,
        c1: -0.25,
        c2: 0.25,
        ..paper_base()
    })
    .with(gap_drift::extension(1e-3, -1e-3))
    .with(curved_borders::extension([0.1, -0.02], [0.1, -0.02]));
    assert_eq!(moved, expected);
    // The pins hold it there: any free values expand to a model with the same ties.
    let th = moved.pack(1.0);
    assert_eq!(pins.0.len(), th.len());
    let mut free = pins.reduce(&th);
    free.iter_mut().for_each(|v| *v += 0.125);
    let other = moved.unpack(&pins.expand(&free), 1.0);
    let (drift, curved) = (&other.exts[0].theta, &other.exts[1].theta);
    assert_eq!(drift[1], -drift[0]);
    assert_eq!(curved[2..], curved[..2]);
    assert_eq!((other.base.m2, other.base.c2), (1.0, -other.base.c1));
}
