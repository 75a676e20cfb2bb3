//! The lumped-parameter fit of paper 003, eqs. (14)-(15) and (22)-(26), on the averaged period, the
//! search over the phase, and the constant-stage candidates of Table 1.
//!
//! For a phase `psi` the regressor (15b) splits the period into two halves: `sigma = 1` where
//! `sin(rho - psi) >= 0` (x decreasing: the descending border, parameters `delta_i`) and `sigma = 0`
//! elsewhere (x increasing: the ascending border, `alpha_i`), with powers of `c = cos(rho - psi)`. The
//! normal matrix of (23b)/(24) is block diagonal, so the two halves are two independent polynomial least
//! squares problems of size `n + 1`. Their rows are weighted by the square root of the number of samples
//! averaged in each bin, so that the cost is the sample-level cost (22). They are solved by Householder QR
//! on the rows (SVD when a branch is rank-deficient), which keeps the residual accurate to rounding even
//! when a branch covers only a short range of `c`.
//!
//! The cost is `pi`-periodic in `psi` (`psi + pi` gives the dual parameterisation, eqs. (6)-(7) and
//! (16)-(17), with the same residual), so `psi` is searched in `[0, pi)`, eq. (25a).

use std::f64::consts::{PI, TAU};

use nalgebra::{DMatrix, DVector};

/// The cost (22) on a fixed set of bins.
pub(super) struct Problem<'a> {
    pub phase: &'a [f64],
    pub w: &'a [f64],
    /// Square roots of the bins' sample counts (row weights).
    pub sw: Vec<f64>,
    /// Bins in the optimisation set `I_N`.
    pub include: Vec<bool>,
    /// Parameters per branch, `n + 1`.
    pub p: usize,
}

/// Least-squares solution of one branch.
#[derive(Debug, Clone)]
pub(super) struct Branch {
    pub theta: Vec<f64>,
    /// Weighted residual sum of squares.
    pub ss: f64,
    pub rows: usize,
    pub rank: usize,
}

/// Both branches at one phase.
#[derive(Debug, Clone)]
pub(super) struct Fit {
    pub ascending: Branch,
    pub descending: Branch,
}

impl Fit {
    /// The cost (22), weighted by the bins' sample counts.
    pub fn cost(&self) -> f64 {
        self.ascending.ss + self.descending.ss
    }
}

/// `sigma(psi, rho)` of eq. (13): 1 on `[psi, psi + pi)` modulo `2 pi`.
pub(super) fn sigma(rho: f64, psi: f64) -> bool {
    (rho - psi).rem_euclid(TAU) < PI
}

fn solve_branch(rows: &[(f64, f64, f64)], p: usize) -> Branch {
    // rows: (c, w, weight)
    let m = rows.len();
    if m == 0 {
        return Branch {
            theta: vec![0.0; p],
            ss: 0.0,
            rows: 0,
            rank: 0,
        };
    }
    // Column-major weighted design matrix [1, c, .., c^n] and right-hand side.
    let mut a = vec![0.0; m * p];
    let mut b = Vec::with_capacity(m);
    for (i, &(c, w, sw)) in rows.iter().enumerate() {
        let mut v = sw;
        for k in 0..p {
            a[k * m + i] = v;
            v *= c;
        }
        b.push(sw * w);
    }
    if m >= p
        && let Some((theta, ss)) = householder_lstsq(&mut a.clone(), &mut b.clone(), m, p)
    {
        return Branch {
            theta,
            ss,
            rows: m,
            rank: p,
        };
    }
    // Rank-deficient (too few distinct rows): minimum-norm solution by SVD.
    let am = DMatrix::from_column_slice(m, p, &a);
    let bm = DVector::from_column_slice(&b);
    let svd = am.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let eps = smax * 1e-12 * (m.max(p) as f64);
    let rank = svd.singular_values.iter().filter(|&&s| s > eps).count();
    let theta = svd.solve(&bm, eps).unwrap_or_else(|_| DVector::zeros(p));
    let r = &bm - &am * &theta;
    Branch {
        theta: theta.iter().copied().collect(),
        ss: r.norm_squared(),
        rows: m,
        rank,
    }
}

