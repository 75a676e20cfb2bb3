"""Monte Carlo studies of co-simulations: BacklashPlant.fmu driving MrgiaEstimator.fmu, run through fmpy, one
task per (plant, SNR, seed) cell, on a dask.distributed cluster (a LocalCluster by default, or a scheduler
address) or serially in this process.

One cell: the input is `cosim.paper_input(max N, seed)` (NumPy's generator: the Rust `backlash study` uses
ChaCha8, so the two studies share the design, not the numbers). A noise-free pass of the plant FMU gives w
and the noise std `std(w) / snr`; then one co-simulation of the plant (noise_std, noise_seed = seed +
0x5EED_0000_0000) and two MrgiaEstimator instances (the paper setting and `recommended`) fed the same u and y
(wiring as in cosim.run_pair), read after each N samples. The result is one tidy row per (plant, SNR, N, seed,
method, parameter), with the same columns as `backlash study`'s study_runs.csv (std_err empty: MRGIA reports
none).

The FMUs travel as bytes: scattered once to every worker (client.scatter(..., broadcast=True)), extracted
once per worker process and cached by their SHA-256, so workers need no shared file system. The tasks are
this module's functions, pickled by reference: every worker needs backlash-fmu installed with its `study`
extra (`pip install "backlash-fmu[study]"`), as a LocalCluster's workers have. Each process instantiates its
FMUs with one process-wide set of FMI callbacks that lives as long as the process
(`cosim.process_callbacks`).

Usage: `python -m backlash_fmu.study --help`.
"""
import atexit
import hashlib
import math
import os
import shutil
import sys
import tempfile
import time
import zipfile

import numpy as np

from ._csv import cell as _fmt
from .cosim import paper_input, process_callbacks

NOISE_SEED_OFFSET = 1_000_000  # the plant FMU's noise_seed is an FMI Integer (int32)
METHODS = ("mrgia-paper", "mrgia-recommended")
HEADER = "plant,snr,n,seed,noise_std,method,param,truth,estimate,error,std_err"

_PAPER = {"na": 2, "nb": 0, "delay": 1, "a1": 0.45, "a2": 0.55, "b0": 0.8, "b1": 0.0,
          "m1": 1.0, "m2": 1.5, "c1": 0.5, "c2": 1.0}
# The plant variants of `backlash study --list-plants` (src/identify/oe/study.rs, PLANT_VARIANTS).
PLANTS = {
    "paper": dict(_PAPER),
    "wide-gaps": {**_PAPER, "c1": 1.0, "c2": 2.0},
    "symmetric": {**_PAPER, "m2": 1.0},
    "reversed-slopes": {**_PAPER, "m2": 0.75},
    "second-order-b": {**_PAPER, "nb": 1, "b1": 0.4},
}


def param_names(plant):
    """The estimated parameters in `backlash study`'s order: a1..a_na, b0..b_nb, m2, c1, c2 (m1 = 1)."""
    p = PLANTS[plant]
    return ([f"a{i}" for i in range(1, p["na"] + 1)] + [f"b{j}" for j in range(p["nb"] + 1)]
            + ["m2", "c1", "c2"])


# --- per-process FMU cache ------------------------------------------------------------------------------------

_UNZIPPED = {}  # sha256 -> (unzip dir, model description, variables by name)


def _unzipped(fmu):
    """(digest, bytes) -> the extracted FMU, once per process."""
    digest, data = fmu
    if digest not in _UNZIPPED:
        import io

        from fmpy import read_model_description

        d = tempfile.mkdtemp(prefix="backlash-fmu-")
        atexit.register(shutil.rmtree, d, True)
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            z.extractall(d)
        md = read_model_description(d)
        _UNZIPPED[digest] = (d, md, {v.name: v for v in md.modelVariables})
    return _UNZIPPED[digest]


def load_fmu(path):
    """(SHA-256, bytes) of an FMU file: what the tasks receive."""
    data = open(path, "rb").read()
    return hashlib.sha256(data).hexdigest(), data


