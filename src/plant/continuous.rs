//! A continuous-time linear block `G(s) = N(s) / D(s)` (paper 003, eq. (1): `x = g * u`), advanced exactly
//! between samples with a zero-order-hold input.
//!
//! - `D` has degree `n` in `0..=4`, `N` degree at most `n` (strictly proper or proper); coefficients are
//!   given in *descending* powers of `s`, as in most control toolboxes: `den = [1.0, 0.6, 1.0]` is
//!   `s^2 + 0.6 s + 1`.
//! - `G` must be BIBO stable (paper 003, section 2: `g` in `L1`): every root of `D` in the open left
//!   half-plane, checked exactly on the coefficients with the Routh-Hurwitz conditions. An unstable or
//!   marginally stable denominator is refused with the largest real part of its poles in the error.
//! - Realisation: controllable canonical form `z' = A z + B u`, `x = C z + D0 u`.
//! - Sampling: with `u(t) = u(k)` on `[k Ts, (k+1) Ts)`, `z(k+1) = Phi z(k) + Gamma u(k)` where
//!   `[[Phi, Gamma], [0, 1]] = exp([[A, B], [0, 0]] Ts)` (matrix exponential of the augmented state matrix,
//!   nalgebra's scaling-and-squaring Pade), which is exact for a piecewise-constant input.
//!
//! Timing: the block is at sample `k` with state `z(k)`; [`ContinuousLinear::output`] gives
//! `x(k) = C z(k) + D0 u(k)` (the direct term uses the input set at the same instant) and
//! [`ContinuousLinear::advance`] holds `u(k)` over one period. [`ContinuousLinear::step`] does both. The state
//! starts at zero.

use nalgebra::{Complex, DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::{ParamError, check_finite, check_positive};

/// Highest denominator degree.
pub const MAX_DEGREE: usize = 4;

/// A rational transfer function, coefficients in descending powers of `s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TransferFunction {
    pub num: Vec<f64>,
    pub den: Vec<f64>,
}

/// Evaluate a polynomial with coefficients in descending powers at a complex point.
fn eval_desc(c: &[f64], s: Complex<f64>) -> Complex<f64> {
    c.iter()
        .fold(Complex::new(0.0, 0.0), |acc, &ci| acc * s + ci)
}

impl TransferFunction {
    /// `G(s) = num(s) / den(s)`, validated.
    pub fn new(num: &[f64], den: &[f64]) -> Result<Self, ParamError> {
        let tf = Self {
            num: num.to_vec(),
            den: den.to_vec(),
        };
        tf.validate()?;
        Ok(tf)
    }

    /// The example used by the experiments: `1 / (s^2 + 0.6 s + 1)` (damping 0.3, unit natural frequency).
    pub fn example() -> Self {
        Self {
            num: vec![1.0],
            den: vec![1.0, 0.6, 1.0],
        }
    }

    /// Degree of the denominator.
    pub fn order(&self) -> usize {
        self.den.len().saturating_sub(1)
    }

    /// Monic denominator coefficients `[p1, .., pn]` of `s^n + p1 s^(n-1) + .. + pn`, and the numerator
    /// `[q0, .., qn]` over the same leading coefficient, padded to degree `n`.
    fn monic(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.order();
        let lead = self.den[0];
        let p: Vec<f64> = self.den[1..].iter().map(|v| v / lead).collect();
        let num = strip_leading_zeros(&self.num);
        let mut q = vec![0.0; n + 1];
        let off = n + 1 - num.len();
        for (k, v) in num.iter().enumerate() {
            q[off + k] = v / lead;
        }
        (p, q)
    }

    /// Coefficients finite, degrees in range, leading denominator coefficient non-zero, stable.
    pub fn validate(&self) -> Result<(), ParamError> {
        if self.den.is_empty() || self.den.len() > MAX_DEGREE + 1 {
            return Err(ParamError::new(
                "den",
                self.den.len() as f64,
                "must have between 1 and 5 coefficients (degree between 0 and 4)",
            ));
        }
        for (k, v) in self.den.iter().enumerate() {
            check_finite(&format!("den[{k}]"), *v)?;
        }
        if self.den[0] == 0.0 {
            return Err(ParamError::new(
                "den[0]",
                0.0,
                "leading denominator coefficient must be non-zero",
            ));
        }
        if self.num.is_empty() {
            return Err(ParamError::new(
                "num",
                0.0,
                "must have at least one coefficient",
            ));
        }
        for (k, v) in self.num.iter().enumerate() {
            check_finite(&format!("num[{k}]"), *v)?;
        }
        let num_deg = strip_leading_zeros(&self.num).len().saturating_sub(1);
        if num_deg > self.order() {
            return Err(ParamError::new(
                "num",
                num_deg as f64,
                "numerator degree must not exceed the denominator degree (G must be proper)",
            ));
        }
        if !self.is_stable() {
            let worst = self
                .poles()
                .iter()
                .map(|p| p.re)
                .fold(f64::NEG_INFINITY, f64::max);
            return Err(ParamError::new(
                "den",
                worst,
                "has a pole with real part >= 0 (largest real part shown): the linear block must be BIBO \
                 stable, every root of the denominator in the open left half-plane",
            ));
        }
        Ok(())
    }

