//! From the raw record to one averaged period: the input's phase reference, the periodic steady state
//! (transient detection) and the periodic averaging of paper 003, eq. (21).
//!
//! # Phase bins
//!
//! Eq. (21) averages `y(t + kT)` over periods, which needs samples at the same phase in every period. A
//! record sampled at `Ts` with `T / Ts` an integer has them; otherwise (or with jittered time stamps) the
//! samples are grouped by phase: the period is cut into `B = round(T / Ts)` bins of width `2 pi / B`
//! centred on the first sample's phase, and each bin's value is the mean of its samples at the mean of their
//! phases. With commensurate sampling every bin holds exactly one sample per period at one phase, so this
//! *is* eq. (21); with incommensurate sampling it is its natural generalisation (the samples of a bin lie
//! within half a bin of its mean phase, which costs a bias of the order of the curvature times `(2 pi/B)^2`).
//!
//! # Steady state
//!
//! Paper 003 takes the record in steady state. A simulated or measured record starts with a transient;
//! it is detected by comparing every full period with the mean of the last half of the periods (the
//! reference, taken to be steady): the mean square difference of period `k`, in units of the noise
//! variance estimated inside the reference, is about `1 + 1/M` for a steady period (`M` reference
//! periods); a period is transient when it exceeds that by more than five standard deviations of the
//! statistic. The steady state starts after the last transient period. Partial periods at the end are
//! dropped. A user may instead give the transient's length in seconds.

use super::FrequencyError;

/// One averaged period, and what it took to get it.
#[derive(Debug, Clone)]
pub(super) struct Folded {
    /// Mean phase of each non-empty bin, rad, on the input's phase scale (`omega t - phi_u`), increasing
    /// over one period.
    pub phase: Vec<f64>,
    /// Averaged output of each bin, eq. (21).
    pub w: Vec<f64>,
    /// Number of samples averaged in each bin.
    pub count: Vec<f64>,
    /// Noise standard deviation of one sample of `y`, estimated in the steady state.
    pub sigma: f64,
    /// Floor under `sigma` (relative to the output's size) so that noise-free records have a scale.
    pub sigma_floor: f64,
    /// Bin width, rad.
    pub delta: f64,
    /// Number of bins per period.
    pub bins: usize,
    /// Steady full periods averaged.
    pub periods_used: usize,
    /// Full periods discarded as transient.
    pub transient_periods: usize,
    pub warnings: Vec<String>,
}

impl Folded {
    /// Noise std of one averaged bin.
    pub fn sigma_bin(&self, j: usize) -> f64 {
        self.sigma.max(self.sigma_floor) / self.count[j].sqrt()
    }
}

/// Robust noise estimate from second differences (used when the steady state has too few periods to
/// pool within-bin variances): for white noise, `y(i+1) - 2 y(i) + y(i-1)` has variance `6 sigma^2`.
fn sigma_from_differences(y: &[f64]) -> f64 {
    if y.len() < 3 {
        return 0.0;
    }
    let d: Vec<f64> = y
        .windows(3)
        .map(|v| (v[2] - 2.0 * v[1] + v[0]).abs())
        .collect();
    let m = crate::stats::median(&d).expect("at least one second difference");
    1.4826 * m / 6f64.sqrt()
}

