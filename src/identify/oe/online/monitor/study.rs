//! Measuring the wear monitor: records of any length with a known change (or none), streamed sample by
//! sample, and the runs of the study (false-alarm run lengths, detection delays, the threshold rule on the
//! estimate and the Kullback-Leibler bound). `examples/monitor_study.rs` prints the tables of docs/RESULTS.md.
//!
//! A record is the paper input (white, uniform, variance 1.93; ChaCha8 seeded by the seed) through a plant
//! with white Gaussian noise of standard deviation `std(w) / snr` (w the noise-free output of 20000 samples
//! of the unchanged plant, as in the other studies). The change acts from sample `at` on.

use super::{Alarm, Monitor, MonitorConfig, Window, play_of};
use crate::identify::mrgia::{MrgiaConfig, PAPER_INPUT_VARIANCE};
use crate::identify::oe::online::{RING, Refined};
use crate::plant::{BacklashParams, Plant, PlantParams};
use crate::stats::std_dev;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardUniform};

/// Samples of the pilot run that sets the noise level.
const PILOT: usize = 20_000;
/// Seed offset of the plant's noise stream (independent of the input stream).
const NOISE_SEED_OFFSET: u64 = 0x5EED_0000_0000;

/// What changes at sample `at`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    None,
    /// Both gaps scaled by `1 + ratio`.
    PlayStep {
        at: u64,
        ratio: f64,
    },
    /// Both gaps scaled by `1 + rate (k - at)` from `at` on.
    PlayDrift {
        at: u64,
        rate: f64,
    },
    /// The input's amplitude multiplied by `factor` (the monitor sees the new input).
    InputAmplitude {
        at: u64,
        factor: f64,
    },
    /// The linear block's gain multiplied by `factor` (the monitor sees the old input: an unmodelled change).
    LinearGain {
        at: u64,
        factor: f64,
    },
    /// A constant added to the measured output.
    OutputOffset {
        at: u64,
        offset: f64,
    },
}

/// A streamed record (module docs).
pub struct Scenario {
    plant: Plant,
    base: BacklashParams,
    rng: ChaCha8Rng,
    amp: f64,
    change: Change,
    k: u64,
}

/// Noise standard deviation of `plant` at `snr` (module docs).
pub fn noise_std(plant: PlantParams, snr: f64) -> f64 {
    let u = paper_input_stream(0).take(PILOT).collect::<Vec<_>>();
    let w: Vec<f64> = Plant::simulate(plant, &u)
        .expect("valid plant")
        .iter()
        .map(|o| o.w)
        .collect();
    std_dev(&w) / snr
}

fn paper_input_stream(seed: u64) -> impl Iterator<Item = f64> {
    let amp = (3.0 * PAPER_INPUT_VARIANCE).sqrt();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    std::iter::repeat_with(move || {
        let r: f64 = StandardUniform.sample(&mut rng);
        amp * (2.0 * r - 1.0)
    })
}

impl Scenario {
    /// `plant` (noise-free parameters) with noise `sigma`, input and noise streams from `seed`.
    pub fn new(plant: PlantParams, sigma: f64, seed: u64, change: Change) -> Self {
        let mut p = plant;
        p.noise_std = sigma;
        p.noise_seed = seed.wrapping_add(NOISE_SEED_OFFSET);
        Self {
            plant: Plant::new(p).expect("valid plant"),
            base: plant.backlash,
            rng: ChaCha8Rng::seed_from_u64(seed),
            amp: (3.0 * PAPER_INPUT_VARIANCE).sqrt(),
            change,
            k: 0,
        }
    }

    fn scale_gaps(&mut self, f: f64) {
        let b = BacklashParams {
            c1: self.base.c1 * f,
            c2: self.base.c2 * f,
            ..self.base
        };
        self.plant.set_backlash(b).expect("scaled gaps are valid");
    }

    /// Sample k: (u(k), y(k)) as the monitor sees them.
    pub fn next_sample(&mut self) -> (f64, f64) {
        let k = self.k;
        let r: f64 = StandardUniform.sample(&mut self.rng);
        let mut u = self.amp * (2.0 * r - 1.0);
        let (mut into_plant, mut offset) = (1.0, 0.0);
        match self.change {
            Change::PlayStep { at, ratio } if k == at => self.scale_gaps(1.0 + ratio),
            Change::PlayDrift { at, rate } if k >= at => {
                self.scale_gaps(1.0 + rate * (k - at) as f64)
            }
            Change::InputAmplitude { at, factor } if k >= at => u *= factor,
            Change::LinearGain { at, factor } if k >= at => into_plant = factor,
            Change::OutputOffset { at, offset: o } if k >= at => offset = o,
            _ => {}
        }
        let y = self.plant.output().y + offset;
        self.plant.advance(into_plant * u);
        self.k += 1;
        (u, y)
    }
}

