"""A straightforward NumPy MRGIA: paper 000 (Dong, Tan, Tan 2009), eqs. (17)-(42), one Python loop iteration
per sample on NumPy arrays.

Written from the paper and from the decisions listed in the Rust module's documentation (src/identify/mrgia.rs,
"Decisions where the paper is ambiguous or wrong", "Degenerate cases"), sharing no code with the Rust
implementation. It serves two purposes: an independent check of the Rust estimator (test_mrgia_reference.py)
and the "straightforward NumPy implementation" that scripts/mrgia_speed.py times the CLI against.

Per sample k, with theta(k-1) = [a_1..a_na, b_0..b_nb, m2 - 1, c1, c2]:
    x^(k)   = -sum a_i x^(k-i) + sum b_j u(k-d-j)                         (27), clamped (overflow guard)
    g3 = [x^(k) - x^(k-1) < 0], m = m2 if g3 else 1                          (34), (26)
    g1 = [y(k-1) + c1 < x^(k)], g2 = [y(k-1)/m2 - c2 > x^(k)]                (32), (33)
    g4 = [y(k) - y(k-1) > 0], g5 = [y(k-1) - y(k) > 0]  (>= eps if eps > 0)  (35)-(38)
    Phi = g1 g4 or g2 g5                                                    (42)
    h = [-x^(k-1..k-na), u(k-d..k-d-nb), g3 x^, -m (sgn dx + 1) g1 g4 / 2, m (1 - sgn dx) g2 g5 / 2]   (25)
    y_hat = h^T theta if Phi else y(k-1); e = y - y_hat                      (40), (41), (17)
    if Phi: rho(k) = max((k+1)^-rho_exp, rho_min), mu = rho(k-1)/rho(k) (1 - rho(k))             (30)
            Sigma = max(Sigma + rho (e^2 - Sigma), 1e-12 max|y|^2)                              (22)
            S = h^T P h + mu Sigma; K = P h / S                                                 (19), (20)
            P = (1/mu) (I - K h^T) P (I - K h^T)^T + Sigma K K^T, symmetrised, trace <= n p0    (21)
            theta = theta + K e                                                                 (18)
"""
import math

import numpy as np

M2_FLOOR = 1e-3
SIGMA_REL_FLOOR = 1e-12
X_CLAMP = 1e6
TINY = np.finfo(float).tiny


class Mrgia:
    def __init__(self, na, nb, delay, p0=1e6, rho_exp=0.25, rho_min=0.0, eps=0.0, sigma0=1.0, c_init=0.01):
        self.na, self.nb, self.delay = na, nb, delay
        self.p0, self.rho_exp, self.rho_min, self.eps = p0, rho_exp, rho_min, eps
        n = na + nb + 4
        self.n = n
        self.theta = np.zeros(n)
        self.theta[na] = 1.0  # b0 = 1
        self.theta[n - 2] = c_init
        self.theta[n - 1] = c_init
        self.P = p0 * np.eye(n)
        self.sigma = sigma0
        # u(k-1), u(k-2), ... (newest first), long enough for the delay and the b terms.
        self.u_past = np.zeros(delay + nb + 1)
        self.x_past = np.zeros(max(na, 1))  # x^(k-1), x^(k-2), ...
        self.y_prev = 0.0
        self.u_max = 0.0
        self.y_max = 0.0
        self.samples = 0

    def rho(self, k):
        return max((k + 1.0) ** -self.rho_exp, self.rho_min)

    def update(self, u, y):
        """Process sample (u(k), y(k)); return (y_hat, e, updated)."""
        if not (math.isfinite(u) and math.isfinite(y)):
            return None
        na, nb, d, n = self.na, self.nb, self.delay, self.n
        th = self.theta
        self.u_max = max(self.u_max, abs(u))
        self.y_max = max(self.y_max, abs(y))
        a, b = th[:na], th[na:na + nb + 1]
        m2 = max(1.0 + th[n - 3], M2_FLOOR)
        c1, c2 = th[n - 2], th[n - 1]

        # (27): u(k-d-j) is u_past[d + j - 1].
        x_lag = self.x_past[:na]
        u_lag = self.u_past[d - 1:d + nb]
        x = -np.dot(a, x_lag) + np.dot(b, u_lag)
        bound = min(X_CLAMP * (1.0 + self.u_max + self.y_max), 1e300)
        x = 0.0 if math.isnan(x) else min(max(x, -bound), bound)
        dx = x - self.x_past[0]

        g3 = dx < 0.0
        m = m2 if g3 else 1.0
        yp = self.y_prev
        g1 = yp + c1 < x
        g2 = yp / m2 - c2 > x
        dy = y - yp
        if self.eps > 0.0:
            g4, g5 = dy >= self.eps, -dy >= self.eps
        else:
            g4, g5 = dy > 0.0, -dy > 0.0
        up, down = g1 and g4, g2 and g5
        phi = up or down

        sgn = float(np.sign(dx))
        h = np.concatenate([-x_lag, u_lag, [x if g3 else 0.0,
                                            -0.5 * m * (sgn + 1.0) if up else 0.0,
                                            0.5 * m * (1.0 - sgn) if down else 0.0]])
        y1 = float(h @ th)
        phi = phi and math.isfinite(y1)
        y_hat = y1 if phi else yp
        e = y - y_hat

        updated = False
        if phi:
            k = self.samples + 1
            rho = self.rho(k)
            mu = self.rho(k - 1) / rho * (1.0 - rho)
            floor = max(SIGMA_REL_FLOOR * self.y_max ** 2, TINY)
            sigma = max(self.sigma + rho * (e * e - self.sigma), floor)
            if math.isfinite(sigma) and self._rls(h, e, mu, sigma):
                self.sigma = sigma
                updated = True

        self.x_past = np.roll(self.x_past, 1)
        self.x_past[0] = x
        self.u_past = np.roll(self.u_past, 1)
        self.u_past[0] = u
        self.y_prev = y
        self.samples += 1
        return y_hat, e, updated

    def _rls(self, h, e, mu, sigma):
        P = self.P
        S = h @ P @ h + mu * sigma
        if not (S > 0.0 and math.isfinite(S)):
            return False
        K = P @ h / S
        theta = self.theta + K * e
        M = np.eye(self.n) - np.outer(K, h)
        P_new = (M @ P @ M.T) / mu + sigma * np.outer(K, K)
        P_new = 0.5 * (P_new + P_new.T)
        tr = np.trace(P_new)
        cap = self.n * self.p0
        if tr > cap:
            P_new *= cap / tr
        if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(P_new))):
            return False
        self.theta, self.P = theta, P_new
        return True

    def estimate(self):
        """{'a': [...], 'b': [...], 'm2', 'c1', 'c2'} as the CLI's --json prints them."""
        na, nb, n, th = self.na, self.nb, self.n, self.theta
        return {"a": list(th[:na]), "b": list(th[na:na + nb + 1]), "m2": 1.0 + th[n - 3],
                "c1": th[n - 2], "c2": th[n - 1]}


def identify(u, y, na, nb, delay, **settings):
    est = Mrgia(na, nb, delay, **settings)
    for uk, yk in zip(np.asarray(u, dtype=float), np.asarray(y, dtype=float)):
        est.update(float(uk), float(yk))
    return est
