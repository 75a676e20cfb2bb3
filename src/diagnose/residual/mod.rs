//! Tests that trace a residual to its cause.
//!
//! Each function takes the residual e(k) = y(k) - y_model(k) of a fitted model (and, where needed, the input
//! and the model's internal signals) and returns a statistic with its threshold, so that a report can say
//! "this test rejects at 95%, here is the evidence". All thresholds are two-sided 95% unless said otherwise.
//!
//! | test | what it sees | effects it points to |
//! | --- | --- | --- |
//! | [`ljung_box`] | autocorrelation of e | coloured-noise, linear-order, periodic-disturbance, friction (a slipping element shifts the output's zero, which then wanders) |
//! | [`cross_correlation`] | e against past inputs | extra-delay, linear-order |
//! | [`billings`] | higher-order correlations (Billings and Voon, 1986) | unmodelled nonlinearity: curved-borders, friction, saturation |
//! | [`by_mode`] | e conditioned on up / down / held | friction (held and just-engaged samples), gap errors |
//! | [`since_reversal`] | e against time since the last reversal | friction (elastic unloading after a reversal) |
//! | [`against_x`] | e against x_hat and x_hat^2 on the borders | curved-borders, saturation |
//! | [`drift`] | CUSUM and split-sample means by mode | gap-drift, friction (slip moves the output's zero) |
//! | [`spectrum_peak`] | periodogram peak against the median level | periodic-disturbance |
//! | [`lattice`] | the values of y on a grid q k + o | quantization |
//! | [`clipping`] | runs of y at its extremes | saturation |
//! | [`extreme_increments`] | residual increments against model increments at the output's extremes | friction, saturation, curved-borders |
//!
//! The diagnosis uses exactly this map: `crate::diagnose::effects::EffectId::pointing_tests`.

/// Names of the residual tests (the `name` of their [`crate::diagnose::residual::Verdict`]).
pub mod test_names {
    pub const LJUNG_BOX: &str = "ljung-box";
    pub const CROSS_CORRELATION: &str = "residual-input cross-correlation";
    pub const BILLINGS: &str = "billings higher-order correlations";
    pub const BY_MODE: &str = "residual by backlash mode";
    pub const SINCE_REVERSAL: &str = "residual by time since reversal";
    pub const AGAINST_X: &str = "residual against x_hat on the borders";
    pub const DRIFT: &str = "drift (CUSUM by mode)";
    pub const SPECTRUM_PEAK: &str = "residual spectrum peak";
    pub const LATTICE: &str = "value lattice (quantization)";
    pub const CLIPPING: &str = "clipping at the extremes";
    pub const EXTREMES: &str = "incremental gain at the output extremes";
}

pub mod statistics;

use crate::plant::Mode;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::stats::{lagged_sums, mean};

/// z for a two-sided 95% band.
pub const Z95: f64 = 1.959_963_984_540_054;

/// The 95% band `Z95 / sqrt(n)` of a white sequence's sample correlations over `n` samples (`n` of 0 counts
/// as 1).
pub fn white_band(n: usize) -> f64 {
    Z95 / (n.max(1) as f64).sqrt()
}

fn centred(x: &[f64]) -> Vec<f64> {
    let m = mean(x);
    x.iter().map(|v| v - m).collect()
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Normalised correlation sum_k a(k) b(k - lag) / (|a| |b|) of centred series, lag >= 0.
fn corr_at(a: &[f64], b: &[f64], lag: usize) -> f64 {
    corrs(a, b, lag..lag + 1)[0]
}

/// [`corr_at`] at each lag of `lags`: the norms once, the lags' sums side by side ([`lagged_sums`]).
fn corrs(a: &[f64], b: &[f64], lags: std::ops::Range<usize>) -> Vec<f64> {
    let (na, nb) = (norm(a), norm(b));
    if na == 0.0 || nb == 0.0 {
        return vec![0.0; lags.len()];
    }
    let n = a.len();
    lags.clone()
        .zip(lagged_sums(a, b, lags))
        .map(|(l, s)| if l >= n { 0.0 } else { s / (na * nb) })
        .collect()
}

/// Autocorrelation r(1..=lags) of the centred series.
pub fn autocorrelation(x: &[f64], lags: usize) -> Vec<f64> {
    let c = centred(x);
    corrs(&c, &c, 1..lags + 1)
}

/// A test statistic against its threshold.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Verdict {
    pub name: &'static str,
    pub statistic: f64,
    pub threshold: f64,
    /// The statistic exceeds the threshold: the model is missing something this test sees.
    pub rejects: bool,
    pub detail: String,
}

impl Verdict {
    /// A verdict that rejects when `statistic` is strictly above `threshold` (equal does not reject; NaN never
    /// does).
    pub fn exceeds(name: &'static str, statistic: f64, threshold: f64, detail: String) -> Self {
        Self {
            name,
            statistic,
            threshold,
            rejects: statistic > threshold,
            detail,
        }
    }
}

/// Ljung-Box portmanteau test of whiteness: Q = N (N + 2) sum_{l=1..L} r_l^2 / (N - l), against the 95%
/// quantile of chi-square with L degrees of freedom. An empty or constant residual is white (Q = 0).
pub fn ljung_box(e: &[f64], lags: usize) -> Verdict {
    let n = e.len() as f64;
    let lags = lags.clamp(1, e.len().saturating_sub(2).max(1));
    let r = autocorrelation(e, lags);
    let q: f64 = n
        * (n + 2.0)
        * r.iter()
            .enumerate()
            .map(|(i, ri)| ri * ri / (n - (i + 1) as f64).max(1.0))
            .sum::<f64>();
    let threshold = chi2_quantile(0.95, lags as f64);
    let (imax, rmax) = r.iter().enumerate().fold((0, 0.0f64), |acc, (i, v)| {
        if v.abs() > acc.1.abs() { (i, *v) } else { acc }
    });
    Verdict::exceeds(
        "ljung-box",
        q,
        threshold,
        format!(
            "Q = {q:.1} over {lags} lags (chi-square 95%: {threshold:.1}); largest autocorrelation {rmax:.3} at lag {}",
            imax + 1
        ),
    )
}

/// The p-quantile of chi-square with `df` degrees of freedom.
pub fn chi2_quantile(p: f64, df: f64) -> f64 {
    ChiSquared::new(df.max(1e-9))
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::INFINITY)
}

