"""A fleet of records diagnosed on a Dask cluster: one task per record, one row per record.

    python -m backlash_fmu.fleet PATH... --out PREFIX [--scheduler ADDRESS] [--workers N]

PATH is a record (a CSV file as `backlash diagnose` reads it) or a folder, which stands for every `.csv` file
in it (sorted by name). Each record is diagnosed by the package's own `backlash diagnose FILE --json` in a
child process of a worker: the file is read by the program's reader (a malformed file is refused with its
name, line and column, as on the command line), and a record that fails, or a worker that dies, gives a row
with its `error` and does not stop the others. The cluster is a `LocalCluster` of `--workers` single-threaded
worker processes, or the running scheduler at `--scheduler` (its workers need backlash-fmu installed and the
records at the same paths). Each diagnosis runs on one thread (RAYON_NUM_THREADS=1), so a worker is a core.

Written: PREFIX.csv and PREFIX.parquet (Parquet through pyarrow), rows in the order of the paths, columns
COLUMNS. Every column but `seconds` (the record's wall time) is a function of the record alone: a run on any
cluster, with any number of workers, writes the same bytes as `run(paths)` without one (the serial run).

The function: `run(paths, client=None, task="diagnose")` returns the rows as dicts. A task is an entry of
TASKS (the command's arguments and the row made from its JSON); a `monitor` task, for the wear monitor, is
one more entry there.
"""
import argparse
import json
import os
import pathlib
import subprocess
import sys
import time

from . import _progress
from ._csv import cell

COLUMNS = ("file", "na", "nb", "delay", "effects", "before_rmse", "after_rmse", "linear_rmse", "fit_percent",
           "constant_rmse", "presence", "play", "play_se", "seconds", "error")
TYPES = {"file": "string", "na": "int64", "nb": "int64", "delay": "int64", "effects": "string",
         "before_rmse": "float64", "after_rmse": "float64", "linear_rmse": "float64", "fit_percent": "float64",
         "constant_rmse": "float64", "presence": "string", "play": "float64", "play_se": "float64",
         "seconds": "float64", "error": "string"}


def _diagnose_args(path):
    return ["diagnose", str(path), "--json"]


def _diagnose_row(answer):
    return {
        "na": answer["na"],
        "nb": answer["nb"],
        "delay": answer["delay"],
        "effects": "+".join(e["id"] for e in answer["effects"]),
        "before_rmse": answer["before"]["rmse"],
        "after_rmse": answer["after"]["rmse"],
        "linear_rmse": answer["linear"]["rmse"],
        "fit_percent": answer["fit_percent"],
        "constant_rmse": answer["constant_rmse"],
        "presence": answer["backlash"]["presence"],
        "play": answer["backlash"]["play"],
        "play_se": answer["backlash"]["play_se"],
    }


# task -> (the command's arguments for one record, the row's columns from its JSON answer)
TASKS = {"diagnose": (_diagnose_args, _diagnose_row)}


def records(paths):
    """The record files of `paths`: files as given, folders as their .csv files sorted by name."""
    out = []
    for p in paths:
        p = pathlib.Path(p)
        if p.is_dir():
            out.extend(str(f) for f in sorted(p.glob("*.csv")) if f.is_file())
        else:
            out.append(str(p))
    return out


def _row(path, seconds, error="", values=None):
    row = dict.fromkeys(COLUMNS)
    row.update(values or {})
    row.update(file=path, seconds=seconds, error=error)
    return row


def _message(stderr, code):
    """The program's message: the last non-empty line of its standard error."""
    lines = [line for line in stderr.splitlines() if line.strip()]
    return lines[-1].strip() if lines else f"backlash exited with status {code} and no message"