class _Instance:
    def __init__(self, fmu, name, start):
        from fmpy.fmi2 import FMU2Slave

        d, md, self.vars = _unzipped(fmu)
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate(callbacks=process_callbacks())
        self.fmu.setupExperiment(startTime=0.0)
        for key, value in {"Ts": 1.0, **start}.items():
            v = self.vars[key]
            if v.type == "Real":
                self.fmu.setReal([v.valueReference], [float(value)])
            elif v.type == "Integer":
                self.fmu.setInteger([v.valueReference], [int(value)])
            else:
                self.fmu.setBoolean([v.valueReference], [bool(value)])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def vr(self, *names):
        return [self.vars[n].valueReference for n in names]

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def _plant_start(plant, noise_std, noise_seed):
    p = PLANTS[plant]
    start = {k: p[k] for k in ("na", "nb", "delay", "a1", "a2", "b0", "b1", "m1", "m2", "c1", "c2")}
    return {**start, "noise_std": noise_std, "noise_seed": noise_seed}


def run_cell(plant_fmu, estimator_fmu, plant, snr, seed, ns):
    """One run: the tidy rows (tuples in HEADER's order) of both MRGIA settings at every N of `ns`."""
    p = PLANTS[plant]
    ns = sorted(set(int(n) for n in ns))
    u = paper_input(ns[-1], seed)
    # Noise-free pass: w, hence the noise std.
    clean = _Instance(plant_fmu, "plant-clean", _plant_start(plant, 0.0, 0))
    try:
        vy, vu = clean.vr("y"), clean.vr("u")
        w = np.empty(len(u))
        for k, uk in enumerate(u):
            w[k] = clean.fmu.getReal(vy)[0]
            clean.fmu.setReal(vu, [float(uk)])
            clean.fmu.doStep(float(k), 1.0)
    finally:
        clean.free()
    noise_std = float(np.std(w)) / snr
    names = param_names(plant)
    instances = []
    try:
        plant_i = _Instance(plant_fmu, "plant",
                            _plant_start(plant, noise_std, seed + NOISE_SEED_OFFSET))
        instances.append(plant_i)
        ests = []
        for method in METHODS:
            e = _Instance(estimator_fmu, method, {"na": p["na"], "nb": p["nb"], "delay": p["delay"],
                                                   "recommended": method == "mrgia-recommended"})
            instances.append(e)
            ests.append(e)
        pf = plant_i.fmu
        vy, vu = plant_i.vr("y"), plant_i.vr("u")
        vin = ests[0].vr("u", "y")
        vout = ests[0].vr(*names)
        read = set(ns)
        rows = []
        for k, uk in enumerate(u):
            yk = pf.getReal(vy)[0]
            uk = float(uk)
            pf.setReal(vu, [uk])
            for e in ests:
                e.fmu.setReal(vin, [uk, yk])
            pf.doStep(float(k), 1.0)
            for e in ests:
                e.fmu.doStep(float(k), 1.0)
            if k + 1 in read:
                for method, e in zip(METHODS, ests):
                    for name, est in zip(names, e.fmu.getReal(vout)):
                        truth = p[name]
                        rows.append((plant, float(snr), k + 1, seed, noise_std, method, name, truth, est,
                                     est - truth, None))
        return rows
    finally:
        for i in reversed(instances):
            i.free()


def cells(seeds, ns, snrs, plants, first_seed=0):
    return [(plant, float(snr), seed) for plant in plants for snr in snrs
            for seed in range(first_seed, first_seed + seeds)]


def _sort_key(row, order):
    plant, snr, n, seed, _, method, name = row[:7]
    return order[(plant, snr)], seed, n, METHODS.index(method), param_names(plant).index(name)


def tidy(rows, grid):
    """Rows in (plant, SNR, seed, N, method, parameter) order, whatever order the cells finished in."""
    order = {(p, r): i for i, (p, r) in enumerate((p, r) for p in grid["plants"] for r in grid["snrs"])}
    return sorted(rows, key=lambda row: _sort_key(row, order))


def to_csv(rows):
    return HEADER + "\n" + "".join(",".join(_fmt(v) for v in row) + "\n" for row in rows)