    /// Routh-Hurwitz test of the denominator (exact conditions for degree <= 4).
    pub fn is_stable(&self) -> bool {
        let (p, _) = self.monic();
        let pos = p.iter().all(|&v| v > 0.0);
        match p.len() {
            0 => true,
            1 | 2 => pos,
            3 => pos && p[0] * p[1] > p[2],
            4 => pos && p[0] * p[1] > p[2] && p[0] * p[1] * p[2] > p[2] * p[2] + p[0] * p[0] * p[3],
            _ => false,
        }
    }

    /// Roots of the denominator (eigenvalues of its companion matrix).
    pub fn poles(&self) -> Vec<Complex<f64>> {
        let (p, _) = self.monic();
        let n = p.len();
        if n == 0 {
            return Vec::new();
        }
        let a = companion(&p);
        a.complex_eigenvalues().iter().copied().collect()
    }

    /// `G(j omega)`.
    pub fn response(&self, omega: f64) -> Complex<f64> {
        let s = Complex::new(0.0, omega);
        eval_desc(&self.num, s) / eval_desc(&self.den, s)
    }

    /// Gain `|G(j omega)|` and phase lag `phi(omega) = -arg G(j omega)` in `[0, 2 pi)` (paper 003, eq. (4a)).
    pub fn gain_phase(&self, omega: f64) -> (f64, f64) {
        gain_phase_of(self.response(omega))
    }
}

/// Gain and phase lag in `[0, 2 pi)` of a complex frequency response.
pub fn gain_phase_of(g: Complex<f64>) -> (f64, f64) {
    let lag = (-g.im.atan2(g.re)).rem_euclid(std::f64::consts::TAU);
    (g.norm(), lag)
}

fn strip_leading_zeros(c: &[f64]) -> &[f64] {
    let first = c.iter().position(|&v| v != 0.0).unwrap_or(c.len());
    if first == c.len() {
        &c[c.len().saturating_sub(1)..]
    } else {
        &c[first..]
    }
}

/// Companion matrix of `s^n + p1 s^(n-1) + .. + pn` in controllable canonical form.
fn companion(p: &[f64]) -> DMatrix<f64> {
    let n = p.len();
    let mut a = DMatrix::zeros(n, n);
    for i in 0..n.saturating_sub(1) {
        a[(i, i + 1)] = 1.0;
    }
    for m in 0..n {
        a[(n - 1, m)] = -p[n - 1 - m];
    }
    a
}

/// The sampled block with its state; serialisable (it is part of an FMU's saved state).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContinuousLinear {
    tf: TransferFunction,
    ts: f64,
    n: usize,
    phi: [[f64; MAX_DEGREE]; MAX_DEGREE],
    gamma: [f64; MAX_DEGREE],
    c: [f64; MAX_DEGREE],
    d: f64,
    z: [f64; MAX_DEGREE],
}

impl ContinuousLinear {
    /// Realise and sample `tf` with period `ts` (seconds); zero state.
    pub fn new(tf: TransferFunction, ts: f64) -> Result<Self, ParamError> {
        tf.validate()?;
        check_positive("Ts", ts)?;
        let (p, q) = tf.monic();
        let n = p.len();
        let mut blk = Self {
            tf,
            ts,
            n,
            phi: [[0.0; MAX_DEGREE]; MAX_DEGREE],
            gamma: [0.0; MAX_DEGREE],
            c: [0.0; MAX_DEGREE],
            d: q[0],
            z: [0.0; MAX_DEGREE],
        };
        if n == 0 {
            return Ok(blk);
        }
        // x = D0 u + sum_m r(m) z_(m+1) with r(m) the s^m coefficient of N - q0 D.
        for m in 0..n {
            blk.c[m] = q[n - m] - q[0] * p[n - 1 - m];
        }
        let a = companion(&p);
        let mut aug = DMatrix::zeros(n + 1, n + 1);
        aug.view_mut((0, 0), (n, n)).copy_from(&(a * ts));
        aug[(n - 1, n)] = ts;
        let e = aug.exp();
        for i in 0..n {
            for j in 0..n {
                blk.phi[i][j] = e[(i, j)];
            }
            blk.gamma[i] = e[(i, n)];
        }
        if blk.phi.iter().flatten().any(|v| !v.is_finite()) {
            return Err(ParamError::new(
                "Ts",
                ts,
                "is too long for this G(s): the transition matrix overflows",
            ));
        }
        Ok(blk)
    }

