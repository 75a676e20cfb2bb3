//! The backlash operator of paper 003 (section 2): borders are polynomials of degree up to
//! [`MAX_DEGREE`], possibly non-invertible and crossing each other,
//!
//! ```text
//! f_a(x) = a0 + a1 x + a2 x^2 + a3 x^3   (ascending border, followed while x increases)
//! f_d(x) = d0 + d1 x + d2 x^2 + d3 x^3   (descending border, followed while x decreases)
//! ```
//!
//! Rules of the paper (section 2), for a working point `(x, w)`:
//! - on the ascending (descending) border, it stays on that border as long as x does not decrease
//!   (increase), whatever the shape of the border (so w may go down while x goes up on a non-invertible
//!   border);
//! - after a reversal it leaves the border and moves horizontally (w constant) towards the opposite border;
//!   when it meets that border it follows it as long as x keeps its direction.
//!
//! # Discrete time
//!
//! The operator is driven by a sampled sequence `x(0), x(1), ...`. Between `x(k-1)` and `x(k)` the input is
//! taken to move monotonically (as along a straight segment), so reversals happen only at samples. One step
//! from `(x(k-1), w(k-1))` to `x(k) > x(k-1)`:
//! - if the point is on the ascending border ([`Mode::Up`]) it follows it: `w(k) = f_a(x(k))`;
//! - otherwise it moves horizontally to the right at height `w(k-1)`. If the horizontal path over
//!   `[x(k-1), x(k)]` meets the ascending border (some `x'` in that interval with `f_a(x') = w(k-1)`,
//!   endpoints included), the point follows the border from the first such `x'` on, so `w(k) = f_a(x(k))`
//!   and the mode becomes `Up` (the border may be met and followed within the sample step);
//! - otherwise it holds: `w(k) = w(k-1)`, mode [`Mode::Held`].
//!
//! A step down is the mirror image with `f_d` and [`Mode::Down`]; `x(k) = x(k-1)` changes nothing. With
//! non-invertible borders only the *first* meeting along the path matters: once on a border the point
//! follows it to `x(k)` even if the border comes back to the height it was met at.
//!
//! Static nonlinearities are the case `f_a = f_d`: a point on the border that reverses meets the other
//! (identical) border where it is, so `w(k) = f(x(k))` at every step once the point is on the curve.
//!
//! With straight borders `f_a(x) = m1 (x - c1)`, `f_d(x) = m2 (x + c2)` ([`PolyBacklashParams::from_straight`])
//! the operator is exactly the backlash of paper 000 ([`crate::plant::backlash`]) wherever the memory zone
//! is non-empty (the descending border lies to the left of the ascending one). Beyond a crossing of the
//! straight borders the two differ on purpose: paper 000's rule jumps onto the border, while paper 003's
//! rule, implemented here, moves horizontally and holds as long as the opposite border is not met.
//!
//! The start state is `x = 0` with `w = 0` projected onto the segment between the two borders at `x = 0`
//! (`w = clamp(0, min(f_a(0), f_d(0)), max(f_a(0), f_d(0)))`), mode `Held`. For paper 000's straight borders
//! that is `w = 0`, the contract's plant; for a static curve it is `w = f(0)`, on the curve.

use serde::{Deserialize, Serialize};

use super::backlash::{BacklashParams, Mode};
use super::{ParamError, check_finite};

/// Highest border degree the plant supports (the paper's `n`; FMU parameters `a0..a3`, `d0..d3`).
pub const MAX_DEGREE: usize = 3;

/// Number of stored coefficients per border.
pub const N_COEFFS: usize = MAX_DEGREE + 1;

/// Coefficients of the two borders, lowest power first: `fa[i]` is `a_i`, `fd[i]` is `d_i` (paper 003,
/// eq. (3)). Unused high powers are zero.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PolyBacklashParams {
    pub fa: [f64; N_COEFFS],
    pub fd: [f64; N_COEFFS],
}

/// Evaluate `c[0] + c[1] x + ...` by Horner's rule.
pub fn poly_eval(c: &[f64], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ci| acc * x + ci)
}

impl PolyBacklashParams {
    /// Borders from coefficient slices (lowest power first, at most [`N_COEFFS`] each, missing powers zero).
    pub fn new(fa: &[f64], fd: &[f64]) -> Result<Self, ParamError> {
        let p = Self {
            fa: pad("a", fa)?,
            fd: pad("d", fd)?,
        };
        p.validate()?;
        Ok(p)
    }

    /// A static nonlinearity `w = f(x)`: both borders equal to `f`.
    pub fn static_curve(f: &[f64]) -> Result<Self, ParamError> {
        Self::new(f, f)
    }

