"""An independent NumPy implementation of the contract's plant equations (docs/INTERFACE.md, BacklashPlant.fmu).

Written from the contract text, sharing no code with the Rust library:
    x(k) = -sum_{i=1..na} a_i x(k-i) + sum_{j=0..nb} b_j u(k-delay-j),   x, u, y = 0 before k = 0
    y(k) = m1 (x - c1)  if x > y(k-1)/m1 + c1
           m2 (x + c2)  if x < y(k-1)/m2 - c2
           y(k-1)       otherwise
"""
import numpy as np


def simulate(u, a=(0.45, 0.55), b=(0.8,), delay=1, m1=1.0, m2=1.5, c1=0.5, c2=1.0):
    """Return x, w for the input sequence u (w is the noise-free backlash output)."""
    u = np.asarray(u, dtype=float)
    n = len(u)
    x = np.zeros(n)
    w = np.zeros(n)
    for k in range(n):
        acc = 0.0
        for i, ai in enumerate(a, start=1):
            if k - i >= 0:
                acc -= ai * x[k - i]
        for j, bj in enumerate(b):
            if k - delay - j >= 0:
                acc += bj * u[k - delay - j]
        x[k] = acc
        prev = w[k - 1] if k > 0 else 0.0
        if acc > prev / m1 + c1:
            w[k] = m1 * (acc - c1)
        elif acc < prev / m2 - c2:
            w[k] = m2 * (acc + c2)
        else:
            w[k] = prev
    return x, w


def random_stable_arx(rng, na, nb):
    """Random a (stable: poles inside radius 0.9) and b coefficients."""
    poles = []
    while len(poles) < na:
        if na - len(poles) >= 2 and rng.random() < 0.5:
            r, th = 0.9 * rng.random(), np.pi * rng.random()
            poles += [r * np.exp(1j * th), r * np.exp(-1j * th)]
        else:
            poles.append(rng.uniform(-0.9, 0.9))
    a = np.real(np.poly(poles))[1:] if na else np.array([])
    b = rng.uniform(-1.0, 1.0, nb + 1)
    b[0] = np.sign(b[0] or 1.0) * max(abs(b[0]), 0.3)
    return list(a), list(b)
