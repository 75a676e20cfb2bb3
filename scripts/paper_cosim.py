"""The main job: co-simulate BacklashPlant.fmu and MrgiaEstimator.fmu on paper 000's example.

Prints how the estimates converge (table of estimates against the truth at a few sample counts, noise-free and
at SNR 43, with the paper's setting and the recommended one), the distribution of the largest relative error
over 20 seeds, and writes the convergence plots (like the paper's Figs. 3-4) to out/.

Usage: python scripts/paper_cosim.py [--out DIR] [--seeds N]
"""
import argparse
import pathlib
import sys
import time

import numpy as np

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from backlash_fmu import simulate  # noqa: E402
from backlash_fmu.cosim import CHECKED, PAPER_TRUTH, max_rel_error, paper_input, run_pair  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]

PLANT = ROOT / "target" / "fmu" / "BacklashPlant.fmu"
ESTIMATOR = ROOT / "target" / "fmu" / "MrgiaEstimator.fmu"
SETTINGS = {"paper": None, "recommended": {"recommended": True}}
TABLE_N = [100, 300, 1000, 3000, 10000]


def noise_std(u, snr=43.0):
    w = simulate(u)["w"]  # the plant of paper 000's example, noise-free
    return float(np.std(w)) / snr


def convergence_run(seed, snr, setting, n=10000):
    u = paper_input(n, seed)
    plant = {"noise_std": noise_std(u, snr), "noise_seed": 1000 + seed} if snr else None
    return run_pair(str(PLANT), str(ESTIMATOR), u, plant_start=plant, estimator_start=SETTINGS[setting],
                    record_every=10)


def print_table(title, runs):
    print(f"\n{title}")
    head = "  N      setting      " + "".join(f"{n:>10}" for n in CHECKED) + "   max rel err"
    print(head)
    print("  truth               " + "".join(f"{PAPER_TRUTH[n]:>10.4f}" for n in CHECKED))
    for n in TABLE_N:
        for setting, r in runs.items():
            i = int(np.searchsorted(r["samples"], n))
            row = dict(zip(r["names"], r["estimates"][i]))
            print(f"  {n:<6} {setting:<12} " + "".join(f"{row[c]:>10.4f}" for c in CHECKED)
                  + f"   {max_rel_error(r['estimates'][i]):.2e}")


def plot(runs, title, path):
    fig, axes = plt.subplots(2, 3, figsize=(13, 7), sharex=True)
    for ax, name in zip(axes.flat, CHECKED):
        for (setting, r), color in zip(runs.items(), ("tab:blue", "tab:orange")):
            col = r["names"].index(name)
            ax.plot(r["samples"], r["estimates"][:, col], color=color, lw=1.2, label=f"{setting} setting")
        ax.axhline(PAPER_TRUTH[name], color="k", ls="--", lw=1, label="truth")
        ax.set_title(name)
        ax.set_xscale("log")
        ax.grid(True, alpha=0.3)
        lo, hi = PAPER_TRUTH[name] - 0.6, PAPER_TRUTH[name] + 0.6
        ax.set_ylim(lo, hi)
    for ax in axes[-1]:
        ax.set_xlabel("samples k")
    axes[0, 0].legend(loc="lower right", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def study(seeds, ns=(1000, 3000, 10000)):
    print(f"\nLargest relative error over a1, a2, b0, m2, c1, c2 at SNR 43, {seeds} seeds (min / median / max):")
    print("  setting        " + "".join(f"{'N = ' + str(n):>26}" for n in ns))
    out = {}
    for setting in SETTINGS:
        errs = np.empty((seeds, len(ns)))
        for s in range(seeds):
            u = paper_input(max(ns), s)
            r = run_pair(str(PLANT), str(ESTIMATOR), u,
                         plant_start={"noise_std": noise_std(u), "noise_seed": 1000 + s},
                         estimator_start=SETTINGS[setting], checkpoints=list(ns))
            errs[s] = [max_rel_error(row) for row in r["estimates"]]
        out[setting] = errs
        print(f"  {setting:<14} " + "".join(
            f"{errs[:, j].min():>8.1e} /{np.median(errs[:, j]):>8.1e} /{errs[:, j].max():>8.1e}"
            for j in range(len(ns))))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "out"), help="folder for the plots (default: out/)")
    ap.add_argument("--seeds", type=int, default=20, help="seeds of the SNR 43 study (default 20)")
    args = ap.parse_args()
    for f in (PLANT, ESTIMATOR):
        if not f.exists():
            sys.exit(f"{f} is missing: run `cargo build --release` first")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()

    free = {s: convergence_run(0, None, s) for s in SETTINGS}
    print_table("Paper 000 example, noise-free (input seed 0): estimates after N samples", free)
    plot(free, "MRGIA in co-simulation (BacklashPlant.fmu -> MrgiaEstimator.fmu), noise-free",
         out / "convergence_noise_free.png")

    noisy = {s: convergence_run(0, 43.0, s) for s in SETTINGS}
    print_table("Paper 000 example, SNR 43 (input and noise seed 0): estimates after N samples", noisy)
    plot(noisy, "MRGIA in co-simulation, SNR 43 (noise std = std(y)/43)", out / "convergence_snr43.png")

    if args.seeds > 0:
        study(args.seeds)
    print(f"\nplots: {out / 'convergence_noise_free.png'}, {out / 'convergence_snr43.png'}"
          f"  ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
