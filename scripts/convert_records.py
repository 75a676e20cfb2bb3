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

The survey set (`python3 scripts/fetch_data.py --survey`; each folder's README gives its commands) adds a
numeric table by column, a MAT-file's series, and the servo logs in the `t,u,y` spelling:

    python scripts/convert_records.py table SRC/gas-furnace/data/gas-furnace.csv InputGasRate CO2 9 OUT.csv
    python scripts/convert_records.py table SRC/Projeto_1/secador/dryer.dat 0 1 1 OUT.csv
    python scripts/convert_records.py mat SRC/F16Data_SineSw_Level7.mat Force "Acceleration(1,:)" OUT.csv \
        --dt 0.0025
    python scripts/convert_records.py mat "SRC/.../data.mat" "rec.act_pos_mot_deg(1,:)" "rec.act_pos_se_deg(1,:)" \
        OUT.csv --time rec.time_cont
    python scripts/convert_records.py servo SRC/logs/motor_telemetry_comp2.csv 1 OUT.csv --spelling t

Only the standard library is used.
"""

import argparse
import csv
import dataclasses
import json
import re
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


def convert_servo(source: str, motor: int, out: str, spelling: str = "time") -> int:
    """One servo's commanded and measured position from a telemetry log; rows lacking either are dropped.
    spelling "time" (data/servo) writes the header `time,u,y` and the seconds with 3 decimals; "t" (the survey
    set) writes `t,u,y` and the seconds rounded to 1 ms with 10 significant digits (0, 0.101, ...)."""
    if spelling not in ("time", "t"):
        raise ValueError(f"spelling {spelling!r}: only 'time' or 't'")
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
        w.writerow([spelling, "u", "y"])
        for r in rows:
            t = seconds_since(r["timestamp"], start)
            w.writerow([f"{t:.3f}" if spelling == "time" else f"{round(t, 3):.10g}", int(r[target]),
                        int(r[position])])
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
    return write_tuy(out, [r[0] for r in rows], [r[1] for r in rows], [r[2] for r in rows])


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


# MATLAB array classes (the flags' low byte): 2 a struct, 6 to 15 the numeric classes (double, single and
# the integers).
MAT_STRUCT, MAT_NUMERIC_CLASSES = 2, range(6, 16)


@dataclasses.dataclass(frozen=True)
class MatArray:
    """A real numeric MATLAB array: its dimensions and its values in column order (MATLAB's)."""

    dims: tuple[int, ...]
    values: list[float]

    def row(self, i: int) -> list[float]:
        """Row i (from 0) of a 2-D array."""
        return self.values[i :: self.dims[0]]

    def column(self, j: int) -> list[float]:
        """Column j (from 0) of a 2-D array."""
        return self.values[j * self.dims[0] : (j + 1) * self.dims[0]]


def mat_matrix(payload: bytes, prefix: str, arrays: dict[str, MatArray], name: str = "") -> None:
    """Add the real numeric arrays of one matrix element to arrays: a numeric array under its name, the fields
    of a 1-by-1 struct as name.field (recursively); cells, characters, sparse arrays and objects are skipped."""
    parts = list(mat_elements(payload))
    if len(parts) < 3:
        return  # an empty element
    cls = struct.unpack_from("<I", parts[0][1])[0] & 0xFF
    if cls != MAT_STRUCT and cls not in MAT_NUMERIC_CLASSES:
        return  # an object's parts are laid out otherwise (no dimensions second)
    dims_data = parts[1][1]
    dims = struct.unpack(f"<{len(dims_data) // 4}i", dims_data)
    name = name or parts[2][1].decode("ascii")
    if cls in MAT_NUMERIC_CLASSES and len(parts) >= 4 and parts[3][0] in MAT_NUMERIC:
        code, data = parts[3]
        fmt = MAT_NUMERIC[code]
        values = struct.unpack(f"<{len(data) // struct.calcsize(fmt)}{fmt}", data)
        arrays[prefix + name] = MatArray(tuple(dims), [float(v) for v in values])
    elif cls == MAT_STRUCT and len(parts) >= 5 and dims == (1, 1):
        width = struct.unpack_from("<i", parts[3][1])[0]
        names = parts[4][1]
        fields = [names[k : k + width].split(b"\0")[0].decode("ascii") for k in range(0, len(names), width)]
        for field, (kind, sub) in zip(fields, parts[5:]):
            if kind == MAT_MATRIX:
                mat_matrix(sub, f"{prefix}{name}.", arrays, field)


def read_mat_arrays(path: str) -> dict[str, MatArray]:
    """Every real numeric array of a MATLAB level-5 MAT-file (not v7.3) by its name, a field of a 1-by-1
    struct as struct.field. Only the standard library: no scipy."""
    with open(path, "rb") as f:
        buf = f.read()
    if buf[126:128] != b"IM":
        raise SystemExit(f"{path}: not a little-endian MATLAB 5 MAT-file (v7.3 files are HDF5, not read here)")
    arrays: dict[str, MatArray] = {}
    for kind, payload in mat_elements(buf, 128):
        if kind == MAT_COMPRESSED:
            kind, payload = next(mat_elements(zlib.decompress(payload)))
        if kind == MAT_MATRIX:
            mat_matrix(payload, "", arrays)
    return arrays


def read_mat_vectors(path: str) -> dict[str, list[float]]:
    """Every real numeric array of a MATLAB level-5 MAT-file (not v7.3) by its name, its values in column
    order (struct fields left out). Only the standard library: no scipy."""
    return {name: a.values for name, a in read_mat_arrays(path).items() if "." not in name}


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
    return write_tuy(out, t, u, y)


def write_tuy(out: str, t: list[float], u: list[float], y: list[float]) -> int:
    """`t,u,y` with a header line, every number with 10 significant digits (the damper's, EMPS's and the survey set's form)."""
    if not len(t) == len(u) == len(y):
        raise SystemExit(f"{out}: t, u and y have {len(t)}, {len(u)} and {len(y)} values")
    with open(out, "w", newline="") as f:
        f.write("t,u,y\n")
        for row in zip(t, u, y):
            f.write("{:.10g},{:.10g},{:.10g}\n".format(*row))
    return len(t)


def sample_times(n: int, dt: float) -> list[float]:
    """k * dt for k = 0 .. n-1 (dt 1 gives the sample index, for a source without a sample time)."""
    return [k * dt for k in range(n)]


def read_columns(source: str, columns: tuple[str, ...] | tuple[int, ...]) -> list[list[float]]:
    """Columns of a numeric table: by name from a CSV file with a header line, or by index (from 0) from a
    file of whitespace-separated numbers without one (DaISy's .dat files)."""
    with open(source, newline="") as f:
        if all(isinstance(c, int) for c in columns):
            rows = [line.split() for line in f if line.strip()]
            picks = columns
        else:
            reader = csv.reader(f)
            header = [h.strip() for h in next(reader)]
            missing = [c for c in columns if c not in header]
            if missing:
                raise SystemExit(f"{source}: no column {', '.join(map(str, missing))} (header {header})")
            picks = tuple(header.index(c) for c in columns)
            rows = [r for r in reader if any(v.strip() for v in r)]
    return [[float(r[k]) for r in rows] for k in picks]


def convert_table(source: str, u: str | int, y: str | int, dt: float, out: str) -> int:
    """Two columns of a numeric table (see read_columns) as u and y, t = k * dt."""
    us, ys = read_columns(source, (u, y))
    return write_tuy(out, sample_times(len(us), dt), us, ys)


def mat_series(arrays: dict[str, MatArray], spec: str, source: str) -> list[float]:
    """The values that spec names, in MATLAB's words: `NAME` (a vector), `NAME(i,:)` (row i, from 1) or
    `NAME(:,j)` (column j); NAME may be struct.field."""
    m = re.fullmatch(r"([\w.]+)(?:\((\d+),:\)|\(:,(\d+)\))?", spec)
    if not m:
        raise ValueError(f"{spec!r}: not NAME, NAME(i,:) or NAME(:,j)")
    name, row, column = m.groups()
    if name not in arrays:
        raise SystemExit(f"{source}: no numeric array {name}")
    a = arrays[name]
    if row:
        return a.row(int(row) - 1)
    return a.column(int(column) - 1) if column else a.values


def convert_mat(source: str, u: str, y: str, out: str, dt: float | None = None, time: str | None = None) -> int:
    """Two series of a MAT-file (mat_series's specs) as u and y; t from the series `time` less its first
    value, or k * dt."""
    arrays = read_mat_arrays(source)
    us, ys = mat_series(arrays, u, source), mat_series(arrays, y, source)
    if time is not None:
        ts = mat_series(arrays, time, source)
        ts = [v - ts[0] for v in ts]
    elif dt is not None:
        ts = sample_times(len(us), dt)
    else:
        raise ValueError("convert_mat needs dt or time")
    return write_tuy(out, ts, us, ys)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="record", required=True)
    s = sub.add_parser("servo", help="a servo telemetry log (commanded -> measured position of one motor)")
    s.add_argument("source")
    s.add_argument("motor", type=int, help="the motor's number in the log's column names")
    s.add_argument("out")
    s.add_argument("--spelling", choices=["time", "t"], default="time",
                   help="`time` (data/servo: header time,u,y, 3 decimals) or `t` (the survey set)")
    tb = sub.add_parser("table", help="two columns of a numeric table (CSV by column name, or whitespace-separated "
                        "numbers by column index from 0), t = k * DT")
    tb.add_argument("source")
    tb.add_argument("u", help="the input's column: a name, or an index when the file has no header")
    tb.add_argument("y", help="the output's column, likewise")
    tb.add_argument("dt", type=float, help="sample time (1: t is the sample index)")
    tb.add_argument("out")
    m = sub.add_parser("mat", help="two series of a MATLAB 5 MAT-file: NAME, NAME(i,:) or NAME(:,j), struct.field")
    m.add_argument("source")
    m.add_argument("u")
    m.add_argument("y")
    m.add_argument("out")
    when = m.add_mutually_exclusive_group(required=True)
    when.add_argument("--dt", type=float, help="sample time: t = k * DT")
    when.add_argument("--time", help="the series holding the time (t is it less its first value)")
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
        n = convert_servo(a.source, a.motor, a.out, a.spelling)
    elif a.record == "table":
        u, y = (int(a.u), int(a.y)) if a.u.isdigit() and a.y.isdigit() else (a.u, a.y)
        n = convert_table(a.source, u, y, a.dt, a.out)
    elif a.record == "mat":
        n = convert_mat(a.source, a.u, a.y, a.out, a.dt, a.time)
    elif a.record == "tanks":
        n = convert_tanks(a.source, a.part, a.out)
    else:
        n = convert_generator(a.x, a.y, a.out)
    print(f"{a.out}: {n} rows")


if __name__ == "__main__":
    main()
