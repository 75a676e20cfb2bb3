//! The backlash operator of paper 000, eqs. (2)-(8), with straight borders.
//!
//! The output follows the upper border `y = m1 (x - c1)` while the input drives it up, the lower border
//! `y = m2 (x + c2)` while the input drives it down, and holds its previous value inside the memory zone
//! `(y(k-1)/m2 - c2, y(k-1)/m1 + c1)` in between.  This is exactly the rule of the project's contract:
//!
//! ```text
//! y(k) = m1 (x(k) - c1)   if x(k) > y(k-1)/m1 + c1
//! y(k) = m2 (x(k) + c2)   if x(k) < y(k-1)/m2 - c2
//! y(k) = y(k-1)           otherwise
//! ```
//!
//! With `m1 != m2` the two straight borders cross at `x* = (m1 c1 + m2 c2) / (m1 - m2)`.  The rule above still
//! gives one output for every input there (the upper test is checked first), but the memory zone is only
//! non-empty on the side of `x*` where the upper border lies to the right of the lower one.  Physical play
//! works on that side; the invariants tested in this module hold there.

use serde::{Deserialize, Serialize};

/// Which of the three regimes produced the latest output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Mode {
    /// Following the upper (driving-up) border `m1 (x - c1)`.
    Up,
    /// Following the lower (driving-down) border `m2 (x + c2)`.
    Down,
    /// Inside the memory zone: the output holds.
    Held,
}

/// Parameters of a straight-border backlash.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BacklashParams {
    pub m1: f64,
    pub m2: f64,
    pub c1: f64,
    pub c2: f64,
}

impl BacklashParams {
    /// The paper 000, section 4 example.
    pub const PAPER: Self = Self {
        m1: 1.0,
        m2: 1.5,
        c1: 0.5,
        c2: 1.0,
    };

    /// Upper border value at `x`.
    pub fn upper(&self, x: f64) -> f64 {
        self.m1 * (x - self.c1)
    }

    /// Lower border value at `x`.
    pub fn lower(&self, x: f64) -> f64 {
        self.m2 * (x + self.c2)
    }