/// The estimator setting the study's monitor runs on: MRGIA's recommended setting for the refine warm-up
/// (the paper's setting does not converge on every input), no forgetting.
pub fn estimator_config(plant: &PlantParams) -> MrgiaConfig {
    MrgiaConfig::recommended(plant.arx.na, plant.arx.nb, plant.arx.delay)
}

/// A monitor and its estimator on one record, sample by sample.
pub struct Run {
    pub est: Refined,
    pub mon: Monitor,
    pub scenario: Scenario,
    pub k: u64,
}

impl Run {
    pub fn new(
        plant: PlantParams,
        sigma: f64,
        seed: u64,
        change: Change,
        cfg: MonitorConfig,
    ) -> Self {
        Self {
            est: Refined::new(estimator_config(&plant)).expect("valid setting"),
            mon: Monitor::new(cfg).expect("valid monitor setting"),
            scenario: Scenario::new(plant, sigma, seed, change),
            k: 0,
        }
    }

    /// One sample; the alarm it raised.
    pub fn step(&mut self) -> Option<Alarm> {
        let (u, y) = self.scenario.next_sample();
        let (_, a) = self.mon.update(&mut self.est, self.k as f64, u, y);
        self.k += 1;
        a
    }

    /// Samples until the reference is frozen (at most `limit`); whether it was.
    pub fn learn(&mut self, limit: u64) -> bool {
        while self.mon.reference().is_none() && self.k < limit {
            self.step();
        }
        self.mon.reference().is_some()
    }

    /// The play estimate of the running estimator (for the threshold rule).
    pub fn play(&self) -> f64 {
        play_of(&self.est).0
    }
}

/// Per-sample Kullback-Leibler distance of a play step by `ratio` on `plant` at noise `sigma`:
/// `mean (w1 - w0)^2 / (2 sigma^2)` over `n` samples of the paper input, w0 and w1 the noise-free outputs of
/// the plant and of the plant with both gaps scaled by `1 + ratio`.
pub fn kl_per_sample(plant: PlantParams, ratio: f64, sigma: f64, n: usize) -> f64 {
    let u: Vec<f64> = paper_input_stream(1).take(n).collect();
    let mut changed = plant;
    changed.backlash.c1 *= 1.0 + ratio;
    changed.backlash.c2 *= 1.0 + ratio;
    let w0 = Plant::simulate(plant, &u).expect("valid plant");
    let w1 = Plant::simulate(changed, &u).expect("valid plant");
    let ss: f64 = w0.iter().zip(&w1).map(|(a, b)| (a.w - b.w).powi(2)).sum();
    ss / n as f64 / (2.0 * sigma * sigma)
}

/// The lower bound on the mean detection delay of a step with per-sample distance `kl` at mean false-alarm
/// period `period`: `ln(period) / kl` (Lorden).
pub fn step_delay_bound(kl: f64, period: f64) -> f64 {
    period.ln() / kl
}

/// The same for a linear drift whose distance after j samples is `kl_unit (rate j / unit)^2`, with
/// `kl_unit` the distance of a step by `unit`: the log-likelihood ratio of a known drift accumulates
/// `sum_{j<=n} kl_unit (rate j / unit)^2 ~ kl_unit (rate / unit)^2 n^3 / 3`, which reaches `ln(period)` at
/// `n = (3 ln(period) / (kl_unit (rate / unit)^2))^(1/3)`.
pub fn drift_delay_bound(kl_unit: f64, unit: f64, rate: f64, period: f64) -> f64 {
    (3.0 * period.ln() / (kl_unit * (rate / unit).powi(2))).cbrt()
}

/// Inputs the test alone keeps after the freeze: a ring longer than the longest lag (delay 64 + nb 4).
const LAGS: usize = 128;

