use super::study::{Change, Run, noise_std};
use super::*;
use crate::identify::test_plants::random_plant;
use crate::plant::PlantParams;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;

fn cfg(period: f64) -> MonitorConfig {
    MonitorConfig {
        alarm_period: period,
        ..MonitorConfig::default()
    }
}

/// Runs `n` samples; the alarms.
fn alarms(run: &mut Run, n: u64) -> Vec<Alarm> {
    (0..n).filter_map(|_| run.step()).collect()
}

#[test]
fn settings_are_checked_in_words() {
    let bad = |c: MonitorConfig| Monitor::new(c).unwrap_err().to_string();
    let d = MonitorConfig::default();
    assert!(
        bad(MonitorConfig {
            wear_ratio: 0.0,
            ..d
        })
        .contains("wear_ratio = 0")
    );
    assert!(
        bad(MonitorConfig {
            wear_ratio: f64::NAN,
            ..d
        })
        .contains("wear_ratio")
    );
    assert!(
        bad(MonitorConfig {
            alarm_period: 1.0,
            ..d
        })
        .contains("alarm_period = 1")
    );
    assert!(
        bad(MonitorConfig {
            reference_play: Some(-1.0),
            ..d
        })
        .contains("reference play")
    );
    assert!(Monitor::new(d).is_ok());
}

#[test]
fn threshold_grows_with_the_period_and_is_infinite_without_information() {
    let h3 = threshold(0.05, 1e3);
    let h6 = threshold(0.05, 1e6);
    assert!(h3 > 0.0 && h6 > h3);
    // Siegmund's ARL at the threshold is the period.
    let x = h6 + OVERSHOOT * (0.1f64).sqrt();
    let arl = (x.exp() - x - 1.0) / 0.05;
    assert!((arl / 1e6 - 1.0).abs() < 1e-6, "{arl}");
    // Below the asymptotic bound ln(period): the overshoot and the 1/K factor both lengthen the run.
    assert!(h6 < 1e6f64.ln());
    assert_eq!(threshold(0.0, 1e6), f64::INFINITY);
}

/// The monitor only reads the estimator's state: its estimates are those of the refined estimator alone.
#[test]
fn the_monitor_leaves_the_estimator_unchanged() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    let mut with = Run::new(plant, sigma, 3, Change::None, cfg(1e3));
    let mut alone = super::study::Scenario::new(plant, sigma, 3, Change::None);
    let mut est = Refined::new(super::study::estimator_config(&plant)).unwrap();
    for _ in 0..4000 {
        with.step();
        let (u, y) = alone.next_sample();
        est.update(u, y);
    }
    assert_eq!(with.est, est);
    assert!(with.mon.reference().is_some());
}

/// A +50% play step at an unknown time on the paper plant at SNR 20: the alarm comes after the step, soon,
/// never before; the onset is near the true time and the play after is measured within its error.
#[test]
fn a_play_step_is_detected_after_it_and_never_before() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    let play = plant.backlash.c1 + plant.backlash.c2;
    for seed in 0..4 {
        let at = 6000 + 500 * seed;
        let mut run = Run::new(
            plant,
            sigma,
            seed,
            Change::PlayStep { at, ratio: 0.5 },
            cfg(1e6),
        );
        let before = alarms(&mut run, at);
        assert!(before.is_empty(), "seed {seed}: false alarm {before:?}");
        let (p0, se0) = run.mon.reference().unwrap();
        assert!(
            (p0 - play).abs() < 4.0 * se0 + 0.01,
            "seed {seed}: {p0} +/- {se0}"
        );
        let after = alarms(&mut run, 3000);
        let a = after
            .first()
            .unwrap_or_else(|| panic!("seed {seed}: no alarm"));
        assert!(a.sample >= at && a.sample < at + 300, "seed {seed}: {a:?}");
        assert!(
            a.onset_sample + 50 >= at && a.onset_sample <= a.sample,
            "{a:?}"
        );
        // First order: a large step is underestimated, but the growth is seen and the reference follows.
        assert!(
            a.play_after > 1.1 * p0 && a.play_after < 1.5 * play + 4.0 * a.play_after_se,
            "{a:?}"
        );
        assert!(run.mon.statistic() < 1.0);
        assert_eq!(run.mon.first_alarm(), Some(a));
    }
}