    /// Paper 000's straight borders: `f_a(x) = m1 (x - c1)`, `f_d(x) = m2 (x + c2)`.
    pub fn from_straight(b: &BacklashParams) -> Self {
        Self {
            fa: [-b.m1 * b.c1, b.m1, 0.0, 0.0],
            fd: [b.m2 * b.c2, b.m2, 0.0, 0.0],
        }
    }

    /// All coefficients finite. (Zero or constant borders are legal operators, if useless for identification.)
    pub fn validate(&self) -> Result<(), ParamError> {
        for (i, a) in self.fa.iter().enumerate() {
            check_finite(&format!("a{i}"), *a)?;
        }
        for (i, d) in self.fd.iter().enumerate() {
            check_finite(&format!("d{i}"), *d)?;
        }
        Ok(())
    }

    /// Highest power with a non-zero coefficient in either border (0 for constant borders).
    pub fn degree(&self) -> usize {
        (0..N_COEFFS)
            .rev()
            .find(|&i| self.fa[i] != 0.0 || self.fd[i] != 0.0)
            .unwrap_or(0)
    }

    /// Ascending border `f_a(x)`.
    pub fn ascending(&self, x: f64) -> f64 {
        poly_eval(&self.fa, x)
    }

    /// Descending border `f_d(x)`.
    pub fn descending(&self, x: f64) -> f64 {
        poly_eval(&self.fd, x)
    }

    /// The start state's output: 0 projected onto the segment between the borders at `x = 0`.
    pub fn initial_output(&self) -> f64 {
        let (lo, hi) = {
            let (a, d) = (self.fa[0], self.fd[0]);
            if a <= d { (a, d) } else { (d, a) }
        };
        0.0f64.clamp(lo, hi)
    }

    /// One step of the operator (see the module documentation): from the working point `(x_prev, w_prev)`
    /// in regime `mode`, the input moves monotonically to `x`. Returns the new output and regime.
    pub fn step(&self, x_prev: f64, w_prev: f64, mode: Mode, x: f64) -> (f64, Mode) {
        if x > x_prev {
            if mode == Mode::Up || meets(&self.fa, w_prev, x_prev, x) {
                (self.ascending(x), Mode::Up)
            } else {
                (w_prev, Mode::Held)
            }
        } else if x < x_prev {
            if mode == Mode::Down || meets(&self.fd, w_prev, x_prev, x) {
                (self.descending(x), Mode::Down)
            } else {
                (w_prev, Mode::Held)
            }
        } else {
            (w_prev, mode)
        }
    }
}

fn pad(prefix: &str, c: &[f64]) -> Result<[f64; N_COEFFS], ParamError> {
    if c.len() > N_COEFFS {
        return Err(ParamError::new(
            format!("{prefix}{}", c.len() - 1),
            c[c.len() - 1],
            "border degree must be at most 3",
        ));
    }
    let mut out = [0.0; N_COEFFS];
    out[..c.len()].copy_from_slice(c);
    Ok(out)
}

/// Does the horizontal path at height `level` from `from` to `to` meet the border `p` (endpoints included)?
///
/// The interval is cut at the stationary points of `p` (roots of `p'`, degree <= 2, closed form), so that
/// `p - level` is monotone on each piece; a piece contains a meeting point iff `p - level` changes sign or
/// vanishes at one of its ends. Where along the path the border is met does not matter for the output.
fn meets(p: &[f64; N_COEFFS], level: f64, from: f64, to: f64) -> bool {
    let (lo, hi) = if from <= to { (from, to) } else { (to, from) };
    let g = |x: f64| poly_eval(p, x) - level;
    let mut cuts = [0.0f64; 4];
    let mut m = 0;
    cuts[m] = lo;
    m += 1;
    let mut crit = stationary_points(p);
    crit.sort_by(f64::total_cmp);
    for c in crit {
        if c > lo && c < hi {
            cuts[m] = c;
            m += 1;
        }
    }
    cuts[m] = hi;
    m += 1;
    let mut prev = g(cuts[0]);
    if prev == 0.0 {
        return true;
    }
    for &c in &cuts[1..m] {
        let v = g(c);
        if v == 0.0 || (v > 0.0) != (prev > 0.0) {
            return true;
        }
        prev = v;
    }
    false
}

/// Real roots of `p'(x) = a1 + 2 a2 x + 3 a3 x^2` (none, one or two; NaN-free).
fn stationary_points(p: &[f64; N_COEFFS]) -> Vec<f64> {
    let (c0, c1, c2) = (p[1], 2.0 * p[2], 3.0 * p[3]);
    if c2 != 0.0 {
        let disc = c1 * c1 - 4.0 * c2 * c0;
        if disc < 0.0 {
            return Vec::new();
        }
        let sq = disc.sqrt();
        // Numerically stable pair of roots.
        let q = -0.5 * (c1 + c1.signum() * sq);
        if q == 0.0 {
            return vec![0.0];
        }
        let r1 = q / c2;
        let r2 = c0 / q;
        vec![r1, r2].into_iter().filter(|r| r.is_finite()).collect()
    } else if c1 != 0.0 {
        vec![-c0 / c1]
    } else {
        Vec::new()
    }
}