    /// Re-check the stored transfer function and period (after deserialising, for instance).
    pub fn validate(&self) -> Result<(), ParamError> {
        self.tf.validate()?;
        check_positive("Ts", self.ts)
    }

    pub fn transfer_function(&self) -> &TransferFunction {
        &self.tf
    }

    /// Sample period in seconds.
    pub fn ts(&self) -> f64 {
        self.ts
    }

    /// State dimension (the denominator degree).
    pub fn order(&self) -> usize {
        self.n
    }

    /// The state `z(k)` (controllable canonical coordinates).
    pub fn state(&self) -> &[f64] {
        &self.z[..self.n]
    }

    /// Output at the current sample for the input `u(k)` set at this instant.
    pub fn output(&self, u: f64) -> f64 {
        self.d * u
            + self.c[..self.n]
                .iter()
                .zip(&self.z[..self.n])
                .map(|(c, z)| c * z)
                .sum::<f64>()
    }

    /// Hold `u` over one period: move the state to the next sample.
    pub fn advance(&mut self, u: f64) {
        let n = self.n;
        let mut next = [0.0; MAX_DEGREE];
        for (i, nx) in next.iter_mut().enumerate().take(n) {
            *nx = self.phi[i][..n]
                .iter()
                .zip(&self.z[..n])
                .map(|(p, z)| p * z)
                .sum::<f64>()
                + self.gamma[i] * u;
        }
        self.z = next;
    }

    /// `x(k)` for `u(k)`, then move to sample `k + 1` holding `u(k)`.
    pub fn step(&mut self, u: f64) -> f64 {
        let x = self.output(u);
        self.advance(u);
        x
    }

    /// Back to the zero state.
    pub fn reset(&mut self) {
        self.z = [0.0; MAX_DEGREE];
    }

