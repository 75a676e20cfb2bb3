#!/usr/bin/env python3
"""Time `backlash identify oe` against scipy.optimize.least_squares on the same output-error problem.

The record is the paper 000, section 4 example (a1 = 0.45, a2 = 0.55, b0 = 0.8, delay 1, m1 = 1, m2 = 1.5,
c1 = 0.5, c2 = 1), N samples (default 3000) of uniform white input of variance 1.93, white Gaussian noise
of std std(w)/43 (the paper's SNR 43), simulated here in NumPy (an implementation independent of the
crate's).

(a) `backlash identify oe FILE --na 2 --nb 0 --delay 1 --json`, wall time of the whole process (CLI start-up,
    CSV parsing, the MRGIA starts and the Levenberg-Marquardt fit), median of --repeat runs.
(b) scipy.optimize.least_squares (method 'lm' = MINPACK, finite-difference Jacobian) on the same cost
    sum (y - w_hat(theta))^2 with the model simulated in NumPy (scipy.signal.lfilter for the linear block,
    a Python loop for the backlash), started from the same point the CLI's fit started from (the "start"
    object of its JSON), median of --repeat runs.

Prints both times and their ratio, and checks that both reach the same optimum (every parameter within
--tol standard errors of the CLI's estimate, and the same cost within 1e-6 relative); exits 1 otherwise.

Usage: scripts/oe_benchmark.py [--cli target/release/backlash] [--n 3000] [--repeat 7] [--json]
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import lfilter

ROOT = pathlib.Path(__file__).resolve().parents[1]
PAPER = dict(a=[0.45, 0.55], b=[0.8], delay=1, m2=1.5, c1=0.5, c2=1.0)


def simulate(u, a, b, delay, m2, c1, c2):
    """Backlash output w of the pseudo-Wiener model (m1 = 1), all signals zero before sample 0.

    x(k) = -sum a_i x(k-i) + sum b_j u(k-d-j);  w(k) = x - c1 if x > w(k-1) + c1,
    m2 (x + c2) if x < w(k-1)/m2 - c2, else w(k-1).
    """
    num = np.concatenate([np.zeros(delay), np.asarray(b, float)])
    den = np.concatenate([[1.0], np.asarray(a, float)])
    x = lfilter(num, den, u)
    w = np.empty_like(x)
    prev = 0.0
    for k, xk in enumerate(x.tolist()):
        if xk > prev + c1:
            prev = xk - c1
        elif xk < prev / m2 - c2:
            prev = m2 * (xk + c2)
        w[k] = prev
    return w


def paper_record(n, seed=1, snr=43.0):
    rng = np.random.default_rng(seed)
    amp = np.sqrt(3 * 1.93)
    u = rng.uniform(-amp, amp, n)
    w = simulate(u, **PAPER)
    y = w + rng.standard_normal(n) * (w.std() / snr)
    return u, y


def write_csv(path, u, y):
    with open(path, "w") as f:
        f.write("time,u,y\n")
        for k, (uk, yk) in enumerate(zip(u, y)):
            f.write(f"{k * 0.01!r},{float(uk)!r},{float(yk)!r}\n")


def split(theta, na, nb):
    return dict(a=theta[:na], b=theta[na:na + nb + 1], m2=theta[-3], c1=theta[-2], c2=theta[-1])


def flat(obj):
    return list(obj["a"]) + list(obj["b"]) + [obj["m2"], obj["c1"], obj["c2"]]


def run_cli(cli, path, repeat):
    cmd = [str(cli), "identify", "oe", str(path), "--na", "2", "--nb", "0", "--delay", "1", "--json"]
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        times.append(time.perf_counter() - t0)
        if p.returncode != 0:
            sys.exit(f"{' '.join(cmd)} failed: {p.stderr}")
        out = json.loads(p.stdout)
    return statistics.median(times), out


def run_scipy(u, y, x0, delay, na, nb, repeat):
    def residual(theta):
        return y - simulate(u, delay=delay, **split(theta, na, nb))

    times, res = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = least_squares(residual, np.asarray(x0, float), method="lm", xtol=1e-10, ftol=1e-12)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), res


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", default=os.environ.get("BACKLASH_CLI", ROOT / "target" / "release" / "backlash"))
    ap.add_argument("--n", type=int, default=3000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--scipy-repeat", type=int, default=3)
    ap.add_argument("--tol", type=float, default=0.2,
                    help="allowed difference, in standard errors (the CLI stops when its Gauss-Newton step is "
                         "shorter than 0.1 standard errors; the cost is piecewise smooth at that scale)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    if not pathlib.Path(args.cli).exists():
        sys.exit(f"{args.cli} is missing: run `cargo build --release` first")

    u, y = paper_record(args.n)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "oe_bench.csv"
        write_csv(path, u, y)
        t_cli, out = run_cli(args.cli, path, args.repeat)
    x0 = flat(out["start"]["estimate"])
    t_scipy, res = run_scipy(u, y, x0, 1, 2, 0, args.scipy_repeat)

    est = np.array(flat(out))
    se = np.array(flat(out["std_err"]))
    diff_se = np.abs(res.x - est) / se
    cost_cli = out["cost"]
    cost_scipy = float(2 * res.cost)  # least_squares reports 0.5 * sum r^2
    same = bool(np.all(diff_se <= args.tol) and abs(cost_scipy - cost_cli) <= 1e-6 * cost_cli)
    # The CLI's model output, re-simulated here, must give the CLI's own cost (independent simulation).
    cost_check = float(np.sum((y - simulate(u, delay=1, **split(est, 2, 0))) ** 2))
    same &= abs(cost_check - cost_cli) <= 1e-9 * cost_cli
    report = {
        "samples": args.n,
        "cli_seconds_median": t_cli,
        "cli_fit_seconds": out["seconds"],
        "scipy_seconds_median": t_scipy,
        "ratio_scipy_over_cli": t_scipy / t_cli,
        "scipy_nfev": int(res.nfev),
        "cli_iterations": out["iterations"],
        "estimate_cli": est.tolist(),
        "estimate_scipy": res.x.tolist(),
        "max_diff_in_std_err": float(diff_se.max()),
        "cost_cli": cost_cli,
        "cost_scipy": cost_scipy,
        "cost_cli_resimulated": cost_check,
        "same_optimum": same,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"N = {args.n}, paper example at SNR 43")
        print(f"backlash identify oe (whole process, median of {args.repeat}): {t_cli * 1e3:.1f} ms "
              f"(fit inside: {out['seconds'] * 1e3:.2f} ms, {out['iterations']} iterations)")
        print(f"scipy least_squares lm (median of {args.scipy_repeat}): {t_scipy * 1e3:.1f} ms "
              f"({res.nfev} evaluations)")
        print(f"ratio scipy / CLI: {t_scipy / t_cli:.1f}")
        print(f"estimates: CLI {np.round(est, 6).tolist()}\n           scipy {np.round(res.x, 6).tolist()}")
        print(f"largest difference {diff_se.max():.2e} standard errors; cost CLI {cost_cli:.6e}, "
              f"scipy {cost_scipy:.6e}, CLI re-simulated {cost_check:.6e}")
        print("same optimum" if same else "DIFFERENT OPTIMA")
    sys.exit(0 if same else 1)


if __name__ == "__main__":
    main()
