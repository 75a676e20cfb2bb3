use super::*;
use crate::diagnose::fit::lm::LmOptions;
use crate::diagnose::fit::model::Rest;
use crate::diagnose::fit::model::tests::{paper_base, paper_record, with_noise};
use crate::diagnose::fit::problem::Problem;
use crate::diagnose::fit::starts::tests::{context, paper};

#[test]
fn friction_gains_grow_by_sqrt_2_up_to_twice_the_ratio() {
    let s = gain_scales(10.0);
    assert_eq!(s[0], 1.0);
    for w in s.windows(2) {
        assert!((w[1] / w[0] - std::f64::consts::SQRT_2).abs() < 1e-12);
    }
    // The first scale at or above 2 r = 20: sqrt(2)^9 = 22.6.
    assert_eq!(s.len(), 10);
    assert!(*s.last().unwrap() >= 20.0 && s[s.len() - 2] < 20.0);
    // Small ratios still reach 8; huge ones stop at 40 scales.
    assert_eq!(gain_scales(0.1).len(), 7);
    assert_eq!(gain_scales(1e30).len(), 40);
}

/// y = 2 u exactly: every slope is 2, over the model's static gain 0.4 a ratio of 5; without moves (a
/// constant input) or without a gain, 1.
#[test]
fn steepness_ratio_by_hand() {
    let m = paper();
    let u: Vec<f64> = (0..20).map(|k| f64::from(k * k) / 10.0).collect();
    let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
    assert!((steepness_ratio(&context(&m, &u, &y, &y)) - 5.0).abs() < 1e-12);
    let flat = vec![1.0; 20];
    assert_eq!(steepness_ratio(&context(&m, &flat, &y, &y)), 1.0);
    let no_gain = EffectModel::plain(BaseModel::zero(2, 0, 1));
    assert_eq!(steepness_ratio(&context(&no_gain, &u, &y, &y)), 1.0);
    // Only moves of u above the median move count: steps of 1, 0.5 and 0.125 in turn (median 0.5, all
    // exact in binary), y rising 2 per unit of u on the steps of 1 and 10 on the others: the slope 2
    // over the gain 0.4 is 5 (counting every move would give 10 / 0.4 = 25).
    let (mut u, mut y) = (vec![0.0], vec![0.0]);
    for k in 0..21 {
        let du = [1.0, 0.5, 0.125][k % 3];
        let slope = if du == 1.0 { 2.0 } else { 10.0 };
        u.push(u[k] + du);
        y.push(y[k] + slope * du);
    }
    assert_eq!(steepness_ratio(&context(&m, &u, &y, &y)), 5.0);
}

/// Friction's grid for y = 2 u (ratio 5: gains 1 .. sqrt(2)^7 = 11.3, 8 of them): per gain 4 offsets x 4
/// slip fractions x 2 gaps in series and 3 plays x 3 offsets x 3 fractions in contact. The first series
/// start keeps the model's gaps (their mean 0.75 plus-minus their half difference 0.25) with m2 = 1 and
/// slip levels at the 99% / 1% quantiles of y; the templates slip at the extremes of y.
/// The series grid's third and fourth gap offsets are +spread and -spread, spread = (q99 - q01) / 8 =
/// (9.8 + 9.8) / 8 = 2.45 for y = 2 u: per offset 4 fractions x 2 gaps = 8 starts, so the first start of
/// each is number 16 (c1 - c2 = -2 spread = -4.9) and number 24 (+4.9).
#[test]
fn friction_offsets_go_both_ways() {
    let u: Vec<f64> = (0..101).map(|k| f64::from(k) / 10.0 - 5.0).collect();
    let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
    let p = Friction.plan(&context(&paper(), &u, &y, &y)).unwrap();
    let series = &p.alternatives[0].starts;
    let diff = |i: usize| series[i].base.c1 - series[i].base.c2;
    assert!((diff(16) + 4.9).abs() < 1e-12, "{}", diff(16));
    assert!((diff(24) - 4.9).abs() < 1e-12, "{}", diff(24));
    // Contact: per play three offsets (0, +g/2, -g/2) of three fractions each; the first play g is 2% of
    // the stroke of x, 0.02 * 0.4 * 9.8: starts 3 and 6 have c1 - c2 = -g and +g.
    let contact = &p.alternatives[1].starts;
    let g = 0.02 * 0.4 * 9.8;
    let cdiff = |i: usize| contact[i].base.c1 - contact[i].base.c2;
    assert!((cdiff(3) + g).abs() < 1e-12, "{}", cdiff(3));
    assert!((cdiff(6) - g).abs() < 1e-12, "{}", cdiff(6));
}

