//! The discrete ARX block of paper 000, eq. (1):
//! `x(k) = -sum_{i=1..na} a_i x(k-i) + sum_{j=0..nb} b_j u(k-d-j)`, all signals zero before k = 0.

use serde::{Deserialize, Serialize};

/// Largest `na` and `nb` the project supports (the FMUs expose `a1..a4`, `b0..b4`).
pub const MAX_ORDER: usize = 4;
/// Largest delay in samples. Bounded so that the history a plant or estimator keeps has a known size.
pub const MAX_DELAY: usize = 64;

/// Whether `1 + a_1 z^-1 + ... + a_n z^-n` has all its roots strictly inside the unit circle (Schur-Cohn
/// step-down: every reflection coefficient below 1 in magnitude). An unstable linear block can stay bounded
/// over a fit window and explode right after it, so the fits refuse it. No allocation (the recursive
/// estimator calls it every sample); polynomials longer than [`MAX_ORDER`], which no model here has, are
/// answered `false` (not checked, so not accepted).
pub fn is_stable(a: &[f64]) -> bool {
    if a.len() > MAX_ORDER {
        return false;
    }
    let mut c = [0.0f64; MAX_ORDER];
    c[..a.len()].copy_from_slice(a);
    let mut tmp = [0.0f64; MAX_ORDER];
    for n in (1..=a.len()).rev() {
        let k = c[n - 1];
        if k.is_nan() || k.abs() >= 1.0 {
            return false;
        }
        let d = 1.0 - k * k;
        for i in 0..n - 1 {
            tmp[i] = (c[i] - k * c[n - 2 - i]) / d;
        }
        c[..n - 1].copy_from_slice(&tmp[..n - 1]);
    }
    true
}

/// Orders and coefficients of the ARX block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ArxParams {
    pub na: usize,
    pub nb: usize,
    pub delay: usize,
    /// `a[i-1]` is `a_i`; entries beyond `na` are ignored.
    pub a: [f64; MAX_ORDER],
    /// `b[j]` is `b_j`; entries beyond `nb` are ignored.
    pub b: [f64; MAX_ORDER + 1],
}

impl ArxParams {
    /// Paper 000, eq. (46): x(k) = -0.45 x(k-1) - 0.55 x(k-2) + 0.8 u(k-1).
    pub const PAPER: Self = Self {
        na: 2,
        nb: 0,
        delay: 1,
        a: [0.45, 0.55, 0.0, 0.0],
        b: [0.8, 0.0, 0.0, 0.0, 0.0],
    };

    /// The used `a` coefficients.
    pub fn a(&self) -> &[f64] {
        &self.a[..self.na]
    }

    /// The used `b` coefficients.
    pub fn b(&self) -> &[f64] {
        &self.b[..=self.nb]
    }

    /// Number of past inputs the block reads: u(k-d) .. u(k-d-nb).
    pub fn input_memory(&self) -> usize {
        self.delay + self.nb + 1
    }
}

/// Shift register of the most recent values, newest first; `get(0)` is the newest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct History {
    buf: Vec<f64>,
    head: usize,
}

impl History {
    /// `len` zeros.
    pub fn zeros(len: usize) -> Self {
        Self {
            buf: vec![0.0; len.max(1)],
            head: 0,
        }
    }

    /// Push a new newest value; the oldest falls off.
    pub fn push(&mut self, v: f64) {
        self.head = if self.head == 0 {
            self.buf.len() - 1
        } else {
            self.head - 1
        };
        self.buf[self.head] = v;
    }

    /// The value `age` pushes ago (0 = newest).
    pub fn get(&self, age: usize) -> f64 {
        let n = self.buf.len();
        debug_assert!(age < n);
        self.buf[(self.head + age) % n]
    }

    /// Length and position consistent, values finite (for states restored from outside).
    pub fn check(&self, len: usize, what: &str) -> Result<(), String> {
        if self.buf.len() != len.max(1) || self.head >= self.buf.len() {
            return Err(format!(
                "{what}: history of length {} with head {} (expected length {})",
                self.buf.len(),
                self.head,
                len.max(1)
            ));
        }
        if self.buf.iter().any(|v| !v.is_finite()) {
            return Err(format!("{what}: history holds a non-finite value"));
        }
        Ok(())
    }

    pub fn clear(&mut self) {
        self.buf.iter_mut().for_each(|v| *v = 0.0);
        self.head = 0;
    }
}

