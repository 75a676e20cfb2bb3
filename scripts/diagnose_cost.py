#!/usr/bin/env python3
"""Cost of `backlash diagnose` against one `backlash identify oe` fit of the same record, in one run.

Records: the paper-000 plant (a = 0.45, 0.55; b = 0.8; delay 1; m1 = 1, m2 = 1.5) with gaps that drift
by +50% over the record (c1 0.5 -> 0.75, c2 1.0 -> 1.5: the `gap-drift` effect), a random-phase multisine
plus uniform input, SNR 43. For each length the commands run alternately (`--repeat` times each) and the
medians are compared like with like: diagnose with the structure declared against identify oe with it
declared, diagnose choosing the structure against identify oe choosing it (both select on the same window of
the fit part), and the time per sample relative to the shortest record. Usage:

    .venv/bin/python scripts/diagnose_cost.py                 # 1e5 and 1e6 samples, 3 repeats
    .venv/bin/python scripts/diagnose_cost.py --sizes 100000 300000 1000000 --repeat 5
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def record(n: int, seed: int = 7) -> tuple[list[float], list[float]]:
    """(u, y) of the drifting-gap paper plant (plain Python: no dependency)."""
    rng = random.Random(seed)
    phases = [rng.uniform(0, 2 * math.pi) for _ in range(5)]
    freqs = [0.013, 0.031, 0.057, 0.11, 0.23]
    u = [
        sum(math.sin(f * k + p) for f, p in zip(freqs, phases)) + rng.uniform(-1, 1)
        for k in range(n)
    ]
    a1, a2, b0, m2 = 0.45, 0.55, 0.8, 1.5
    x1 = x2 = 0.0
    w = 0.0
    ws = []
    for k in range(n):
        x = -a1 * x1 - a2 * x2 + (b0 * u[k - 1] if k >= 1 else 0.0)
        c1 = 0.5 * (1 + 0.5 * k / n)
        c2 = 1.0 * (1 + 0.5 * k / n)
        if x > w + c1:
            w = x - c1
        elif x < w / m2 - c2:
            w = m2 * (x + c2)
        ws.append(w)
        x1, x2 = x, x1
    mean = sum(ws) / n
    sigma = math.sqrt(sum((v - mean) ** 2 for v in ws) / n) / 43.0
    y = [v + rng.gauss(0.0, sigma) for v in ws]
    return u, y


def write(path: Path, u: list[float], y: list[float]) -> None:
    with path.open("w") as f:
        f.write("time,u,y\n")
        for k, (a, b) in enumerate(zip(u, y)):
            f.write(f"{k},{a!r},{b!r}\n")


def timed(cmd: list[str]) -> tuple[float, dict]:
    t = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return time.perf_counter() - t, json.loads(out)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--backlash", default=str(ROOT / "target/release/backlash"))
    a = p.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.sizes:
            f = Path(tmp) / f"drift_{n}.csv"
            print(f"writing a {n}-sample record ...", file=sys.stderr, flush=True)
            write(f, *record(n))
            declared = ["--na", "2", "--nb", "0", "--delay", "1"]
            cmds = {
                "identify oe": [a.backlash, "identify", "oe", str(f), *declared, "--json"],
                "diagnose (declared)": [a.backlash, "diagnose", str(f), *declared, "--json"],
                "identify oe (auto)": [a.backlash, "identify", "oe", str(f), "--json"],
                "diagnose (auto)": [a.backlash, "diagnose", str(f), "--json"],
            }
            times: dict[str, list[float]] = {k: [] for k in cmds}
            answers = {}
            for r in range(a.repeat):
                for name, cmd in cmds.items():
                    print(f"  n = {n}, run {r + 1}/{a.repeat}: {name}", file=sys.stderr, flush=True)
                    s, out = timed(cmd)
                    times[name].append(s)
                    answers[name] = out
            med = {k: statistics.median(v) for k, v in times.items()}
            rows.append((n, med, answers))
    n0, med0, _ = rows[0]
    print("| samples | structure (na, nb, delay) | identify oe [s] | diagnose [s] | ratio | per sample vs "
          f"{n0} | effects found |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for n, med, ans in rows:
        for kind, oe_key, dg_key in (("declared", "identify oe", "diagnose (declared)"),
                                     ("chosen", "identify oe (auto)", "diagnose (auto)")):
            oe, dg = med[oe_key], med[dg_key]
            per = (dg / n) / (med0[dg_key] / n0)
            d = ans[dg_key]
            found = " + ".join(e["id"] for e in d["effects"]) or "none"
            print(f"| {n} | {kind} ({d['na']}, {d['nb']}, {d['delay']}) | {oe:.2f} | {dg:.2f} | {dg / oe:.1f} "
                  f"| {per:.2f} | {found} |")
    print(f"\n(medians of {a.repeat} alternating runs on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
