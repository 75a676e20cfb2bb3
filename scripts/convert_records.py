#!/usr/bin/env python3
"""Convert the public measured records in data/ from their published form to `time,u,y` CSV files.

The sources are not part of this repository; each data/<name>/README.md names the repository, commit and
path the input came from and its licence. `python3 scripts/fetch_data.py` downloads them and calls this
script's functions; by hand, give the files of those commits to this script to rebuild the CSVs byte for byte:

    python scripts/convert_records.py brfd "SRC/data/dataset-2/earthquake profiles/KocaeliDBE.json" \
        data/brfd/KocaeliDBE_36lb.csv
    python scripts/convert_records.py emps SRC/examples/EMPS/data/DATA_EMPS.mat data/emps/emps.csv
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
import json
import struct
import zlib
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


def convert_brfd(source: str, out: str) -> int:
    """A friction-damper test (dataset-2's JSON: "data" rows of time, displacement, friction force, ...): the
    first three columns as t,u,y with 10 significant digits."""
    with open(source) as f:
        rows = json.load(f)["data"]
    with open(out, "w", newline="") as f:
        f.write("t,u,y\n")
        for r in rows:
            f.write(f"{r[0]:.10g},{r[1]:.10g},{r[2]:.10g}\n")
    return len(rows)


# MATLAB level-5 MAT-file element types (the MAT-File Format document): numeric types by code, with the
# struct format of one value; 14 is a matrix, 15 a zlib-compressed element.
MAT_NUMERIC = {1: "b", 2: "B", 3: "h", 4: "H", 5: "i", 6: "I", 7: "f", 9: "d", 12: "q", 13: "Q"}
MAT_MATRIX, MAT_COMPRESSED = 14, 15


def mat_elements(buf: bytes, pos: int = 0):
    """(type, payload) of each data element in buf from pos, little-endian; a small element (its size in the
    tag's upper half) carries its payload in the tag's second word."""
    while pos + 8 <= len(buf):
        kind, size = struct.unpack_from("<II", buf, pos)
        if kind >> 16:
            kind, size = kind & 0xFFFF, kind >> 16
            yield kind, buf[pos + 4 : pos + 4 + size]
            pos += 8
            continue
        yield kind, buf[pos + 8 : pos + 8 + size]
        # A compressed element is not padded; every other one ends on a multiple of 8 bytes.
        pos += 8 + (size if kind == MAT_COMPRESSED else (size + 7) // 8 * 8)


def read_mat_vectors(path: str) -> dict[str, list[float]]:
    """Every real numeric array of a MATLAB level-5 MAT-file (not v7.3) by its name, its values in column
    order. Only the standard library: no scipy."""
    with open(path, "rb") as f:
        buf = f.read()
    if buf[126:128] != b"IM":
        raise SystemExit(f"{path}: not a little-endian MATLAB 5 MAT-file (v7.3 files are HDF5, not read here)")
    arrays = {}
    for kind, payload in mat_elements(buf, 128):
        if kind == MAT_COMPRESSED:
            kind, payload = next(mat_elements(zlib.decompress(payload)))
        if kind != MAT_MATRIX:
            continue
        parts = list(mat_elements(payload))
        if len(parts) < 4 or parts[3][0] not in MAT_NUMERIC:
            continue  # a cell, struct, sparse, character or empty array: not a vector of numbers
        name = parts[2][1].decode("ascii")
        code, data = parts[3]
        fmt = MAT_NUMERIC[code]
        arrays[name] = [float(v) for v in struct.unpack(f"<{len(data) // struct.calcsize(fmt)}{fmt}", data)]
    return arrays


def convert_emps(source: str, out: str) -> int:
    """The EMPS benchmark's estimation record (DATA_EMPS.mat): t, u = vir (the controller's force command),
    y = qm (the measured motor position), 10 significant digits; the reference qg is dropped."""
    arrays = read_mat_vectors(source)
    missing = [k for k in ("t", "vir", "qm") if k not in arrays]
    if missing:
        raise SystemExit(f"{source}: no array {', '.join(missing)}")
    t, u, y = arrays["t"], arrays["vir"], arrays["qm"]
    if not len(t) == len(u) == len(y):
        raise SystemExit(f"{source}: t, vir and qm have {len(t)}, {len(u)} and {len(y)} values")
    with open(out, "w", newline="") as f:
        f.write("t,u,y\n")
        for row in zip(t, u, y):
            f.write("{:.10g},{:.10g},{:.10g}\n".format(*row))
    return len(t)


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
    b = sub.add_parser("brfd", help="a friction-damper test of dataset-2 (its JSON file)")
    b.add_argument("source")
    b.add_argument("out")
    e = sub.add_parser("emps", help="the EMPS estimation record (DATA_EMPS.mat)")
    e.add_argument("source")
    e.add_argument("out")
    a = p.parse_args()
    if a.record == "brfd":
        n = convert_brfd(a.source, a.out)
    elif a.record == "emps":
        n = convert_emps(a.source, a.out)
    elif a.record == "servo":
        n = convert_servo(a.source, a.motor, a.out)
    elif a.record == "tanks":
        n = convert_tanks(a.source, a.part, a.out)
    else:
        n = convert_generator(a.x, a.y, a.out)
    print(f"{a.out}: {n} rows")


if __name__ == "__main__":
    main()
