#!/usr/bin/env python3
"""The worst-parameter error in Cramer-Rao units from a `backlash study --out DIR` run (study_runs.csv).

For every run (plant, SNR, seed) and N, each estimator's worst parameter error max_i |error_i| / crb_std_i;
pooled over the plants, per SNR: median, share of runs above 10 and above 100 CRB std, largest. Also the
95% interval coverage of the methods that report standard errors (refine, oe), per parameter pooled over the
plants, at the given N: smallest and largest over plants x SNRs x parameters.

    python scripts/study_crb_table.py out/grid/study_runs.csv [--coverage-n 3000]

Prints Markdown tables (the ones in docs/RESULTS.md). Standard library only.
"""
import argparse
import csv
import statistics
from collections import defaultdict

ESTIMATORS = ("mrgia-paper", "mrgia-recommended", "refine", "oe")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs_csv")
    ap.add_argument("--coverage-n", type=int, default=3000)
    args = ap.parse_args()
    crb = {}  # (plant, snr, seed, n, param) -> crb std
    err = defaultdict(dict)  # (method, plant, snr, seed, n) -> {param: (error, std_err)}
    with open(args.runs_csv, newline="") as f:
        for r in csv.DictReader(f):
            key = (r["plant"], r["snr"], r["seed"], int(r["n"]))
            if r["method"] == "crb":
                if r["std_err"]:
                    crb[key + (r["param"],)] = float(r["std_err"])
            elif r["method"] in ESTIMATORS and r["error"]:
                se = float(r["std_err"]) if r["std_err"] else None
                err[(r["method"],) + key][r["param"]] = (float(r["error"]), se)
    worst = defaultdict(list)  # (method, snr, n) -> [worst]
    cover = defaultdict(lambda: [0, 0])  # (method, plant, snr, param) -> [covered, runs] at coverage-n
    for (method, plant, snr, seed, n), params in err.items():
        units = [abs(e) / crb[(plant, snr, seed, n, p)] for p, (e, _) in params.items()
                 if (plant, snr, seed, n, p) in crb]
        if units:
            worst[(method, snr, n)].append(max(units))
        if n == args.coverage_n:
            for p, (e, se) in params.items():
                if se is not None:
                    c = cover[(method, plant, snr, p)]
                    c[0] += abs(e) <= 1.96 * se
                    c[1] += 1
    ns = sorted({k[2] for k in worst})
    for snr in sorted({k[1] for k in worst}, key=float):
        print(f"\nSNR {snr}: worst-parameter error in CRB std, median / share > 10 / share > 100 / max "
              f"(pooled over the plants; runs per cell in brackets)\n")
        print("| method | " + " | ".join(f"N = {n}" for n in ns) + " |")
        print("| --- |" + " --- |" * len(ns))
        for m in ESTIMATORS:
            cells = []
            for n in ns:
                v = worst.get((m, snr, n))
                if not v:
                    cells.append("-")
                    continue
                share = lambda t: 100.0 * sum(x > t for x in v) / len(v)
                cells.append(f"{statistics.median(v):.2f} / {share(10):.1f}% / {share(100):.1f}% / "
                             f"{max(v):.3g} ({len(v)})")
            print(f"| {m} | " + " | ".join(cells) + " |")
    print(f"\n95% interval coverage at N = {args.coverage_n} (per plant, SNR and parameter): smallest / largest\n")
    for m in ("refine", "oe"):
        fr = [c / r for (mm, *_), (c, r) in cover.items() if mm == m and r]
        if fr:
            pooled = sum(c for (mm, *_), (c, r) in cover.items() if mm == m) / sum(
                r for (mm, *_), (c, r) in cover.items() if mm == m)
            print(f"- {m}: {100 * min(fr):.1f}% / {100 * max(fr):.1f}% (all pooled: {100 * pooled:.1f}%)")


if __name__ == "__main__":
    main()
