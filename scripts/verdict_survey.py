#!/usr/bin/env python3
"""The verdict on play of `backlash diagnose` on every measured record in place: a table, and a summary that sets
each verdict beside what the record's source says about play.

The records are those of data/*/README.md (scripts/data_records.py: data/, or BACKLASH_DATA): the default set,
the optional set (`extra`) and the survey set (`survey`). `python3 scripts/fetch_data.py` puts the default set
in place, `--extra` the optional set too, `--survey` the survey set (with `--from DIR` each is copied from a
folder of the same layout). A missing record of the default set is an error; a missing optional or survey
record is skipped with a line saying so.

    python3 scripts/verdict_survey.py                          # seed 0, fit fraction 0.7: docs/verdict_survey.csv
    python3 scripts/verdict_survey.py --seeds 0 1 2 --fractions 0.6 0.7 0.8 --out out/survey.csv
    python3 scripts/verdict_survey.py --binary PATH/backlash --records f16gvt/f16gvt_sinesweep_level7.csv
    python3 scripts/verdict_survey.py --summary-only docs/verdict_survey.csv   # the summary of a written table

Each record runs `BINARY diagnose FILE --json --time-col T --seed S --fit-fraction F` once per seed and fraction
(T is the record's time column, `t` or `time`, read from its header), two at a time (`--jobs`). The binary is
target/release/backlash of the repository (`cargo build --release`) unless --binary names another.

The CSV (`--out`) has one row per record, seed and fraction: set (default, extra, survey), record
(folder/file.csv), play_documented (yes, no or unknown: PLAY_DOCUMENTED below, taken from each folder's
README), seed, fit_fraction, and from the answer's `backlash` object presence (present, absent, undetermined;
`error` when diagnose failed), play, play_se, play_bound, the first entry of undecided_by (or diagnose's error),
and the wall time in seconds. The Markdown summary on stdout counts the verdicts per documented-play class,
lists the records whose verdict changes across seeds and fractions, and flags every `present` on a record
without documented play and every `absent` on one with documented play.
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures
import csv
import dataclasses
import json
import pathlib
import subprocess
import sys
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import data_records  # noqa: E402 - the sibling script, found through the line above

ROOT = data_records.ROOT
DEFAULT_BINARY = pathlib.Path("target") / "release" / "backlash"  # relative to ROOT
DEFAULT_OUT = pathlib.Path("docs") / "verdict_survey.csv"  # relative to ROOT
TIMEOUT = 1800.0  # seconds for one diagnose run (its own --time-budget is 300 s by default)
CLASSES = ("yes", "no", "unknown")
VERDICTS = ("present", "absent", "undetermined", "error")
FIELDS = ["set", "record", "play_documented", "seed", "fit_fraction", "presence", "play", "play_se", "play_bound",
          "undecided_by", "seconds"]

# Whether the record's source documents mechanical play, as its data/<folder>/README.md says: a folder's class,
# or a file's where the folder's records differ. The one place this is written in machine-readable form.
PLAY_DOCUMENTED = {
    "brfd": "yes",  # "a banded rotary friction damper whose linkage has real play"
    "brfd_survey": "yes",  # the same damper: "exhibits hysteretic and backlash effects"
    "servo": "yes",  # the gear play shows as a direction-dependent rest position
    "servo_survey": "yes",  # "their geartrains introduce mechanical backlash"
    "tanks": "no",  # water tanks, no mechanical transmission
    "dc_generator": "unknown",
    "emps": "unknown",
    "nonlinear_identification/silverbox_SNLS80mV.csv": "no",  # an electronic circuit
    "nonlinear_identification/daisy_ballbeam.csv": "unknown",
    "nonlinear_identification/daisy_exchanger.csv": "no",  # a thermal process
    "nonlinear_identification/daisy_flexible_robot_arm.csv": "unknown",
    "hair_dryer": "no",  # a thermal process
    "gas_furnace": "no",  # a chemical/thermal process
    "f16gvt/f16gvt_sinesweep_level1.csv": "no",  # "can be considered as a linear dataset"
    "f16gvt/f16gvt_fullmsine_level1.csv": "no",
    "f16gvt/f16gvt_sinesweep_level7.csv": "yes",  # the payload interface's clearance, excited at this level
    "dc_motor_keiel": "unknown",
    "hsm150": "unknown",
    "lpv_sysid/matlab_robotarm_wernholt_estimation.csv": "unknown",
    "lpv_sysid/matlab_mrdamper_estimation.csv": "no",  # hysteresis that is not play
    "lpv_sysid/wiener_hammerstein_2009_estimation_slice.csv": "no",  # an electronic circuit
    "kuka_kr300": "unknown",
}


@dataclasses.dataclass(frozen=True)
class Run:
    """One diagnose run: a record of a set at one seed and fit fraction."""

    set: str
    record: str
    seed: int
    fraction: float


def play_documented(record: str) -> str:
    """yes, no or unknown for "folder/file.csv" (PLAY_DOCUMENTED: the file's entry, else its folder's)."""
    return PLAY_DOCUMENTED.get(record, PLAY_DOCUMENTED.get(record.split("/")[0], "unknown"))


def records_in_place() -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """(set, record) of every record to measure, and of the optional and survey records that are not in place.
    MissingRecord for a missing record of the default set."""
    sets = [("default", data_records.manifest()), ("extra", data_records.manifest(extra=True)),
            ("survey", data_records.manifest(survey=True))]
    found, missing = [], []
    for name, records in sets:
        for record in sorted(records):
            if name != "default" and not (data_records.data_dir() / record).is_file():
                missing.append((name, record))
                continue
            data_records.record_path(record)  # MissingRecord, naming the fetch step, for the default set
            found.append((name, record))
    return found, missing


def time_column(path: pathlib.Path) -> str:
    """The record's time column: `t` or `time`, its header's first cell."""
    with open(path, newline="") as f:
        return next(csv.reader(f))[0].strip()


def number(value) -> str:
    return "" if value is None else f"{value:.6g}"


def diagnose(binary: pathlib.Path, run: Run) -> dict[str, str]:
    """One row of the table: diagnose's verdict on play for the run, and its wall time."""
    path = data_records.record_path(run.record)
    cmd = [str(binary), "diagnose", str(path), "--json", "--time-col", time_column(path), "--seed", str(run.seed),
           "--fit-fraction", str(run.fraction)]
    row = {"set": run.set, "record": run.record, "play_documented": play_documented(run.record),
           "seed": str(run.seed), "fit_fraction": f"{run.fraction:g}"}
    t0 = time.monotonic()
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT, check=False)
        answer = json.loads(done.stdout)["backlash"] if done.returncode == 0 else None
        why = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
    except subprocess.TimeoutExpired:
        answer, why = None, f"no answer within {TIMEOUT:.0f} s"
    except (json.JSONDecodeError, KeyError, TypeError) as e:
        answer, why = None, f"unreadable answer: {e}"
    seconds = f"{time.monotonic() - t0:.1f}"
    if answer is None:
        return {**row, "presence": "error", "play": "", "play_se": "", "play_bound": "", "undecided_by": why,
                "seconds": seconds}
    undecided = answer.get("undecided_by") or []
    return {**row, "presence": answer["presence"], "play": number(answer.get("play")),
            "play_se": number(answer.get("play_se")), "play_bound": number(answer.get("play_bound")),
            "undecided_by": undecided[0] if undecided else "", "seconds": seconds}


