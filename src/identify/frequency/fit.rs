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

mod moments;

use moments::{Arc, Moments};

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

/// Column-major weighted design matrix `[1, c, .., c^n]` of a branch's rows `(c, w, weight)` into `a`, and the
/// weighted right-hand side into `b`.
fn design(rows: &[(f64, f64, f64)], p: usize, a: &mut Vec<f64>, b: &mut Vec<f64>) {
    let m = rows.len();
    a.clear();
    a.resize(m * p, 0.0);
    b.clear();
    for (i, &(c, w, sw)) in rows.iter().enumerate() {
        let mut v = sw;
        for k in 0..p {
            a[k * m + i] = v;
            v *= c;
        }
        b.push(sw * w);
    }
}

fn solve_branch(rows: &[(f64, f64, f64)], p: usize) -> Branch {
    let m = rows.len();
    if m == 0 {
        return Branch {
            theta: vec![0.0; p],
            ss: 0.0,
            rows: 0,
            rank: 0,
        };
    }
    let (mut a, mut b) = (Vec::new(), Vec::new());
    design(rows, p, &mut a, &mut b);
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
    if !householder(a, b, m, p, &mut Vec::new(), &mut diag) {
        return None;
    }
    let mut theta = vec![0.0; p];
    for k in (0..p).rev() {
        let mut s = b[k];
        for j in k + 1..p {
            s -= a[j * m + k] * theta[j];
        }
        theta[k] = s / diag[k];
    }
    Some((theta, residual_ss(b, p)))
}

/// The residual sum of squares of a reduced right-hand side.
fn residual_ss(b: &[f64], p: usize) -> f64 {
    b[p..].iter().map(|v| v * v).sum()
}

/// Householder reduction of `a` (column-major `m x p`, `m >= p`) to `R` in place, `b` to `Q^T b`, the
/// diagonal of `R` in `diag`; `v` is a work buffer. False when a diagonal element of `R` is negligible.
fn householder(
    a: &mut [f64],
    b: &mut [f64],
    m: usize,
    p: usize,
    v: &mut Vec<f64>,
    diag: &mut [f64],
) -> bool {
    let mut rmax = 0.0f64;
    for k in 0..p {
        let col = &a[k * m..(k + 1) * m];
        let norm = col[k..].iter().map(|v| v * v).sum::<f64>().sqrt();
        rmax = rmax.max(norm);
        if norm == 0.0 || norm <= 1e-13 * rmax {
            return false;
        }
        let alpha = if col[k] > 0.0 { -norm } else { norm };
        // v = x - alpha e1; v^T v = 2 norm (norm + |x0|).
        v.clear();
        v.extend_from_slice(&col[k..]);
        v[0] -= alpha;
        let vtv: f64 = v.iter().map(|x| x * x).sum();
        diag[k] = alpha;
        for j in k + 1..p {
            let cj = &mut a[j * m + k..(j + 1) * m];
            let f = 2.0 * v.iter().zip(cj.iter()).map(|(x, y)| x * y).sum::<f64>() / vtv;
            for (y, x) in cj.iter_mut().zip(v.iter()) {
                *y -= f * x;
            }
        }
        let f = 2.0 * v.iter().zip(&b[k..]).map(|(x, y)| x * y).sum::<f64>() / vtv;
        for (y, x) in b[k..].iter_mut().zip(v.iter()) {
            *y -= f * x;
        }
    }
    true
}

/// Work buffers of [`Problem::cost`], kept per thread between calls.
#[derive(Default)]
struct Scratch {
    asc: Vec<(f64, f64, f64)>,
    desc: Vec<(f64, f64, f64)>,
    a: Vec<f64>,
    b: Vec<f64>,
    v: Vec<f64>,
    diag: Vec<f64>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// `solve_branch(rows, p).ss`, in the buffers of `s` (the same arithmetic, without allocating).
fn branch_ss(
    rows: &[(f64, f64, f64)],
    p: usize,
    a: &mut Vec<f64>,
    b: &mut Vec<f64>,
    v: &mut Vec<f64>,
    diag: &mut Vec<f64>,
) -> f64 {
    let m = rows.len();
    if m == 0 {
        return 0.0;
    }
    design(rows, p, a, b);
    diag.resize(p, 0.0);
    if m >= p && householder(a, b, m, p, v, diag) {
        return residual_ss(b, p);
    }
    solve_branch(rows, p).ss
}

impl Problem<'_> {
    /// The rows `(c, w, weight)` of each branch at phase `psi`.
    fn rows(&self, psi: f64, asc: &mut Vec<(f64, f64, f64)>, desc: &mut Vec<(f64, f64, f64)>) {
        asc.clear();
        desc.clear();
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
    }