/// The operator with its state `(x, w, mode)`; serialisable (it is part of an FMU's saved state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolyBacklash {
    params: PolyBacklashParams,
    x: f64,
    w: f64,
    mode: Mode,
}

impl PolyBacklash {
    /// The operator at its start state (module documentation).
    pub fn new(params: PolyBacklashParams) -> Result<Self, ParamError> {
        params.validate()?;
        Ok(Self {
            params,
            x: 0.0,
            w: params.initial_output(),
            mode: Mode::Held,
        })
    }

    /// The operator at a given working point.
    pub fn with_state(
        params: PolyBacklashParams,
        x: f64,
        w: f64,
        mode: Mode,
    ) -> Result<Self, ParamError> {
        params.validate()?;
        check_finite("x", x)?;
        check_finite("w", w)?;
        Ok(Self { params, x, w, mode })
    }

    pub fn params(&self) -> &PolyBacklashParams {
        &self.params
    }

    pub fn validate(&self) -> Result<(), ParamError> {
        self.params.validate()
    }

    /// Back to the start state.
    pub fn reset(&mut self) {
        self.x = 0.0;
        self.w = self.params.initial_output();
        self.mode = Mode::Held;
    }

    /// Move the input to `x`; returns the new output.
    pub fn step(&mut self, x: f64) -> f64 {
        let (w, mode) = self.params.step(self.x, self.w, self.mode, x);
        self.x = x;
        self.w = w;
        self.mode = mode;
        w
    }

    /// The current output.
    pub fn output(&self) -> f64 {
        self.w
    }

    /// The current input.
    pub fn input(&self) -> f64 {
        self.x
    }

