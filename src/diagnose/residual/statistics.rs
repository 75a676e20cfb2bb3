//! The statistics of the decision: the Diebold-Mariano comparison of two forecasts, least-squares AR fits of
//! a residual, and whether the input carries a frequency (so that a residual peak there belongs to the
//! model's structure, not to a disturbance).

use nalgebra::{DMatrix, DVector};

/// Diebold-Mariano statistic for "e1 has smaller squared errors than e0": the mean of d = e0^2 - e1^2 over
/// its standard error, with a Bartlett (Newey-West) long-run variance over floor(n^(1/3)) lags so that
/// autocorrelated errors do not inflate it. Fewer than 2 pairs: 0 (no evidence). A zero long-run variance:
/// +infinity when the mean is positive (every error smaller), else 0.
pub fn diebold_mariano(e0: &[f64], e1: &[f64]) -> f64 {
    let d: Vec<f64> = e0.iter().zip(e1).map(|(a, b)| a * a - b * b).collect();
    let n = d.len();
    if n < 2 {
        return 0.0;
    }
    let nf = n as f64;
    let mean = d.iter().sum::<f64>() / nf;
    let c: Vec<f64> = d.iter().map(|v| v - mean).collect();
    let lags = (nf.cbrt().floor() as usize).min(n - 1);
    // The autocovariances at lags 0..=lags, their sums side by side in one pass per group of lags.
    let gamma: Vec<f64> = crate::stats::lagged_sums(&c, &c, 0..lags + 1)
        .into_iter()
        .map(|s| s / nf)
        .collect();
    let mut v = gamma[0];
    for (l, g) in gamma.iter().enumerate().skip(1) {
        v += 2.0 * (1.0 - l as f64 / (lags + 1) as f64) * g;
    }
    if v <= 0.0 {
        return if mean > 0.0 { f64::INFINITY } else { 0.0 };
    }
    mean / (v / nf).sqrt()
}

/// Least-squares AR(order) coefficients of e, conditional on the first `order` values:
/// e(k) = sum_i phi_i e(k-i) + v(k) for k >= order. `None` when the normal equations are singular (a
/// constant zero residual) or `order` is 0 or not below the length.
pub fn ar_ls(e: &[f64], order: usize) -> Option<Vec<f64>> {
    if order == 0 || order >= e.len() {
        return None;
    }
    let mut h = DMatrix::<f64>::zeros(order, order);
    let mut g = DVector::<f64>::zeros(order);
    for k in order..e.len() {
        for a in 0..order {
            g[a] += e[k - 1 - a] * e[k];
            for b in 0..order {
                h[(a, b)] += e[k - 1 - a] * e[k - 1 - b];
            }
        }
    }
    let th = h.cholesky()?.solve(&g);
    th.iter()
        .all(|v| v.is_finite())
        .then(|| th.iter().copied().collect())
}

/// The innovations of e under an AR model: v(k) = e(k) - sum_i phi_i e(k-i), with e = 0 before the start.
pub fn ar_filter(e: &[f64], phi: &[f64]) -> Vec<f64> {
    (0..e.len())
        .map(|k| {
            let mut v = e[k];
            for (i, p) in phi.iter().enumerate() {
                if k > i {
                    v -= p * e[k - 1 - i];
                }
            }
            v
        })
        .collect()
}

