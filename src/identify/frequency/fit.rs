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
    /// `(cos rho, sin rho)` of each bin: a row's `cos(rho - psi)` by the angle difference, no cosine per
    /// solve.
    trig: Vec<(f64, f64)>,
}

/// One bin's row at a phase `psi`: `c = cos(rho - psi)`, `s = sin(rho - psi)` (`dc/dpsi`), the averaged
/// output and the row weight.
#[derive(Debug, Clone, Copy)]
struct Row {
    c: f64,
    s: f64,
    w: f64,
    sw: f64,
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
fn design(rows: &[Row], p: usize, a: &mut Vec<f64>, b: &mut Vec<f64>) {
    let m = rows.len();
    a.clear();
    a.resize(m * p, 0.0);
    b.clear();
    for (i, row) in rows.iter().enumerate() {
        let mut v = row.sw;
        for k in 0..p {
            a[k * m + i] = v;
            v *= row.c;
        }
        b.push(row.sw * row.w);
    }
}

fn solve_branch(rows: &[Row], p: usize) -> Branch {
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
    back_substitute(a, b, &diag, m, &mut theta);
    Some((theta, residual_ss(b, p)))
}

/// `R theta = (Q^T b)[..p]` for the reduction of [`householder`] (`R` above the diagonal in `a`, its
/// diagonal in `diag`); `p` is `theta.len()`.
fn back_substitute(a: &[f64], b: &[f64], diag: &[f64], m: usize, theta: &mut [f64]) {
    let p = theta.len();
    for k in (0..p).rev() {
        let mut s = b[k];
        for j in k + 1..p {
            s -= a[j * m + k] * theta[j];
        }
        theta[k] = s / diag[k];
    }
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
    asc: Vec<Row>,
    desc: Vec<Row>,
    work: Work,
}

/// The buffers of one branch's solve.
#[derive(Default)]
struct Work {
    a: Vec<f64>,
    b: Vec<f64>,
    v: Vec<f64>,
    diag: Vec<f64>,
    theta: Vec<f64>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// `solve_branch(rows, p).ss` in the buffers of `w` (the same arithmetic, without allocating) and, with
/// `slope`, the derivative of that minimum in `psi` (else 0).
///
/// Variable projection (Golub and Pereyra): at the least-squares `theta` the residual is orthogonal to
/// the columns, so the derivative of the minimum is the partial derivative at fixed `theta`,
/// `-2 sum_j sw_j r_j f'(c_j) dc_j/dpsi` with `r_j = sw_j (w_j - f(c_j))`: one solve gives the cost and
/// its slope, accurate where the cost itself only locates its minimum to the square root of rounding.
fn branch_ss(rows: &[Row], p: usize, w: &mut Work, slope: bool) -> (f64, f64) {
    let m = rows.len();
    if m == 0 {
        return (0.0, 0.0);
    }
    design(rows, p, &mut w.a, &mut w.b);
    w.diag.resize(p, 0.0);
    w.theta.resize(p, 0.0);
    let ss = if m >= p && householder(&mut w.a, &mut w.b, m, p, &mut w.v, &mut w.diag) {
        if slope {
            back_substitute(&w.a, &w.b, &w.diag, m, &mut w.theta);
        }
        residual_ss(&w.b, p)
    } else {
        let branch = solve_branch(rows, p);
        w.theta.copy_from_slice(&branch.theta);
        branch.ss
    };
    (ss, if slope { ss_slope(rows, &w.theta) } else { 0.0 })
}

/// `d/dpsi sum_j (sw_j (w_j - f(c_j)))^2` at fixed coefficients `theta` (lowest power first).
fn ss_slope(rows: &[Row], theta: &[f64]) -> f64 {
    let sum: f64 = rows
        .iter()
        .map(|row| {
            // f(c) and f'(c) by Horner.
            let (mut f, mut df) = (0.0, 0.0);
            for &t in theta.iter().rev() {
                df = df * row.c + f;
                f = f * row.c + t;
            }
            row.sw * row.sw * (row.w - f) * df * row.s
        })
        .sum();
    -2.0 * sum
}

impl<'a> Problem<'a> {
    /// The cost over the bins `include` of the averaged period (`phase`, `w`), rows weighted by `sw`, `p`
    /// parameters per branch.
    pub fn new(
        phase: &'a [f64],
        w: &'a [f64],
        sw: Vec<f64>,
        include: Vec<bool>,
        p: usize,
    ) -> Problem<'a> {
        let trig = phase
            .iter()
            .map(|r| {
                let (s, c) = r.sin_cos();
                (c, s)
            })
            .collect();
        Problem {
            phase,
            w,
            sw,
            include,
            p,
            trig,
        }
    }