/// Least squares by Householder QR of the column-major `m x p` matrix `a` (`m >= p`): the solution and
/// the residual sum of squares (from the trailing part of `Q^T b`, accurate to rounding). `None` when a
/// diagonal element of `R` is negligible (rank deficiency).
fn householder_lstsq(a: &mut [f64], b: &mut [f64], m: usize, p: usize) -> Option<(Vec<f64>, f64)> {
    let mut diag = vec![0.0; p];
    let mut rmax = 0.0f64;
    for k in 0..p {
        let col = &a[k * m..(k + 1) * m];
        let norm = col[k..].iter().map(|v| v * v).sum::<f64>().sqrt();
        rmax = rmax.max(norm);
        if norm == 0.0 || norm <= 1e-13 * rmax {
            return None;
        }
        let alpha = if col[k] > 0.0 { -norm } else { norm };
        // v = x - alpha e1, stored in place of the column; v^T v = 2 norm (norm + |x0|).
        let mut v: Vec<f64> = col[k..].to_vec();
        v[0] -= alpha;
        let vtv: f64 = v.iter().map(|x| x * x).sum();
        diag[k] = alpha;
        for j in k + 1..p {
            let cj = &mut a[j * m + k..(j + 1) * m];
            let f = 2.0 * v.iter().zip(cj.iter()).map(|(x, y)| x * y).sum::<f64>() / vtv;
            for (y, x) in cj.iter_mut().zip(&v) {
                *y -= f * x;
            }
        }
        let f = 2.0 * v.iter().zip(&b[k..]).map(|(x, y)| x * y).sum::<f64>() / vtv;
        for (y, x) in b[k..].iter_mut().zip(&v) {
            *y -= f * x;
        }
    }
    let mut theta = vec![0.0; p];
    for k in (0..p).rev() {
        let mut s = b[k];
        for j in k + 1..p {
            s -= a[j * m + k] * theta[j];
        }
        theta[k] = s / diag[k];
    }
    let ss = b[p..].iter().map(|v| v * v).sum();
    Some((theta, ss))
}

impl Problem<'_> {
    /// Solve (24) at phase `psi`.
    pub fn fit(&self, psi: f64) -> Fit {
        let mut asc = Vec::with_capacity(self.w.len());
        let mut desc = Vec::with_capacity(self.w.len());
        for j in 0..self.w.len() {
            if !self.include[j] {
                continue;
            }
            let r = self.phase[j] - psi;
            let row = (r.cos(), self.w[j], self.sw[j]);
            if sigma(self.phase[j], psi) {
                desc.push(row);
            } else {
                asc.push(row);
            }
        }
        Fit {
            ascending: solve_branch(&asc, self.p),
            descending: solve_branch(&desc, self.p),
        }
    }

    pub fn cost(&self, psi: f64) -> f64 {
        self.fit(psi).cost()
    }

    /// Number of bins in the optimisation set.
    pub fn included(&self) -> usize {
        self.include.iter().filter(|&&b| b).count()
    }

    /// Minimise the cost over `[lo, hi]` with a grid of at most `spacing` and golden-section refinement of
    /// the best local minima of the grid. `periodic`: the interval is one period of the cost.
    pub fn minimise(&self, lo: f64, hi: f64, spacing: f64, periodic: bool) -> (f64, f64) {
        let width = hi - lo;
        let n = ((width / spacing).ceil() as usize).max(2);
        let pts: Vec<f64> = if periodic {
            (0..n).map(|i| lo + width * i as f64 / n as f64).collect()
        } else {
            (0..=n).map(|i| lo + width * i as f64 / n as f64).collect()
        };
        let h = width / n as f64;
        let vals: Vec<f64> = pts.iter().map(|&x| self.cost(x)).collect();
        let m = pts.len();
        let mut minima: Vec<usize> = (0..m)
            .filter(|&i| {
                let (l, r) = if periodic {
                    ((i + m - 1) % m, (i + 1) % m)
                } else {
                    (i.saturating_sub(1), (i + 1).min(m - 1))
                };
                vals[i] <= vals[l] && vals[i] <= vals[r]
            })
            .collect();
        minima.sort_by(|&a, &b| vals[a].total_cmp(&vals[b]));
        minima.truncate(3);
        let mut best = (pts[minima[0]], vals[minima[0]]);
        for &i in &minima {
            let (x, f) = golden(|x| self.cost(x), pts[i] - h, pts[i] + h, pts[i], vals[i]);
            if f < best.1 {
                best = (x, f);
            }
        }
        best
    }
}

