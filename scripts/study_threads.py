#!/usr/bin/env python3
"""Speedup of `backlash study` on T threads against 1 thread, measured in the same run.

Runs the same grid with --threads 1 and --threads T alternately (REPEAT times each, so that a change in the
machine's load hits both), takes each one's median wall time from the command's own --json "seconds", and
checks that the tables are identical. Also reports the CPU time the process got per wall second (on a shared
machine a second thread only helps if a second core is free) and the load average. Prints one JSON object.

Usage: scripts/study_threads.py [--cli target/release/backlash] [--threads 2] [--repeat 3] [study args...]
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli", default=str(ROOT / "target" / "release" / "backlash"))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    a, study = ap.parse_known_args()
    study = study or ["--seeds", "200", "--ns", "300,1000,3000"]
    times = {1: [], a.threads: []}
    cpu = {1: [], a.threads: []}
    tables = {}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(a.repeat):
            for t in times:
                out = pathlib.Path(tmp) / f"t{t}"
                before = os.times()
                p = subprocess.run([a.cli, "study", *study, "--threads", str(t), "--json", "--out", str(out)],
                                   capture_output=True, text=True)
                if p.returncode != 0:
                    sys.exit(p.stderr)
                after = os.times()
                times[t].append(json.loads(p.stdout)["seconds"])
                cpu[t].append(after.children_user + after.children_system - before.children_user
                              - before.children_system)
                tables[t] = (out / "study_runs.csv").read_text()
    med = {t: statistics.median(v) for t, v in times.items()}
    print(json.dumps({
        "study": study,
        "seconds": times,
        "median_seconds": med,
        "speedup": med[1] / med[a.threads],
        # CPU seconds of the whole process (incl. writing the files) per wall second of the study: how many
        # cores the threads actually got on a shared machine.
        "cores_used": {t: statistics.median(c) / m for (t, c), m in zip(cpu.items(), med.values())},
        "load_average": os.getloadavg(),
        "threads": a.threads,
        "identical_tables": tables[1] == tables[a.threads],
    }))


if __name__ == "__main__":
    main()