    /// The rows of each branch at phase `psi`.
    fn rows(&self, psi: f64, asc: &mut Vec<Row>, desc: &mut Vec<Row>) {
        asc.clear();
        desc.clear();
        let (sp, cp) = psi.sin_cos();
        for j in 0..self.w.len() {
            if !self.include[j] {
                continue;
            }
            let (cr, sr) = self.trig[j];
            let row = Row {
                c: cr * cp + sr * sp,
                s: sr * cp - cr * sp,
                w: self.w[j],
                sw: self.sw[j],
            };
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
        self.evaluate(psi, false).0
    }

    /// The cost at `psi` and its derivative in `psi` (on the side of `psi` where the branches are those of
    /// `psi`: the cost is smooth between the phases where a bin changes branch).
    fn cost_slope(&self, psi: f64) -> (f64, f64) {
        self.evaluate(psi, true)
    }

    fn evaluate(&self, psi: f64, slope: bool) -> (f64, f64) {
        SCRATCH.with_borrow_mut(|s| {
            let Scratch { asc, desc, work } = s;
            self.rows(psi, asc, desc);
            let (ss_asc, g_asc) = branch_ss(asc, self.p, work, slope);
            let (ss_desc, g_desc) = branch_ss(desc, self.p, work, slope);
            (ss_asc + ss_desc, g_asc + g_desc)
        })
    }

    /// Number of bins in the optimisation set.
    pub fn included(&self) -> usize {
        self.include.iter().filter(|&&b| b).count()
    }

    /// Minimise the cost over `[lo, hi]` with a grid of at most `spacing` and refinement ([`Self::descend`]) of
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
    ///
    /// The points are visited by increasing lower bound (fast value minus its error); once three minima
    /// are known exactly, a point whose lower bound exceeds the third's value cannot be among the best
    /// three, nor can any later point. A point is solved exactly only when its bounds leave it possibly a
    /// local minimum, and a neighbour only when its bounds do not decide the comparison.
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
        let lower = |i: usize| fast[i].map_or(f64::NEG_INFINITY, |(f, e)| f - e);
        let mut order: Vec<usize> = (0..pts.len()).collect();
        order.sort_by(|&a, &b| lower(a).total_cmp(&lower(b)));
        let mut exact: Vec<Option<f64>> = vec![None; pts.len()];
        let mut value = |i: usize| *exact[i].get_or_insert_with(|| self.cost(pts[i]));
        let mut minima: Vec<(usize, f64)> = Vec::new();
        let mut third = f64::INFINITY;
        for i in order {
            if lower(i) > third {
                break;
            }
            let (l, r) = grid.neighbours(i);
            if !maybe_minimum(fast[i], fast[l], fast[r]) {
                continue;
            }
            let v = value(i);
            let at_most = |n: usize, value: &mut dyn FnMut(usize) -> f64| match fast[n] {
                Some((f, e)) if v <= f - e => true,
                Some((f, e)) if v > f + e => false,
                _ => v <= value(n),
            };
            if at_most(l, &mut value) && at_most(r, &mut value) {
                minima.push((i, v));
                if minima.len() >= 3 {
                    let mut vals: Vec<f64> = minima.iter().map(|m| m.1).collect();
                    vals.sort_by(f64::total_cmp);
                    third = vals[2];
                }
            }
        }
        // Grid order, so that ties keep it in `best_three`.
        minima.sort_by_key(|m| m.0);
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

    /// Refinement around each grid minimum (within a grid step); the best point found.
    fn refine(&self, grid: &Grid, minima: &[(usize, f64)]) -> (f64, f64) {
        let (pts, h) = (&grid.pts, grid.step);
        let mut best = (pts[minima[0].0], minima[0].1);
        for &(i, v) in minima {
            #[cfg(test)]
            let (x, f) = if GOLDEN.get() {
                golden(|x| self.cost(x), pts[i] - h, pts[i] + h, pts[i], v)
            } else {
                self.descend(pts[i], v, h)
            };
            #[cfg(not(test))]
            let (x, f) = self.descend(pts[i], v, h);
            if f < best.1 {
                best = (x, f);
            }
        }
        best
    }

    /// The minimum of the cost in `[x0 - h, x0 + h]`, `x0` (cost `f0`) included. The cost is smooth
    /// between the phases where a bin changes branch ([`Self::piece`]) and may jump there: the minimum of
    /// each piece in the bracket ([`Self::piece_descend`], from its point nearest `x0`), the best of them.
    /// A bracket of a grid step holds two or three pieces: a dozen solves where the golden section on the
    /// cost took about 46.
    fn descend(&self, x0: f64, f0: f64, h: f64) -> (f64, f64) {
        let (lo, hi) = (x0 - h, x0 + h);
        let mut best = (x0, f0);
        let mut x = lo;
        for _ in 0..DESCENT_STEPS {
            let (a, b) = self.piece(x);
            let (left, right) = ((a + EDGE).max(lo), b.min(hi));
            if left < right {
                let start = x0.max(left).min(right);
                let (f, g) = self.cost_slope(start);
                if f < best.1 {
                    best = (start, f);
                }
                let (xm, fm) = self.piece_descend(start, g, left, right);
                if fm < best.1 {
                    best = (xm, fm);
                }
            }
            if b >= hi {
                break;
            }
            x = b + EDGE;
        }
        best
    }

    /// The piece `(a, b]` of phases around `psi` on which no included bin changes branch (`rho = psi`
    /// modulo `pi` for some bin: the partition of [`sigma`] changes just after such a phase).
    fn piece(&self, psi: f64) -> (f64, f64) {
        let (mut left, mut right) = (PI, PI);
        for (j, &r) in self.phase.iter().enumerate() {
            if self.include[j] {
                let d = (psi - r).rem_euclid(PI);
                left = left.min(if d == 0.0 { PI } else { d });
                right = right.min((r - psi).rem_euclid(PI));
            }
        }
        (psi - left, psi + right)
    }

    /// The minimum of the smooth cost on `[lo, hi]` inside one piece, from `x` (slope `g`): secant steps
    /// on the derivative ([`branch_ss`]) inside the bracket its signs leave, an end of the piece tried once
    /// when a step passes it, bisection when a step leaves the bracket or two steps did not halve it;
    /// bounded by [`DESCENT_STEPS`]. The best point evaluated and its cost.
    fn piece_descend(&self, x: f64, g: f64, lo: f64, hi: f64) -> (f64, f64) {
        let (ends, mut lo, mut hi) = ((lo, hi), lo, hi);
        let (mut x, mut g) = (x.max(lo).min(hi), g);
        let mut best = (x, f64::INFINITY);
        let mut prev: Option<(f64, f64)> = None;
        let mut widths = [hi - lo; 2];
        let mut tried = (false, false);
        for _ in 0..DESCENT_STEPS {
            if g > 0.0 {
                hi = hi.min(x);
            } else if g < 0.0 {
                lo = lo.max(x);
            } else {
                break;
            }
            let width = hi - lo;
            if width <= BRACKET_TOLERANCE {
                break;
            }
            let stalled = width > 0.5 * widths[0];
            widths = [widths[1], width];
            let step = match prev {
                Some((xp, gp)) if gp != g && !stalled => x - g * (x - xp) / (g - gp),
                None => x - g.signum() * 0.25 * (ends.1 - ends.0),
                _ => f64::NAN,
            };
            let next = if step > lo && step < hi {
                step
            } else if step >= hi && hi == ends.1 && !tried.1 {
                tried.1 = true;
                hi
            } else if step <= lo && lo == ends.0 && !tried.0 {
                tried.0 = true;
                lo
            } else {
                0.5 * (lo + hi)
            };
            if (next - x).abs() <= STEP_TOLERANCE * x.abs().max(1.0) {
                break;
            }
            let (f, gn) = self.cost_slope(next);
            if f < best.1 {
                best = (next, f);
            }
            (prev, x, g) = (Some((x, g)), next, gn);
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
    /// Tests set it to refine the grid's minima by the golden section on the cost, as a reference.
    pub(super) static GOLDEN: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
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

/// Within the errors of the fast values `(value, bound)` of a point and its neighbours, may the point be at
/// most both neighbours? (Always, where a value is missing.)
fn maybe_minimum(
    at: Option<(f64, f64)>,
    left: Option<(f64, f64)>,
    right: Option<(f64, f64)>,
) -> bool {
    match (at, left, right) {
        (Some((f, e)), Some((fl, el)), Some((fr, er))) => f <= fl + e + el && f <= fr + e + er,
        _ => true,
    }
}

/// Most solves of one [`Problem::piece_descend`], and most pieces of one [`Problem::descend`].
const DESCENT_STEPS: usize = 60;
/// [`Problem::piece_descend`] stops when the bracket is this narrow (rad), as the golden section did,
const BRACKET_TOLERANCE: f64 = 1e-12;
/// or when a step is this small relative to the phase.
const STEP_TOLERANCE: f64 = 1e-14;
/// How far inside a piece its open end is taken (rad): well above the rounding of `rho - psi`.
const EDGE: f64 = 1e-13;

/// The three lowest of the local minima (index, value), in order; ties keep the grid's order.
fn best_three(mut minima: Vec<(usize, f64)>) -> Vec<(usize, f64)> {
    minima.sort_by(|a, b| a.1.total_cmp(&b.1));
    minima.truncate(3);
    minima
}

/// Golden-section search on `[a, b]`, keeping the best point seen (`x0`, `f0` included): the reference
/// [`Problem::descend`] is tested against.
#[cfg(test)]
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
        let pb = Problem::new(&phase, &w, vec![1.0; b], vec![true; b], 4);
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
        let (phase, w) = noisy_cycle();
        for (degree, excluded) in [(1, 0..0), (3, 0..0), (6, 0..0), (3, 40..70), (6, 200..260)] {
            let pb = Problem::new(
                &phase,
                &w,
                (0..b).map(|j| (1.0 + (j % 3) as f64).sqrt()).collect(),
                (0..b).map(|j| !excluded.contains(&j)).collect(),
                degree + 1,
            );
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

    /// 300 bins of a cubic-border cycle at `psi = 0.7` with deterministic pseudo-noise and an offset.
    fn noisy_cycle() -> (Vec<f64>, Vec<f64>) {
        let b = 300;
        let psi = 0.7;
        let phase: Vec<f64> = (0..b).map(|j| TAU * j as f64 / b as f64 - 0.3).collect();
        let w = phase
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
        (phase, w)
    }

    #[test]
    fn the_cost_slope_is_the_derivative_of_the_cost() {
        // Against a central difference of the QR cost, between the phases where a bin changes branch.
        let (phase, w) = noisy_cycle();
        for degree in [1, 3, 6] {
            let pb = Problem::new(&phase, &w, vec![1.5; 300], vec![true; 300], degree + 1);
            for x in [0.4, 0.705, 1.3, 2.9] {
                // Midway between two bins' phases (and their opposites): one smooth piece around x.
                let x = x + 0.5 * TAU / 600.0 - (x + 0.3).rem_euclid(TAU / 600.0);
                let h = 1e-6;
                let numeric = (pb.cost(x + h) - pb.cost(x - h)) / (2.0 * h);
                let (_, slope) = pb.cost_slope(x);
                assert!(
                    (slope - numeric).abs() <= 1e-5 * numeric.abs().max(1e-3),
                    "degree {degree}, psi {x}: {slope} against {numeric}"
                );
            }
        }
    }

    #[test]
    fn the_refinement_stops_where_the_derivative_changes_sign() {
        // The minimum found is certified to 1e-9 rad: the cost falls towards it from both sides, or it
        // lies on a phase where a bin changes branch (there the cost may jump, and degree 1 does not fit
        // this cycle's cubic border).
        let (phase, w) = noisy_cycle();
        for degree in [1, 3, 6] {
            let pb = Problem::new(&phase, &w, vec![1.5; 300], vec![true; 300], degree + 1);
            let (x, f) = pb.minimise(0.0, PI, TAU / 300.0 / 4.0, true);
            assert!((x - 0.7).abs() < 0.05, "degree {degree}: {x}");
            let (left, right) = (pb.cost_slope(x - 1e-9).1, pb.cost_slope(x + 1e-9).1);
            let on_a_break = phase.iter().any(|r| {
                let d = (r - x).rem_euclid(PI);
                d.min(PI - d) < 1e-9
            });
            let near = phase
                .iter()
                .map(|r| {
                    let d = (r - x).rem_euclid(PI);
                    d.min(PI - d)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                (left < 0.0 && right > 0.0) || on_a_break,
                "degree {degree}: slopes {left}, {right} at {x}, {near:e} from a break"
            );
            assert_eq!(pb.cost(x), f);
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
