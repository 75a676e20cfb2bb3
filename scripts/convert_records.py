#!/usr/bin/env python3
"""Convert the public measured records in data/ from their published form to `time,u,y` CSV files.

The sources are not part of this repository; each data/<name>/README.md names the repository, commit and
path the input came from and its licence. Give the files of those commits to this script to rebuild the CSVs
byte for byte:

    python scripts/convert_records.py servo SRC/logs/motor_telemetry_single.csv 5 data/servo/sts3215_hold.csv
    python scripts/convert_records.py servo SRC/logs/motor_telemetry_single_3250.csv 4 data/servo/sts3250_hold.csv
    python scripts/convert_records.py generator SRC/datasets/generator/x_cc.csv SRC/datasets/generator/y_cc.csv \
        data/dc_generator/dc_generator.csv
    python scripts/convert_records.py tanks SRC/dataBenchmark.csv Est data/tanks/tanks_est.csv
    python scripts/convert_records.py tanks SRC/dataBenchmark.csv Val data/tanks/tanks_val.csv

Only the standard library is used.
"""

import argparse
import csv
from datetime import datetime

# Block length of the generator record's mean decimation (the source's input holds each level for a multiple
# of 500 samples, starting at sample 500, so blocks of 50 never straddle an input switch).
GENERATOR_BLOCK = 50


def seconds_since(stamp: str, start: datetime) -> float:
    """ISO 8601 time stamp with a trailing Z, as seconds after `start`."""
    t = datetime.fromisoformat(stamp.replace("Z", "+00:00"))
    return (t - start).total_seconds()


def convert_servo(source: str, motor: int, out: str) -> int:
    """One servo's commanded and measured position from a telemetry log; rows lacking either are dropped."""
    target, position = f"target pos ({motor})", f"pos ({motor})"
    with open(source, newline="") as f:
        reader = csv.DictReader(f)
        if target not in reader.fieldnames or position not in reader.fieldnames:
            raise SystemExit(f"{source}: no columns '{target}' and '{position}' for motor {motor}")
        rows = [r for r in reader if r[target].strip() and r[position].strip()]
    if not rows:
        raise SystemExit(f"{source}: motor {motor} has no row with both positions")
    start = datetime.fromisoformat(rows[0]["timestamp"].replace("Z", "+00:00"))
    with open(out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["time", "u", "y"])
        for r in rows:
            t = seconds_since(r["timestamp"], start)
            w.writerow([f"{t:.3f}", int(r[target]), int(r[position])])
    return len(rows)


def read_column(path: str) -> list[float]:
    with open(path) as f:
        return [float(line) for line in f if line.strip()]


def convert_generator(x_path: str, y_path: str, out: str) -> int:
    """Input and output columns joined, block means of GENERATOR_BLOCK samples (a partial last block dropped);
    time is the source's sample index at the block's centre (the source gives no sample period)."""
    u, y = read_column(x_path), read_column(y_path)
    if len(u) != len(y):
        raise SystemExit(f"{x_path} has {len(u)} values but {y_path} has {len(y)}")
    n = len(u) // GENERATOR_BLOCK
    with open(out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["time", "u", "y"])
        for k in range(n):
            lo, hi = k * GENERATOR_BLOCK, (k + 1) * GENERATOR_BLOCK
            centre = (lo + hi - 1) / 2
            w.writerow(
                [
                    f"{centre:.1f}",
                    f"{sum(u[lo:hi]) / GENERATOR_BLOCK:.6g}",
                    f"{sum(y[lo:hi]) / GENERATOR_BLOCK:.6g}",
                ]
            )
    return n


def convert_tanks(source: str, part: str, out: str) -> int:
    """One part (`Est` or `Val`) of the cascaded-tanks benchmark's table (columns uEst, uVal, yEst, yVal, Ts;
    the sample time in the first row's Ts): time from 0 in seconds, the pump's input and the lower tank's level,
    as the file spells the numbers."""
    with open(source, newline="") as f:
        rows = list(csv.DictReader(f))
    ts = float(rows[0]["Ts"])
    with open(out, "w", newline="") as f:
        f.write("time,u,y\n")
        for k, r in enumerate(rows):
            f.write(f"{k * ts:g},{r['u' + part]},{r['y' + part]}\n")
    return len(rows)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="record", required=True)
    s = sub.add_parser("servo", help="a servo telemetry log (commanded -> measured position of one motor)")
    s.add_argument("source")
    s.add_argument("motor", type=int, help="the motor's number in the log's column names")
    s.add_argument("out")
    g = sub.add_parser("generator", help="the DC motor/generator record (x_cc.csv, y_cc.csv)")
    g.add_argument("x")
    g.add_argument("y")
    g.add_argument("out")
    t = sub.add_parser("tanks", help="a part of the cascaded-tanks benchmark (dataBenchmark.csv)")
    t.add_argument("source")
    t.add_argument("part", choices=["Est", "Val"])
    t.add_argument("out")
    a = p.parse_args()
    if a.record == "servo":
        n = convert_servo(a.source, a.motor, a.out)
    elif a.record == "tanks":
        n = convert_tanks(a.source, a.part, a.out)
    else:
        n = convert_generator(a.x, a.y, a.out)
    print(f"{a.out}: {n} rows")


if __name__ == "__main__":
    main()