    /// Solve (24) at phase `psi`.
    pub fn fit(&self, psi: f64) -> Fit {
        let (mut asc, mut desc) = (Vec::new(), Vec::new());
        self.rows(psi, &mut asc, &mut desc);
        Fit {
            ascending: solve_branch(&asc, self.p),
            descending: solve_branch(&desc, self.p),
        }
    }

    /// `self.fit(psi).cost()`, bit for bit, without allocating.
    pub fn cost(&self, psi: f64) -> f64 {
        SCRATCH.with_borrow_mut(|s| {
            let Scratch {
                asc,
                desc,
                a,
                b,
                v,
                diag,
            } = s;
            self.rows(psi, asc, desc);
            let ss_asc = branch_ss(asc, self.p, a, b, v, diag);
            ss_asc + branch_ss(desc, self.p, a, b, v, diag)
        })
    }

    /// Number of bins in the optimisation set.
    pub fn included(&self) -> usize {
        self.include.iter().filter(|&&b| b).count()
    }

    /// Minimise the cost over `[lo, hi]` with a grid of at most `spacing` and golden-section refinement of
    /// the best local minima of the grid. `periodic`: the interval is one period of the cost.
    ///
    /// The grid's values come from the prefix sums of [`moments`]; only the points that may be local
    /// minima within that evaluation's error are evaluated exactly, with their neighbours, so the minima
    /// and the result are those of an exact grid.
    pub fn minimise(&self, lo: f64, hi: f64, spacing: f64, periodic: bool) -> (f64, f64) {
        #[cfg(test)]
        if EXACT_GRID.get() {
            return self.minimise_exact(lo, hi, spacing, periodic);
        }
        let grid = Grid::new(lo, hi, spacing, periodic);
        let minima = self
            .grid_minima(&grid)
            .unwrap_or_else(|| self.exact_grid_minima(&grid));
        self.refine(&grid, &minima)
    }

    /// The best three local minima of the grid (index, exact cost) from the fast evaluation; `None` if it
    /// found none (its error bound failed).
    fn grid_minima(&self, grid: &Grid) -> Option<Vec<(usize, f64)>> {
        let pts = &grid.pts;
        let moments = Moments::new(self);
        let mut arc = Arc::new(self.phase);
        let fast: Vec<Option<(f64, f64)>> = pts
            .iter()
            .map(|&x| {
                let (start, len) = arc.locate(x)?;
                moments.cost(x, start, len)
            })
            .collect();
        let mut exact: Vec<Option<f64>> = vec![None; pts.len()];
        let mut value = |i: usize| *exact[i].get_or_insert_with(|| self.cost(pts[i]));
        let mut minima = Vec::new();
        for i in 0..pts.len() {
            let (l, r) = grid.neighbours(i);
            // Within the evaluations' errors, is point i at most its neighbours?
            let maybe = match (fast[i], fast[l], fast[r]) {
                (Some((f, e)), Some((fl, el)), Some((fr, er))) => {
                    f <= fl + e + el && f <= fr + e + er
                }
                _ => true,
            };
            if maybe {
                let v = value(i);
                if v <= value(l) && v <= value(r) {
                    minima.push((i, v));
                }
            }
        }
        (!minima.is_empty()).then(|| best_three(minima))
    }

    /// [`Self::grid_minima`] with every grid point evaluated exactly.
    fn exact_grid_minima(&self, grid: &Grid) -> Vec<(usize, f64)> {
        let vals: Vec<f64> = grid.pts.iter().map(|&x| self.cost(x)).collect();
        let minima = (0..vals.len())
            .filter(|&i| {
                let (l, r) = grid.neighbours(i);
                vals[i] <= vals[l] && vals[i] <= vals[r]
            })
            .map(|i| (i, vals[i]))
            .collect();
        best_three(minima)
    }