/// Cross-correlation of the residual with past inputs, r_eu(lag) = corr(e(k), u(k - lag)) for lag 0..=lags,
/// with the 95% band +-1.96/sqrt(N) of a white residual independent of u.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CrossCorrelation {
    pub lags: Vec<usize>,
    pub r: Vec<f64>,
    pub band: f64,
    /// Lags whose |r| exceeds the band.
    pub outside: Vec<usize>,
    pub verdict: Verdict,
}

/// How many of `count` correlations may fall outside their 95% band by chance: under independence each does
/// with probability 0.05, so the count is binomial(count, 0.05); its mean plus 1.96 standard deviations, plus
/// one for the discreteness.
pub fn allowed_outside(count: usize) -> f64 {
    let expected = 0.05 * count as f64;
    expected + Z95 * (expected * 0.95).sqrt() + 1.0
}

/// Correlations `r` against a white sequence's band: how many fall outside it, the largest |r|, and whether
/// to reject: more outside than chance allows ([`allowed_outside`]), or one far outside (|r| > 2 band).
fn outside_band(r: &[f64], band: f64) -> (Vec<usize>, f64, bool) {
    let outside: Vec<usize> = (0..r.len()).filter(|&l| r[l].abs() > band).collect();
    let peak = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rejects = outside.len() as f64 > allowed_outside(r.len()) || peak > 2.0 * band;
    (outside, peak, rejects)
}

pub fn cross_correlation(e: &[f64], u: &[f64], lags: usize) -> CrossCorrelation {
    let (ec, uc) = (centred(e), centred(u));
    let r = corrs(&ec, &uc, 0..lags + 1);
    let band = white_band(e.len());
    let (outside, peak, rejects) = outside_band(&r, band);
    let statistic = peak / band;
    CrossCorrelation {
        lags: (0..=lags).collect(),
        verdict: Verdict {
            name: "residual-input cross-correlation",
            statistic,
            threshold: 2.0,
            rejects,
            detail: format!(
                "{} of {} lags outside +-{band:.3}; peak |r| = {peak:.3} ({statistic:.1} bands)",
                outside.len(),
                lags + 1
            ),
        },
        r,
        band,
        outside,
    }
}

/// Billings and Voon (1986) correlation tests for a nonlinear model: with e the residual and u the input,
/// all of phi_ee(l) (l != 0), phi_ue(l), phi_{u2'e}(l), phi_{u2'e2}(l) and phi_{e(eu)}(l) (l >= 0) should lie
/// within +-1.96/sqrt(N) when nothing is missing; u2' = u^2 - mean(u^2). Returns each function's largest
/// |value| in band units and a verdict on the higher-order ones (the three that see nonlinearity).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Billings {
    pub band: f64,
    /// (name, values at lags 0..=L).
    pub functions: Vec<(&'static str, Vec<f64>)>,
    pub verdict: Verdict,
}

pub fn billings(e: &[f64], u: &[f64], lags: usize) -> Billings {
    let n = e.len();
    let ec = centred(e);
    let uc = centred(u);
    let u2: Vec<f64> = centred(&u.iter().map(|v| v * v).collect::<Vec<_>>());
    let e2: Vec<f64> = centred(&e.iter().map(|v| v * v).collect::<Vec<_>>());
    // e(k+1) u(k+1) shifted: phi_{e(eu)}(l) = corr(e(k), e(k-1-l) u(k-1-l)).
    let eu: Vec<f64> = centred(&e.iter().zip(u).map(|(a, b)| a * b).collect::<Vec<_>>());
    let band = white_band(n);
    let f = |a: &[f64], b: &[f64], shift: usize| corrs(a, b, shift..lags + 1 + shift);
    let functions = vec![
        ("phi_ee", f(&ec, &ec, 1)),
        ("phi_ue", f(&ec, &uc, 0)),
        ("phi_u2e", f(&ec, &u2, 0)),
        ("phi_u2e2", f(&e2, &u2, 0)),
        ("phi_e_eu", f(&ec, &eu, 1)),
    ];
    let peak = |v: &Vec<f64>| v.iter().fold(0.0f64, |m, x| m.max(x.abs())) / band;
    let hoc = functions[2..]
        .iter()
        .map(|(_, v)| peak(v))
        .fold(0.0f64, f64::max);
    let detail = functions
        .iter()
        .map(|(name, v)| format!("{name} {:.1}", peak(v)))
        .collect::<Vec<_>>()
        .join(", ");
    Billings {
        band,
        verdict: Verdict::exceeds(
            "billings higher-order correlations",
            hoc,
            2.0,
            format!("largest |phi| in bands: {detail}"),
        ),
        functions,
    }
}

/// Residual statistics of one group of samples.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct GroupStats {
    pub label: String,
    pub count: usize,
    pub mean: f64,
    pub rms: f64,
}