    /// Frequency response of the sampled block, `C (e^(j w Ts) I - Phi)^(-1) Gamma + D0`: what a sampled
    /// sine `u(k) = U cos(w k Ts)` produces at the samples in steady state (the zero-order hold delays by
    /// about half a period and attenuates slightly compared with `G(j w)`).
    pub fn sampled_response(&self, omega: f64) -> Complex<f64> {
        let n = self.n;
        let mut g = Complex::new(self.d, 0.0);
        if n == 0 {
            return g;
        }
        let z = Complex::from_polar(1.0, omega * self.ts);
        let m = DMatrix::from_fn(n, n, |i, j| {
            let diag = if i == j { z } else { Complex::new(0.0, 0.0) };
            diag - Complex::new(self.phi[i][j], 0.0)
        });
        let b = DVector::from_fn(n, |i, _| Complex::new(self.gamma[i], 0.0));
        if let Some(v) = m.lu().solve(&b) {
            for i in 0..n {
                g += v[i] * self.c[i];
            }
        } else {
            g = Complex::new(f64::NAN, f64::NAN);
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_order_step_response_is_exact() {
        // G = 2 / (s + 0.5): x(k) = 4 (1 - e^(-0.5 k Ts)) for a unit step.
        let ts = 0.1;
        let mut b =
            ContinuousLinear::new(TransferFunction::new(&[2.0], &[1.0, 0.5]).unwrap(), ts).unwrap();
        for k in 0..200 {
            let x = b.step(1.0);
            let want = 4.0 * (1.0 - (-0.5 * k as f64 * ts).exp());
            assert!((x - want).abs() < 1e-13, "k {k}: {x} vs {want}");
        }
    }

    #[test]
    fn second_order_matches_a_fine_rk4_integration() {
        // G = (0.5 s + 1) / (s^2 + 0.6 s + 1), input a staircase of random-ish values.
        let tf = TransferFunction::new(&[0.5, 1.0], &[1.0, 0.6, 1.0]).unwrap();
        let ts = 0.05;
        let mut b = ContinuousLinear::new(tf, ts).unwrap();
        // Independent integration: z1' = z2, z2' = -z1 - 0.6 z2 + u, x = z1 + 0.5 z2.
        let mut z = [0.0f64, 0.0];
        let f = |z: [f64; 2], u: f64| [z[1], -z[0] - 0.6 * z[1] + u];
        let sub = 200;
        let h = ts / sub as f64;
        for k in 0..400 {
            let u = ((k * 7919) % 13) as f64 / 6.0 - 1.0;
            let x = b.step(u);
            let want = z[0] + 0.5 * z[1];
            assert!((x - want).abs() < 1e-10, "k {k}: {x} vs {want}");
            for _ in 0..sub {
                let k1 = f(z, u);
                let k2 = f([z[0] + 0.5 * h * k1[0], z[1] + 0.5 * h * k1[1]], u);
                let k3 = f([z[0] + 0.5 * h * k2[0], z[1] + 0.5 * h * k2[1]], u);
                let k4 = f([z[0] + h * k3[0], z[1] + h * k3[1]], u);
                for i in 0..2 {
                    z[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
                }
            }
        }
    }

    #[test]
    fn proper_block_has_direct_feedthrough() {
        // G = (s + 3) / (s + 1) = 1 + 2 / (s + 1): x(0) = u(0).
        let mut b = ContinuousLinear::new(
            TransferFunction::new(&[1.0, 3.0], &[1.0, 1.0]).unwrap(),
            0.1,
        )
        .unwrap();
        assert_eq!(b.step(2.0), 2.0);
        // After one period: 2 + 2 * 2 (1 - e^-0.1).
        let want = 2.0 + 4.0 * (1.0 - (-0.1f64).exp());
        assert!((b.output(2.0) - want).abs() < 1e-14);
        // Pure gain.
        let mut g =
            ContinuousLinear::new(TransferFunction::new(&[3.0], &[2.0]).unwrap(), 0.1).unwrap();
        assert_eq!(g.step(4.0), 6.0);
    }

    #[test]
    fn sampled_sine_reaches_the_sampled_response() {
        let tf = TransferFunction::new(&[1.0, 2.0], &[1.0, 2.0, 3.0, 1.5]).unwrap();
        let ts = 0.02;
        let w = 1.3;
        let mut b = ContinuousLinear::new(tf.clone(), ts).unwrap();
        let gd = b.sampled_response(w);
        let mut max_err = 0.0f64;
        for k in 0..6000 {
            let t = k as f64 * ts;
            let x = b.step((w * t).cos());
            if k > 4000 {
                let want = (gd * Complex::from_polar(1.0, w * t)).re;
                max_err = max_err.max((x - want).abs());
            }
        }
        assert!(max_err < 1e-9, "{max_err}");
        // And the sampled response is G(jw) up to the hold: |ratio| = 1 + O(Ts^2), phase ~ w Ts / 2.
        let g = tf.response(w);
        let r = gd / g;
        assert!((r.norm() - 1.0).abs() < 1e-3);
        assert!((r.arg() + w * ts / 2.0).abs() < 1e-3);
    }

    #[test]
    fn unstable_or_improper_blocks_are_refused() {
        let e = TransferFunction::new(&[1.0], &[1.0, -0.1, 1.0]).unwrap_err();
        assert_eq!(e.name, "den");
        assert!((e.value - 0.05).abs() < 1e-9, "{}", e.value);
        assert!(e.to_string().contains("stable"));
        // Pole at the origin (marginal) is refused too.
        assert_eq!(
            TransferFunction::new(&[1.0], &[1.0, 1.0, 0.0])
                .unwrap_err()
                .name,
            "den"
        );
        // Third order with positive coefficients but p1 p2 < p3.
        assert!(TransferFunction::new(&[1.0], &[1.0, 1.0, 1.0, 2.0]).is_err());
        assert!(TransferFunction::new(&[1.0], &[1.0, 3.0, 3.0, 1.0]).is_ok());
        // Fourth order: (s+1)^4 is stable; s^4 + s^3 + s^2 + s + 1 is not.
        assert!(TransferFunction::new(&[1.0], &[1.0, 4.0, 6.0, 4.0, 1.0]).is_ok());
        assert!(TransferFunction::new(&[1.0], &[1.0, 1.0, 1.0, 1.0, 1.0]).is_err());
        assert_eq!(
            TransferFunction::new(&[1.0, 0.0, 0.0], &[1.0, 1.0])
                .unwrap_err()
                .name,
            "num"
        );
        assert!(TransferFunction::new(&[1.0], &[1.0, 1.0, 1.0, 1.0, 1.0, 1.0]).is_err());
        assert!(ContinuousLinear::new(TransferFunction::example(), 0.0).is_err());
    }

    #[test]
    fn reset_and_serde_round_trip() {
        let mut b = ContinuousLinear::new(TransferFunction::example(), 0.1).unwrap();
        for k in 0..10 {
            b.step(k as f64);
        }
        let s = serde_json::to_string(&b).unwrap();
        let mut c: ContinuousLinear = serde_json::from_str(&s).unwrap();
        assert_eq!(b, c);
        assert_eq!(b.step(0.3), c.step(0.3));
        c.reset();
        assert_eq!(c.state(), &[0.0, 0.0]);
    }
}