class _Progress:
    """A one-line text progress bar on stderr."""

    def __init__(self, total, quiet):
        self.total, self.done, self.quiet, self.t0 = total, 0, quiet, time.perf_counter()

    def tick(self):
        self.done += 1
        if self.quiet:
            return
        width = 40
        full = self.done * width // max(self.total, 1)
        el = time.perf_counter() - self.t0
        eta = el / self.done * (self.total - self.done)
        sys.stderr.write(f"\r{'#' * full}{'-' * (width - full)} {self.done}/{self.total} runs (eta {eta:.0f} s)")
        if self.done == self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def run_study(plant_fmu, estimator_fmu, seeds, ns, snrs=(43.0,), plants=("paper",), first_seed=0, client=None,
              quiet=False):
    """Run the grid; with `client` (a dask.distributed Client) one task per cell, else serially here.

    Returns (rows sorted as `tidy`, seconds)."""
    unknown = [p for p in plants if p not in PLANTS]
    if unknown:
        raise ValueError(f"unknown plant variant(s) {unknown}; known: {', '.join(PLANTS)}")
    if first_seed < 0 or first_seed + seeds + NOISE_SEED_OFFSET >= 2**31:
        raise ValueError(f"seeds must lie in 0..{2**31 - 1 - NOISE_SEED_OFFSET} (the FMU's noise seed is an int32)")
    if seeds < 1 or not ns or min(ns) < 1 or not snrs or not all(math.isfinite(r) and r > 0 for r in snrs):
        raise ValueError("need seeds >= 1, every N >= 1 and every SNR a finite number > 0")
    grid = {"plants": list(plants), "snrs": [float(r) for r in snrs]}
    todo = cells(seeds, ns, snrs, plants, first_seed)
    pf, ef = load_fmu(plant_fmu), load_fmu(estimator_fmu)
    bar = _Progress(len(todo), quiet)
    rows = []
    t0 = time.perf_counter()
    if client is None:
        for plant, snr, seed in todo:
            rows.extend(run_cell(pf, ef, plant, snr, seed, ns))
            bar.tick()
    else:
        from distributed import as_completed

        # run_cell is pickled by reference: the workers import backlash_fmu.study (installed with the package).
        pf_f, ef_f = client.scatter([pf, ef], broadcast=True)
        futures = [client.submit(run_cell, pf_f, ef_f, plant, snr, seed, list(ns), pure=False)
                   for plant, snr, seed in todo]
        for fut in as_completed(futures):
            rows.extend(fut.result())
            bar.tick()
            fut.release()
    return tidy(rows, grid), time.perf_counter() - t0


def summary(rows):
    """RMSE and bias per (plant, snr, method, n, param) over the seeds: {key: (rmse, bias, runs)}."""
    acc = {}
    for plant, snr, n, _seed, _ns, method, name, _t, _e, err, _se in rows:
        acc.setdefault((plant, snr, method, n, name), []).append(err)
    return {k: (math.sqrt(sum(e * e for e in v) / len(v)), sum(v) / len(v), len(v)) for k, v in acc.items()}