fn stats(label: impl Into<String>, v: &[f64]) -> GroupStats {
    GroupStats {
        label: label.into(),
        count: v.len(),
        mean: mean(v),
        rms: if v.is_empty() {
            0.0
        } else {
            (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
        },
    }
}

/// Groups of at most this many samples are reported but not judged (their mean and rms are too uncertain).
const MIN_JUDGED: usize = 10;

fn judged(g: &GroupStats) -> bool {
    g.count > MIN_JUDGED
}

/// The largest group mean of the judged groups in standard errors of the overall rms (0 when none is judged).
fn worst_mean(groups: &[GroupStats], overall_rms: f64) -> f64 {
    groups
        .iter()
        .filter(|g| judged(g))
        .map(|g| g.mean.abs() / (overall_rms / (g.count as f64).sqrt()))
        .fold(0.0, f64::max)
}

/// The residual by backlash mode of the fitted model. A mode whose mean is more than 3 standard errors
/// (from the overall rms) from zero, or whose rms is more than twice another's, rejects (modes of at most
/// ten samples are not judged).
pub fn by_mode(e: &[f64], modes: &[Mode]) -> (Vec<GroupStats>, Verdict) {
    let pick = |m: Mode| -> Vec<f64> {
        e.iter()
            .zip(modes)
            .filter(|(_, mm)| **mm == m)
            .map(|(v, _)| *v)
            .collect()
    };
    let groups = vec![
        stats("up", &pick(Mode::Up)),
        stats("down", &pick(Mode::Down)),
        stats("held", &pick(Mode::Held)),
    ];
    let overall = stats("all", e).rms.max(f64::MIN_POSITIVE);
    let worst = worst_mean(&groups, overall);
    let rms: Vec<f64> = groups.iter().filter(|g| judged(g)).map(|g| g.rms).collect();
    let ratio = if rms.len() >= 2 {
        rms.iter().cloned().fold(0.0, f64::max)
            / rms
                .iter()
                .cloned()
                .fold(f64::INFINITY, f64::min)
                .max(1e-300)
    } else {
        1.0
    };
    let detail = groups
        .iter()
        .map(|g| {
            format!(
                "{}: n {} mean {:.3e} rms {:.3e}",
                g.label, g.count, g.mean, g.rms
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    (
        groups,
        Verdict {
            name: "residual by backlash mode",
            statistic: worst,
            threshold: 3.0,
            rejects: worst > 3.0 || ratio > 2.0,
            detail: format!("{detail}; rms ratio {ratio:.2}"),
        },
    )
}

/// Mode changes of the model's working point: sample indices where it leaves one border for the other
/// (the last engaged direction changes).
pub fn reversals(modes: &[Mode]) -> Vec<usize> {
    let mut last = None;
    let mut out = Vec::new();
    for (k, m) in modes.iter().enumerate() {
        if *m == Mode::Held {
            continue;
        }
        if last.is_some_and(|l| l != *m) {
            out.push(k);
        }
        last = Some(*m);
    }
    out
}

/// The residual against the number of samples since the last direction change of x_hat, in bins of
/// doubling width (0, 1-2, 3-6, 7-14, ...; the eighth bin also takes every count above its range). Friction
/// shows as a residual pattern right after reversals.
pub fn since_reversal(e: &[f64], x_hat: &[f64]) -> (Vec<GroupStats>, Verdict) {
    let mut since = vec![usize::MAX; e.len()];
    let mut dir = 0i8;
    let mut count = usize::MAX / 2;
    for k in 1..x_hat.len() {
        let d = (x_hat[k] - x_hat[k - 1]).signum() as i8;
        if d != 0 && d != dir {
            if dir != 0 {
                count = 0;
            }
            dir = d;
        } else {
            count = count.saturating_add(1);
        }
        since[k] = count;
    }
    let mut bins: Vec<Vec<f64>> = vec![Vec::new(); 8];
    for (k, s) in since.iter().enumerate() {
        if *s == usize::MAX || *s >= usize::MAX / 4 {
            continue;
        }
        let b = (usize::BITS - (s + 1).leading_zeros()) as usize - 1;
        bins[b.min(7)].push(e[k]);
    }
    let groups: Vec<GroupStats> = bins
        .iter()
        .enumerate()
        .map(|(b, v)| {
            stats(
                format!("{}-{}", (1usize << b) - 1, (1usize << (b + 1)) - 2),
                v,
            )
        })
        .collect();
    let overall = stats("all", e).rms.max(f64::MIN_POSITIVE);
    let worst = worst_mean(&groups, overall);
    (
        groups,
        Verdict::exceeds(
            "residual by time since reversal",
            worst,
            3.0,
            format!("largest bin mean in standard errors: {worst:.1}"),
        ),
    )
}

/// Correlation of the residual with x_hat and x_hat^2 on engaged samples (the borders): straight borders
/// leave none; curved ones leave a quadratic or cubic trend.
pub fn against_x(e: &[f64], x_hat: &[f64], modes: &[Mode]) -> Verdict {
    let idx: Vec<usize> = (0..e.len()).filter(|&k| modes[k] != Mode::Held).collect();
    let ee: Vec<f64> = centred(&idx.iter().map(|&k| e[k]).collect::<Vec<_>>());
    let x1: Vec<f64> = centred(&idx.iter().map(|&k| x_hat[k]).collect::<Vec<_>>());
    let x2: Vec<f64> = centred(&idx.iter().map(|&k| x_hat[k] * x_hat[k]).collect::<Vec<_>>());
    let x3: Vec<f64> = centred(&idx.iter().map(|&k| x_hat[k].powi(3)).collect::<Vec<_>>());
    let band = white_band(idx.len());
    let r = [
        corr_at(&ee, &x1, 0),
        corr_at(&ee, &x2, 0),
        corr_at(&ee, &x3, 0),
    ];
    let peak = r.iter().fold(0.0f64, |m, v| m.max(v.abs())) / band;
    Verdict::exceeds(
        "residual against x_hat on the borders",
        peak,
        3.0,
        format!(
            "corr with x_hat {:.3}, x_hat^2 {:.3}, x_hat^3 {:.3} (band {band:.3}, {} engaged samples)",
            r[0],
            r[1],
            r[2],
            idx.len()
        ),
    )
}

/// Drift over the record: the largest excursion of the CUSUM of the residual (standardised: under a
/// stationary white residual max |S_k| / (sigma sqrt(N)) follows the Kolmogorov distribution, 95% point
/// 1.358), computed on the residual of each engaged mode separately, since wear moves the up and down
/// borders in opposite directions and their effects cancel in the overall mean.
pub fn drift(e: &[f64], modes: &[Mode]) -> Verdict {
    let mut worst = 0.0f64;
    let mut detail = Vec::new();
    for (label, m) in [("up", Mode::Up), ("down", Mode::Down)] {
        let v: Vec<f64> = e
            .iter()
            .zip(modes)
            .filter(|(_, mm)| **mm == m)
            .map(|(x, _)| *x)
            .collect();
        if v.len() < 20 {
            continue;
        }
        let c = centred(&v);
        let sigma = (c.iter().map(|x| x * x).sum::<f64>() / c.len() as f64).sqrt();
        if sigma == 0.0 {
            continue;
        }
        let mut s = 0.0f64;
        let mut peak = 0.0f64;
        for x in &c {
            s += x;
            peak = peak.max(s.abs());
        }
        let stat = peak / (sigma * (c.len() as f64).sqrt());
        // Split-sample: mean of the last third against the first third.
        let third = c.len() / 3;
        let shift = mean(&c[c.len() - third..]) - mean(&c[..third]);
        detail.push(format!(
            "{label}: CUSUM {stat:.2}, late - early mean {shift:.3e} ({} samples)",
            v.len()
        ));
        worst = worst.max(stat);
    }
    Verdict::exceeds("drift (CUSUM by mode)", worst, 1.358, detail.join("; "))
}

/// Periodogram of the residual (FFT, zero-padded to twice the next power of two so that a sinusoid between
/// Fourier frequencies is not missed), over (0, pi] rad/sample. White-noise ordinates are exponential with
/// mean = median / ln 2, and the largest of M is about ln M times the mean: a peak above (ln M + 6) / ln 2
/// times the median rejects (a false alarm probability of about e^-6 per record). Returns the peak's angular
/// frequency.
pub fn spectrum_peak(e: &[f64]) -> (f64, Verdict) {
    let n = e.len().max(2);
    let (omegas, power) = periodogram(e, true);
    let median = crate::stats::quantile(&power, 0.5)
        .unwrap_or(0.0)
        .max(f64::MIN_POSITIVE);
    let (imax, pmax) =
        power.iter().enumerate().fold(
            (0, 0.0),
            |acc, (i, p)| if *p > acc.1 { (i, *p) } else { acc },
        );
    let w = omegas.get(imax).copied().unwrap_or(std::f64::consts::PI);
    // Independent ordinates: the n/2 Fourier frequencies (padding interpolates between them).
    let threshold = (((n / 2).max(2) as f64).ln() + 6.0) / std::f64::consts::LN_2;
    let stat = pmax / median;
    (
        w,
        Verdict::exceeds(
            "residual spectrum peak",
            stat,
            threshold,
            format!(
                "peak {stat:.1} x median at {w:.4} rad/sample (period {:.1} samples)",
                2.0 * std::f64::consts::PI / w
            ),
        ),
    )
}

/// Periodogram |X(w)|^2 / n of the centred series at w = 2 pi i / m, i = 1..=m/2, m the FFT length: n
/// itself, or with `pad` the power of two at least 2n (which interpolates between the Fourier frequencies).
/// Returns (w, power); empty for fewer than 2 samples.
pub fn periodogram(x: &[f64], pad: bool) -> (Vec<f64>, Vec<f64>) {
    use rustfft::{FftPlanner, num_complex::Complex};
    let n = x.len();
    if n < 2 {
        return (Vec::new(), Vec::new());
    }
    let m = if pad { (2 * n).next_power_of_two() } else { n };
    let c = centred(x);
    let mut buf: Vec<Complex<f64>> = c.iter().map(|&v| Complex::new(v, 0.0)).collect();
    buf.resize(m, Complex::new(0.0, 0.0));
    FftPlanner::new().plan_fft_forward(m).process(&mut buf);
    let half = m / 2;
    let w = (1..=half)
        .map(|i| 2.0 * std::f64::consts::PI * i as f64 / m as f64)
        .collect();
    let p = buf[1..=half]
        .iter()
        .map(|z| z.norm_sqr() / n as f64)
        .collect();
    (w, p)
}

/// Whether the measured values sit on a lattice q k + o: the step q is the smallest difference between
/// distinct sorted values that recurs (at least 10% of the distinct gaps are within 1e-9 relative of a whole
/// multiple of it), and the fraction of values on the lattice must exceed 99%. A continuous sensor has
/// distinct values with no common step; a quantised one has few distinct values on a grid.
pub fn lattice(y: &[f64]) -> (Option<f64>, Verdict) {
    let mut v: Vec<f64> = y.to_vec();
    v.sort_by(f64::total_cmp);
    v.dedup();
    let distinct = v.len();
    let gaps: Vec<f64> = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|g| *g > 0.0)
        .collect();
    let none = |detail: String| {
        (
            None,
            Verdict {
                name: "value lattice (quantization)",
                statistic: distinct as f64 / y.len().max(1) as f64,
                threshold: 0.5,
                rejects: false,
                detail,
            },
        )
    };
    if gaps.is_empty() || distinct * 2 > y.len() {
        return none(format!(
            "{distinct} distinct values in {} samples: no lattice",
            y.len()
        ));
    }
    let mut sorted_gaps = gaps.clone();
    sorted_gaps.sort_by(f64::total_cmp);
    let q = sorted_gaps[sorted_gaps.len() / 10];
    let scale = v.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(q);
    let tol = 1e-6 * scale;
    let on = gaps
        .iter()
        .filter(|g| {
            let r = *g / q;
            (r - r.round()).abs() * q <= tol
        })
        .count();
    let frac = on as f64 / gaps.len() as f64;
    if frac < 0.99 {
        return none(format!(
            "{distinct} distinct values; gaps are not multiples of a common step ({:.1}% on a {q:.3e} grid)",
            100.0 * frac
        ));
    }
    (
        Some(q),
        Verdict {
            name: "value lattice (quantization)",
            statistic: distinct as f64 / y.len() as f64,
            threshold: 0.5,
            rejects: true,
            detail: format!(
                "{distinct} distinct values in {} samples, all gaps multiples of q = {q:.4e}",
                y.len()
            ),
        },
    )
}

/// Clipping at the extremes: the fraction of samples equal (to 1e-9 relative) to the maximum or the minimum
/// of y. A clean record touches its extremes once; a clipped one sits there in runs.
pub fn clipping(y: &[f64]) -> (f64, f64, Verdict) {
    let hi = y.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let lo = y.iter().cloned().fold(f64::INFINITY, f64::min);
    let tol = 1e-9 * hi.abs().max(lo.abs()).max(1e-300);
    let at_hi = y.iter().filter(|v| (*v - hi).abs() <= tol).count();
    let at_lo = y.iter().filter(|v| (*v - lo).abs() <= tol).count();
    let n = y.len().max(1) as f64;
    let frac = (at_hi.max(at_lo)) as f64 / n;
    (
        lo,
        hi,
        Verdict {
            name: "clipping at the extremes",
            statistic: frac,
            threshold: 0.005,
            rejects: frac > 0.005 && at_hi.max(at_lo) >= 5,
            detail: format!(
                "{at_hi} samples at the maximum {hi:.4}, {at_lo} at the minimum {lo:.4}"
            ),
        },
    )
}

/// The incremental gain at the output's extremes: on the samples where the model output is in its top 15%
/// and still rising (or bottom 15% and still falling), the least-squares slope of the residual's increment
/// e(k) - e(k-1) on the model's increment y_hat(k) - y_hat(k-1). With nothing missing the residual's increments
/// are noise and the slope is zero; an output that stops while the model keeps going (friction slipping,
/// saturation) gives a slope near -1, a border that bends gives a slope of the bend's sign. Rejects when
/// either slope's |t| exceeds 4 (conservative: the test looks at two groups, and the increments of a
/// white residual are negatively correlated, which makes the t-ratio's nominal standard error too large).
pub fn extreme_increments(e: &[f64], y_hat: &[f64]) -> Verdict {
    let n = e.len().min(y_hat.len());
    let mut sorted: Vec<f64> = y_hat[..n].to_vec();
    sorted.sort_by(f64::total_cmp);
    let mut worst = 0.0f64;
    let mut detail = Vec::new();
    if n >= 20 {
        let hi = sorted[(0.85 * (n - 1) as f64) as usize];
        let lo = sorted[(0.15 * (n - 1) as f64) as usize];
        for (label, top) in [("top", true), ("bottom", false)] {
            let idx: Vec<usize> = (1..n)
                .filter(|&k| {
                    let dy = y_hat[k] - y_hat[k - 1];
                    if top {
                        y_hat[k] >= hi && dy > 0.0
                    } else {
                        y_hat[k] <= lo && dy < 0.0
                    }
                })
                .collect();
            if idx.len() < 10 {
                continue;
            }
            let (mut sxx, mut sxy) = (0.0, 0.0);
            for &k in &idx {
                let (dx, de) = (y_hat[k] - y_hat[k - 1], e[k] - e[k - 1]);
                sxx += dx * dx;
                sxy += dx * de;
            }
            if sxx <= 0.0 {
                continue;
            }
            let b = sxy / sxx;
            let ss: f64 = idx
                .iter()
                .map(|&k| {
                    let r = (e[k] - e[k - 1]) - b * (y_hat[k] - y_hat[k - 1]);
                    r * r
                })
                .sum();
            let se = (ss / (idx.len() - 1) as f64 / sxx).sqrt();
            // A slope with no scatter about it is infinitely significant (b / 0 = +-inf); none, not at all.
            let t = if b == 0.0 { 0.0 } else { b / se };
            worst = worst.max(t.abs());
            detail.push(format!(
                "{label} 15%: slope {b:.3} (t {t:.1}, {} samples)",
                idx.len()
            ));
        }
    }
    Verdict::exceeds(
        "incremental gain at the output extremes",
        worst,
        4.0,
        if detail.is_empty() {
            "too few samples at the extremes".into()
        } else {
            detail.join("; ")
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::ChaCha8Rng;
    use rand_core::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut r = ChaCha8Rng::seed_from_u64(seed);
        (0..n).map(|_| StandardNormal.sample(&mut r)).collect()
    }

    #[test]
    fn chi2_quantile_matches_tables() {
        // Tabulated 95% points: df 1: 3.841, df 10: 18.307, df 20: 31.410.
        assert!((chi2_quantile(0.95, 1.0) - 3.841).abs() < 1e-3);
        assert!((chi2_quantile(0.95, 10.0) - 18.307).abs() < 1e-3);
        assert!((chi2_quantile(0.95, 20.0) - 31.410).abs() < 1e-3);
    }

    #[test]
    fn ljung_box_accepts_white_and_rejects_coloured() {
        let mut rejected = 0;
        for s in 0..100 {
            rejected += usize::from(ljung_box(&white(2000, s), 20).rejects);
        }
        // 5% nominal; allow sampling error.
        assert!(rejected <= 12, "white rejected {rejected}/100");
        let w = white(2000, 1);
        let ar: Vec<f64> = w
            .iter()
            .scan(0.0, |s, x| {
                *s = 0.5 * *s + x;
                Some(*s)
            })
            .collect();
        assert!(ljung_box(&ar, 20).rejects);
    }

    #[test]
    fn cross_correlation_finds_the_lag() {
        let u = white(3000, 2);
        let noise = white(3000, 3);
        // e(k) = 0.3 u(k-3) + noise: a delay the model missed.
        let e: Vec<f64> = (0..3000)
            .map(|k| noise[k] + if k >= 3 { 0.3 * u[k - 3] } else { 0.0 })
            .collect();
        let c = cross_correlation(&e, &u, 10);
        assert!(c.verdict.rejects);
        assert!(c.outside.contains(&3));
        assert!(!cross_correlation(&noise, &u, 10).verdict.rejects);
    }

    #[test]
    fn billings_sees_a_squared_input_term() {
        let u = white(4000, 4);
        let noise = white(4000, 5);
        let e: Vec<f64> = (0..4000)
            .map(|k| noise[k] + 0.4 * (u[k] * u[k] - 1.0))
            .collect();
        assert!(billings(&e, &u, 10).verdict.rejects);
        assert!(!billings(&noise, &u, 10).verdict.rejects);
    }

    #[test]
    fn spectrum_peak_finds_a_sinusoid() {
        let noise = white(4000, 6);
        let w0 = 0.37;
        let e: Vec<f64> = (0..4000)
            .map(|k| noise[k] + 0.3 * (w0 * k as f64).sin())
            .collect();
        let (w, v) = spectrum_peak(&e);
        assert!(v.rejects, "{}", v.detail);
        assert!((w - w0).abs() < 2e-3, "{w}");
        let mut false_alarms = 0;
        for s in 0..50 {
            false_alarms += usize::from(spectrum_peak(&white(4000, 100 + s)).1.rejects);
        }
        assert!(
            false_alarms <= 2,
            "{false_alarms} of 50 white records flagged"
        );
    }

    #[test]
    fn lattice_finds_the_quantisation_step() {
        let y: Vec<f64> = white(3000, 7)
            .iter()
            .map(|v| (v / 0.05).round() * 0.05)
            .collect();
        let (q, v) = lattice(&y);
        assert!(v.rejects);
        assert!((q.unwrap() - 0.05).abs() < 1e-9);
        assert!(!lattice(&white(3000, 8)).1.rejects);
    }

    #[test]
    fn clipping_is_seen() {
        let y: Vec<f64> = white(3000, 9).iter().map(|v| v.clamp(-1.0, 1.0)).collect();
        assert!(clipping(&y).2.rejects);
        assert!(!clipping(&white(3000, 10)).2.rejects);
    }

    /// Many lags just outside the band reject, as does one far outside; a few just outside do not. With 21
    /// lags chance allows 0.05 * 21 + 1.96 sqrt(0.05 * 21 * 0.95) + 1 = 4.0075 outside.
    #[test]
    fn outside_band_by_hand() {
        assert!((allowed_outside(21) - 4.0075).abs() < 1e-4);
        let mut r = vec![0.0; 21];
        r[..5].iter_mut().for_each(|v| *v = -1.5);
        assert_eq!(outside_band(&r, 1.0), (vec![0, 1, 2, 3, 4], 1.5, true));
        r[0] = 0.5;
        assert_eq!(outside_band(&r, 1.0), (vec![1, 2, 3, 4], 1.5, false));
        r[7] = 2.01;
        assert_eq!(outside_band(&r, 1.0), (vec![1, 2, 3, 4, 7], 2.01, true));
        assert_eq!(outside_band(&[1.0, 2.0], 1.0), (vec![1], 2.0, false));
        assert_eq!(outside_band(&[1.0, 2.01], 1.0), (vec![1], 2.01, true));
    }

    /// Only a statistic strictly above its threshold rejects.
    #[test]
    fn a_verdict_rejects_strictly_above_its_threshold() {
        let v = |s: f64| Verdict::exceeds("t", s, 1.358, String::new()).rejects;
        assert!(!v(1.358));
        assert!(v(1.358_000_001));
        assert!(!v(1.0));
        assert!(!v(f64::NAN));
    }

    /// Clipped at the bottom only (at -2, away from 0): the fraction is the samples sitting at the minimum.
    #[test]
    fn clipping_counts_the_minimum() {
        let mut y: Vec<f64> = (0..1000).map(|k| k as f64 * 0.001).collect();
        y[..10].iter_mut().for_each(|v| *v = -2.0);
        let (lo, hi, v) = clipping(&y);
        assert_eq!((lo, hi), (-2.0, 0.999));
        assert_eq!(v.statistic, 0.01);
        assert!(v.rejects);
    }

    /// The clipping rule is strict on the fraction and needs five samples: 10 of 2000 at the maximum (exactly
    /// 0.5%) is no clipping, 11 is; 4 of 400 (1%) is too few samples, 5 are enough.
    #[test]
    fn clipping_is_strictly_above_half_a_percent_and_five_samples() {
        let clipped = |n: usize, at_max: usize| {
            let mut y: Vec<f64> = (0..n).map(|k| k as f64).collect();
            y[n - at_max..].iter_mut().for_each(|v| *v = n as f64);
            clipping(&y).2
        };
        let v = clipped(2000, 10);
        assert_eq!(v.statistic, 0.005);
        assert!(!v.rejects);
        assert!(clipped(2000, 11).rejects);
        assert!(!clipped(400, 4).rejects);
        assert!(clipped(400, 5).rejects);
    }

    #[test]
    fn white_band_by_hand() {
        assert!((white_band(100) - 0.195_996_398_454_005_4).abs() < 1e-15);
        assert_eq!(white_band(0), Z95);
        assert_eq!(white_band(1), Z95);
    }

    #[test]
    fn drift_sees_a_trend_in_the_up_mode_residual() {
        let n = 3000;
        let noise = white(n, 11);
        let modes: Vec<Mode> = (0..n)
            .map(|k| if k % 2 == 0 { Mode::Up } else { Mode::Down })
            .collect();
        let e: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / n as f64;
                noise[k] * 0.1 + if k % 2 == 0 { 0.1 * t } else { -0.1 * t }
            })
            .collect();
        assert!(drift(&e, &modes).rejects);
        let e0: Vec<f64> = noise.iter().map(|v| 0.1 * v).collect();
        assert!(!drift(&e0, &modes).rejects);
    }

    #[test]
    fn extreme_increments_sees_an_output_that_stops() {
        let n = 4000;
        let noise = white(n, 12);
        let yh: Vec<f64> = (0..n).map(|k| 2.0 * (k as f64 * 0.05).sin()).collect();
        // Measured output clipped at +-1.5: the residual's increments follow -dy_hat there.
        let e: Vec<f64> = (0..n)
            .map(|k| yh[k].clamp(-1.5, 1.5) - yh[k] + 0.05 * noise[k])
            .collect();
        assert!(extreme_increments(&e, &yh).rejects);
        let e0: Vec<f64> = noise.iter().map(|v| 0.05 * v).collect();
        let mut false_alarms = 0;
        for s in 0..40 {
            let w = white(n, 200 + s);
            let e: Vec<f64> = w.iter().map(|v| 0.05 * v).collect();
            false_alarms += usize::from(extreme_increments(&e, &yh).rejects);
        }
        assert!(!extreme_increments(&e0, &yh).rejects);
        assert!(false_alarms <= 1, "{false_alarms} of 40");
    }

    // Exact values on a small fixed record, computed independently with NumPy/SciPy from the definitions in
    // the doc comments (the script: e, u, x and the modes as in `small`; correlations as
    // sum a(k) b(k - l) / (|a| |b|) of the centred series, chi-square quantiles from scipy.stats.chi2).

    /// n = 80: e(k) = sin(1.3 k) + 0.5 cos(0.7 k^1.1) + 0.02 k, u(k) = cos(0.9 k) + 0.3 sin(2.1 k + 0.4),
    /// x(k) = 2 sin(0.25 k) + 0.1 k, and the modes up, up, up, down, down, held, held repeating.
    fn small() -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<Mode>) {
        let ks = (0..80).map(f64::from);
        let e = ks
            .clone()
            .map(|k| (1.3 * k).sin() + 0.5 * (0.7 * k.powf(1.1)).cos() + 0.02 * k)
            .collect();
        let u = ks
            .clone()
            .map(|k| (0.9 * k).cos() + 0.3 * (2.1 * k + 0.4).sin())
            .collect();
        let x = ks.map(|k| 2.0 * (0.25 * k).sin() + 0.1 * k).collect();
        let modes = (0..80)
            .map(|k| match k % 7 {
                0..=2 => Mode::Up,
                3 | 4 => Mode::Down,
                _ => Mode::Held,
            })
            .collect();
        (e, u, x, modes)
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-9 * b.abs().max(1e-3)
    }

    #[test]
    fn ljung_box_and_cross_correlation_match_numpy() {
        let (e, u, _, _) = small();
        // Q = n (n + 2) sum_{l=1..5} r_l^2 / (n - l); chi2.ppf(0.95, 5).
        let v = ljung_box(&e, 5);
        assert!(close(v.statistic, 117.2271449265346), "{}", v.statistic);
        assert!(close(v.threshold, 11.070497693516351), "{}", v.threshold);
        assert!(v.rejects);
        assert!(
            v.detail.ends_with("largest autocorrelation 0.844 at lag 5"),
            "{}",
            v.detail
        );
        let c = cross_correlation(&e, &u, 6);
        let r = [
            0.09114875534533756,
            0.047659417670627084,
            -0.047604365152363305,
            -0.09052656560511146,
            -0.056754372285824216,
            0.012180457229958051,
            0.047594138601635784,
        ];
        for (a, b) in c.r.iter().zip(r) {
            assert!(close(*a, b), "{a} {b}");
        }
        assert_eq!(c.lags, (0..=6).collect::<Vec<_>>());
        assert!(close(c.band, 0.21913063514414538));
        assert!(c.outside.is_empty());
        assert!(close(c.verdict.statistic, 0.41595624128675296));
        assert!(!c.verdict.rejects);
        // e itself as the "input": lag 0 is 1, far outside the band.
        let own = cross_correlation(&e, &e, 3);
        assert!(close(own.r[0], 1.0));
        assert!(own.outside.contains(&0) && own.verdict.rejects);
    }

    #[test]
    fn billings_by_mode_and_against_x_match_numpy() {
        let (e, u, x, modes) = small();
        let b = billings(&e, &u, 4);
        let peaks = [
            3.8497631262144423,
            0.41595624128675296,
            0.4734272177555907,
            0.6636314858697671,
            0.32346694615038,
        ];
        for ((_, v), p) in b.functions.iter().zip(peaks) {
            let peak = v.iter().fold(0.0f64, |m, x| m.max(x.abs())) / b.band;
            assert!(close(peak, p), "{peak} {p}");
            assert_eq!(v.len(), 5);
        }
        assert!(close(b.verdict.statistic, 0.6636314858697671));
        assert!(!b.verdict.rejects);

        let (groups, v) = by_mode(&e, &modes);
        let want = [
            ("up", 36, 0.8504297189618152, 1.217654634636744),
            ("down", 22, 0.6633425325408094, 1.2262652371306302),
            ("held", 22, 0.8790917693121348, 1.2160060861135193),
        ];
        for (g, (label, count, mean, rms)) in groups.iter().zip(want) {
            assert_eq!((g.label.as_str(), g.count), (label, count));
            assert!(close(g.mean, mean) && close(g.rms, rms), "{g:?}");
        }
        // The worst group mean in standard errors of the overall rms; rms ratio 1.0084.
        assert!(close(v.statistic, 4.183894073218108), "{}", v.statistic);
        assert!(v.rejects);
        assert!(v.detail.ends_with("rms ratio 1.01"), "{}", v.detail);

        let a = against_x(&e, &x, &modes);
        assert!(close(a.statistic, 1.6738158355460249), "{}", a.statistic);
        assert!(!a.rejects);
        assert!(
            a.detail
                .contains("x_hat 0.431, x_hat^2 0.420, x_hat^3 0.387"),
            "{}",
            a.detail
        );
        assert!(a.detail.contains("58 engaged samples"), "{}", a.detail);
    }

    #[test]
    fn since_reversal_drift_and_spectrum_match_numpy() {
        let (e, _, x, modes) = small();
        // Samples s since the last direction change of x (none before the first change), in bins of
        // floor(log2(s + 1)), that is s = 0, 1-2, 3-6, 7-14, ...: counts 6, 12, 24, 30, then empty.
        let (groups, v) = since_reversal(&e, &x);
        let want = [
            (6, 0.8262201380091555, 1.2708948315532909),
            (12, 1.159644228636328, 1.4520497933077101),
            (24, 0.7981895215965609, 1.2021404640878406),
            (30, 0.803518904936991, 1.1791453106053018),
        ];
        assert_eq!(groups.len(), 8);
        for (g, (count, mean, rms)) in groups.iter().zip(want) {
            assert_eq!(g.count, count, "{g:?}");
            assert!(close(g.mean, mean) && close(g.rms, rms), "{g:?}");
        }
        assert!(groups[4..].iter().all(|g| g.count == 0));
        assert_eq!(groups[2].label, "3-6");
        assert!(close(v.statistic, 3.608674645112946), "{}", v.statistic);
        assert!(v.rejects);

        // CUSUM by mode: up 1.487 (36 samples), down 1.457 (22); late - early third means 0.852, 1.821.
        let d = drift(&e, &modes);
        assert!(close(d.statistic, 1.487011167370218), "{}", d.statistic);
        assert!(d.rejects);
        assert!(
            d.detail.contains("late - early mean 8.520e-1 (36"),
            "{}",
            d.detail
        );
        assert!(
            d.detail
                .contains("down: CUSUM 1.46, late - early mean 1.821e0 (22"),
            "{}",
            d.detail
        );

        // Periodogram zero-padded to 256 points: the peak is at 2 pi 53 / 256 rad/sample, 503.4 times the
        // median ordinate (the 65th smallest of 128); threshold (ln 40 + 6) / ln 2.
        let (w, s) = spectrum_peak(&e);
        assert!(close(w, 1.3008157081270237), "{w}");
        assert!(close(s.statistic, 503.36253452947955), "{}", s.statistic);
        assert!(close(s.threshold, 13.978098340221143), "{}", s.threshold);
        assert!(s.rejects);
    }

    /// By hand: a drop of 1 in the middle of 21 samples (ten 0s, eleven 1s). Centred, the CUSUM reaches
    /// 10 (11/21) = 110/21 at sample 10; sigma^2 = (10 (11/21)^2 + 11 (10/21)^2) / 21 = 2310 / 9261; the
    /// statistic 110/21 / (sigma sqrt 21) = 2.2886885 (NumPy); the last third (7 samples) minus the first is 1.
    #[test]
    fn drift_by_hand_on_a_step() {
        let e: Vec<f64> = (0..21).map(|k| if k < 10 { 0.0 } else { 1.0 }).collect();
        let modes = vec![Mode::Up; 21];
        let d = drift(&e, &modes);
        assert!(close(d.statistic, 2.2886885410853175), "{}", d.statistic);
        assert!(d.rejects);
        assert_eq!(
            d.detail,
            "up: CUSUM 2.29, late - early mean 1.000e0 (21 samples)"
        );
        // Fewer than 20 samples of a mode are not looked at.
        assert_eq!(drift(&e[..19], &modes[..19]).statistic, 0.0);
    }

    /// By hand: reversals are where the engaged direction changes, held samples in between ignored.
    #[test]
    fn reversals_by_hand() {
        use Mode::{Down, Held, Up};
        assert_eq!(reversals(&[Up, Held, Up, Down, Held, Down, Up]), vec![3, 6]);
        assert_eq!(reversals(&[Held, Down, Held, Down]), Vec::<usize>::new());
    }

    /// The lattice needs at least 99% of the distinct gaps on the step: values 0, 1, ..., 99 and 99.5, each
    /// twice (202 samples, 101 distinct values), leave 99 gaps of 1 and one of 0.5 (exactly 99%); the step
    /// is the gap at the 10th percentile, 1.
    #[test]
    fn lattice_accepts_exactly_ninety_nine_percent() {
        let mut y: Vec<f64> = (0..100).map(f64::from).collect();
        y.push(99.5);
        let twice: Vec<f64> = y.iter().chain(&y).copied().collect();
        let (q, v) = lattice(&twice);
        assert_eq!(q, Some(1.0), "{}", v.detail);
        assert!(v.rejects);
        // One more off-grid gap (100 -> 100.25 after 99.5 -> 100): 99 of 102 is below 99%.
        let mut more = twice.clone();
        more.extend([100.25, 100.25, 100.0, 100.0]);
        assert_eq!(lattice(&more).0, None);
    }

    #[test]
    fn extreme_increments_match_numpy() {
        // n = 120, y_hat(k) = 2 sin(0.15 k) + 0.01 k, e as in `small`: 10 rising samples in the top 15% and
        // 10 falling in the bottom 15%; slopes -1.9545 (t -0.920) and 2.2958 (t 1.107).
        let yh: Vec<f64> = (0..120)
            .map(|k| 2.0 * (0.15 * f64::from(k)).sin() + 0.01 * f64::from(k))
            .collect();
        let e: Vec<f64> = (0..120)
            .map(f64::from)
            .map(|k| (1.3 * k).sin() + 0.5 * (0.7 * k.powf(1.1)).cos() + 0.02 * k)
            .collect();
        let v = extreme_increments(&e, &yh);
        assert!(close(v.statistic, 1.1071154018110818), "{}", v.statistic);
        assert!(!v.rejects);
        assert_eq!(
            v.detail,
            "top 15%: slope -1.955 (t -0.9, 10 samples); bottom 15%: slope 2.296 (t 1.1, 10 samples)"
        );
        // The output clipped at +-1.5: at the top the residual's increments are exactly -dy_hat (slope -1,
        // zero scatter: t infinite).
        let clipped: Vec<f64> = yh.iter().map(|y| y.clamp(-1.5, 1.5) - y).collect();
        let v = extreme_increments(&clipped, &yh);
        assert_eq!(v.statistic, f64::INFINITY);
        assert!(v.rejects);
    }

    /// Held samples at an extreme are not moves: y_hat falls once to 0, holds there 19 samples, then rises
    /// 1, 2, ..., 19. Only one sample falls at the bottom and 7 rise at the top (fewer than 10 each), so the
    /// test has nothing to say, whatever the residual does while the output holds; likewise for an output held
    /// at its top.
    #[test]
    fn extreme_increments_ignore_held_samples() {
        let mut yh = vec![1.0];
        yh.extend([0.0; 20]);
        yh.extend((1..20).map(f64::from));
        let mut e = vec![0.0; yh.len()];
        e[1] = 0.5;
        e[5] = 0.1;
        let v = extreme_increments(&e, &yh);
        assert_eq!(v.statistic, 0.0);
        assert_eq!(v.detail, "too few samples at the extremes");
        // The mirror image: y_hat rises 0, 1, ..., 19, holds at 19 for 20 samples, falls once to 0; one
        // sample rises at the top.
        let mut yh: Vec<f64> = (0..20).map(f64::from).collect();
        yh.extend([19.0; 20]);
        yh.push(0.0);
        let mut e = vec![0.0; yh.len()];
        e[25] = 0.5;
        e[30] = 0.1;
        let v = extreme_increments(&e, &yh);
        assert_eq!(v.detail, "too few samples at the extremes");
    }

    /// The binomial allowance by hand: 21 lags, mean 1.05, variance 1.05 * 0.95 = 0.9975, so 1.05 + 1.96 *
    /// 0.998749 + 1 = 4.007511; 41 lags, mean 2.05, variance 1.9475, so 2.05 + 1.96 * 1.395529 + 1 = 5.785186.
    #[test]
    fn allowed_outside_is_the_binomial_upper_bound_plus_one() {
        assert!(
            (allowed_outside(21) - 4.007_511).abs() < 1e-5,
            "{}",
            allowed_outside(21)
        );
        assert!(
            (allowed_outside(41) - 5.785_186).abs() < 1e-5,
            "{}",
            allowed_outside(41)
        );
        assert_eq!(allowed_outside(0), 1.0);
    }

    /// Groups of at most ten samples are not judged: up and down alternate +-1 (mean 0, rms 1), and a held
    /// group alternating +-5 has five times their rms. Ten held samples leave the rms ratio at 1; twelve
    /// make it 5 and reject.
    #[test]
    fn mode_groups_of_ten_or_fewer_are_not_judged() {
        let verdict = |held: usize| {
            let mut e = Vec::new();
            let mut modes = Vec::new();
            for (mode, count, size) in [
                (Mode::Up, 50, 1.0),
                (Mode::Down, 50, 1.0),
                (Mode::Held, held, 5.0),
            ] {
                for k in 0..count {
                    e.push(if k % 2 == 0 { size } else { -size });
                    modes.push(mode);
                }
            }
            by_mode(&e, &modes).1
        };
        let ten = verdict(10);
        assert!(
            !ten.rejects && ten.detail.ends_with("rms ratio 1.00"),
            "{}",
            ten.detail
        );
        let twelve = verdict(12);
        assert!(
            twelve.rejects && twelve.detail.ends_with("rms ratio 5.00"),
            "{}",
            twelve.detail
        );
    }
}