    /// One step of the operator: the new output for input `x` after output `y_prev`, and the regime.
    pub fn step(&self, x: f64, y_prev: f64) -> (f64, Mode) {
        if x > y_prev / self.m1 + self.c1 {
            (self.upper(x), Mode::Up)
        } else if x < y_prev / self.m2 - self.c2 {
            (self.lower(x), Mode::Down)
        } else {
            (y_prev, Mode::Held)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const B: BacklashParams = BacklashParams::PAPER;

    #[test]
    fn holds_inside_the_memory_zone() {
        // y_prev = 0: the zone is (0/1.5 - 1, 0/1 + 0.5) = (-1, 0.5).
        for x in [-1.0, -0.99, 0.0, 0.3, 0.5] {
            assert_eq!(B.step(x, 0.0), (0.0, Mode::Held), "x = {x}");
        }
    }

    #[test]
    fn engages_the_upper_border() {
        // 0.8 > 0.5: y = 1 * (0.8 - 0.5) = 0.3.
        let (y, m) = B.step(0.8, 0.0);
        assert_eq!(m, Mode::Up);
        assert!((y - 0.3).abs() < 1e-15);
    }

    #[test]
    fn engages_the_lower_border() {
        // -1.4 < -1: y = 1.5 * (-1.4 + 1) = -0.6.
        let (y, m) = B.step(-1.4, 0.0);
        assert_eq!(m, Mode::Down);
        assert!((y + 0.6).abs() < 1e-15);
    }

    #[test]
    fn hand_worked_reversal_sequence() {
        // x rises to 2, falls back through the gap, engages the lower border, rises again.
        let xs = [0.0, 1.0, 2.0, 1.5, 0.6, 0.4, -0.2, 0.5, 1.6, 2.5];
        // Worked by hand with m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1:
        //  x=0    zone (-1, .5)          held  0
        //  x=1    1 > .5                 up    .5
        //  x=2    2 > 1                  up    1.5
        //  x=1.5  zone (0, 2)            held  1.5
        //  x=.6   .6 < 1.5/1.5-1 = 0     no; zone (0, 2) held 1.5
        //  x=.4   held 1.5
        //  x=-.2  -.2 < 0                down  1.5 * (.8) = 1.2
        //  x=.5   zone (-.2, 1.7)        held  1.2
        //  x=1.6  zone upper 1.7         held  1.2
        //  x=2.5  2.5 > 1.7              up    2.0
        let want = [
            (0.0, Mode::Held),
            (0.5, Mode::Up),
            (1.5, Mode::Up),
            (1.5, Mode::Held),
            (1.5, Mode::Held),
            (1.5, Mode::Held),
            (1.2, Mode::Down),
            (1.2, Mode::Held),
            (1.2, Mode::Held),
            (2.0, Mode::Up),
        ];
        let mut y = 0.0;
        for (k, (&x, &(wy, wm))) in xs.iter().zip(want.iter()).enumerate() {
            let (ny, m) = B.step(x, y);
            assert_eq!(m, wm, "sample {k}");
            assert!((ny - wy).abs() < 1e-12, "sample {k}: {ny} vs {wy}");
            y = ny;
        }
    }

    #[test]
    fn zero_gaps_and_unit_slopes_are_the_identity() {
        let b = BacklashParams {
            m1: 1.0,
            m2: 1.0,
            c1: 0.0,
            c2: 0.0,
        };
        let mut y = 0.0;
        for x in [0.3, -2.0, 5.0, 5.0, 1.0] {
            y = b.step(x, y).0;
            assert_eq!(y, x);
        }
    }

    fn params() -> impl Strategy<Value = BacklashParams> {
        (0.2f64..3.0, 0.2f64..3.0, 0.0f64..2.0, 0.0f64..2.0)
            .prop_map(|(m1, m2, c1, c2)| BacklashParams { m1, m2, c1, c2 })
    }

    proptest! {
        /// The working point never leaves the region between the borders: after every step
        /// y/m2 - c2 <= x <= y/m1 + c1, as long as the input stays on the side of the crossing
        /// point where the memory zone is non-empty (inputs bounded to |x| <= 3, slopes chosen so).
        #[test]
        fn working_point_stays_between_the_borders(
            b in params(),
            xs in proptest::collection::vec(-3.0f64..3.0, 1..200),
        ) {
            // Keep the crossing point outside the tested range (the zone is empty beyond it).
            let cross = (b.m1 * b.c1 + b.m2 * b.c2) / (b.m1 - b.m2);
            prop_assume!(!cross.is_finite() || cross.abs() > 3.5 || b.m1 == b.m2);
            let mut y = 0.0;
            // Start from a point between the borders at x = 0.
            for &x in &xs {
                let (ny, _) = b.step(x, y);
                y = ny;
                let tol = 1e-9 * (1.0 + y.abs() + x.abs());
                prop_assert!(x <= y / b.m1 + b.c1 + tol, "x {x} right of the upper border at y {y}");
                prop_assert!(x >= y / b.m2 - b.c2 - tol, "x {x} left of the lower border at y {y}");
            }
        }

        /// The output changes only on a border, and then in the direction of the input's motion.
        #[test]
        fn output_moves_with_the_input(
            b in params(),
            xs in proptest::collection::vec(-3.0f64..3.0, 2..200),
        ) {
            let cross = (b.m1 * b.c1 + b.m2 * b.c2) / (b.m1 - b.m2);
            prop_assume!(!cross.is_finite() || cross.abs() > 3.5 || b.m1 == b.m2);
            let mut y = 0.0;
            for &x in &xs {
                let (ny, m) = b.step(x, y);
                match m {
                    Mode::Held => prop_assert_eq!(ny, y),
                    Mode::Up => prop_assert!(ny > y),
                    Mode::Down => prop_assert!(ny < y),
                }
                y = ny;
            }
        }
    }
}
