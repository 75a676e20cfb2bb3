#!/usr/bin/env python3
"""`backlash identify mrgia` against a straightforward NumPy MRGIA (tests/python/mrgia_reference.py) on a
200,000-sample record of the paper 000 example (SNR 43), and against reading the same file with polars.

    .venv/bin/python scripts/mrgia_speed.py [--samples 200000] [--repeats 5] [--numpy-samples 20000]
    .venv/bin/python scripts/mrgia_speed.py --polars --repeats 15 [--other-cli OLD/backlash]

--polars (needs `pip install polars`): polars' read of the same file on one thread (POLARS_MAX_THREADS=1, set
before polars is imported, in a child process that times the read alone, without its own start), alternating
run by run with the CLI so that both see the same load; the ratio CLI / polars is what the reader is held to.
--other-cli: another build of `backlash` (e.g. before a change) timed the same way in the same run.

The CLI is timed end to end as a user runs it (process start, CSV parsing, the estimator, JSON output), median
of --repeats runs. The NumPy implementation (one Python iteration per sample on NumPy arrays) is timed on the
first --numpy-samples samples and extrapolated linearly to the whole record (its cost per sample is constant:
fixed-size arrays, no growth); pass --numpy-samples equal to --samples to time it on everything. Both run on
the same data in the same run; the ratio is what docs/RESULTS.md quotes. The two also agree on the subset's
estimate (printed), as tests/python/test_mrgia_reference.py checks to 1e-9.
"""
import argparse
import importlib.util
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from backlash_fmu import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _numpy_mrgia():
    """The NumPy MRGIA is a test oracle (tests/python/mrgia_reference.py), not part of the package: loaded
    from its file."""
    spec = importlib.util.spec_from_file_location("mrgia_reference", ROOT / "tests" / "python" / "mrgia_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.identify


identify = _numpy_mrgia()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--numpy-samples", type=int, default=20_000)
    ap.add_argument("--cli", default=os.environ.get("BACKLASH_CLI", str(ROOT / "target" / "release" / "backlash")))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--polars", action="store_true", help="also time polars' one-thread read of the file")
    ap.add_argument("--other-cli", help="also time this build of backlash, alternating with the first")
    args = ap.parse_args()
    cli = pathlib.Path(args.cli)
    if not cli.exists():
        sys.exit(f"{cli} is missing: run `cargo build --release` first (or set BACKLASH_CLI)")
    n, m = args.samples, min(args.numpy_samples, args.samples)

    rng = np.random.default_rng(args.seed)
    amp = np.sqrt(3 * 1.93)
    u = rng.uniform(-amp, amp, n)
    w = simulate(u)["w"]  # the plant of paper 000's example, noise-free
    y = w + rng.normal(0.0, np.std(w) / 43.0, n)

    with tempfile.TemporaryDirectory() as tmp:
        csv = pathlib.Path(tmp) / "paper_200k.csv"
        np.savetxt(csv, np.column_stack([np.arange(n, dtype=float), u, y]), delimiter=",",
                   header="time,u,y", comments="", fmt="%.17g")
        size_mb = csv.stat().st_size / 1e6
        cmd = [str(cli), "identify", "mrgia", str(csv), "--na", "2", "--nb", "0", "--delay", "1", "--json"]
        times, other_times, polars_times = [], [], []
        out = None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
            times.append(time.perf_counter() - t0)
            if args.other_cli:
                t0 = time.perf_counter()
                subprocess.run([args.other_cli, *cmd[1:]], check=True, capture_output=True, text=True)
                other_times.append(time.perf_counter() - t0)
            if args.polars:
                polars_times.append(_polars_read(csv))
        cli_t = statistics.median(times)
        got = json.loads(out)
        # The same CLI on the first m samples, to compare estimates with the NumPy run.
        sub = pathlib.Path(tmp) / "subset.csv"
        np.savetxt(sub, np.column_stack([np.arange(m, dtype=float), u[:m], y[:m]]), delimiter=",",
                   header="time,u,y", comments="", fmt="%.17g")
        got_sub = json.loads(subprocess.run(cmd[:3] + [str(sub)] + cmd[4:], check=True, capture_output=True,
                                            text=True).stdout)

    t0 = time.perf_counter()
    ref = identify(u[:m], y[:m], 2, 0, 1)
    np_t_sub = time.perf_counter() - t0
    np_t = np_t_sub * n / m
    est = ref.estimate()

    def row(e):
        return [*e["a"], *e["b"], e["m2"], e["c1"], e["c2"]]

    diff = np.max(np.abs(np.array(row(got_sub)) - np.array(row(est))) / np.abs(np.array(row(est))))
    print(f"record: {n} samples of the paper 000 example at SNR 43, CSV {size_mb:.1f} MB")
    print(f"CLI   `{' '.join(cmd[1:3])} ... --na 2 --nb 0 --delay 1 --json`: median {cli_t * 1e3:.1f} ms "
          f"over {args.repeats} runs (min {min(times) * 1e3:.1f}, max {max(times) * 1e3:.1f}); "
          f"{got['updates']} updates; {cli_t / n * 1e9:.0f} ns/sample end to end")
    extra = "" if m == n else f" (timed on the first {m} samples: {np_t_sub:.2f} s, extrapolated linearly)"
    print(f"NumPy {n} samples: {np_t:.2f} s{extra}; {np_t / n * 1e6:.1f} us/sample")
    print(f"estimates on the first {m} samples, CLI vs NumPy: max relative difference {diff:.1e}")
    print(f"ratio NumPy / CLI: {np_t / cli_t:.0f}x")
    load = os.getloadavg()
    if args.other_cli:
        o = statistics.median(other_times)
        print(f"other CLI {args.other_cli}: median {o * 1e3:.1f} ms (min {min(other_times) * 1e3:.1f}); "
              f"this one / other: {cli_t / o:.2f}")
    if args.polars:
        p = statistics.median(polars_times)
        print(f"polars read_csv, one thread: median {p * 1e3:.1f} ms (min {min(polars_times) * 1e3:.1f}); "
              f"CLI end to end / polars read: {cli_t / p:.2f}x"
              + (f"; other CLI / polars read: {statistics.median(other_times) / p:.2f}x" if args.other_cli else ""))
    print(f"load average (1, 5, 15 min) at the end: {load[0]:.1f}, {load[1]:.1f}, {load[2]:.1f} on {os.cpu_count()} cores")


_POLARS = """
import os, sys, time
os.environ["POLARS_MAX_THREADS"] = "1"
import polars as pl
t0 = time.perf_counter()
df = pl.read_csv(sys.argv[1])
t = time.perf_counter() - t0
assert df.height > 0
print(t)
"""


def _polars_read(csv):
    """Seconds polars takes to read `csv` on one thread (timed inside a fresh process)."""
    env = {**os.environ, "POLARS_MAX_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", _POLARS, str(csv)], check=True, capture_output=True, text=True,
                          env=env)
    return float(done.stdout)


if __name__ == "__main__":
    main()