/// Run lengths between false alarms on an unchanged record of `samples` samples after the reference
/// (the test restarts on the same reference after each alarm): (samples tested, alarms). After the freeze
/// only the test runs ([`Monitor::test_sample`]): the estimator is not needed for a frozen reference, and
/// the study costs half as much per sample.
pub fn false_alarms(
    plant: PlantParams,
    sigma: f64,
    seed: u64,
    cfg: MonitorConfig,
    samples: u64,
) -> (u64, u64) {
    let cfg = MonitorConfig {
        follow: false,
        ..cfg
    };
    let mut run = Run::new(plant, sigma, seed, Change::None, cfg);
    if !run.learn(100_000) {
        return (0, 0);
    }
    let delay = run.mon.input_delay().expect("the reference is frozen");
    let mut ring = [0.0; LAGS];
    for back in 1..=LAGS.min(RING) as u64 {
        if let Some(k) = run.k.checked_sub(back) {
            ring[k as usize % LAGS] = run.est.u_ring[k as usize % RING];
        }
    }
    let start = run.k;
    let mut alarms = 0;
    for k in start..start + samples {
        let (u, y) = run.scenario.next_sample();
        let lag = |j: usize| {
            let l = (delay + j) as u64;
            if k >= l {
                ring[(k - l) as usize % LAGS]
            } else {
                0.0
            }
        };
        alarms += u64::from(run.mon.test_sample((k, k as f64), lag, y).is_some());
        ring[k as usize % LAGS] = u;
    }
    (samples, alarms)
}

/// Mean run length and its 95% interval from `samples` tested and `alarms` (exponential run lengths: the
/// chi-square interval of a Poisson count).
pub fn arl_interval(samples: u64, alarms: u64) -> (f64, f64, f64) {
    let n = alarms as f64;
    let s = samples as f64;
    if alarms == 0 {
        return (f64::INFINITY, s / 3.689, f64::INFINITY);
    }
    // Wilson-Hilferty approximations of the chi-square quantiles with 2n and 2n + 2 degrees of freedom.
    let q =
        |dof: f64, z: f64| dof * (1.0 - 2.0 / (9.0 * dof) + z * (2.0 / (9.0 * dof)).sqrt()).powi(3);
    let lo = 2.0 * s / q(2.0 * n + 2.0, 1.959964);
    let hi = 2.0 * s / q(2.0 * n, -1.959964);
    (s / n, lo, hi)
}

/// One detection run: the change at `at` samples after the reference; the delay of the first alarm after
/// the change (None if none within `horizon`), the alarm, and whether a false alarm came before the change.
pub struct Detection {
    pub delay: Option<u64>,
    pub alarm: Option<Alarm>,
    pub early: bool,
    /// The change's sample index.
    pub at: u64,
    /// The monitor's information per sample about the play growth at the change
    /// ([`Monitor::play_information`]).
    pub information: Option<f64>,
}

/// `change_at(reference_sample)` builds the change relative to the sample at which the reference froze.
pub fn detect(
    plant: PlantParams,
    sigma: f64,
    seed: u64,
    cfg: MonitorConfig,
    after: u64,
    horizon: u64,
    change: impl Fn(u64) -> Change,
) -> Detection {
    // The reference freezes at the same sample whatever the change (the change comes after it), so a
    // pilot without change finds that sample.
    let cfg = MonitorConfig {
        follow: false,
        ..cfg
    };
    let mut pilot = Run::new(plant, sigma, seed, Change::None, cfg);
    pilot.learn(100_000);
    let at = pilot.k + after;
    let mut run = Run::new(plant, sigma, seed, change(at), cfg);
    let mut early = false;
    let mut information = None;
    while run.k < at + horizon {
        if run.k == at {
            information = run.mon.play_information();
        }
        if let Some(a) = run.step() {
            if run.k <= at {
                early = true;
                continue;
            }
            return Detection {
                delay: Some(run.k - 1 - at),
                alarm: Some(a),
                early,
                at,
                information,
            };
        }
    }
    Detection {
        delay: None,
        alarm: None,
        early,
        at,
        information,
    }
}

/// The comparison rule: the refined estimate with forgetting `rho_min` (the estimator FMU's `refine` with a
/// floor on rho, as for tracking wear), alarming when its play exceeds the play at the reference sample by
/// `tau`.
pub struct ThresholdRule {
    est: Refined,
    scenario: Scenario,
    k: u64,
    reference: Option<f64>,
    freeze: u64,
}

impl ThresholdRule {
    /// The reference play is the estimate's at sample `freeze`.
    pub fn new(
        plant: PlantParams,
        sigma: f64,
        seed: u64,
        change: Change,
        rho_min: f64,
        freeze: u64,
    ) -> Self {
        let cfg = MrgiaConfig {
            rho_min,
            ..estimator_config(&plant)
        };
        Self {
            est: Refined::new(cfg).expect("valid setting"),
            scenario: Scenario::new(plant, sigma, seed, change),
            k: 0,
            reference: None,
            freeze,
        }
    }