/// Changes that are not wear raise no alarm at a period of 1e6: a doubled input amplitude, a 10% change of
/// the linear block's gain either way, an output offset of 5 noise standard deviations.
#[test]
fn changes_that_are_not_wear_raise_no_alarm() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    let changes = [
        Change::InputAmplitude {
            at: 5000,
            factor: 2.0,
        },
        Change::LinearGain {
            at: 5000,
            factor: 1.1,
        },
        Change::LinearGain {
            at: 5000,
            factor: 0.9,
        },
        Change::OutputOffset {
            at: 5000,
            offset: 5.0 * sigma,
        },
    ];
    for (i, change) in changes.into_iter().enumerate() {
        let mut run = Run::new(plant, sigma, 10 + i as u64, change, cfg(1e6));
        let got = alarms(&mut run, 15_000);
        assert!(got.is_empty(), "{change:?}: {got:?}");
    }
}

/// Random plants (orders, delays, slopes, gaps) and seeds at SNR 20: no false alarm in 8000 samples at a
/// period of 1e5, and a +50% step is found after it.
#[test]
fn random_plants_no_false_alarm_and_a_step_is_found() {
    let mut rng = ChaCha8Rng::seed_from_u64(34);
    let (mut found, mut tried) = (0, 0);
    for seed in 0..10 {
        let plant = random_plant(&mut rng, 2, 1, &[1, 2, 3]);
        let sigma = noise_std(plant, 20.0);
        let at = 10_000;
        let mut run = Run::new(
            plant,
            sigma,
            seed,
            Change::PlayStep { at, ratio: 0.5 },
            cfg(1e5),
        );
        let before = alarms(&mut run, at);
        assert!(before.is_empty(), "plant {plant:?} seed {seed}: {before:?}");
        if run.mon.status() != Status::Testing {
            continue;
        }
        tried += 1;
        let after = alarms(&mut run, 4000);
        if let Some(a) = after.first() {
            assert!(a.sample >= at);
            found += 1;
        }
    }
    assert!(tried >= 8 && found == tried, "{found} of {tried}");
}

/// With `follow`, a second step raises a second alarm whose play before is the first one's play after.
#[test]
fn follow_rereferences_after_an_alarm() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 43.0);
    let mut run = Run::new(
        plant,
        sigma,
        1,
        Change::PlayDrift {
            at: 5000,
            rate: 1e-4,
        },
        cfg(1e4),
    );
    let got = alarms(&mut run, 12_000);
    assert!(got.len() >= 2, "{got:?}");
    assert!(got[0].sample >= 5000);
    assert!((got[1].play_before - got[0].play_after).abs() < 1e-12);
    assert!(got[1].play_before > got[0].play_before);
}

/// A reference play given by the user replaces the learned one.
#[test]
fn a_given_reference_play_is_used() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 43.0);
    let c = MonitorConfig {
        reference_play: Some(1.0),
        ..cfg(1e6)
    };
    let mut run = Run::new(plant, sigma, 2, Change::None, c);
    // The true play is 1.5: against a reference of 1.0 that is a 50% growth, found at once.
    let got = alarms(&mut run, 6000);
    assert!(!got.is_empty());
    assert_eq!(got[0].play_before, 1.0);
    assert!(got[0].play_after > 1.1, "{got:?}");
    // Following the alarms, the reference reaches the true play.
    let (p, _) = run.mon.reference().unwrap();
    assert!((p - 1.5).abs() < 0.1, "{p} {got:?}");
}

#[test]
fn learning_and_serde_state_round_trip() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 43.0);
    let mut run = Run::new(plant, sigma, 5, Change::None, cfg(1e6));
    assert_eq!(run.mon.status(), Status::Learning);
    assert_eq!(run.mon.statistic(), 0.0);
    alarms(&mut run, 3000);
    assert_eq!(run.mon.status(), Status::Testing);
    let json = serde_json::to_string(&run.mon).unwrap();
    let back: Monitor = serde_json::from_str(&json).unwrap();
    assert_eq!(back, run.mon);
    back.check().unwrap();
    let mut bad = back.clone();
    if let Some(d) = &mut bad.det {
        d.sigma2 = -1.0;
    }
    assert!(bad.check().is_err());
    // Every CUSUM of the bank is part of the state that is checked.
    let mut bad = back.clone();
    bad.det.as_mut().unwrap().stat[BANK.len() - 1] = -1.0;
    assert!(bad.check().is_err());
    let mut bad = back;
    bad.det.as_mut().unwrap().window[1].sums[0] = f64::NAN;
    assert!(bad.check().is_err());
}

