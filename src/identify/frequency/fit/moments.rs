//! The cost (22) at many phases at once: the grid of the phase search (eq. (25a)) in `O(n^2)` per phase
//! instead of a least-squares solve over every bin.
//!
//! The columns `1, c, .., c^n` of a branch (`c = cos(rho - psi)`) span the same space as the Chebyshev
//! columns `cos(k (rho - psi))`, `k = 0..n` (`T_k(cos t) = cos(k t)`), so both give the same residual.
//! In that basis every entry of the normal equations is a sum over the branch's bins of
//! `count cos(m (rho - psi))` or `count w cos(k (rho - psi))`, and `cos(m (rho - psi))` splits into
//! `cos(m rho) cos(m psi) + sin(m rho) sin(m psi)`: with prefix sums over the bins (in phase order) of
//! `count cos(m rho)`, `count sin(m rho)` (`m <= 2n`), of the same times `w` (`k <= n`) and of
//! `count w^2`, a branch's normal equations at any phase cost `O(n^2)`, whatever the number of bins. A
//! branch is a half period: a circular run of bins, which a sweep over increasing phases follows in `O(1)`
//! per phase.
//!
//! The value is the normal equations' residual: its error grows with their condition number, not accurate
//! to rounding as the QR solve of [`super`]. Each value comes with a bound on that error
//! ([`ERROR_PER_BIN`] times the bins, the condition number and the output's sum of squares), and
//! [`super::Problem::minimise`] only uses it to skip the grid points that cannot be minima within the
//! bounds; it recomputes the others exactly. A branch whose normal equations are too ill-conditioned (too
//! few bins) gives no value, and the exact solve is used there.

use super::{Problem, sigma};
use crate::identify::frequency::MAX_DEGREE;

/// Error of a value per bin summed, per unit of condition number and of `sum count w^2`: rounding (1.1e-16)
/// with a factor 10 of margin; the tests of `fit` hold the actual error under a tenth of the bound.
const ERROR_PER_BIN: f64 = 1e-15;

/// Largest condition estimate accepted (`p` times the ratio of the largest to the smallest squared Cholesky
/// pivot); beyond it the bound says nothing useful.
const MAX_CONDITION: f64 = 1e10;

/// Values per bin at the highest degree.
const MAX_STRIDE: usize = 2 * (2 * MAX_DEGREE + 1) + 2 * (MAX_DEGREE + 1) + 2;

/// Prefix sums over the bins of the quantities of the module documentation.
pub(super) struct Moments {
    bins: usize,
    /// Parameters per branch, `n + 1`.
    p: usize,
    /// Values per bin: `2 (2n + 1)` angle moments, `2 (n + 1)` output moments, `sum count w^2`, rows.
    stride: usize,
    /// `(bins + 1) * stride`, row `j` the sums over bins `0..j`.
    prefix: Vec<f64>,
    /// `sum count w^2` over the included bins.
    pub total_ss: f64,
}

impl Moments {
    pub fn new(pb: &Problem) -> Moments {
        let b = pb.w.len();
        let p = pb.p;
        let angles = 2 * p - 1;
        let stride = 2 * angles + 2 * p + 2;
        let mut prefix = vec![0.0; (b + 1) * stride];
        let mut row = vec![0.0; stride];
        for j in 0..b {
            row.iter_mut().for_each(|v| *v = 0.0);
            if pb.include[j] {
                let cnt = pb.sw[j] * pb.sw[j];
                let w = pb.w[j];
                let mut trig = [(0.0, 0.0); 2 * MAX_DEGREE + 1];
                multiples(pb.phase[j], &mut trig[..angles]);
                for (m, &(c, s)) in trig[..angles].iter().enumerate() {
                    row[2 * m] = cnt * c;
                    row[2 * m + 1] = cnt * s;
                    if m < p {
                        row[2 * angles + 2 * m] = cnt * w * c;
                        row[2 * angles + 2 * m + 1] = cnt * w * s;
                    }
                }
                row[stride - 2] = cnt * w * w;
                row[stride - 1] = 1.0;
            }
            let (done, rest) = prefix.split_at_mut((j + 1) * stride);
            let before = &done[j * stride..];
            for ((out, prev), v) in rest[..stride].iter_mut().zip(before).zip(&row) {
                *out = prev + v;
            }
        }
        let total_ss = prefix[b * stride + stride - 2];
        Moments {
            bins: b,
            p,
            stride,
            prefix,
            total_ss,
        }
    }

    /// Sums over the circular run of `len` bins from `start` (into `out`), and over the other bins (into
    /// `rest`).
    fn run_sums(&self, start: usize, len: usize, out: &mut [f64], rest: &mut [f64]) {
        let s = self.stride;
        let at = |j: usize| &self.prefix[j * s..(j + 1) * s];
        let end = start + len;
        let all = at(self.bins);
        if end <= self.bins {
            let (to, from) = (at(end), at(start));
            for i in 0..s {
                out[i] = to[i] - from[i];
                rest[i] = all[i] - out[i];
            }
        } else {
            let (from, wrap) = (at(start), at(end - self.bins));
            for i in 0..s {
                out[i] = all[i] - from[i] + wrap[i];
                rest[i] = from[i] - wrap[i];
            }
        }
    }