/// Fold the record: `rho[i] = omega t[i] - phi_u` is each sample's phase, `bins` the number of bins per
/// period, `skip` (rad of phase) an explicit transient to drop, or `None` to detect it.
pub(super) fn fold(
    rho: &[f64],
    y: &[f64],
    bins: usize,
    skip: Option<f64>,
) -> Result<Folded, FrequencyError> {
    let b = bins;
    let delta = std::f64::consts::TAU / b as f64;
    let rho0 = rho[0];
    let scale = y.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
    let sigma_floor = 1e-12 * scale;

    // Global bin index, period, bin in period, offset from the bin centre.
    let mut period = Vec::with_capacity(rho.len());
    let mut bin = Vec::with_capacity(rho.len());
    let mut offset = Vec::with_capacity(rho.len());
    for &r in rho {
        let x = (r - rho0) / delta;
        let g = x.round();
        let gi = g as i64;
        period.push(gi.div_euclid(b as i64) as usize);
        bin.push(gi.rem_euclid(b as i64) as usize);
        offset.push((x - g) * delta);
    }
    let last_global = ((rho[rho.len() - 1] - rho0) / delta).round() as usize;
    let full = (last_global + 1) / b;
    let span = (rho[rho.len() - 1] - rho0) / std::f64::consts::TAU;
    if full == 0 {
        return Err(FrequencyError::NoFullPeriod {
            periods: span,
            transient: 0,
        });
    }
    let mut warnings = Vec::new();

    // Per-bin means over a set of periods.
    let bin_means = |from: usize, to: usize| -> (Vec<f64>, Vec<f64>) {
        let mut s = vec![0.0; b];
        let mut c = vec![0.0; b];
        for i in 0..y.len() {
            if period[i] >= from && period[i] < to {
                s[bin[i]] += y[i];
                c[bin[i]] += 1.0;
            }
        }
        for j in 0..b {
            if c[j] > 0.0 {
                s[j] /= c[j];
            }
        }
        (s, c)
    };
    // Pooled within-bin variance over a set of periods, with its degrees of freedom.
    let pooled = |from: usize, to: usize, mean: &[f64], cnt: &[f64]| -> (f64, f64) {
        let mut ss = 0.0;
        let mut n = 0.0;
        for i in 0..y.len() {
            if period[i] >= from && period[i] < to {
                ss += (y[i] - mean[bin[i]]).powi(2);
                n += 1.0;
            }
        }
        let used = cnt.iter().filter(|&&c| c > 0.0).count() as f64;
        let dof = n - used;
        (if dof > 0.0 { ss / dof } else { 0.0 }, dof)
    };

    let k0 = match skip {
        Some(s) => {
            let k = (s / std::f64::consts::TAU - 1e-9).ceil().max(0.0) as usize;
            if k >= full {
                return Err(FrequencyError::NoFullPeriod {
                    periods: span,
                    transient: k,
                });
            }
            k
        }
        None if full == 1 => {
            warnings.push(
                "only one full period: the steady state could not be checked (record more periods)"
                    .to_string(),
            );
            0
        }
        None => {
            let m_ref = if full >= 4 { full / 2 } else { full.min(2) };
            let from = full - m_ref;
            let (rmean, rcnt) = bin_means(from, full);
            let (var, dof) = pooled(from, full, &rmean, &rcnt);
            let var = if dof >= 0.5 * b as f64 {
                var
            } else {
                sigma_from_differences(y).powi(2)
            };
            let var = var + sigma_floor * sigma_floor;
            let mut ss = vec![0.0; full];
            let mut n = vec![0.0; full];
            for i in 0..y.len() {
                if period[i] < full {
                    ss[period[i]] += (y[i] - rmean[bin[i]]).powi(2);
                    n[period[i]] += 1.0;
                }
            }
            let mut k0 = 0;
            for k in 0..full {
                if n[k] == 0.0 {
                    continue;
                }
                let chi = ss[k] / n[k] / var;
                let thr = (1.0 + 1.0 / m_ref as f64) * (1.0 + 5.0 * (2.0 / n[k]).sqrt());
                if chi > thr {
                    k0 = k + 1;
                }
            }
            k0.min(full - 1)
        }
    };
    if skip.is_none() && k0 > 0 && k0 * 2 > full {
        warnings.push(format!(
            "the transient took {k0} of {full} full periods: record more periods so that the steady \
             state dominates the record"
        ));
    }

    let (mean, cnt) = bin_means(k0, full);
    let (var, dof) = pooled(k0, full, &mean, &cnt);
    let sigma = if dof >= 0.5 * b as f64 {
        var.sqrt()
    } else {
        let steady: Vec<f64> = (0..y.len())
            .filter(|&i| period[i] >= k0 && period[i] < full)
            .map(|i| y[i])
            .collect();
        sigma_from_differences(&steady)
    };
    // Mean phase offsets.
    let mut off = vec![0.0; b];
    for i in 0..y.len() {
        if period[i] >= k0 && period[i] < full {
            off[bin[i]] += offset[i];
        }
    }
    let mut out = Folded {
        phase: Vec::with_capacity(b),
        w: Vec::with_capacity(b),
        count: Vec::with_capacity(b),
        sigma,
        sigma_floor,
        delta,
        bins: b,
        periods_used: full - k0,
        transient_periods: k0,
        warnings,
    };
    for j in 0..b {
        if cnt[j] > 0.0 {
            out.phase.push(rho0 + j as f64 * delta + off[j] / cnt[j]);
            out.w.push(mean[j]);
            out.count.push(cnt[j]);
        }
    }
    if out.w.len() < b {
        out.warnings.push(format!(
            "{} of {b} phase bins are empty (sampling incommensurate with the period and few periods)",
            b - out.w.len()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commensurate_averaging_is_eq_21() {
        // 10 samples per period, 5 periods, the first two periods carry a decaying offset.
        let b = 10;
        let w = 0.7;
        let ts = std::f64::consts::TAU / w / b as f64;
        let n = 5 * b;
        let rho: Vec<f64> = (0..n).map(|i| w * i as f64 * ts).collect();
        let base = |j: usize| (j as f64 * 0.9).sin();
        let y: Vec<f64> = (0..n)
            .map(|i| base(i % b) + if i < 2 * b { 1.0 } else { 0.0 })
            .collect();
        let f = fold(&rho, &y, b, None).unwrap();
        assert_eq!(f.transient_periods, 2);
        assert_eq!(f.periods_used, 3);
        for j in 0..b {
            assert!((f.w[j] - base(j)).abs() < 1e-14);
            assert!((f.phase[j] - j as f64 * std::f64::consts::TAU / b as f64).abs() < 1e-12);
            assert_eq!(f.count[j], 3.0);
        }
        // Explicit transient: one period of phase dropped.
        let f = fold(&rho, &y, b, Some(std::f64::consts::TAU)).unwrap();
        assert_eq!(f.transient_periods, 1);
    }

    #[test]
    fn too_short_a_record_is_refused() {
        let rho: Vec<f64> = (0..5).map(|i| i as f64 * 0.5).collect();
        let y = vec![0.0; 5];
        assert!(matches!(
            fold(&rho, &y, 12, None),
            Err(FrequencyError::NoFullPeriod { .. })
        ));
    }

    #[test]
    fn difference_noise_estimate() {
        // Deterministic pseudo-noise with known std: alternating +-s has second differences 4 s.
        let y: Vec<f64> = (0..101)
            .map(|i| if i % 2 == 0 { 0.1 } else { -0.1 })
            .collect();
        let s = sigma_from_differences(&y);
        assert!((s - 1.4826 * 0.4 / 6f64.sqrt()).abs() < 1e-12);
    }
}