def run_all(binary: pathlib.Path, runs: list[Run], jobs: int) -> list[dict[str, str]]:
    """Every run, `jobs` at a time, each reported on stderr as it ends; the rows in the order of runs."""
    rows: dict[Run, dict[str, str]] = {}
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(diagnose, binary, run): run for run in runs}
        for i, future in enumerate(concurrent.futures.as_completed(futures), 1):
            run, row = futures[future], future.result()
            rows[run] = row
            print(f"[{i}/{len(runs)}] {run.record} seed {run.seed} fraction {run.fraction:g}: {row['presence']} "
                  f"({row['seconds']} s)", file=sys.stderr, flush=True)
    return [rows[run] for run in runs]


def write_table(path: pathlib.Path, rows: list[dict[str, str]]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def read_table(path: pathlib.Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def summary(rows: list[dict[str, str]]) -> str:
    """The Markdown summary: counts per documented-play class, verdicts that move, and the flagged verdicts."""
    runs = {(r["seed"], r["fit_fraction"]) for r in rows}
    records = {r["record"] for r in rows}
    lines = [f"## Verdict on play: {len(records)} records, {len(runs)} seed/fraction "
             f"combination{'s' if len(runs) != 1 else ''}, {len(rows)} runs", "",
             "| play documented | runs | " + " | ".join(VERDICTS) + " |", "| --- | --- |" + " --- |" * len(VERDICTS)]
    for cls in CLASSES:
        counts = collections.Counter(r["presence"] for r in rows if r["play_documented"] == cls)
        lines.append(f"| {cls} | {sum(counts.values())} | " + " | ".join(str(counts[v]) for v in VERDICTS) + " |")
    by_record: dict[str, list[dict[str, str]]] = collections.defaultdict(list)
    for r in rows:
        by_record[r["record"]].append(r)
    moving = {name: rs for name, rs in by_record.items() if len({r["presence"] for r in rs}) > 1}
    lines += ["", f"### Verdicts that change across seeds and fractions: {len(moving) or 'none'}"]
    if moving:
        lines += ["", "| record | play documented | verdicts (seed/fraction: presence) |", "| --- | --- | --- |"]
        for name in sorted(moving):
            rs = moving[name]
            each = ", ".join(f"{r['seed']}/{r['fit_fraction']}: {r['presence']}" for r in rs)
            lines.append(f"| {name} | {rs[0]['play_documented']} | {each} |")
    flagged = [r for r in rows if (r["presence"] == "present" and r["play_documented"] != "yes")
               or (r["presence"] == "absent" and r["play_documented"] == "yes")]
    lines += ["", f"### Flagged: `present` without documented play, `absent` with it: {len(flagged) or 'none'}"]
    if flagged:
        lines += ["", "| record | play documented | seed | fraction | presence | play | play_se | first undecided_by |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in flagged:
            lines.append(f"| {r['record']} | {r['play_documented']} | {r['seed']} | {r['fit_fraction']} | "
                         f"{r['presence']} | {r['play']} | {r['play_se']} | {r['undecided_by']} |")
    errors = [r for r in rows if r["presence"] == "error"]
    if errors:
        lines += ["", f"### Failed runs: {len(errors)}", ""]
        lines += [f"- {r['record']} seed {r['seed']} fraction {r['fit_fraction']}: {r['undecided_by']}" for r in errors]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", nargs="+", type=int, default=[0], metavar="S", help="seeds of diagnose (default: 0)")
    p.add_argument("--fractions", nargs="+", type=float, default=[0.7], metavar="F",
                   help="fit fractions of diagnose (default: 0.7)")
    p.add_argument("--binary", type=pathlib.Path, default=None,
                   help=f"the backlash binary (default: {DEFAULT_BINARY} of the repository)")
    p.add_argument("--out", type=pathlib.Path, default=None, help=f"the CSV written (default: {DEFAULT_OUT})")
    p.add_argument("--jobs", type=int, default=2, help="diagnose runs at a time (default: 2)")
    p.add_argument("--records", nargs="+", metavar="NAME", help="only these records (folder/file.csv)")
    p.add_argument("--summary-only", type=pathlib.Path, metavar="CSV",
                   help="run nothing: print the summary of a table written before")
    a = p.parse_args(argv)
    if a.summary_only:
        print(summary(read_table(a.summary_only)))
        return 0
    binary = a.binary or ROOT / DEFAULT_BINARY
    if not binary.is_file():
        p.error(f"no binary {binary}: run `cargo build --release` or pass --binary")
    try:
        found, missing = records_in_place()
    except data_records.MissingRecord as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    for name, record in missing:
        if not a.records or record in a.records:
            print(f"skipped {record} ({name} set): not in {data_records.shown(data_records.data_dir())} "
                  f"(`python3 scripts/fetch_data.py --{name}` puts it there)", file=sys.stderr)
    if a.records:
        unknown = set(a.records) - {record for _, record in found + missing}
        if unknown:
            p.error(f"unknown record {', '.join(sorted(unknown))}")
        found = [(s, record) for s, record in found if record in a.records]
    runs = [Run(s, record, seed, fraction) for s, record in found for seed in a.seeds for fraction in a.fractions]
    rows = run_all(binary, runs, a.jobs)
    out = a.out or ROOT / DEFAULT_OUT
    write_table(out, rows)
    print(f"wrote {data_records.shown(out)}: {len(rows)} rows", file=sys.stderr)
    print(summary(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
