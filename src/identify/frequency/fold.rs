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

/// Each sample's place on the phase grid: its period, its bin in the period and its offset from the bin's
/// centre (rad), with the output it carries.
struct Grid<'a> {
    y: &'a [f64],
    period: Vec<usize>,
    bin: Vec<usize>,
    offset: Vec<f64>,
    bins: usize,
}

impl<'a> Grid<'a> {
    /// Place the samples of phases `rho` on bins of width `delta` centred on the first sample's phase.
    fn new(rho: &[f64], y: &'a [f64], bins: usize, delta: f64) -> Self {
        let b = bins as i64;
        let mut grid = Grid {
            y,
            period: Vec::with_capacity(rho.len()),
            bin: Vec::with_capacity(rho.len()),
            offset: Vec::with_capacity(rho.len()),
            bins,
        };
        for &r in rho {
            let x = (r - rho[0]) / delta;
            let g = x.round();
            let gi = g as i64;
            grid.period.push(gi.div_euclid(b) as usize);
            grid.bin.push(gi.rem_euclid(b) as usize);
            grid.offset.push((x - g) * delta);
        }
        grid
    }

    /// The samples of the periods `from..to`.
    fn within(&self, from: usize, to: usize) -> impl Iterator<Item = usize> + '_ {
        (0..self.y.len()).filter(move |&i| self.period[i] >= from && self.period[i] < to)
    }

    /// Per-bin means and counts over the periods `from..to`.
    fn bin_means(&self, from: usize, to: usize) -> (Vec<f64>, Vec<f64>) {
        let mut s = vec![0.0; self.bins];
        let mut c = vec![0.0; self.bins];
        for i in self.within(from, to) {
            s[self.bin[i]] += self.y[i];
            c[self.bin[i]] += 1.0;
        }
        for (s, &c) in s.iter_mut().zip(&c) {
            if c > 0.0 {
                *s /= c;
            }
        }
        (s, c)
    }

    /// Pooled within-bin variance over the periods `from..to`, with its degrees of freedom.
    fn pooled(&self, from: usize, to: usize, mean: &[f64], cnt: &[f64]) -> (f64, f64) {
        let mut ss = 0.0;
        let mut n = 0.0;
        for i in self.within(from, to) {
            ss += (self.y[i] - mean[self.bin[i]]).powi(2);
            n += 1.0;
        }
        let used = cnt.iter().filter(|&&c| c > 0.0).count() as f64;
        let dof = n - used;
        (if dof > 0.0 { ss / dof } else { 0.0 }, dof)
    }

    /// The noise variance of one sample inside the periods `from..to` (pooled within bins when the bins
    /// give at least half a degree of freedom per bin, from second differences of the whole record
    /// otherwise).
    fn noise_variance(&self, from: usize, to: usize, mean: &[f64], cnt: &[f64]) -> f64 {
        let (var, dof) = self.pooled(from, to, mean, cnt);
        if dof >= 0.5 * self.bins as f64 {
            var
        } else {
            sigma_from_differences(self.y).powi(2)
        }
    }

    /// The first steady period of the `full` periods (module docs, "Steady state").
    fn steady_start(&self, full: usize, sigma_floor: f64) -> usize {
        let m_ref = if full >= 4 { full / 2 } else { full.min(2) };
        let from = full - m_ref;
        let (rmean, rcnt) = self.bin_means(from, full);
        let var = self.noise_variance(from, full, &rmean, &rcnt) + sigma_floor * sigma_floor;
        let mut ss = vec![0.0; full];
        let mut n = vec![0.0; full];
        for i in self.within(0, full) {
            ss[self.period[i]] += (self.y[i] - rmean[self.bin[i]]).powi(2);
            n[self.period[i]] += 1.0;
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

    /// The noise standard deviation of one sample in the steady periods `k0..full`.
    fn steady_sigma(&self, k0: usize, full: usize, mean: &[f64], cnt: &[f64]) -> f64 {
        let (var, dof) = self.pooled(k0, full, mean, cnt);
        if dof >= 0.5 * self.bins as f64 {
            var.sqrt()
        } else {
            let steady: Vec<f64> = self.within(k0, full).map(|i| self.y[i]).collect();
            sigma_from_differences(&steady)
        }
    }

    /// Per-bin sums of the offsets from the bin centres over the periods `from..to`.
    fn offset_sums(&self, from: usize, to: usize) -> Vec<f64> {
        let mut off = vec![0.0; self.bins];
        for i in self.within(from, to) {
            off[self.bin[i]] += self.offset[i];
        }
        off
    }
}

/// The first period to average: after the `skip` given (rad of phase), or after the detected transient,
/// with a warning when it cannot be checked or when it takes most of the record.
fn first_steady(
    grid: &Grid,
    full: usize,
    skip: Option<f64>,
    span: f64,
    sigma_floor: f64,
    warnings: &mut Vec<String>,
) -> Result<usize, FrequencyError> {
    let k0 = match skip {
        Some(s) => {
            let k = (s / std::f64::consts::TAU - 1e-9).ceil().max(0.0) as usize;
            if k >= full {
                return Err(FrequencyError::NoFullPeriod {
                    periods: span,
                    transient: k,
                });
            }
            return Ok(k);
        }
        None if full == 1 => {
            warnings.push(
                "only one full period: the steady state could not be checked (record more periods)"
                    .to_string(),
            );
            0
        }
        None => grid.steady_start(full, sigma_floor),
    };
    if k0 > 0 && k0 * 2 > full {
        warnings.push(format!(
            "the transient took {k0} of {full} full periods: record more periods so that the steady \
             state dominates the record"
        ));
    }
    Ok(k0)
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
    let grid = Grid::new(rho, y, b, delta);
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
    let k0 = first_steady(&grid, full, skip, span, sigma_floor, &mut warnings)?;
    let (mean, cnt) = grid.bin_means(k0, full);
    let sigma = grid.steady_sigma(k0, full, &mean, &cnt);
    let off = grid.offset_sums(k0, full);
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
