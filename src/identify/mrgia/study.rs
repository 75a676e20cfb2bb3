//! The numerical example of paper 000, section 4, as a reusable study (for tests, the CLI and docs/RESULTS.md).

use super::{Estimate, Mrgia, MrgiaConfig};
use crate::plant::{Plant, PlantParams};
use crate::stats::std_dev;
use rand_chacha::ChaCha8Rng;
use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardUniform};

/// Variance of the paper's input, section 4 ("bounded white noise with the variance 1.93").
pub const PAPER_INPUT_VARIANCE: f64 = 1.93;

/// Offset between the input seed and the noise seed of a study run (distinct ChaCha8 streams, so that the
/// input and the noise are independent).
const NOISE_SEED_OFFSET: u64 = 0x5EED_0000_0000;

/// The paper's input: `n` samples of white noise uniform on `[-A, A]`, `A = sqrt(3 * 1.93)` (variance 1.93),
/// from a ChaCha8 generator seeded with `seed`.
pub fn paper_input(n: usize, seed: u64) -> Vec<f64> {
    let amp = (3.0 * PAPER_INPUT_VARIANCE).sqrt();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let r: f64 = StandardUniform.sample(&mut rng);
            amp * (2.0 * r - 1.0)
        })
        .collect()
}

/// Largest relative error over the estimated parameters a_1..a_na, b_0..b_nb, m2, c1, c2 against the plant's
/// (m1 = 1 is the normalisation, the truth is taken as is); a parameter whose true value is 0 counts by its
/// absolute error.
pub fn max_rel_error(est: &Estimate, truth: &PlantParams) -> f64 {
    let bl = &truth.backlash;
    let pairs = est
        .a
        .iter()
        .zip(truth.arx.a.iter())
        .chain(est.b.iter().zip(truth.arx.b.iter()))
        .map(|(e, t)| (*e, *t))
        .chain([(est.m2, bl.m2), (est.c1, bl.c1), (est.c2, bl.c2)]);
    pairs
        .map(|(e, t)| {
            let err = (e - t).abs();
            if t != 0.0 { err / t.abs() } else { err }
        })
        .fold(0.0, f64::max)
}

/// The paper's study: for each seed `s` in `0..seeds`, the paper plant (`PlantParams::PAPER`) driven by
/// [`paper_input`]`(max ns, s)`; with `snr = Some(r)` white Gaussian noise of standard deviation
/// `std(w) / r` (w the noise-free output over the whole record, seed `s + 0x5EED_0000_0000`) is added, as in
/// the paper's "SNR 43". The estimator with `cfg_of(noise_std)` (0 when noise-free) runs over the record, and
/// the result `r[i][s]` is [`max_rel_error`] after `ns[i]` samples.
pub fn paper_study_with(
    seeds: u64,
    ns: &[usize],
    cfg_of: impl Fn(f64) -> MrgiaConfig,
    snr: Option<f64>,
) -> Vec<Vec<f64>> {
    let n_max = ns.iter().copied().max().unwrap_or(0);
    let truth = PlantParams::PAPER;
    let mut out = vec![Vec::with_capacity(seeds as usize); ns.len()];
    for s in 0..seeds {
        let u = paper_input(n_max, s);
        let clean = Plant::simulate(truth, &u).expect("the paper plant is valid");
        let (y, noise_std): (Vec<f64>, f64) = match snr {
            None => (clean.iter().map(|o| o.w).collect(), 0.0),
            Some(r) => {
                let w: Vec<f64> = clean.iter().map(|o| o.w).collect();
                let std = std_dev(&w) / r;
                let mut p = truth;
                p.noise_std = std;
                p.noise_seed = s.wrapping_add(NOISE_SEED_OFFSET);
                let noisy = Plant::simulate(p, &u).expect("noise std is finite");
                (noisy.iter().map(|o| o.y).collect(), std)
            }
        };
        let mut est = Mrgia::new(cfg_of(noise_std)).expect("study configuration is valid");
        let mut done = 0;
        let mut order: Vec<usize> = (0..ns.len()).collect();
        order.sort_by_key(|&i| ns[i]);
        let mut results = vec![0.0; ns.len()];
        for &i in &order {
            while done < ns[i] {
                est.update(u[done], y[done]);
                done += 1;
            }
            results[i] = max_rel_error(&est.estimate(), &truth);
        }
        for (o, r) in out.iter_mut().zip(results) {
            o.push(r);
        }
    }
    out
}

/// [`paper_study_with`] for a configuration that does not depend on the noise level.
pub fn paper_study(
    seeds: u64,
    ns: &[usize],
    cfg_of: impl Fn() -> MrgiaConfig,
    snr: Option<f64>,
) -> Vec<Vec<f64>> {
    paper_study_with(seeds, ns, |_| cfg_of(), snr)
}

/// (min, median, max) of a sample (median of an even count: mean of the two middle values).
pub fn summary(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let m = s.len() / 2;
    let med = if s.len().is_multiple_of(2) {
        0.5 * (s[m - 1] + s[m])
    } else {
        s[m]
    };
    (s[0], med, s[s.len() - 1])
}