    /// The cost at `psi` whose descending branch is the run `(start, len)` (from [`Arc::locate`]), and a
    /// bound on its error; `None` where the normal equations are not trusted.
    pub fn cost(&self, psi: f64, start: usize, len: usize) -> Option<(f64, f64)> {
        let mut desc = [0.0; MAX_STRIDE];
        let mut asc = [0.0; MAX_STRIDE];
        self.run_sums(start, len, &mut desc, &mut asc);
        let mut trig = [(0.0, 0.0); 2 * MAX_DEGREE + 1];
        multiples(psi, &mut trig[..2 * self.p - 1]);
        let (fd, cd) = self.branch_cost(&desc, &trig)?;
        let (fa, ca) = self.branch_cost(&asc, &trig)?;
        let bound = ERROR_PER_BIN * self.bins as f64 * cd.max(ca) * self.total_ss;
        Some((fd + fa, bound))
    }

    /// One branch's residual from its sums (normal equations in the Chebyshev basis, Cholesky), and the
    /// condition estimate.
    fn branch_cost(&self, sums: &[f64], trig: &[(f64, f64)]) -> Option<(f64, f64)> {
        let p = self.p;
        if sums[self.stride - 1] < p as f64 - 0.5 {
            return None;
        }
        let angles = 2 * p - 1;
        let mut cm = [0.0; 2 * MAX_DEGREE + 1];
        let mut rhs = [0.0; MAX_DEGREE + 1];
        for (m, &(c, s)) in trig[..angles].iter().enumerate() {
            cm[m] = c * sums[2 * m] + s * sums[2 * m + 1];
            if m < p {
                rhs[m] = c * sums[2 * angles + 2 * m] + s * sums[2 * angles + 2 * m + 1];
            }
        }
        // G_kl = sum count cos(k t) cos(l t) = (C_|k-l| + C_(k+l)) / 2; Cholesky in place, lower part.
        const P: usize = MAX_DEGREE + 1;
        let mut g = [[0.0; P]; P];
        for k in 0..p {
            for l in 0..=k {
                g[k][l] = 0.5 * (cm[k - l] + cm[k + l]);
            }
        }
        let (mut dmin, mut dmax) = (f64::INFINITY, 0.0f64);
        for k in 0..p {
            for l in 0..=k {
                let s = g[k][l] - (0..l).map(|i| g[k][i] * g[l][i]).sum::<f64>();
                if l == k {
                    if s.is_nan() || s <= 0.0 {
                        return None;
                    }
                    (dmin, dmax) = (dmin.min(s), dmax.max(s));
                    g[k][k] = s.sqrt();
                } else {
                    g[k][l] = s / g[l][l];
                }
            }
        }
        let condition = p as f64 * dmax / dmin;
        if condition > MAX_CONDITION {
            return None;
        }
        // Forward substitution L z = rhs; the residual is yy - |z|^2.
        let mut z = [0.0; P];
        for k in 0..p {
            z[k] = (rhs[k] - (0..k).map(|i| g[k][i] * z[i]).sum::<f64>()) / g[k][k];
        }
        Some((
            sums[self.stride - 2] - z[..p].iter().map(|v| v * v).sum::<f64>(),
            condition,
        ))
    }
}

/// `(cos m x, sin m x)` for `m = 0, 1, ..` into `out`, by rotations of `x` (one `sin_cos`; the error grows
/// by about one rounding per multiple, far inside the bound of [`ERROR_PER_BIN`]).
fn multiples(x: f64, out: &mut [(f64, f64)]) {
    let (s1, c1) = x.sin_cos();
    let (mut c, mut s) = (1.0, 0.0);
    for v in out.iter_mut() {
        *v = (c, s);
        (c, s) = (c * c1 - s * s1, s * c1 + c * s1);
    }
}

/// The descending branch (bins with `sigma(rho, psi)`, eq. (13)) as a circular run of bins, followed over
/// increasing phases.
pub(super) struct Arc<'a> {
    phase: &'a [f64],
    start: usize,
    len: usize,
    known: bool,
}

impl<'a> Arc<'a> {
    pub fn new(phase: &'a [f64]) -> Arc<'a> {
        Arc {
            phase,
            start: 0,
            len: 0,
            known: false,
        }
    }

    /// `(start, len)` of the run at `psi`, by the exact rule of [`sigma`]; `None` if the bins in the branch
    /// do not form one run (rounding at a bin's edge can only move a boundary by a bin). Cheapest when
    /// called with increasing `psi`.
    pub fn locate(&mut self, psi: f64) -> Option<(usize, usize)> {
        let b = self.phase.len();
        let g = |j: usize| sigma(self.phase[j % b], psi);
        if self.known {
            while self.len > 0 && !g(self.start) {
                self.start = (self.start + 1) % b;
                self.len -= 1;
            }
            while self.len < b && g(self.start + self.len) {
                self.len += 1;
            }
        }
        let valid = |s: usize, len: usize| {
            len > 0 && len < b && g(s) && g(s + len - 1) && !g(s + b - 1) && !g(s + len)
        };
        if !(self.known && valid(self.start, self.len)) {
            self.known = false;
            let flags: Vec<bool> = (0..b).map(g).collect();
            let len = flags.iter().filter(|&&f| f).count();
            let mut starts = (0..b).filter(|&j| flags[j] && !flags[(j + b - 1) % b]);
            let start = starts.next()?;
            if starts.next().is_some() || !valid(start, len) {
                return None;
            }
            (self.start, self.len, self.known) = (start, len, true);
        }
        Some((self.start, self.len))
    }
}
