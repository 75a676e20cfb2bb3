#!/usr/bin/env python3
"""The README's Python walk-through, end to end, with its one plot: a worn test bench (a gap that grows over
the record), the on-line estimator following it in co-simulation, the off-line fit, and the diagnosis.

    .venv/bin/python scripts/python_walkthrough.py [--out docs/python_walkthrough.png]

Uses only the installed package (backlash_fmu with its `cosim` extra) and matplotlib; prints the numbers the
README quotes.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import backlash_fmu as bf  # noqa: E402
from backlash_fmu.cosim import paper_input, run_pair  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="docs/python_walkthrough.png")
    a = ap.parse_args()

    # 1. The test bench: paper 000's plant FMU co-simulated with the on-line estimator FMU; at sample 4000 the
    #    gaps c1, c2 widen by 50 % (wear, set on the plant FMU); noise std 0.02 (SNR about 40).
    n, step = 8000, 4000
    u = paper_input(n, 3)
    pair = run_pair(bf.fmu_path("BacklashPlant"), bf.fmu_path("MrgiaEstimator"), u,
                    plant_start={"noise_std": 0.02, "noise_seed": 1},
                    estimator_start={"recommended": True, "rho_min": 0.01},
                    plant_events={step: {"c1": 0.75, "c2": 1.5}}, record_every=20)
    y = pair["y"]  # the measured record
    names = list(pair["names"])
    c1_track = pair["estimates"][:, names.index("c1")]
    c2_track = pair["estimates"][:, names.index("c2")]

    # 2. The off-line output-error fit on each half, with standard errors.
    first = bf.identify_oe(u[:step], y[:step], na=2, nb=0, delay=1)
    second = bf.identify_oe(u[step:], y[step:], na=2, nb=0, delay=1)
    for label, f in (("samples 0-3999", first), ("samples 4000-7999", second)):
        print(f"OE on {label}: c1 = {f['c1']:.3f} +/- {f['std_err']['c1']:.3f}, "
              f"c2 = {f['c2']:.3f} +/- {f['std_err']['c2']:.3f}")

    # 3. The diagnosis of the whole record with one declared model: the gaps drift.
    d = bf.diagnose(u, y, na=2, nb=0, delay=1, ts=1.0, max_effects=1)
    print(f"diagnose: effect {d['effect']['id'] if d['effect'] else None}; held-out RMSE "
          f"{d['before']['rmse']:.4f} -> {d['after']['rmse']:.4f}")

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(pair["samples"], c1_track, label="c1, MrgiaEstimator.fmu (co-simulation)", color="C0")
    ax.plot(pair["samples"], c2_track, label="c2, MrgiaEstimator.fmu (co-simulation)", color="C1")
    for f, lo, hi in ((first, 0, step), (second, step, n)):
        for name, color in (("c1", "C0"), ("c2", "C1")):
            v, s = f[name], f["std_err"][name]
            ax.fill_between([lo, hi], v - 2 * s, v + 2 * s, color=color, alpha=0.3, lw=0)
    ax.step([0, step, n], [0.5, 0.75, 0.75], where="post", color="k", ls="--", lw=0.8, label="true gaps")
    ax.step([0, step, n], [1.0, 1.5, 1.5], where="post", color="k", ls="--", lw=0.8)
    ax.set_xlabel("sample k")
    ax.set_ylabel("gap")
    ax.set_ylim(0, 2)
    ax.set_title(f"Wear at k = {step}: on-line estimates; bands: identify_oe +/- 2 std_err per half; "
                 f"diagnose: {d['effect']['id'] if d['effect'] else None}", fontsize=8)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(a.out, dpi=100)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
