use super::*;
use proptest::prelude::*;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

const PAPER: BacklashParams = BacklashParams::PAPER;

/// Runs the reference through inverse and backlash; returns the inverse's inputs and the backlash outputs.
fn through(inv: &mut BacklashInverse, p: &BacklashParams, r: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut w = 0.0;
    let (mut vs, mut ws) = (Vec::new(), Vec::new());
    for &rk in r {
        let a = inv.commit(rk, p);
        assert!(a.degenerate.is_none(), "{:?} at r = {rk}", a.degenerate);
        w = p.step(a.v, w).0;
        assert_eq!(w, a.w, "the inverse's output memory is the backlash's");
        vs.push(a.v);
        ws.push(w);
    }
    (vs, ws)
}

fn tol(r: f64) -> f64 {
    1e-9 * (1.0 + r.abs())
}

/// Borders that do not cross for |r| <= 5.
fn params() -> impl Strategy<Value = BacklashParams> {
    (0.5..3.0f64, -0.1..0.1f64, 0.1..2.0f64, 0.1..2.0f64)
        .prop_filter("borders cross within |r| <= 5", |&(m1, e, c1, c2)| {
            let m2 = m1 * (1.0 + e);
            5.0 * (1.0 / m2 - 1.0 / m1).abs() < c1 + c2
        })
        .prop_map(|(m1, e, c1, c2)| BacklashParams {
            m1,
            m2: m1 * (1.0 + e),
            c1,
            c2,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// backlash(inverse(r)) == r on random references (random values and random walks with holds).
    #[test]
    fn the_exact_inverse_is_exact(
        p in params(),
        r in proptest::collection::vec(-5.0..5.0f64, 1..200),
        walk in proptest::collection::vec(prop_oneof![Just(0.0), -0.3..0.3f64], 1..200),
    ) {
        let mut inv = BacklashInverse::new(0.0).unwrap();
        let (_, w) = through(&mut inv, &p, &r);
        for (rk, wk) in r.iter().zip(&w) {
            prop_assert!((rk - wk).abs() <= tol(*rk), "r {rk} w {wk}");
        }
        let mut acc = 0.0f64;
        let r2: Vec<f64> = walk.iter().map(|d| { acc = (acc + d).clamp(-5.0, 5.0); acc }).collect();
        let mut inv = BacklashInverse::new(0.0).unwrap();
        let (_, w) = through(&mut inv, &p, &r2);
        for (rk, wk) in r2.iter().zip(&w) {
            prop_assert!((rk - wk).abs() <= tol(*rk), "r {rk} w {wk}");
        }
    }

    /// Committing a reference and asking again for the same reference and estimate answers the committed v
    /// bit for bit (what a master reads after the step that committed it), with or without smoothing.
    #[test]
    fn a_held_reference_answers_the_committed_v(
        p in params(),
        s in prop_oneof![Just(0.0), 0.0..0.5f64],
        r in proptest::collection::vec(-5.0..5.0f64, 1..200),
    ) {
        let mut inv = BacklashInverse::new(s).unwrap();
        for &rk in &r {
            let v = inv.commit(rk, &p).v;
            prop_assert_eq!(inv.evaluate(rk, &p).v, v, "r {}", rk);
            prop_assert_eq!(inv.commit(rk, &p).v, v, "r {}", rk);
        }
    }

    /// With smoothing s the output is never further than s from the reference.
    #[test]
    fn smoothing_costs_at_most_its_width(
        p in params(),
        s in 0.0..0.5f64,
        r in proptest::collection::vec(-5.0..5.0f64, 1..200),
    ) {
        let mut inv = BacklashInverse::new(s).unwrap();
        let (_, w) = through(&mut inv, &p, &r);
        for (rk, wk) in r.iter().zip(&w) {
            prop_assert!((rk - wk).abs() <= s + tol(*rk), "r {rk} w {wk} s {s}");
        }
    }

    /// Whatever the estimate, v is a finite number.
    #[test]
    fn any_estimate_gives_a_finite_v(
        m1 in prop_oneof![Just(f64::NAN), Just(0.0), Just(1e-320), -2.0..3.0f64],
        m2 in prop_oneof![Just(f64::INFINITY), Just(0.0), -2.0..3.0f64],
        c1 in prop_oneof![Just(f64::NAN), -2.0..2.0f64],
        c2 in -2.0..2.0f64,
        r in proptest::collection::vec(prop_oneof![Just(f64::NAN), Just(1e300), -5.0..5.0f64], 1..50),
    ) {
        let mut inv = BacklashInverse::new(0.1).unwrap();
        let p = BacklashParams { m1, m2, c1, c2 };
        for rk in r {
            let a = inv.commit(rk, &p);
            prop_assert!(a.v.is_finite() && a.w.is_finite(), "{a:?}");
        }
    }
}

#[test]
fn a_hand_worked_sequence() {
    // Paper backlash: up border v = r + 0.5, down border v = r / 1.5 - 1.
    let mut inv = BacklashInverse::new(0.0).unwrap();
    let v: Vec<f64> = [0.0, 1.0, 1.0, 0.3, 0.3, 0.6]
        .iter()
        .map(|&r| inv.commit(r, &PAPER).v)
        .collect();
    let want = [0.0, 1.5, 1.5, 0.2 - 1.0, 0.2 - 1.0, 1.1];
    for (a, b) in v.iter().zip(want) {
        assert!((a - b).abs() < 1e-12, "{v:?}");
    }
}

/// A constant reference with noise: the exact inverse crosses the gap on most samples; a smoothing width
/// of 4 noise standard deviations never in 5000 samples, and the output stays within the width.
#[test]
fn smoothing_stops_chattering_on_a_noisy_constant_reference() {
    let sigma = 0.05;
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let r: Vec<f64> = (0..5000)
        .map(|_| {
            let z: f64 = StandardNormal.sample(&mut rng);
            1.0 + sigma * z
        })
        .collect();
    let gap = PAPER.c1 + PAPER.c2;
    let exact = through(&mut BacklashInverse::new(0.0).unwrap(), &PAPER, &r).0;
    let (smooth, w) = through(&mut BacklashInverse::new(4.0 * sigma).unwrap(), &PAPER, &r);
    let (ce, cs) = (chattering(&exact, gap), chattering(&smooth, gap));
    assert!(ce > 0.4, "exact inverse chattering {ce}");
    assert!(cs == 0.0, "smoothed inverse chattering {cs}");
    assert!(
        r.iter()
            .zip(&w)
            .all(|(a, b)| (a - b).abs() <= 4.0 * sigma + 1e-12)
    );
}

fn one(p: BacklashParams, r: f64) -> Answer {
    let mut inv = BacklashInverse::new(0.0).unwrap();
    inv.commit(1.0, &PAPER);
    inv.commit(r, &p)
}

#[test]
fn a_non_positive_slope_keeps_the_last_valid_estimate() {
    for m2 in [0.0, -1.5, f64::NAN] {
        let a = one(BacklashParams { m2, ..PAPER }, 0.3);
        assert!((a.v - (0.3 / 1.5 - 1.0)).abs() < 1e-12, "{a:?}");
        assert!(
            matches!(a.degenerate, Some(Degenerate::Slope { name: "m2", .. })),
            "{a:?}"
        );
    }
    // Before any valid estimate: v = r.
    let mut inv = BacklashInverse::new(0.0).unwrap();
    let a = inv.commit(0.7, &BacklashParams { m1: 0.0, ..PAPER });
    assert_eq!(a.v, 0.7);
    let msg = a.degenerate.unwrap().to_string();
    assert!(msg.contains("m1 = 0 is not a positive number"), "{msg}");
}

#[test]
fn a_negative_gap_is_taken_as_zero() {
    let a = one(BacklashParams { c2: -0.2, ..PAPER }, 0.3);
    assert!((a.v - 0.3 / 1.5).abs() < 1e-12, "{a:?}");
    assert_eq!(
        a.degenerate,
        Some(Degenerate::NegativeGap {
            name: "c2",
            value: -0.2
        })
    );
}

/// m1 = 1, m2 = 1.5, c1 = c2 = 0.1: from w = -3 the upper border drives above -2.9, but the lower border's
/// input for -3.3 is -2.3: no input gives -3.3. v = -2.9 would give 1.5 (-2.9 + 0.1) = -4.2, just above it the
/// upper border holds -3: the nearer.
#[test]
fn crossing_borders_give_the_nearest_output() {
    let p = BacklashParams {
        c1: 0.1,
        c2: 0.1,
        ..PAPER
    };
    let mut inv = BacklashInverse::new(0.0).unwrap();
    let a = inv.commit(-3.0, &p);
    assert!(a.degenerate.is_none() && (a.w + 3.0).abs() < 1e-12, "{a:?}");
    let a = inv.commit(-3.3, &p);
    assert!(matches!(
        a.degenerate,
        Some(Degenerate::CrossedBorders { .. })
    ));
    assert!((a.w + 3.0).abs() < 1e-9 && a.v > -2.9, "{a:?}");
    assert_eq!(p.step(a.v, -3.0).0, a.w);
}

#[test]
fn a_bad_reference_or_overflow_holds_v() {
    let mut inv = BacklashInverse::new(0.0).unwrap();
    let v = inv.commit(1.0, &PAPER).v;
    let a = inv.commit(f64::NAN, &PAPER);
    assert_eq!((a.v, a.degenerate.is_some()), (v, true));
    let tiny = BacklashParams {
        m1: 1e-320,
        ..PAPER
    };
    let a = inv.commit(1e300, &tiny);
    assert_eq!(a.v, v);
    assert!(matches!(a.degenerate, Some(Degenerate::Overflow(_))));
}

#[test]
fn a_bad_smoothing_width_is_refused_in_words() {
    for s in [-0.1, f64::NAN, f64::INFINITY] {
        let e = BacklashInverse::new(s).unwrap_err().to_string();
        assert!(e.contains("must be a finite number of 0 or more"), "{e}");
    }
}

#[test]
fn chattering_counts_gap_sized_moves() {
    assert_eq!(chattering(&[0.0, 1.0, 1.1, 0.0], 3.0), 0.0);
    assert_eq!(chattering(&[0.0, 1.0, 1.1, -0.5], 3.0), 1.0 / 3.0);
    assert_eq!(chattering(&[1.0], 1.5), 0.0);
}
