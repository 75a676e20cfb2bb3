#!/usr/bin/env python3
"""`backlash diagnose` on records sampled far faster than their dynamics: the rate it chooses and its held-out
error against the true model's on the same samples.

The plant is the test bench's with the continuous linear block G(s) = 1 / (s^2 + 0.6 s + 1) (the plant FMU's
`linear = 1`; paper 003's example) and the default backlash (m1 = 1, m2 = 1.5, c1 = 0.5, c2 = 1). Its own
rate is one sample per second (about six per period of G's resonance); the input is a uniform level in
[-2.4, 2.4] held for one second. Each record samples the same experiment F times faster (Ts = 1/F s,
T seconds long, sensor noise of std NOISE at every sample) and is diagnosed with no options. "rates compared"
lists the factors the rate choice judged on the fit part (`rate.candidates`: each factor's validation free-run
RMSE at the record's samples; "-" when only the time-constant rule's factor was possible).

The true model's error is judged like diagnose's own: the noise-free backlash output w of the record is block-
averaged by the factor diagnose chose, and its RMSE against the block-averaged measured output is taken on
the same held-out part (the last 30% of the decimated samples).

    .venv/bin/python scripts/oversampling.py                 # F = 1, 10, 30, 100
    .venv/bin/python scripts/oversampling.py --factors 30 --seed 1
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
NOISE = 0.05


def block_means(x: np.ndarray, factor: int) -> np.ndarray:
    m = (len(x) // factor) * factor
    return x[:m].reshape(-1, factor).mean(axis=1)


def measure(binary: str, factor: int, seed: int, seconds: int, folder: pathlib.Path) -> dict:
    """Make the record sampled `factor` times per second and diagnose it with no options: its answer (`doc`,
    None when refused, then `error`), the true model's held-out error at the rate chosen (`true`) and the
    diagnosis's wall time."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(-2.4, 2.4, seconds), factor)
    t = np.arange(len(u)) / factor
    inp, rec = folder / f"u{factor}.csv", folder / f"r{factor}.csv"
    np.savetxt(inp, np.c_[t, u], delimiter=",", header="time,u", comments="")
    subprocess.run([binary, "simulate", str(inp), "--ts", repr(1.0 / factor), "--linear", "1", "--num0", "1",
                    "--den0", "1", "--den1", "0.6", "--den2", "1", "--noise-std", repr(NOISE), "--noise-seed",
                    str(seed), "-o", str(rec)], check=True)
    data = np.loadtxt(rec, delimiter=",", skiprows=1)
    started = time.time()
    out = subprocess.run([binary, "diagnose", str(rec), "--json"], capture_output=True, text=True)
    secs = time.time() - started
    if out.returncode:
        return {"factor": factor, "n": len(u), "doc": None, "error": out.stderr.strip(), "seconds": secs}
    doc = json.loads(out.stdout)
    d = int(doc["decimate"])
    w, y = block_means(data[:, 3], d), block_means(data[:, 4], d)
    n_fit = min(max(int(round(0.7 * len(y))), 1), len(y) - 1)
    true = float(np.sqrt(np.mean((y[n_fit:] - w[n_fit:]) ** 2)))
    return {"factor": factor, "n": len(u), "doc": doc, "true": true, "seconds": secs}


def one(binary: str, factor: int, seed: int, seconds: int, folder: pathlib.Path) -> str:
    """The table row of `measure`."""
    m = measure(binary, factor, seed, seconds, folder)
    doc = m["doc"]
    if doc is None:
        return f"| {factor} | {m['n']} | refused: {m['error']} |"
    true, after = m["true"], doc["after"]["rmse"]
    effects = "+".join(e["id"] for e in doc["effects"]) or "none"
    compared = ", ".join(f"{c['decimate']}: {c['validation_rmse']:.4g}" if c["validation_rmse"] is not None
                         else f"{c['decimate']}: -" for c in doc["rate"].get("candidates", [])) or "-"
    return (f"| {factor} | {m['n']} | {doc['decimate']} ({doc['rate']['chosen_by']}) | {compared} | {doc['na']}, "
            f"{doc['nb']}, {doc['delay']} | {doc['linear']['rmse']:.4g} | {doc['before']['rmse']:.4g} | "
            f"{after:.4g} | {true:.4g} | {after / true:.3f} | {effects} | {m['seconds']:.1f} |")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--factors", type=int, nargs="+", default=[1, 10, 30, 100])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seconds", type=int, default=2000, help="length of the experiment in seconds")
    p.add_argument("--binary", default=str(ROOT / "target" / "release" / "backlash"))
    a = p.parse_args()
    print("| F (samples per second) | N | rate: decimate (chosen by) | rates compared (factor: RMSE) | na, nb, delay "
          "| linear | before | after | true model | after / true | effects | time [s] |")
    print("|" + " --- |" * 12)
    with tempfile.TemporaryDirectory() as tmp:
        for f in a.factors:
            print(one(a.binary, f, a.seed, a.seconds, pathlib.Path(tmp)), flush=True)


if __name__ == "__main__":
    main()
