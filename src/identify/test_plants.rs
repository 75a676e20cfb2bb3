//! Random plants shared by the estimators' tests (MRGIA and output error).

use crate::plant::{ArxParams, BacklashParams, PlantParams};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardUniform};

/// A random stable ARX block (poles inside radius 0.8) with na <= `max_na`, nb <= `max_nb` and a delay drawn
/// from `delays`, and a random backlash (m1 = 1, m2 in 0.5..2, gaps in 0.1..1), noise-free.
pub(crate) fn random_plant(
    rng: &mut ChaCha8Rng,
    max_na: usize,
    max_nb: usize,
    delays: &[usize],
) -> PlantParams {
    let mut unif = |lo: f64, hi: f64| -> f64 {
        let r: f64 = StandardUniform.sample(rng);
        lo + (hi - lo) * r
    };
    // One uniform draw each, in this order, whatever the ranges: the drawn plants depend on the seed only.
    let na = (unif(0.0, (max_na + 1) as f64) as usize).min(max_na);
    let nb = (unif(0.0, (max_nb + 1) as f64) as usize).min(max_nb);
    let delay = delays[(unif(0.0, delays.len() as f64) as usize).min(delays.len() - 1)];
    // A(z) = prod (1 - p z^-1), complex pairs as (1 - 2 r cos(phi) z^-1 + r^2 z^-2).
    let mut poly = vec![1.0];
    while poly.len() - 1 < na {
        let factor = if na - (poly.len() - 1) >= 2 && unif(0.0, 1.0) < 0.5 {
            let (r, phi) = (unif(0.2, 0.8), unif(0.0, std::f64::consts::PI));
            vec![1.0, -2.0 * r * phi.cos(), r * r]
        } else {
            vec![1.0, -unif(-0.8, 0.8)]
        };
        let mut next = vec![0.0; poly.len() + factor.len() - 1];
        for (i, p) in poly.iter().enumerate() {
            for (j, f) in factor.iter().enumerate() {
                next[i + j] += p * f;
            }
        }
        poly = next;
    }
    let mut a = [0.0; 4];
    a[..na].copy_from_slice(&poly[1..]);
    let mut b = [0.0; 5];
    for v in b.iter_mut().take(nb + 1) {
        *v = unif(-1.0, 1.0);
    }
    b[0] = if b[0] < 0.0 { b[0] - 0.3 } else { b[0] + 0.3 };
    PlantParams {
        arx: ArxParams {
            na,
            nb,
            delay,
            a,
            b,
        },
        backlash: BacklashParams {
            m1: 1.0,
            m2: unif(0.5, 2.0),
            c1: unif(0.1, 1.0),
            c2: unif(0.1, 1.0),
        },
        noise_std: 0.0,
        noise_seed: 0,
    }
}