/// The bank spends the false-alarm rate `1 / period` in shares that add up to it: each CUSUM's threshold is
/// the one of a lone CUSUM at the period over its share, higher than at the period itself.
#[test]
fn the_bank_shares_the_false_alarm_rate() {
    assert!((BANK_SHARE.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let plant = PlantParams::PAPER;
    let mut run = Run::new(plant, noise_std(plant, 20.0), 3, Change::None, cfg(1e4));
    alarms(&mut run, 3000);
    let mut d = run.mon.det.clone().expect("testing");
    // The thresholds from the moments as they are now (they are refreshed every REFRESH samples).
    d.refresh_threshold(0.1, 1e4);
    let var = d.projection().2;
    for i in 0..BANK.len() {
        let kl = (BANK[i] * 0.1).powi(2) * var / (2.0 * d.sigma2);
        let own = threshold(kl, 1e4 / BANK_SHARE[i]) / d.tilt[i];
        assert!((d.threshold[i] / own - 1.0).abs() < 1e-9, "{i}: {d:?}");
        assert!(d.threshold[i] > threshold(kl, 1e4) / d.tilt[i]);
    }
    assert!(
        run.mon
            .threshold()
            .is_some_and(|h| (h / d.threshold[0] - 1.0).abs() < 0.05)
    );
}

/// A 10% increase of the linear block's gain at period 1e4: the tracker follows the gain (log gain near
/// ln 1.1) and the alarms come no more often than without a change (before the tracker: one every ~7,800
/// samples, so about 13 in these 100,000).
#[test]
fn a_gain_change_is_tracked_not_called_wear() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    let no_follow = MonitorConfig {
        follow: false,
        ..cfg(1e4)
    };
    let mut total = 0;
    for seed in 0..2u64 {
        let at = 5000;
        let change = Change::LinearGain { at, factor: 1.1 };
        let mut run = Run::new(plant, sigma, 4000 + seed, change, no_follow);
        alarms(&mut run, at);
        total += alarms(&mut run, 50_000).len();
        let gain = run.mon.det.as_ref().unwrap().nuisance.log_gain;
        assert!(
            (gain - 1.1f64.ln()).abs() < 0.01,
            "seed {seed}: log gain {gain}"
        );
    }
    assert!(total <= 3, "{total} alarms");
}

/// The study's test alone after the freeze gives the alarms of the full run (estimator and test).
#[test]
fn the_test_alone_equals_the_full_run_on_a_frozen_reference() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    let no_follow = MonitorConfig {
        follow: false,
        ..cfg(1e3)
    };
    let alone = super::study::false_alarms(plant, sigma, 7, no_follow, 30_000);
    let mut run = Run::new(plant, sigma, 7, Change::None, no_follow);
    run.learn(100_000);
    let full = alarms(&mut run, 30_000).len() as u64;
    assert_eq!(alone, (30_000, full));
    assert!(full > 0, "period 1e3 over 30 periods: some alarms expected");
}

/// The confirmation scans the recent onsets with the play change simulated from each: on records where the
/// confirmation on the CUSUM's excursion with the first-order direction g (before the scan) took 24, 35 and
/// 61 samples to confirm a +50% step (SNR 20, period 1e4), the alarm comes within 15 samples, none before.
#[test]
fn a_large_play_step_is_confirmed_without_waiting_for_the_excursion() {
    let plant = PlantParams::PAPER;
    let sigma = noise_std(plant, 20.0);
    for seed in [1, 3, 8] {
        let step = |at| Change::PlayStep { at, ratio: 0.5 };
        let d = super::study::detect(plant, sigma, seed, cfg(1e4), 2000, 2000, step);
        assert!(!d.early, "seed {seed}: an alarm before the step");
        let delay = d.delay.unwrap_or(u64::MAX);
        assert!(delay <= 15, "seed {seed}: confirmed after {delay} samples");
    }
}
