#!/usr/bin/env python3
"""Held-out free-run error of `backlash diagnose` beside two peers, on the measured records in data/.

Every model is judged the way `diagnose` judges its own: the record (after block-mean decimation, the same
as `diagnose --decimate`) is split into the first 70% of samples (fit; round(0.7 N) samples) and the rest
(held out). Each model is fitted on the fit part only, then simulated free-run over the whole record from
rest (zero initial state: outputs and inputs before the first sample are 0, in the record's own units), so
the held-out part starts from the state the fit part left. The score is the RMSE of that simulation on the
held-out part.

Peers:
- ARX by least squares with a constant: y(k) = -sum a_i y(k-i) + sum b_j u(k-d-j) + c, na and nb in 0..4,
  d in 1..3 (75 structures). The structure is chosen by the lowest free-run RMSE on the fit part (not BIC:
  the score is a free-run error, so the choice uses the same kind of error, on the fit part only). A
  structure whose A polynomial is unstable is not eligible.
- Polynomial NARX (sysidentpy, FROLS, degree 2, BIC term selection) on standardised data (fit-part mean and
  standard deviation), for the lags in NARX_LAGS. Each is simulated free-run from rest by this script (not by
  sysidentpy's predict, which starts from measured outputs). Structures are ranked by fit-part free-run RMSE;
  the best one whose free run over the whole record stays bounded (finite, within DIVERGED_FACTOR fit-part
  standard deviations of the fit-part mean) is taken; diverged ones are counted in the table.

Then `backlash diagnose FILE --json` runs on the same record and decimation. It is first called without
--na/--nb/--delay (the tool chooses); if the program refuses that (an older CLI where they are required),
it is called again with the record's fallback structure, and the table says so. Its wall time and peak
resident memory (GNU time, see run_process) are recorded; a run longer than --timeout is stopped and
reported as such.

    .venv/bin/python scripts/peer_compare.py                    # every record, Markdown table on stdout
    .venv/bin/python scripts/peer_compare.py --records servo-sts3215 dc-generator --csv out.csv

Any peer that fails gives its reason in the row; the script does not stop.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np
from scipy.signal import lfilter

ROOT = pathlib.Path(__file__).resolve().parents[1]
FIT_FRACTION = 0.7
ARX_ORDERS = range(0, 5)
ARX_DELAYS = range(1, 4)
# (ylag, xlag) of the NARX structures tried, all with polynomial degree 2.
NARX_LAGS = [(1, 1), (1, 2), (2, 1), (2, 2), (2, 3), (3, 2), (3, 3), (4, 4)]
NARX_DEGREE = 2
NARX_MAX_TERMS = 20
DIVERGED_FACTOR = 1e3


@dataclasses.dataclass(frozen=True)
class Record:
    """A measured record and how to read it."""

    name: str
    file: str  # relative to the repository root
    time_col: str = "time"
    u_col: str = "u"
    y_col: str = "y"
    # None: diagnose chooses the rate itself (no --decimate); the peers are then fitted at the rate it chose.
    decimate: int | None = 1
    # (na, nb, delay) passed to diagnose only when it refuses to choose a structure itself.
    fallback: tuple[int, int, int] = (1, 0, 1)
    note: str = ""
    # Shown instead of a read error when the file is not there (records not redistributed here).
    if_absent: str = ""


SERVO_ABSENT = "not in the repository (licence unclear); data/servo/README.md says how to rebuild it"
TANKS_ABSENT = ("not in the repository (the data's terms are not stated); data/tanks/README.md says how to "
                "rebuild it")

RECORDS = [
    Record(
        "brfd-sine",
        "data/brfd/char_0.5Hz_36lb_1in.csv",
        time_col="t",
        decimate=16,
        fallback=(0, 0, 1),
        note="friction damper with play, 0.5 Hz sine; 1024 Hz / 16 (the choice of docs/RESULTS.md)",
    ),
    Record(
        "brfd-sine-rate",
        "data/brfd/char_0.5Hz_36lb_1in.csv",
        time_col="t",
        decimate=None,
        fallback=(0, 0, 1),
        note="the same sine record at its full 1024 Hz: diagnose chooses the rate",
    ),
    Record(
        "brfd-kocaeli",
        "data/brfd/KocaeliDBE_36lb.csv",
        time_col="t",
        decimate=16,
        fallback=(0, 0, 1),
        note="same damper, Kocaeli earthquake history; 1024 Hz / 16",
    ),
    Record(
        "servo-sts3215",
        "data/servo/sts3215_hold.csv",
        fallback=(1, 0, 1),
        note="hobby servo (STS3215) gear play, integer encoder counts, 10 Hz",
        if_absent=SERVO_ABSENT,
    ),
    Record(
        "servo-sts3250",
        "data/servo/sts3250_hold.csv",
        fallback=(1, 0, 1),
        note="hobby servo (STS3250) gear play, integer encoder counts, 10 Hz",
        if_absent=SERVO_ABSENT,
    ),
    Record(
        "cascaded-tanks",
        "data/tanks/tanks_est.csv",
        decimate=None,
        fallback=(2, 0, 1),
        note="cascaded tanks with overflow (benchmark estimation part, 4 s); square-root outflows, the level "
        "clipped at 10 at the top only",
        if_absent=TANKS_ABSENT,
    ),
    Record(
        "cascaded-tanks-val",
        "data/tanks/tanks_val.csv",
        decimate=None,
        fallback=(2, 0, 1),
        note="the benchmark's validation part, another multisine, as a record of its own",
        if_absent=TANKS_ABSENT,
    ),
    Record(
        "dc-generator",
        "data/dc_generator/dc_generator.csv",
        decimate=5,
        fallback=(1, 0, 1),
        note="DC motor driving a generator, PRBS input; file already block means of 50, here 5 more "
        "(2 samples per PRBS bit)",
    ),
    Record(
        "dc-generator-rate",
        "data/dc_generator/dc_generator.csv",
        decimate=None,
        fallback=(1, 0, 1),
        note="the same record as the file gives it (10 samples per PRBS bit): diagnose chooses the rate",
    ),
]


# ---------------------------------------------------------------- data


def read_record(rec: Record, root: pathlib.Path = ROOT) -> tuple[np.ndarray, np.ndarray]:
    """(u, y) of a record, block-mean decimated like `diagnose --decimate` (a partial last block dropped)."""
    path = root / rec.file
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in (rec.u_col, rec.y_col) if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: no column {', '.join(missing)}")
        rows = [(float(r[rec.u_col]), float(r[rec.y_col])) for r in reader]
    data = np.asarray(rows, dtype=float).reshape(-1, 2)
    factor = rec.decimate or 1
    return block_means(data[:, 0], factor), block_means(data[:, 1], factor)


def block_means(x: np.ndarray, factor: int) -> np.ndarray:
    if factor <= 1:
        return np.asarray(x, dtype=float)
    n = len(x) // factor
    return np.asarray(x[: n * factor], dtype=float).reshape(n, factor).mean(axis=1)


def split_index(n: int) -> int:
    """Number of fit samples: round(0.7 n), at least 1 and at most n - 1 (diagnose's rule)."""
    return min(max(int(round(n * FIT_FRACTION)), 1), n - 1)


def rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


# ---------------------------------------------------------------- ARX


@dataclasses.dataclass
class ArxModel:
    na: int
    nb: int
    delay: int
    a: np.ndarray  # a_1..a_na
    b: np.ndarray  # b_0..b_nb
    c: float

    def simulate(self, u: np.ndarray) -> np.ndarray:
        """Free run from rest: y and u are 0 before the first sample."""
        den = np.concatenate(([1.0], self.a))
        num = np.concatenate((np.zeros(self.delay), self.b))
        return lfilter(num, den, u) + lfilter([self.c], den, np.ones_like(u))


def fit_arx(u: np.ndarray, y: np.ndarray, na: int, nb: int, delay: int) -> ArxModel | None:
    """Equation-error least squares on the given (fit) samples, regressors 0 before the first sample.
    None when the problem has fewer rows than unknowns or the fitted A polynomial is not stable."""
    n = len(y)
    k = na + nb + 2
    if n <= k:
        return None
    cols = []
    for i in range(1, na + 1):
        cols.append(-shifted(y, i))
    for j in range(nb + 1):
        cols.append(shifted(u, delay + j))
    cols.append(np.ones(n))
    phi = np.column_stack(cols)
    theta, *_ = np.linalg.lstsq(phi, y, rcond=None)
    a, b, c = theta[:na], theta[na : na + nb + 1], float(theta[-1])
    if na and np.any(np.abs(np.roots(np.concatenate(([1.0], a)))) >= 1.0):
        return None
    return ArxModel(na, nb, delay, a, b, c)


def shifted(x: np.ndarray, lag: int) -> np.ndarray:
    out = np.zeros_like(x, dtype=float)
    if lag < len(x):
        out[lag:] = x[: len(x) - lag]
    return out


@dataclasses.dataclass
class PeerResult:
    structure: str = ""
    heldout_rmse: float = math.nan
    fit_rmse: float = math.nan
    reason: str = ""  # why there is no result, or a remark


def arx_peer(u: np.ndarray, y: np.ndarray) -> PeerResult:
    """The ARX structure with the lowest fit-part free-run RMSE, scored on the held-out part."""
    n_fit = split_index(len(y))
    best = None
    for na in ARX_ORDERS:
        for nb in ARX_ORDERS:
            for d in ARX_DELAYS:
                m = fit_arx(u[:n_fit], y[:n_fit], na, nb, d)
                if m is None:
                    continue
                sim = m.simulate(u)
                if not np.all(np.isfinite(sim)):
                    continue
                e = rmse(sim[:n_fit], y[:n_fit])
                if best is None or e < best[0]:
                    best = (e, m, sim)
    if best is None:
        return PeerResult(reason="no stable ARX structure")
    e, m, sim = best
    return PeerResult(
        structure=f"{m.na},{m.nb},{m.delay}",
        heldout_rmse=rmse(sim[n_fit:], y[n_fit:]),
        fit_rmse=e,
    )


# ---------------------------------------------------------------- NARX


@dataclasses.dataclass
class NarxModel:
    """y(k) = sum theta_t prod(lagged values of term t), codes as sysidentpy writes them: 0 for the constant,
    1000 + i for y(k-i), 2000 + i for u(k-i)."""

    codes: np.ndarray  # (terms, degree)
    theta: np.ndarray  # (terms,)

    def simulate(self, u: np.ndarray, y_rest: float, u_rest: float, bound: float) -> np.ndarray | None:
        """Free run; before the first sample y = y_rest and u = u_rest. None once |y| exceeds bound."""
        max_lag = int(max(1, np.max(self.codes % 1000)))
        n = len(u)
        yp = np.full(n + max_lag, y_rest)
        up = np.concatenate((np.full(max_lag, u_rest), u))
        terms = [[(int(c) // 1000, int(c) % 1000) for c in row if c != 0] for row in self.codes]
        for k in range(n):
            kk = k + max_lag
            acc = 0.0
            for coef, factors in zip(self.theta, terms):
                v = coef
                for kind, lag in factors:
                    v *= yp[kk - lag] if kind == 1 else up[kk - lag]
                acc += v
            if not math.isfinite(acc) or abs(acc) > bound:
                return None
            yp[kk] = acc
        return yp[max_lag:]


def fit_narx(u: np.ndarray, y: np.ndarray, ylag: int, xlag: int) -> NarxModel:
    """FROLS with BIC term selection on the given (already standardised) fit samples."""
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares

    model = FROLS(
        order_selection=True,
        n_info_values=NARX_MAX_TERMS,
        ylag=ylag,
        xlag=xlag,
        info_criteria="bic",
        estimator=LeastSquares(),
        basis_function=Polynomial(degree=NARX_DEGREE),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(X=u.reshape(-1, 1), y=y.reshape(-1, 1))
    return NarxModel(np.asarray(model.final_model), np.asarray(model.theta).ravel())


def narx_peer(u: np.ndarray, y: np.ndarray, lags=NARX_LAGS) -> PeerResult:
    """The bounded NARX structure with the lowest fit-part free-run RMSE, scored on the held-out part."""
    n_fit = split_index(len(y))
    mu_u, sd_u = float(np.mean(u[:n_fit])), float(np.std(u[:n_fit]))
    mu_y, sd_y = float(np.mean(y[:n_fit])), float(np.std(y[:n_fit]))
    if sd_u == 0.0 or sd_y == 0.0:
        return PeerResult(reason="input or output constant on the fit part")
    us, ys = (u - mu_u) / sd_u, (y - mu_y) / sd_y
    y_rest, u_rest = -mu_y / sd_y, -mu_u / sd_u
    bound = DIVERGED_FACTOR + abs(y_rest)
    ranked, failures, diverged = [], [], 0
    for ylag, xlag in lags:
        try:
            m = fit_narx(us[:n_fit], ys[:n_fit], ylag, xlag)
        except Exception as e:  # noqa: BLE001 - a failing structure is reported, not fatal
            failures.append(f"{ylag},{xlag}: {type(e).__name__}")
            continue
        sim = m.simulate(us, y_rest, u_rest, bound)
        if sim is None:
            diverged += 1
            continue
        e_fit = rmse(sim[:n_fit], ys[:n_fit]) * sd_y
        ranked.append((e_fit, (ylag, xlag), len(m.theta), sim))
    if not ranked:
        why = f"all {len(lags)} structures failed ({diverged} diverged"
        why += f"; {'; '.join(failures)})" if failures else ")"
        return PeerResult(reason=why)
    e_fit, (ylag, xlag), terms, sim = min(ranked, key=lambda r: r[0])
    remark = f"{diverged} of {len(lags)} diverged" if diverged else ""
    if failures:
        remark += ("; " if remark else "") + f"{len(failures)} failed to fit"
    return PeerResult(
        structure=f"{ylag},{xlag} ({terms} terms)",
        heldout_rmse=rmse(sim[n_fit:], ys[n_fit:]) * sd_y,
        fit_rmse=e_fit,
        reason=remark,
    )


# ---------------------------------------------------------------- diagnose


@dataclasses.dataclass
class DiagnoseResult:
    structure: str = ""
    chosen_by: str = ""  # "tool" or "fallback"
    before: float = math.nan
    after: float = math.nan
    linear: float = math.nan
    effects: str = ""
    # The decimation diagnose worked at and who chose it ("user" or "data").
    decimate: int = 1
    rate_by: str = ""
    seconds: float = math.nan
    peak_mib: float = math.nan
    reason: str = ""


GNU_TIME = shutil.which("time")  # GNU time, found on PATH (the shell builtin has no -f)


def run_process(cmd: list[str], timeout: float) -> tuple[int | None, str, str, float, float]:
    """Run cmd; (exit code or None when stopped at the timeout, stdout, stderr, wall seconds, peak MiB).

    The peak resident size is that of cmd alone. This Python process is large, and Linux carries a
    process's high-water mark across exec, so wait4 on a child started from here would report at least
    this process's size; GNU time (Debian package `time`) starts cmd from its own small process and reports
    cmd's peak. Without it the peak is read from /proc/PID/status (VmHWM) while cmd runs, which can miss a
    rise in its last few milliseconds."""
    use_time = GNU_TIME is not None
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err, \
            tempfile.NamedTemporaryFile("r") as peak_file:
        full = [GNU_TIME, "-f", "%M", "-o", peak_file.name, *cmd] if use_time else cmd
        t0 = time.monotonic()
        # Own process group: a timeout stops cmd and, with GNU time, its child too.
        proc = subprocess.Popen(full, stdout=out, stderr=err, start_new_session=True)
        timed_out, hwm_kib = False, 0.0
        while proc.poll() is None:
            if not use_time:
                hwm_kib = max(hwm_kib, vm_hwm_kib(proc.pid))
            if time.monotonic() - t0 > timeout:
                os.killpg(proc.pid, 9)
                proc.wait()
                timed_out = True
                break
            time.sleep(0.005)
        seconds = time.monotonic() - t0
        out.seek(0)
        err.seek(0)
        stdout = out.read().decode(errors="replace")
        stderr = err.read().decode(errors="replace")
        peak_kib = last_number(peak_file.read()) if use_time else hwm_kib
    code = None if timed_out else proc.returncode
    return code, stdout, stderr, seconds, peak_kib / 1024.0


def vm_hwm_kib(pid: int) -> float:
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1])
    except OSError:
        pass
    return 0.0


def last_number(text: str) -> float:
    """The last line of GNU time's -o file as a number (it starts with a note when cmd was killed)."""
    lines = text.strip().splitlines()
    try:
        return float(lines[-1])
    except (IndexError, ValueError):
        return math.nan


def refused_for_structure(stderr: str) -> bool:
    """The CLI says the orders are required (an older CLI)."""
    return "--na" in stderr and "required" in stderr


def diagnose_command(binary: str, rec: Record, root: pathlib.Path, structure=None) -> list[str]:
    cmd = [binary, "diagnose", str(root / rec.file), "--json"]
    if rec.decimate is not None:
        cmd += ["--decimate", str(rec.decimate)]
    cmd += ["--time-col", rec.time_col, "--u-col", rec.u_col, "--y-col", rec.y_col]
    if structure is not None:
        na, nb, d = structure
        cmd += ["--na", str(na), "--nb", str(nb), "--delay", str(d)]
    return cmd


def run_diagnose(binary: str, rec: Record, timeout: float, root: pathlib.Path = ROOT) -> DiagnoseResult:
    if not pathlib.Path(binary).is_file():
        return DiagnoseResult(reason=f"{binary} not found: run `cargo build --release`")
    try:
        code, out, err, secs, mib = run_process(diagnose_command(binary, rec, root), timeout)
        chosen_by = "tool"
        if code not in (0, None) and refused_for_structure(err):
            cmd = diagnose_command(binary, rec, root, rec.fallback)
            code, out, err, secs, mib = run_process(cmd, timeout)
            chosen_by = "fallback"
    except OSError as e:
        return DiagnoseResult(reason=f"cannot run {binary}: {e}")
    res = DiagnoseResult(chosen_by=chosen_by, seconds=secs, peak_mib=mib)
    if code is None:
        res.reason = f"stopped after {timeout:g} s without an answer"
        return res
    if code != 0:
        last = err.strip().splitlines()[-1] if err.strip() else "(no message)"
        res.reason = f"exit {code}: {last}"
        return res
    try:
        doc = json.loads(out)
    except json.JSONDecodeError as e:
        res.reason = f"output is not JSON ({e})"
        return res
    fill_from_json(res, doc)
    return res


def fill_from_json(res: DiagnoseResult, doc: dict) -> None:
    res.structure = f"{doc.get('na')},{doc.get('nb')},{doc.get('delay')}"
    res.decimate = int(doc.get("decimate") or 1)
    res.rate_by = (doc.get("rate") or {}).get("chosen_by", "user")
    res.before = number(doc.get("before", {}).get("rmse"))
    res.after = number(doc.get("after", {}).get("rmse"))
    res.linear = number((doc.get("linear") or {}).get("rmse"))
    effects = doc.get("effects")
    if effects is None:  # older JSON: only the one chosen effect
        effect = (doc.get("effect") or {}).get("id")
        effects = [] if effect is None else [{"id": effect}]
    res.effects = "+".join(str(e.get("id")) for e in effects) or "none"
    kind = (doc.get("after") or {}).get("error_kind")
    if kind and kind != "simulation":
        res.reason = f"after.rmse is a {kind} error"


def number(v) -> float:
    return float(v) if isinstance(v, (int, float)) else math.nan


# ---------------------------------------------------------------- table


COLUMNS = [
    "record",
    "N",
    "mean predictor",
    "ARX na,nb,d",
    "ARX RMSE",
    "NARX ylag,xlag",
    "NARX RMSE",
    "rate (decimate)",
    "diagnose na,nb,d",
    "before",
    "after",
    "linear",
    "effects",
    "time [s]",
    "peak [MiB]",
    "notes",
]


def compare(rec: Record, binary: str, timeout: float, root: pathlib.Path = ROOT) -> dict:
    row = {c: "" for c in COLUMNS}
    row["record"] = rec.name
    notes = []
    if rec.if_absent and not (root / rec.file).is_file():
        row["notes"] = rec.if_absent
        return row
    d = run_diagnose(binary, rec, timeout, root)
    if rec.decimate is None:
        # The peers work at the rate diagnose chose, so that every error is on the same held-out samples.
        rec = dataclasses.replace(rec, decimate=d.decimate)
    row["rate (decimate)"] = f"{d.decimate} ({d.rate_by})" if d.rate_by else ""
    try:
        u, y = read_record(rec, root)
    except (OSError, ValueError) as e:
        row["notes"] = f"cannot read: {e}"
        return row
    n = len(y)
    row["N"] = n
    if n < 20:
        row["notes"] = f"only {n} samples after decimation"
        return row
    n_fit = split_index(n)
    # The error of predicting the fit part's mean on the held-out part: the bar any model should clear.
    row["mean predictor"] = fmt(rmse(y[n_fit:], np.mean(y[:n_fit])))
    for label, peer in (("ARX", arx_peer), ("NARX", narx_peer)):
        try:
            p = peer(u, y)
        except Exception as e:  # noqa: BLE001 - any peer failure becomes a note
            p = PeerResult(reason=f"{type(e).__name__}: {e}")
        key = "ARX na,nb,d" if label == "ARX" else "NARX ylag,xlag"
        row[key] = p.structure or "failed"
        row[f"{label} RMSE"] = fmt(p.heldout_rmse)
        if p.reason:
            notes.append(f"{label}: {p.reason}")
    row["diagnose na,nb,d"] = d.structure + (" (fallback)" if d.chosen_by == "fallback" else "")
    row["before"], row["after"], row["linear"] = fmt(d.before), fmt(d.after), fmt(d.linear)
    row["effects"] = d.effects
    row["time [s]"] = fmt(d.seconds, 3)
    row["peak [MiB]"] = fmt(d.peak_mib, 3)
    if d.reason:
        notes.append(f"diagnose: {d.reason}")
    row["notes"] = "; ".join(notes)
    return row


def fmt(v: float, digits: int = 4) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    return f"{v:.{digits}g}"


def markdown(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    for r in rows:
        lines.append("| " + " | ".join(str(r[c]).replace("|", "/") for c in COLUMNS) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    names = [r.name for r in RECORDS]
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--records", nargs="+", metavar="NAME", help=f"records to run (default all: {', '.join(names)})")
    p.add_argument("--backlash", default=str(ROOT / "target" / "release" / "backlash"), help="the CLI program")
    p.add_argument("--timeout", type=float, default=120.0, help="seconds one diagnose run may take (120)")
    p.add_argument("--csv", metavar="FILE", help="also write the table as CSV")
    a = p.parse_args(argv)
    chosen = RECORDS
    if a.records:
        unknown = [n for n in a.records if n not in names]
        if unknown:
            p.error(f"unknown record {', '.join(unknown)}; known: {', '.join(names)}")
        chosen = [r for r in RECORDS if r.name in a.records]
    rows = []
    for rec in chosen:
        print(f"{rec.name} ...", file=sys.stderr, flush=True)
        rows.append(compare(rec, a.backlash, a.timeout))
    print(markdown(rows))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