    /// Golden-section refinement around each grid minimum; the best point found.
    fn refine(&self, grid: &Grid, minima: &[(usize, f64)]) -> (f64, f64) {
        let (pts, h) = (&grid.pts, grid.step);
        let mut best = (pts[minima[0].0], minima[0].1);
        for &(i, v) in minima {
            let (x, f) = golden(|x| self.cost(x), pts[i] - h, pts[i] + h, pts[i], v);
            if f < best.1 {
                best = (x, f);
            }
        }
        best
    }

    /// [`Self::minimise`] with an exact grid: the reference the fast grid is tested against.
    #[cfg(test)]
    pub fn minimise_exact(&self, lo: f64, hi: f64, spacing: f64, periodic: bool) -> (f64, f64) {
        let grid = Grid::new(lo, hi, spacing, periodic);
        self.refine(&grid, &self.exact_grid_minima(&grid))
    }
}

#[cfg(test)]
thread_local! {
    /// Tests set it to run [`Problem::minimise`] on an exact grid in this thread, as a reference.
    pub(super) static EXACT_GRID: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// The phase grid of [`Problem::minimise`].
struct Grid {
    pts: Vec<f64>,
    step: f64,
    periodic: bool,
}

impl Grid {
    fn new(lo: f64, hi: f64, spacing: f64, periodic: bool) -> Grid {
        let width = hi - lo;
        let n = ((width / spacing).ceil() as usize).max(2);
        let pts: Vec<f64> = if periodic {
            (0..n).map(|i| lo + width * i as f64 / n as f64).collect()
        } else {
            (0..=n).map(|i| lo + width * i as f64 / n as f64).collect()
        };
        Grid {
            pts,
            step: width / n as f64,
            periodic,
        }
    }

    /// The points either side of point `i` (itself at an end of a non-periodic grid).
    fn neighbours(&self, i: usize) -> (usize, usize) {
        let m = self.pts.len();
        if self.periodic {
            ((i + m - 1) % m, (i + 1) % m)
        } else {
            (i.saturating_sub(1), (i + 1).min(m - 1))
        }
    }
}

/// The three lowest of the local minima (index, value), in order; ties keep the grid's order.
fn best_three(mut minima: Vec<(usize, f64)>) -> Vec<(usize, f64)> {
    minima.sort_by(|a, b| a.1.total_cmp(&b.1));
    minima.truncate(3);
    minima
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
    fn the_fast_grid_cost_is_within_its_error_bound() {
        // 300 bins of a cubic-border cycle with deterministic pseudo-noise, a stage excluded or not, a
        // large offset; the prefix-sum cost against the QR cost at 1000 phases, within a tenth of its bound.
        let b = 300;
        let psi = 0.7;
        let phase: Vec<f64> = (0..b).map(|j| TAU * j as f64 / b as f64 - 0.3).collect();
        let w: Vec<f64> = phase
            .iter()
            .enumerate()
            .map(|(j, &r)| {
                let c = (r - psi).cos();
                let noise = 0.01 * ((j * 7919 % 1000) as f64 / 500.0 - 1.0);
                let border = if sigma(r, psi) {
                    0.3 + 0.8 * c + 0.2 * c * c
                } else {
                    -0.25 + 0.9 * c + 0.15 * c * c * c
                };
                5.0 + border + noise
            })
            .collect();
        for (degree, excluded) in [(1, 0..0), (3, 0..0), (6, 0..0), (3, 40..70), (6, 200..260)] {
            let pb = Problem {
                phase: &phase,
                w: &w,
                sw: (0..b).map(|j| (1.0 + (j % 3) as f64).sqrt()).collect(),
                include: (0..b).map(|j| !excluded.contains(&j)).collect(),
                p: degree + 1,
            };
            let m = Moments::new(&pb);
            let mut arc = Arc::new(&phase);
            // The largest error as a fraction of its bound.
            let mut worst = 0.0f64;
            let mut trusted = 0;
            for i in 0..1000 {
                let x = -1.0 + 5.0 * i as f64 / 1000.0;
                let (start, len) = arc.locate(x).expect("one run");
                if let Some((f, bound)) = m.cost(x, start, len) {
                    worst = worst.max((f - pb.cost(x)).abs() / bound);
                    trusted += 1;
                }
            }
            assert!(trusted >= 900, "degree {degree}: {trusted} of 1000 trusted");
            assert!(worst < 0.1, "degree {degree}: error {worst:e} of its bound");
        }
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