def plot(rows, path, title):
    """RMSE against N per parameter (log-log), one line per method and (plant, SNR)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = summary(rows)
    groups = sorted({(k[0], k[1]) for k in s}, key=lambda g: (list(PLANTS).index(g[0]), g[1]))
    names = []
    for plant, _ in groups:
        names += [n for n in param_names(plant) if n not in names]
    cols = 3
    rws = -(-len(names) // cols)
    fig, axes = plt.subplots(rws, cols, figsize=(5 * cols, 3.6 * rws), squeeze=False)
    styles = {"mrgia-paper": "-", "mrgia-recommended": "--"}
    for ax, name in zip(axes.flat, names):
        for gi, (plant, snr) in enumerate(groups):
            for method in METHODS:
                pts = sorted((k[3], v[0]) for k, v in s.items()
                             if k[0] == plant and k[1] == snr and k[2] == method and k[4] == name)
                if pts:
                    ax.plot(*zip(*pts), styles[method], marker="o", ms=3, color=f"C{gi}",
                            label=f"{plant}, SNR {snr:g}, {method}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name)
        ax.set_xlabel("samples N")
        ax.set_ylabel("RMSE")
        ax.grid(True, which="both", alpha=0.3)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    axes[0][0].legend(fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None):
    import argparse
    import json
    import pathlib

    from . import fmu_path

    env_dir = os.environ.get("BACKLASH_FMU_DIR")

    def default_fmu(name):
        return str(pathlib.Path(env_dir) / f"{name}.fmu") if env_dir else fmu_path(name)

    ap = argparse.ArgumentParser(description="Co-simulation Monte Carlo study of the MRGIA FMUs with Dask.")
    ap.add_argument("--seeds", type=int, default=10, help="runs per (plant, SNR) (default 10)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--ns", default="300,1000,3000", help="record lengths, comma-separated")
    ap.add_argument("--snrs", default="43", help="signal-to-noise ratios std(w)/noise std, comma-separated")
    ap.add_argument("--plants", default="paper", help=f"plant variants, comma-separated: {', '.join(PLANTS)}")
    ap.add_argument("--scheduler", help="address of a running dask scheduler (default: start a LocalCluster)")
    ap.add_argument("--workers", type=int, default=os.cpu_count(), help="LocalCluster worker processes")
    ap.add_argument("--serial", action="store_true", help="run in this process, without Dask")
    ap.add_argument("--plant-fmu", default=default_fmu("BacklashPlant"),
                    help="default: the package's (or $BACKLASH_FMU_DIR/BacklashPlant.fmu)")
    ap.add_argument("--estimator-fmu", default=default_fmu("MrgiaEstimator"),
                    help="default: the package's (or $BACKLASH_FMU_DIR/MrgiaEstimator.fmu)")
    ap.add_argument("--out", help="folder for cosim_study.csv (tidy rows) and cosim_study.png (RMSE against N)")
    ap.add_argument("--json", action="store_true", help="print a JSON summary on stdout, no progress bar")
    ap.add_argument("--compare-serial", type=int, default=0, metavar="R",
                    help="also run the grid serially in this process, alternating R times with the distributed "
                         "run, report both throughputs and check that the tables are identical")
    a = ap.parse_args(argv)
    for f in (a.plant_fmu, a.estimator_fmu):
        if not os.path.exists(f):
            ap.error(f"{f} is missing: pass the path of an FMU")
    ns = [int(x) for x in a.ns.split(",")]
    snrs = [float(x) for x in a.snrs.split(",")]
    plants = a.plants.split(",")
    client = cluster = None
    mode = "serial"
    try:
        if not a.serial:
            from distributed import Client, LocalCluster

            if a.scheduler:
                client, mode = Client(a.scheduler), f"scheduler {a.scheduler}"
            else:
                cluster = LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
                client, mode = Client(cluster), f"LocalCluster, {a.workers} worker processes"
        args = (a.plant_fmu, a.estimator_fmu, a.seeds, ns, snrs, plants, a.first_seed)
        rows, seconds = run_study(*args, client=client, quiet=a.json)
        compare = None
        if a.compare_serial and client is not None:
            dist, ser, same = [seconds], [], True
            for i in range(a.compare_serial):
                r_s, t_s = run_study(*args, quiet=True)
                ser.append(t_s)
                same &= to_csv(r_s) == to_csv(rows)
                if i + 1 < a.compare_serial:
                    r_d, t_d = run_study(*args, client=client, quiet=True)
                    dist.append(t_d)
                    same &= to_csv(r_d) == to_csv(rows)
            import statistics

            compare = {"distributed_seconds": dist, "serial_seconds": ser,
                       "speedup": statistics.median(ser) / statistics.median(dist), "identical_tables": same}
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    runs = a.seeds * len(snrs) * len(plants)
    files = []
    if a.out:
        out = pathlib.Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "cosim_study.csv").write_text(to_csv(rows))
        plot(rows, out / "cosim_study.png",
             f"MRGIA in co-simulation (fmpy, {mode}): RMSE over {a.seeds} runs against N")
        files = [str(out / "cosim_study.csv"), str(out / "cosim_study.png")]
    report = {"runs": runs, "mode": mode, "seconds": seconds, "runs_per_second": runs / seconds,
              "samples_per_second": runs * max(ns) / seconds, "files": files}
    if compare:
        report["compare_serial"] = compare
    if a.json:
        print(json.dumps(report))
    else:
        print(f"{runs} co-simulations ({mode}) in {seconds:.1f} s: {runs / seconds:.2f} runs/s, "
              f"{runs * max(ns) / seconds:.0f} samples/s")
        s = summary(rows)
        for plant in plants:
            for snr in snrs:
                for method in METHODS:
                    for n in sorted(set(ns)):
                        vals = [s[(plant, snr, method, n, p)][0] for p in param_names(plant)]
                        print(f"  {plant:<16} SNR {snr:<5g} {method:<18} N = {n:<6} RMSE "
                              + " ".join(f"{p}={v:.2e}" for p, v in zip(param_names(plant), vals)))
        if compare:
            print(f"serial in this process: {compare['serial_seconds']} s; distributed: "
                  f"{compare['distributed_seconds']} s; speedup {compare['speedup']:.2f}; "
                  f"tables {'identical' if compare['identical_tables'] else 'DIFFERENT'}")
        for f in files:
            print(f"wrote {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