#[test]
fn friction_grid_by_hand() {
    let m = paper();
    let u: Vec<f64> = (0..101).map(|k| f64::from(k) / 10.0 - 5.0).collect();
    let y: Vec<f64> = u.iter().map(|v| 2.0 * v).collect();
    let p = Friction.plan(&context(&m, &u, &y, &y)).unwrap();
    let [series, contact] = &p.alternatives[..] else {
        panic!("two arrangements")
    };
    assert_eq!(series.starts.len(), 8 * 32);
    assert_eq!(contact.starts.len(), 8 * 27);
    let first = &series.starts[0];
    assert_eq!(
        (first.base.c1, first.base.c2, first.base.m2),
        (0.5, 1.0, 1.0)
    );
    assert_eq!(first.base.b, vec![0.8]);
    // The next gain (start 32, after 4 offsets x 4 fractions x 2 gaps) scales the gaps with it.
    let second = &series.starts[32];
    let r2 = std::f64::consts::SQRT_2;
    assert!((second.base.b[0] - 0.8 * r2).abs() < 1e-12);
    assert!(
        (second.base.c1 - 0.5 * r2).abs() < 1e-12 && (second.base.c2 - r2).abs() < 1e-12,
        "{:?}",
        (second.base.c1, second.base.c2)
    );
    // quantile(y, 0.99): the element at round(100 * 0.99) = 99 of the sorted 101, 2 (99 / 10 - 5) = 9.8.
    let [f_plus, f_minus] = first.exts[0].theta[..] else {
        panic!("two slip levels")
    };
    assert!((f_plus - 9.8).abs() < 1e-12 && (f_minus - 9.8).abs() < 1e-12);
    assert_eq!(form(&first.exts[0]), FrictionForm::Series);
    assert_eq!(series.template.exts[0].theta, vec![10.0, 10.0]);
    // The last gain is sqrt(2)^7 times the model's b.
    let last = &series.starts[series.starts.len() - 1];
    assert!((last.base.b[0] - 0.8 * 2f64.sqrt().powi(7)).abs() < 1e-12);
    // Contact: the first play is 2% of the stroke of x, gain 0.4 times the 1%..99% range of u (9.8).
    let c = &contact.starts[0];
    assert!((c.base.c1 - 0.02 * 0.4 * 9.8).abs() < 1e-12 && c.base.c1 == c.base.c2);
    // On curved borders the contact form is not offered.
    let curved = m.with(crate::diagnose::effects::curved_borders::extension(
        [0.0; 2], [0.0; 2],
    ));
    let p = Friction.plan(&context(&curved, &u, &y, &y)).unwrap();
    assert_eq!(p.alternatives.len(), 1);
    assert_eq!(
        p.alternatives[0].template.exts.last(),
        Some(&extension(10.0, 10.0, FrictionForm::Series))
    );
}

/// The extension's own validity: a non-empty slip range, and a play of non-negative width for the contact
/// form; the contact form rules out curved borders, the series form does not.
#[test]
fn slip_range_play_and_exclusion() {
    let b = crate::diagnose::fit::model::tests::paper_base();
    assert!(Friction.valid(&extension(0.5, -0.2, FrictionForm::Series), &b));
    assert!(!Friction.valid(&extension(0.5, -0.5, FrictionForm::Series), &b));
    assert!(!Friction.valid(&extension(f64::NAN, 1.0, FrictionForm::Series), &b));
    let narrow = BaseModel {
        c1: 0.5,
        c2: -0.6,
        ..b.clone()
    };
    assert!(Friction.valid(&extension(0.5, 0.5, FrictionForm::Series), &narrow));
    assert!(!Friction.valid(&extension(0.5, 0.5, FrictionForm::Contact), &narrow));
    let curved = super::super::curved_borders::ID;
    let contact = extension(1.0, 1.0, FrictionForm::Contact);
    assert!(Friction.blocks(&contact, curved));
    assert!(!Friction.blocks(&contact, super::super::saturation::ID));
    assert!(!Friction.blocks(&extension(1.0, 1.0, FrictionForm::Series), curved));
}

/// The paper's plant (m1 = 1, m2 = 1.5) with a series friction element after it, at noise 0.05, its
/// input 5 above the paper's (at rest there, on a border): the element sees only the changes of the
/// borders' output, so no half determines its level, nor the play of unequal slopes read at a level.
/// Held at the whole model's level, each half still gives the play with a standard error, within 3 of
/// them of the truth.
#[test]
fn a_half_after_friction_reads_the_play_at_the_whole_models_level() {
    let n = 3000;
    let (u, _) = paper_record(n);
    let u: Vec<f64> = u.iter().map(|v| v + 5.0).collect();
    let truth = EffectModel::plain(paper_base()).with(extension(2.0, 2.0, FrictionForm::Series));
    let sim = truth.simulate(&u, Rest(u[0]), n, 1e6).unwrap();
    let y = with_noise(&sim.y, 0.05, 3);
    let p = Problem {
        rest: Rest(u[0]),
        ..Problem::new(&u, &y, n, LmOptions::default())
    };
    for range in [0..n / 2, n / 2..n] {
        let (play, se) = p.range_play(&truth, range.clone()).unwrap();
        assert!(se.is_finite() && se > 0.0, "{range:?}: {se}");
        assert!((play - 1.5).abs() < 3.0 * se, "{range:?}: {play} +/- {se}");
    }
}

/// The play's own parameters among the packed ones: the paper block (a1, a2, b0) then m2, c1, c2 at 3, 4, 5,
/// and a friction element's two slip levels wherever it sits; a saturation's limits are not among them.
#[test]
fn the_plays_own_entries_are_the_gaps_and_the_friction_elements() {
    use crate::diagnose::effects::saturation;
    let base = EffectModel::plain(paper_base());
    let sat = saturation::extension(-5.0, 5.0);
    let fr = extension(1.0, 1.0, FrictionForm::Contact);
    assert_eq!(base.play_entries(), [3, 4, 5]);
    let after = base.with(sat.clone()).with(fr.clone());
    assert_eq!(after.play_entries(), [3, 4, 5, 8, 9]);
    let before = base.with(fr).with(sat);
    assert_eq!(before.play_entries(), [3, 4, 5, 6, 7]);
}