def one(path, task="diagnose"):
    """The row of one record: never raises (a refused record has its message in `error`)."""
    args, make_row = TASKS[task]
    env = {**os.environ, "RAYON_NUM_THREADS": "1"}
    start = time.perf_counter()
    try:
        done = subprocess.run([sys.executable, "-m", "backlash_fmu._cli", *args(path)], capture_output=True,
                              text=True, env=env, check=False)
        seconds = time.perf_counter() - start
        if done.returncode != 0:
            return _row(path, seconds, _message(done.stderr, done.returncode))
        return _row(path, seconds, values=make_row(json.loads(done.stdout)))
    except Exception as e:  # a row, whatever happened: the other records go on
        return _row(path, time.perf_counter() - start, f"{type(e).__name__}: {e}")


def run(paths, client=None, task="diagnose", progress=None):
    """Rows of every record of `paths` (see `records`), in order: on the Dask `client`'s cluster, or here
    one after the other without one. progress: None (default), True (a bar on standard error) or a callable
    progress(done, total), records done of all."""
    progress = _progress(progress)
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}: one of {', '.join(TASKS)}")
    files = records(paths)
    rows = [None] * len(files)
    if client is None:
        for i, f in enumerate(files):
            rows[i] = one(f, task)
            if progress:
                progress(i + 1, len(files))
        return rows
    from distributed import as_completed

    futures = client.map(one, files, task=task, pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    for n, fut in enumerate(as_completed(futures), 1):
        i = index[fut.key]
        try:
            rows[i] = fut.result()
        except Exception as e:  # the worker died under the task, or the task could not be sent
            rows[i] = _row(files[i], float("nan"), f"{type(e).__name__}: {e}")
        if progress:
            progress(n, len(files))
    return rows


def to_csv(rows, columns=COLUMNS):
    """The rows as CSV text (floats in their shortest exact form, empty for missing values)."""
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(columns)
    for r in rows:
        w.writerow([cell(r[c]) for c in columns])
    return buf.getvalue()


def write(rows, prefix):
    """PREFIX.csv and PREFIX.parquet; returns their paths."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    prefix = pathlib.Path(prefix)
    prefix.parent.mkdir(parents=True, exist_ok=True)
    csv_path = prefix.with_name(prefix.name + ".csv")
    parquet_path = prefix.with_name(prefix.name + ".parquet")
    csv_path.write_text(to_csv(rows))
    schema = pa.schema([(c, getattr(pa, TYPES[c])()) for c in COLUMNS])
    pq.write_table(pa.Table.from_pylist([{c: r[c] for c in COLUMNS} for r in rows], schema=schema),
                   parquet_path)
    return csv_path, parquet_path


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m backlash_fmu.fleet",
                                 description="Diagnose every record of a fleet on a Dask cluster.")
    ap.add_argument("paths", nargs="+", metavar="PATH", help="record files, or folders (their .csv files)")
    ap.add_argument("--out", required=True, metavar="PREFIX", help="writes PREFIX.csv and PREFIX.parquet")
    ap.add_argument("--scheduler", metavar="ADDRESS", help="a running Dask scheduler (default: a LocalCluster)")
    ap.add_argument("--workers", type=int, default=os.cpu_count(), metavar="N",
                    help="LocalCluster worker processes (default: one per core)")
    ap.add_argument("--serial", action="store_true", help="run here one record after the other, without Dask")
    ap.add_argument("--quiet", action="store_true", help="no progress on standard error")
    a = ap.parse_args(argv)
    if a.workers < 1:
        ap.error(f"--workers {a.workers} must be at least 1")
    files = records(a.paths)
    if not files:
        ap.error("no record: the paths name no file and their folders hold no .csv file")
    start = time.perf_counter()
    if a.serial:
        rows = run(files, progress=not a.quiet)
    else:
        from distributed import Client, LocalCluster

        if a.scheduler:
            with Client(a.scheduler) as client:
                rows = run(files, client, progress=not a.quiet)
        else:
            with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster, Client(cluster) as client:
                rows = run(files, client, progress=not a.quiet)
    wall = time.perf_counter() - start
    csv_path, parquet_path = write(rows, a.out)
    refused = sum(1 for r in rows if r["error"])
    print(f"{len(rows)} records ({refused} refused) in {wall:.1f} s: {csv_path}, {parquet_path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