    /// The current regime.
    pub fn mode(&self) -> Mode {
        self.mode
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn run(p: &PolyBacklashParams, xs: &[f64]) -> Vec<(f64, Mode)> {
        let mut b = PolyBacklash::new(*p).unwrap();
        xs.iter()
            .map(|&x| {
                let w = b.step(x);
                (w, b.mode())
            })
            .collect()
    }

    #[test]
    fn hand_worked_sequence_on_curved_borders() {
        // f_a(x) = x^2 - 1 (non-invertible), f_d(x) = 0.5 x + 1.
        let p = PolyBacklashParams::new(&[-1.0, 0.0, 1.0], &[1.0, 0.5]).unwrap();
        // Start: f_a(0) = -1, f_d(0) = 1, w = 0 held.
        assert_eq!(p.initial_output(), 0.0);
        let out = run(&p, &[0.5, 1.0, 2.0, 1.5, -1.0, -3.0, 0.0]);
        // 0 -> 0.5: f_a - 0 = x^2 - 1 < 0 on [0, .5]: held 0.
        assert_eq!(out[0], (0.0, Mode::Held));
        // 0.5 -> 1: f_a(1) = 0 = w: met at the end point, w = f_a(1) = 0, up.
        assert_eq!(out[1], (0.0, Mode::Up));
        // 1 -> 2: follow, w = 3.
        assert_eq!(out[2], (3.0, Mode::Up));
        // 2 -> 1.5: f_d = 3 at x = 4, not in [1.5, 2]: held 3.
        assert_eq!(out[3], (3.0, Mode::Held));
        // 1.5 -> -1: f_d(x) = 3 needs x = 4: never: held 3.
        assert_eq!(out[4], (3.0, Mode::Held));
        // -1 -> -3: still held.
        assert_eq!(out[5], (3.0, Mode::Held));
        // -3 -> 0: f_a = 3 at x = +-2; the path [-3, 0] meets x = -2 first: follow to f_a(0) = -1.
        assert_eq!(out[6], (-1.0, Mode::Up));
    }

    #[test]
    fn non_invertible_border_is_followed_down_and_up() {
        // f_a(x) = x - x^3/3 rises to 2/3 at x = 1, then falls; f_d far to the left.
        let p = PolyBacklashParams::new(&[0.0, 1.0, 0.0, -1.0 / 3.0], &[10.0, 1.0]).unwrap();
        let mut b = PolyBacklash::with_state(p, 0.0, 0.0, Mode::Up).unwrap();
        let w1 = b.step(1.0);
        assert!((w1 - 2.0 / 3.0).abs() < 1e-15);
        let w2 = b.step(2.0);
        // 2 - 8/3 = -2/3: the output fell while x kept rising.
        assert!((w2 + 2.0 / 3.0).abs() < 1e-15);
        assert_eq!(b.mode(), Mode::Up);
    }

    #[test]
    fn meeting_within_the_step_follows_the_border_to_the_sample() {
        // Straight borders f_a = x - 1, f_d = x + 1, start held at (0, 0); one step to x = 3 meets f_a at 1.
        let p = PolyBacklashParams::new(&[-1.0, 1.0], &[1.0, 1.0]).unwrap();
        let out = run(&p, &[3.0, 2.5, -0.5]);
        assert_eq!(out[0], (2.0, Mode::Up));
        // Reversal: f_d = 2 at x = 1, not reached at 2.5: held.
        assert_eq!(out[1], (2.0, Mode::Held));
        // Down to -0.5 passes x = 1: follow f_d, w = 0.5.
        assert_eq!(out[2], (0.5, Mode::Down));
    }

    #[test]
    fn static_curve_is_memoryless_once_on_the_curve() {
        let f = [0.1, 1.2, 0.5, -0.9];
        let p = PolyBacklashParams::static_curve(&f).unwrap();
        assert_eq!(p.initial_output(), 0.1);
        let mut b = PolyBacklash::new(p).unwrap();
        for k in 0..400 {
            let x = 1.7 * (0.37 * k as f64).sin() + 0.3 * (1.3 * k as f64).cos();
            let w = b.step(x);
            assert_eq!(w, poly_eval(&f, x), "sample {k}");
        }
    }

    #[test]
    fn bad_coefficients_are_refused_with_their_name() {
        assert_eq!(
            PolyBacklashParams::new(&[0.0, f64::NAN], &[0.0])
                .unwrap_err()
                .name,
            "a1"
        );
        assert_eq!(
            PolyBacklashParams::new(&[0.0], &[0.0, 1.0, 2.0, 3.0, 4.0])
                .unwrap_err()
                .name,
            "d4"
        );
    }

    #[test]
    fn reset_and_serde_round_trip() {
        let p = PolyBacklashParams::new(&[-0.2, 1.0, 0.1], &[0.3, 0.9]).unwrap();
        let mut b = PolyBacklash::new(p).unwrap();
        for x in [0.5, 1.0, 0.2] {
            b.step(x);
        }
        let s = serde_json::to_string(&b).unwrap();
        let mut c: PolyBacklash = serde_json::from_str(&s).unwrap();
        assert_eq!(b, c);
        assert_eq!(b.step(-1.0), c.step(-1.0));
        c.reset();
        assert_eq!(c, PolyBacklash::new(p).unwrap());
    }

    fn straight() -> impl Strategy<Value = BacklashParams> {
        (0.2f64..3.0, 0.2f64..3.0, 0.0f64..2.0, 0.0f64..2.0)
            .prop_map(|(m1, m2, c1, c2)| BacklashParams { m1, m2, c1, c2 })
    }

    proptest! {
        /// Straight borders reproduce paper 000's backlash (crate::plant::backlash) on random sequences, on the
        /// side of the borders' crossing point where the memory zone is non-empty.
        #[test]
        fn straight_borders_are_paper_000_backlash(
            b in straight(),
            xs in proptest::collection::vec(-3.0f64..3.0, 1..300),
        ) {
            let cross = (b.m1 * b.c1 + b.m2 * b.c2) / (b.m1 - b.m2);
            prop_assume!(!cross.is_finite() || cross.abs() > 3.5 || b.m1 == b.m2);
            let p = PolyBacklashParams::from_straight(&b);
            let mut op = PolyBacklash::new(p).unwrap();
            prop_assert_eq!(op.output(), 0.0);
            let mut y = 0.0;
            for (k, &x) in xs.iter().enumerate() {
                let (ny, m) = b.step(x, y);
                let w = op.step(x);
                let tol = 1e-12 * (1.0 + ny.abs());
                prop_assert!((w - ny).abs() <= tol, "sample {}: {} vs {}", k, w, ny);
                // Same regime, except that paper 000 reports a move exactly onto the border as Held.
                if m != Mode::Held {
                    prop_assert_eq!(op.mode(), m);
                }
                y = ny;
            }
        }

        /// The output only changes on a border; with f_a = f_d it is the curve itself once on it.
        #[test]
        fn output_changes_only_on_a_border(
            fa in proptest::collection::vec(-2.0f64..2.0, 1..=4),
            fd in proptest::collection::vec(-2.0f64..2.0, 1..=4),
            xs in proptest::collection::vec(-3.0f64..3.0, 1..100),
        ) {
            let p = PolyBacklashParams::new(&fa, &fd).unwrap();
            let mut op = PolyBacklash::new(p).unwrap();
            for &x in &xs {
                let before = op.output();
                let w = op.step(x);
                match op.mode() {
                    Mode::Held => prop_assert_eq!(w, before),
                    Mode::Up => prop_assert_eq!(w, p.ascending(x)),
                    Mode::Down => prop_assert_eq!(w, p.descending(x)),
                }
            }
        }
    }
}
