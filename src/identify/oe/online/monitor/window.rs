//! The running sums of a confirmation window and the tracked output offset and gain (the module docs of
//! [`super`] give the formulas).

use serde::{Deserialize, Serialize};

use super::{MIN_WINDOW, NUISANCE_CLIP, NUISANCE_MEMORY, NUISANCE_START, well_posed};

/// Running sums over the samples of a confirmation window (a CUSUM's current excursion, or a recent onset to
/// now): n, e, h, h^2, d, d h, e h, e d, d^2, with d the play change's signature (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub(super) struct Window {
    pub(super) start: u64,
    pub(super) start_time: f64,
    pub(super) sums: [f64; 9],
}

impl Window {
    pub(super) fn add(&mut self, e: f64, h: f64, d: f64) {
        let terms = [1.0, e, h, h * h, d, d * h, e * h, e * d, d * d];
        for (s, t) in self.sums.iter_mut().zip(terms) {
            *s += t;
        }
    }

    /// The GLR of a play change along d against an offset and gain change within the window (module docs);
    /// 0 on fewer than [`MIN_WINDOW`] samples or a fit that points away from growth.
    pub(super) fn glr(&self, sigma2: f64) -> f64 {
        if self.sums[0] >= MIN_WINDOW as f64 {
            let (ed, dd) = self.projected();
            growth_glr(ed, dd, sigma2)
        } else {
            0.0
        }
    }

    /// (e' . d', d' . d') after least squares on (1, h) within the window (module docs).
    pub(super) fn projected(&self) -> (f64, f64) {
        let [n, se, sh, shh, sg, sgh, seh, seg, sgg] = self.sums;
        let det = n * shh - sh * sh;
        if !well_posed(det, n * shh) {
            // h constant within the window: the constant only.
            return (seg - se * sg / n, sgg - sg * sg / n);
        }
        // [se, seh] M^-1 [sg, sgh] and [sg, sgh] M^-1 [sg, sgh], M = [[n, sh], [sh, shh]].
        let quad = |a: [f64; 2], b: [f64; 2]| {
            (a[0] * (shh * b[0] - sh * b[1]) + a[1] * (n * b[1] - sh * b[0])) / det
        };
        (
            seg - quad([se, seh], [sg, sgh]),
            (sgg - quad([sg, sgh], [sg, sgh])).max(0.0),
        )
    }
}

/// The GLR `(e' . d')^2 / (2 sigma^2 d' . d')` of a play change from the projected sums `ed` = e' . d' and
/// `dd` = d' . d' (module docs); 0 when the fit points away from growth (`ed <= 0`) or d' vanishes.
pub(super) fn growth_glr(ed: f64, dd: f64, sigma2: f64) -> f64 {
    if ed > 0.0 && dd > 0.0 {
        ed * ed / (2.0 * sigma2 * dd)
    } else {
        0.0
    }
}

/// The tracked output offset and log gain of the linear block (module docs): recursive least squares of the
/// residual on (1, h) with forgetting `1 - 1 / NUISANCE_MEMORY`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub(super) struct Nuisance {
    pub(super) offset: f64,
    pub(super) log_gain: f64,
    /// Discounted information sum of (1, h)(1, h)^T: [n, sh, shh].
    pub(super) info: [f64; 3],
}

impl Nuisance {
    /// Sample with residual `e` (against the model with the current offset and gain) and sensitivity `h`.
    pub(super) fn update(&mut self, e: f64, h: f64, sigma: f64) {
        let lambda = 1.0 - 1.0 / NUISANCE_MEMORY;
        let [n, sh, shh] = &mut self.info;
        *n = lambda * *n + 1.0;
        *sh = lambda * *sh + h;
        *shh = lambda * *shh + h * h;
        if *n < NUISANCE_START {
            return;
        }
        let e = e.clamp(-NUISANCE_CLIP * sigma, NUISANCE_CLIP * sigma);
        let det = *n * *shh - *sh * *sh;
        if well_posed(det, *n * *shh) {
            // [d_offset, d_log_gain] = M^-1 (1, h) e, M = [[n, sh], [sh, shh]].
            self.offset += (*shh - *sh * h) * e / det;
            self.log_gain += (*n * h - *sh) * e / det;
        } else {
            self.offset += e / *n;
        }
    }
}