/// Golden-section search on `[a, b]`, keeping the best point seen (`x0`, `f0` included).
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64, x0: f64, f0: f64) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut best = (x0, f0);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let mut fc = f(c);
    let mut fd = f(d);
    for _ in 0..80 {
        if fc < best.1 {
            best = (c, fc);
        }
        if fd < best.1 {
            best = (d, fd);
        }
        if (b - a).abs() < 1e-12 {
            break;
        }
        if fc <= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    if fc < best.1 {
        best = (c, fc);
    }
    if fd < best.1 {
        best = (d, fd);
    }
    best
}

/// A run of bins where the averaged output is flat: `len` bins from `start`, circularly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Run {
    pub start: usize,
    pub len: usize,
}

impl Run {
    pub fn contains(&self, j: usize, b: usize) -> bool {
        (j + b - self.start) % b < self.len
    }

    /// Phases of the first and last bins, unwrapped so that `last >= first`.
    pub fn phases(&self, phase: &[f64]) -> (f64, f64) {
        let b = phase.len();
        let first = phase[self.start];
        let end = (self.start + self.len - 1) % b;
        let mut last = phase[end];
        while last < first {
            last += TAU;
        }
        (first, last)
    }
}

/// Maximal circular runs of at least two bins whose values stay within a band of `2 tol` (the largest
/// tolerance of their bins), longest first.
pub(super) fn flat_runs(w: &[f64], tol: &[f64]) -> Vec<Run> {
    let b = w.len();
    let mut ends = vec![0usize; b];
    for s in 0..b {
        let (mut lo, mut hi, mut t) = (w[s], w[s], tol[s]);
        let mut e = s + 1;
        while e < s + b - 1 {
            let v = w[e % b];
            let (nlo, nhi, nt) = (lo.min(v), hi.max(v), t.max(tol[e % b]));
            if nhi - nlo > 2.0 * nt {
                break;
            }
            (lo, hi, t) = (nlo, nhi, nt);
            e += 1;
        }
        ends[s] = e;
    }
    let mut runs: Vec<Run> = (0..b)
        .filter(|&s| {
            // Keep a run unless the run starting one bin earlier already covers it.
            let prev_end = if s == 0 { ends[b - 1] - b } else { ends[s - 1] };
            prev_end < ends[s] || (s == 0 && ends[b - 1] < b)
        })
        .map(|s| Run {
            start: s,
            len: ends[s] - s,
        })
        .filter(|r| r.len >= 2)
        .collect();
    runs.sort_by(|a, b| b.len.cmp(&a.len).then(a.start.cmp(&b.start)));
    runs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn branches_recover_exact_polynomials() {
        // 40 bins; w = 0.3 + 2c - c^3 on the ascending half, -0.5 + c + c^2 on the descending half,
        // psi = 1.1.
        let b = 40;
        let psi = 1.1;
        let phase: Vec<f64> = (0..b).map(|j| TAU * j as f64 / b as f64 + 0.01).collect();
        let w: Vec<f64> = phase
            .iter()
            .map(|&r| {
                let c = (r - psi).cos();
                if sigma(r, psi) {
                    -0.5 + c + c * c
                } else {
                    0.3 + 2.0 * c - c * c * c
                }
            })
            .collect();
        let pb = Problem {
            phase: &phase,
            w: &w,
            sw: vec![1.0; b],
            include: vec![true; b],
            p: 4,
        };
        let f = pb.fit(psi);
        assert!(f.cost() < 1e-25);
        let want_a = [0.3, 2.0, 0.0, -1.0];
        let want_d = [-0.5, 1.0, 1.0, 0.0];
        for i in 0..4 {
            assert!((f.ascending.theta[i] - want_a[i]).abs() < 1e-10);
            assert!((f.descending.theta[i] - want_d[i]).abs() < 1e-10);
        }
        // The search finds psi (mod pi) to rounding.
        let (found, j) = pb.minimise(0.0, PI, PI / 200.0, true);
        let err = (found - psi).rem_euclid(PI);
        assert!(err.min(PI - err) < 1e-9, "{found} {j}");
        // The dual phase has the same cost.
        assert!((pb.cost(psi + PI) - pb.cost(psi)).abs() < 1e-20);
    }

    #[test]
    fn flat_runs_are_found_circularly() {
        let w = [1.0, 1.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0, 1.0, 1.0];
        let tol = [0.01; 10];
        let runs = flat_runs(&w, &tol);
        assert_eq!(runs[0], Run { start: 8, len: 5 });
        assert_eq!(runs[1], Run { start: 6, len: 2 });
        assert_eq!(runs.len(), 2);
        assert!(runs[0].contains(0, 10) && runs[0].contains(9, 10) && !runs[0].contains(3, 10));
    }
}