/// How strongly the (mean-removed) input carries the frequency `omega` [rad/sample]: its periodogram at
/// omega (the largest of the padded ordinates within one Fourier spacing of it, for leakage) over the
/// median of its periodogram. A white input gives a few; a periodic input at one of its harmonics gives
/// hundreds or more. A constant input or fewer than 8 samples: 0.
pub fn input_line_ratio(u: &[f64], omega: f64) -> f64 {
    if u.len() < 8 {
        return 0.0;
    }
    let (w, p) = crate::diagnose::residual::periodogram(u, true);
    let Some(med) = crate::stats::quantile(&p, 0.5) else {
        return 0.0;
    };
    let spacing = 2.0 * std::f64::consts::PI / u.len() as f64;
    let at = w
        .iter()
        .zip(&p)
        .filter(|(wi, _)| (**wi - omega).abs() <= spacing)
        .map(|(_, pi)| *pi)
        .fold(0.0f64, f64::max);
    if med > 0.0 {
        at / med
    } else if at > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// Above this [`input_line_ratio`] the input carries the frequency: a residual peak there is model error
/// driven by the input.
pub const INPUT_LINE_RATIO: f64 = 20.0;

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;
    use rand_distr::{Distribution, Uniform};

    // Reference numbers computed independently in Python (NumPy, statsmodels 0.14 `AutoReg(trend="n")`,
    // scipy) from the same series; see each test.

    /// `z` of the NumPy computation (mean of d over sqrt(v / n), v the Bartlett long-run variance, 5 lags).
    const DM_REF: f64 = 12.270749529068988;
    /// statsmodels `AutoReg(e0, lags=2, trend="n").fit().params` on `pair(300).0`.
    const AR2_REF: [f64; 2] = [0.5520844762859931, -0.9936045624547709];

    /// A fixed series: e0(k) = sin(1.3 k) + 0.5 cos(0.7 k^1.1), e1(k) = 0.8 e0(k) + 0.1 sin(3.1 k).
    fn pair(n: usize) -> (Vec<f64>, Vec<f64>) {
        let e0: Vec<f64> = (0..n)
            .map(|k| {
                let k = k as f64;
                (1.3 * k).sin() + 0.5 * (0.7 * k.powf(1.1)).cos()
            })
            .collect();
        let e1 = e0
            .iter()
            .enumerate()
            .map(|(k, v)| 0.8 * v + 0.1 * (3.1 * k as f64).sin())
            .collect();
        (e0, e1)
    }

    #[test]
    fn diebold_mariano_matches_an_independent_computation() {
        let (e0, e1) = pair(200);
        // numpy: d = e0**2 - e1**2; L = floor(200**(1/3)) = 5; Bartlett weights 1 - l/6; z = mean / sqrt(v/n)
        let z = diebold_mariano(&e0, &e1);
        assert!((z - DM_REF).abs() < 1e-9 * DM_REF.abs(), "{z}");
        // Symmetry and degenerate cases.
        assert!((diebold_mariano(&e1, &e0) + z).abs() < 1e-12 * z.abs());
        assert_eq!(diebold_mariano(&[1.0], &[0.0]), 0.0);
        assert_eq!(diebold_mariano(&[], &[]), 0.0);
        assert_eq!(
            diebold_mariano(&[1.0, 1.0, 1.0], &[0.0, 0.0, 0.0]),
            f64::INFINITY
        );
        assert_eq!(diebold_mariano(&[0.0, 0.0, 0.0], &[1.0, 1.0, 1.0]), 0.0);
    }

    #[test]
    fn diebold_mariano_by_hand_on_two_pairs_and_on_equal_errors() {
        // d = [1, 4], mean 2.5, centred [-1.5, 1.5]; one lag (floor of the cube root of 2), Bartlett weight
        // 1/2: v = 2.25 + 2 (1/2) (-1.125) = 1.125, z = 2.5 / sqrt(1.125 / 2) = 10/3.
        let z = diebold_mariano(&[1.0, 2.0], &[0.0, 0.0]);
        assert!((z - 10.0 / 3.0).abs() < 1e-12, "{z}");
        // Identical errors are no evidence either way.
        let (e0, _) = pair(50);
        assert_eq!(diebold_mariano(&e0, &e0), 0.0);
    }

    #[test]
    fn ar_ls_matches_statsmodels_autoreg() {
        let (e0, _) = pair(300);
        let phi = ar_ls(&e0, 2).unwrap();
        for (a, b) in phi.iter().zip(AR2_REF) {
            assert!((a - b).abs() < 1e-10, "{phi:?}");
        }
        assert_eq!(ar_ls(&[0.0; 50], 1), None);
        assert_eq!(ar_ls(&e0, 0), None);
        assert_eq!(ar_ls(&e0[..2], 2), None);
        let v = ar_filter(&[1.0, 2.0, 3.0], &[0.5]);
        assert_eq!(v, vec![1.0, 1.5, 2.0]);
    }

    #[test]
    fn input_line_ratio_sees_a_periodic_input_only() {
        let n = 2000;
        let w = 2.0 * std::f64::consts::PI / 50.0;
        let periodic: Vec<f64> = (0..n).map(|k| (w * k as f64).sin()).collect();
        assert!(input_line_ratio(&periodic, w) > 1000.0);
        // Pseudo-random input: no line anywhere.
        let uniform = Uniform::new(-0.5, 0.5).expect("a finite, non-empty range");
        let mut rng = ChaCha8Rng::seed_from_u64(12345);
        let noise: Vec<f64> = (0..n).map(|_| uniform.sample(&mut rng)).collect();
        assert!(input_line_ratio(&noise, w) < INPUT_LINE_RATIO);
        // Far from the input's line the ratio is small: only ordinates within one Fourier spacing count.
        assert!(input_line_ratio(&periodic, 2.0) < 1.0);
        // Eight samples are enough to see a line; seven are not looked at.
        let quarter: Vec<f64> = (0..8)
            .map(|k| (std::f64::consts::FRAC_PI_2 * k as f64).sin())
            .collect();
        assert!(input_line_ratio(&quarter, std::f64::consts::FRAC_PI_2) > 1.0);
        assert_eq!(
            input_line_ratio(&quarter[..7], std::f64::consts::FRAC_PI_2),
            0.0
        );
        assert_eq!(input_line_ratio(&[2.0; 100], w), 0.0);
        assert_eq!(input_line_ratio(&[1.0; 4], w), 0.0);
    }
}
