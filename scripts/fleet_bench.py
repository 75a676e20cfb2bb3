#!/usr/bin/env python3
"""The fleet on simulated records with known effects: wall time with 1 and 2 Dask workers and the fraction
of the effects that the diagnosis names.

Records: BacklashPlant.fmu (stepped through FMPy's FMU2Slave) with paper 000's plant, the paper's input (white, uniform,
variance 1.93, Ts = 0.01 s), noise std 0.04, and one test-bench effect per record, cycling through `EFFECTS`
(magnitudes of tests/python/test_plant_effects.py, inside the ranges of the diagnose bench) and a clean
record; every record has its own input and noise seed. The structure is left to the diagnosis (so the
effects that are structure, extra-delay and linear-order, are not in the list). An effect counts as named
when the record's `effects` holds its id (a clean record: when `effects` is empty); "exactly" when nothing
else is named.

    .venv/bin/python scripts/fleet_bench.py --records 1000 --samples 20000 --out out/fleet   # the issue's size
    .venv/bin/python scripts/fleet_bench.py --records 40 --out out/fleet                       # what RESULTS quotes

The runs with 1 and 2 workers are made one after the other in one invocation, each on a fresh LocalCluster;
both tables must be equal but for `seconds` (checked, and reported).
"""
import argparse
import json
import os
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
TS = 0.01
EFFECTS = {
    "clean": {},
    "gap-drift": {},  # rates set per record length in make_records: the gaps grow by 60 % over the record
    "curved-borders": {"curve_up2": 0.1, "curve_up3": 0.04, "curve_down2": -0.12, "curve_down3": 0.05},
    "coloured-noise": {"noise_phi": 0.8, "noise_std": 0.1},
    "saturation": {"saturation": 1, "sat_lo": -1.2, "sat_hi": 1.6},
    "periodic-disturbance": {"dist_amplitude": 0.06, "dist_omega": 70.0, "dist_phase": 1.0},
    "quantization": {"quant_step": 0.3, "noise_std": 0.02},
    "friction": {"friction": 1, "k_e": 1.0, "f_plus": 0.9, "f_minus": 0.9},
    "direction-dependent": {"direction_dependent": 1, "a1_fall": 0.45 * 0.55, "a2_fall": 0.55 * 0.55 ** 2,
                            "b0_fall": 0.8 * (1 + 0.45 * 0.55 + 0.55 * 0.55 ** 2) / 2.0},
}


def make_records(folder, count, samples, plant_fmu):
    """Write `count` records into `folder` (the plant FMU stepped directly, one instance per record); returns
    {file: known effect}."""
    from backlash_fmu.study import _Instance, load_fmu

    fmu = load_fmu(plant_fmu)
    folder.mkdir(parents=True, exist_ok=True)
    names = list(EFFECTS)
    known = {}
    for i in range(count):
        effect = names[i % len(names)]
        path = folder / f"record_{i:05d}.csv"
        known[str(path)] = effect
        if path.exists():
            continue
        a = np.sqrt(3 * 1.93)
        u = np.random.default_rng(1000 + i).uniform(-a, a, samples)
        start = {"Ts": TS, "noise_std": 0.04, "noise_seed": 1 + i, **EFFECTS[effect]}
        if effect == "gap-drift":
            duration = samples * TS
            start.update(c1_rate=0.3 / duration, c2_rate=0.6 / duration)
        plant = _Instance(fmu, "plant", start)
        vr_u, vr_y = plant.vr("u"), plant.vr("y")
        y = np.empty(samples)
        for k in range(samples):
            # The output at t_k is sample k's; u(k) drives the step from t_k.
            y[k] = plant.fmu.getReal(vr_y)[0]
            plant.fmu.setReal(vr_u, [float(u[k])])
            plant.fmu.doStep(k * TS, TS)
        plant.free()
        t = np.arange(samples) * TS
        tmp = path.with_suffix(".tmp")
        np.savetxt(tmp, np.column_stack([t, u, y]), delimiter=",", header="time,u,y", comments="", fmt="%.17g")
        tmp.rename(path)
    return known


def named(rows, known):
    hit = exact = 0
    for r in rows:
        got = r["effects"].split("+") if r["effects"] else []
        want = known[r["file"]]
        if want == "clean":
            hit += not got
            exact += not got
        else:
            hit += want in got
            exact += got == [want]
    return hit / len(rows), exact / len(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--workers", default="1,2", help="worker counts, comma-separated, one run each")
    ap.add_argument("--out", default=str(ROOT / "out" / "fleet"))
    ap.add_argument("--plant-fmu", default=str(ROOT / "target" / "fmu" / "BacklashPlant.fmu"))
    a = ap.parse_args()
    from distributed import Client, LocalCluster

    from backlash_fmu import fleet

    load = os.getloadavg()
    out = pathlib.Path(a.out)
    folder = out / f"records_{a.samples}"
    t0 = time.perf_counter()
    known = make_records(folder, a.records, a.samples, a.plant_fmu)
    made = time.perf_counter() - t0
    files = sorted(known)
    runs = []
    tables = []
    for n in [int(x) for x in a.workers.split(",")]:
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            start = time.perf_counter()
            rows = fleet.run(files, client)
            wall = time.perf_counter() - start
        fleet.write(rows, out / f"fleet_{n}_workers")
        tables.append(fleet.to_csv(rows, [c for c in fleet.COLUMNS if c != "seconds"]))
        hit, exact = named(rows, known)
        runs.append({"workers": n, "wall_seconds": round(wall, 2),
                     "records_per_second": round(len(rows) / wall, 3),
                     "median_record_seconds": round(float(np.median([r["seconds"] for r in rows])), 3),
                     "refused": sum(1 for r in rows if r["error"]), "named": round(hit, 4),
                     "named_exactly": round(exact, 4)})
    print(json.dumps({"records": len(files), "samples": a.samples, "making_records_seconds": round(made, 1),
                      "cpu_count": os.cpu_count(), "load_average_before": load,
                      "identical_tables": all(t == tables[0] for t in tables), "runs": runs}, indent=1))


if __name__ == "__main__":
    sys.exit(main())