/// The ARX block with its state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arx {
    pub params: ArxParams,
    /// u(k-1), u(k-2), ... (newest first) once u(k-1) has been pushed.
    u_hist: History,
    /// x(k-1), x(k-2), ...
    x_hist: History,
}

impl Arx {
    pub fn new(params: ArxParams) -> Self {
        Self {
            params,
            u_hist: History::zeros(params.input_memory()),
            x_hist: History::zeros(MAX_ORDER),
        }
    }

    /// x(k) from the inputs and outputs pushed so far (u(k-1) and x(k-1) newest). It does not read u(k):
    /// the delay is at least one sample, so the block has no direct feedthrough.
    pub fn peek(&self) -> f64 {
        self.peek_with(self.params.a(), self.params.b())
    }

    /// x(k) as [`Arx::peek`] but with the coefficients `a`, `b` over the same history (the falling set of a
    /// direction-dependent block, [`crate::plant::effects::DirectionDependent`]); the orders and the delay
    /// are the block's, so `a` and `b` must not be longer than `na` and `nb + 1`.
    pub fn peek_with(&self, a: &[f64], b: &[f64]) -> f64 {
        let mut x = 0.0;
        for (i, a) in a.iter().enumerate() {
            x -= a * self.x_hist.get(i);
        }
        // u_hist.get(0) is u(k-1): u(k-d-j) is age d + j - 1.
        for (j, b) in b.iter().enumerate() {
            x += b * self.u_hist.get(self.params.delay + j - 1);
        }
        x
    }

    /// x(k-1), the newest output pushed (0 before the first).
    pub fn last_output(&self) -> f64 {
        self.x_hist.get(0)
    }

    /// x(k-i), `i` from 1 to [`MAX_ORDER`] (0 before the first outputs).
    pub fn output_ago(&self, i: usize) -> f64 {
        self.x_hist.get(i - 1)
    }

    /// Close sample k: remember its input `u_k` and output `x_k`.
    pub fn push(&mut self, u_k: f64, x_k: f64) {
        self.x_hist.push(x_k);
        self.u_hist.push(u_k);
    }

    /// x(k) for input u(k), moving on to sample k + 1.
    pub fn step(&mut self, u_k: f64) -> f64 {
        let x = self.peek();
        self.push(u_k, x);
        x
    }

    /// Internal consistency of a restored block.
    pub fn check(&self) -> Result<(), String> {
        self.params.validate().map_err(|e| e.to_string())?;
        self.u_hist
            .check(self.params.input_memory(), "input history")?;
        self.x_hist.check(MAX_ORDER, "output history")
    }

    pub fn reset(&mut self) {
        self.u_hist.clear();
        self.x_hist.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_block_hand_worked() {
        // u = 1, 0, 0, ...: x(0) = 0, x(1) = 0.8, x(2) = -0.45*0.8 = -0.36,
        // x(3) = -0.45*(-0.36) - 0.55*0.8 = 0.162 - 0.44 = -0.278.
        let mut arx = Arx::new(ArxParams::PAPER);
        let xs: Vec<f64> = [1.0, 0.0, 0.0, 0.0].iter().map(|&u| arx.step(u)).collect();
        let want = [0.0, 0.8, -0.36, -0.278];
        for (x, w) in xs.iter().zip(want) {
            assert!((x - w).abs() < 1e-15, "{xs:?}");
        }
    }

    #[test]
    fn delay_and_fir_terms() {
        let p = ArxParams {
            na: 0,
            nb: 2,
            delay: 3,
            a: [0.0; 4],
            b: [1.0, 10.0, 100.0, 0.0, 0.0],
        };
        let mut arx = Arx::new(p);
        // Impulse at k = 0 appears at k = 3, 4, 5 weighted by b0, b1, b2.
        let xs: Vec<f64> = (0..8)
            .map(|k| arx.step(if k == 0 { 1.0 } else { 0.0 }))
            .collect();
        assert_eq!(xs, vec![0.0, 0.0, 0.0, 1.0, 10.0, 100.0, 0.0, 0.0]);
    }

    #[test]
    fn history_shifts() {
        let mut h = History::zeros(3);
        for v in [1.0, 2.0, 3.0, 4.0] {
            h.push(v);
        }
        assert_eq!((h.get(0), h.get(1), h.get(2)), (4.0, 3.0, 2.0));
    }
}