    /// One sample: the play estimate minus the reference (None before the reference).
    pub fn step(&mut self) -> Option<f64> {
        let (u, y) = self.scenario.next_sample();
        self.est.update(u, y);
        self.k += 1;
        let play = play_of(&self.est).0;
        if self.k == self.freeze {
            self.reference = Some(play);
        }
        self.reference.map(|r| play - r)
    }

    pub fn sample(&self) -> u64 {
        self.k
    }
}

/// Up-crossings of each of `taus` by the rule's deviation over `samples` samples after `freeze` on an
/// unchanged record: the rule's mean run length at tau is about `samples / crossings`.
pub fn rule_crossings(
    plant: PlantParams,
    sigma: f64,
    seed: u64,
    rho_min: f64,
    freeze: u64,
    samples: u64,
    taus: &[f64],
) -> Vec<u64> {
    let mut rule = ThresholdRule::new(plant, sigma, seed, Change::None, rho_min, freeze);
    let mut above = vec![false; taus.len()];
    let mut count = vec![0u64; taus.len()];
    while rule.sample() < freeze + samples {
        let Some(dev) = rule.step() else { continue };
        for ((t, a), c) in taus.iter().zip(&mut above).zip(&mut count) {
            let now = dev > *t;
            *c += u64::from(now && !*a);
            *a = now;
        }
    }
    count
}

/// Delay of the rule at `tau` for a change at `at` (None: no alarm within `horizon`; a crossing before the
/// change is ignored, as the monitor's early alarms are).
#[expect(
    clippy::too_many_arguments,
    reason = "the study's cell: plant, noise, seed, rule, change"
)]
pub fn rule_delay(
    plant: PlantParams,
    sigma: f64,
    seed: u64,
    rho_min: f64,
    freeze: u64,
    tau: f64,
    change: Change,
    at: u64,
    horizon: u64,
) -> Option<u64> {
    let mut rule = ThresholdRule::new(plant, sigma, seed, change, rho_min, freeze);
    while rule.sample() < at + horizon {
        let dev = rule.step();
        if rule.sample() > at && dev.is_some_and(|d| d > tau) {
            return Some(rule.sample() - 1 - at);
        }
    }
    None
}

/// The information as it arrives, for a change at sample `at` of record `seed`: the samples after the change
/// until the expected log-likelihood ratio of an oracle that knows the plant, the change and its time reaches
/// `ln(period)`, i.e. the first n with `sum_{at <= k <= at + n} d(k)^2 / (2 sigma^2) >= ln(period)`, d = w1 - w0
/// the difference of the noise-free outputs with and without `change` (a play change shows in the output
/// only once the backlash is engaged again after it). Two such delays: with the offset and the linear gain
/// known (d as it is), and with an offset and a gain change allowed at the change time (d' the residual of d
/// after least squares on (1, h) over the samples since the change, h the output's sensitivity to the log of
/// the linear block's gain): what a detector that must not call an offset or a gain change play can use. A
/// play step looks like an offset step as long as the backlash stays engaged on one side, so the second
/// waits for a reversal. None if not reached within `horizon` samples.
pub fn arrival_delays(
    plant: PlantParams,
    sigma: f64,
    seed: u64,
    change: Change,
    at: u64,
    (period, horizon): (f64, u64),
) -> (Option<u64>, Option<u64>) {
    /// Relative gain change of the finite difference for h.
    const EPS: f64 = 1e-6;
    let mut changed = Scenario::new(plant, 0.0, seed, change);
    let mut same = Scenario::new(plant, 0.0, seed, Change::None);
    let gain = Change::LinearGain {
        at: 0,
        factor: 1.0 + EPS,
    };
    let mut scaled = Scenario::new(plant, 0.0, seed, gain);
    let (ln_p, two_s2) = (period.ln(), 2.0 * sigma * sigma);
    let (mut known, mut efficient) = (None, None);
    let (mut llr, mut window) = (0.0, Window::default());
    for k in 0..at + horizon {
        let (w1, w0, wg) = (
            changed.next_sample().1,
            same.next_sample().1,
            scaled.next_sample().1,
        );
        if k < at {
            continue;
        }
        let d = w1 - w0;
        llr += d * d / two_s2;
        window.add(d, (wg - w0) / EPS, d);
        if known.is_none() && llr >= ln_p {
            known = Some(k - at);
        }
        if efficient.is_none() && window.projected().1 / two_s2 >= ln_p {
            efficient = Some(k - at);
        }
        if efficient.is_some() && known.is_some() {
            break;
        }
    }
    (known, efficient)
}
