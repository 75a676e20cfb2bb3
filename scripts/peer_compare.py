#!/usr/bin/env python3
"""Held-out free-run error of `backlash diagnose` beside two peers as strong as a user's, on the nine measured
records of the default set and the six of the optional set, and the ratchet that keeps `diagnose` from getting
worse on them.

The records are found by scripts/data_records.py (data/, or BACKLASH_DATA); `python3 scripts/fetch_data.py`
puts them there (`--extra`: the optional set too). A missing record of the default set is an error, never a
skipped row. A record of the optional set (Record.optional) that is not in place is skipped, with a line
saying so, by --ratchet and --update over all records (CI has only the default set); named with --records it
is required like any other.

Every model is judged the way `diagnose` judges its own: the record (after block-mean decimation, the same as
`diagnose --decimate`) is split into the first 70% of samples (fit; round(0.7 N) samples) and the rest (held
out); each model is fitted on the fit part only, simulated free-run over the whole record, and scored by the
RMSE of that simulation on the held-out part, in the record's units.

Peers (the recipe of issue 45): u and y standardised with the fit part's mean and standard deviation; every
free run starts from the record's first sample (u and y held at their first values before it, as a user
starting a simulation from the measured initial condition would);
- ARX with an intercept by least squares: y(k) = -sum a_i y(k-i) + sum_{j=0..nb} b_j u(k-d-j) + c, na 1-4,
  nb 1-4, delay d 1-3 (48 structures), fitted on the fit part's rows whose regressors are all measured;
- polynomial NARX by sysidentpy 0.9's FROLS (NARMAX, AIC, n_info_values 15, least squares), degree 2 and 3,
  ylag = xlag 1-4 (8 structures), simulated free-run by this script.
Structures whose free run diverges (beyond DIVERGED_FACTOR fit-part standard deviations) are not eligible.
Each family's structure is chosen by free-run RMSE on the fit part and scored on the held-out part. Both are
fitted at the record's own rate and, where `diagnose` works on a decimated record, at that rate too (on the
same block means, so on the same held-out samples as `diagnose`). sysidentpy: tests/python/requirements-peers.txt
(`pip install --no-deps -r tests/python/requirements-peers.txt`; its other dependencies are numpy and scipy).

`backlash diagnose FILE --json` runs with each record's settings (RECORDS: `--decimate` where given, otherwise
the tool chooses the rate); its wall time and peak memory are recorded (GNU time, see run_process).

The results are kept in MEASURED (docs/measured_records.json), so that neither CI nor a reader refits the peers:

    .venv/bin/python scripts/peer_compare.py                 # the committed table, as Markdown (runs nothing)
    .venv/bin/python scripts/peer_compare.py --ratchet       # diagnose again on every record; exit 1 where a
                                                             # final held-out error is > 2% above the committed one
    .venv/bin/python scripts/peer_compare.py --update        # diagnose again on every record and write its
                                                             # numbers into docs/measured_records.json (the peers
                                                             # kept; a rate not fitted before is fitted)
    .venv/bin/python scripts/peer_compare.py --update --refit-peers   # the peers fitted again too (minutes)

After a change to `diagnose` that moves its numbers on purpose, `--update` is the one command that regenerates
the committed numbers (review the diff of docs/measured_records.json). `--records NAME...` limits any mode to
some records; `--csv FILE` also writes the table as CSV.
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

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import data_records  # noqa: E402 - the sibling script, found through the line above

ROOT = pathlib.Path(__file__).resolve().parents[1]
MEASURED = ROOT / "docs" / "measured_records.json"
FIT_FRACTION = 0.7
ARX_NA = range(1, 5)
ARX_NB = range(1, 5)
ARX_DELAYS = range(1, 4)
NARX_LAGS = range(1, 5)  # ylag = xlag
NARX_DEGREES = (2, 3)
NARX_INFO_VALUES = 15
DIVERGED_FACTOR = 1e3  # a free run beyond this many fit-part standard deviations has diverged
RATCHET_TOLERANCE = 0.02  # the ratchet fails where a final error is more than 2% above the committed one


@dataclasses.dataclass(frozen=True)
class Record:
    """A measured record and how `diagnose` runs on it."""

    name: str
    file: str  # the record's name in data/ (scripts/data_records.py finds it)
    time_col: str = "time"
    u_col: str = "u"
    y_col: str = "y"
    # None: diagnose chooses the rate itself (no --decimate).
    decimate: int | None = 1
    # (na, nb, delay) passed to diagnose only when it refuses to choose a structure itself (an older CLI).
    fallback: tuple[int, int, int] = (1, 0, 1)
    note: str = ""
    # A record of the optional set (`fetch_data.py --extra`): skipped where it is not in place.
    optional: bool = False


RECORDS = [
    Record("brfd-sine", "brfd/char_0.5Hz_36lb_1in.csv", time_col="t", decimate=16, fallback=(0, 0, 1),
           note="friction damper with play, 0.5 Hz sine; 1024 Hz / 16"),
    Record("brfd-kocaeli", "brfd/KocaeliDBE_36lb.csv", time_col="t", decimate=16, fallback=(0, 0, 1),
           note="same damper, Kocaeli earthquake history; 1024 Hz / 16"),
    Record("brfd-imperial", "brfd/ImperialValleyDBE_36lb.csv", time_col="t", decimate=16, fallback=(0, 0, 1),
           note="same damper, Imperial Valley earthquake history; 1024 Hz / 16"),
    Record("servo-sts3215", "servo/sts3215_hold.csv",
           note="hobby servo (STS3215) gear play, integer encoder counts, 10 Hz"),
    Record("servo-sts3250", "servo/sts3250_hold.csv",
           note="hobby servo (STS3250) gear play, integer encoder counts, 10 Hz"),
    Record("cascaded-tanks", "tanks/tanks_est.csv", decimate=None, fallback=(2, 0, 1),
           note="cascaded tanks with overflow (benchmark estimation part, 4 s); square-root outflows, the level "
           "clipped at 10 at the top only"),
    Record("cascaded-tanks-val", "tanks/tanks_val.csv", decimate=None, fallback=(2, 0, 1),
           note="the benchmark's validation part, another multisine, as a record of its own"),
    Record("dc-generator", "dc_generator/dc_generator.csv", decimate=5,
           note="DC motor driving a generator, PRBS input; file already block means of 50, here 5 more "
           "(2 samples per PRBS bit)"),
    Record("emps", "emps/emps.csv", time_col="t", decimate=None, fallback=(2, 0, 1),
           note="electro-mechanical positioning system (EMPS), closed loop, 1 kHz; force command -> position"),
    # The optional set (data/brfd/README.md's second table): more tests of the damper, measured as the three
    # above.
    *[Record(name, f"brfd/{file}", time_col="t", decimate=16, fallback=(0, 0, 1), optional=True,
             note=f"same damper, {what}; 1024 Hz / 16; optional set")
      for name, file, what in (
          ("brfd-sine-1hz", "char_1Hz_36lb_1in.csv", "1 Hz sine +/-1 in, 36 lb"),
          ("brfd-sine-0.25hz-30lb", "char_0.25Hz_30lb_0.5in.csv", "0.25 Hz sine +/-0.5 in, 30 lb"),
          ("brfd-sine-0.5hz-0lb", "char_0.5Hz_0lb_1.5in.csv", "0.5 Hz sine +/-1.5 in, 0 lb"),
          ("brfd-sine-2hz", "char_2Hz_36lb_0.5in.csv", "2 Hz sine +/-0.5 in, 36 lb"),
          ("brfd-kocaeli-mce", "KocaeliMCE_36lb.csv", "Kocaeli earthquake history at the MCE scale, 36 lb"),
          ("brfd-d1-sine-0.5hz", "d1_char_0.5Hz_35lb.csv", "2022 series (dataset-1), 0.5 Hz sine, 35 lb"),
      )],
]


# ---------------------------------------------------------------- data


def read_record(rec: Record, factor: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(u, y) of a record, block-mean decimated by factor like `diagnose --decimate` (a partial last block
    dropped). MissingRecord (naming the fetch command) when the record is not in place."""
    path = data_records.record_path(rec.file)
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in (rec.u_col, rec.y_col) if c not in (reader.fieldnames or [])]
        if missing:
            raise ValueError(f"{path}: no column {', '.join(missing)}")
        rows = [(float(r[rec.u_col]), float(r[rec.y_col])) for r in reader]
    data = np.asarray(rows, dtype=float).reshape(-1, 2)
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


@dataclasses.dataclass(frozen=True)
class Standardised:
    """u and y with the fit part's mean subtracted and divided by its standard deviation."""

    u: np.ndarray
    y: np.ndarray
    y_mean: float
    y_std: float
    n_fit: int

    @staticmethod
    def of(u: np.ndarray, y: np.ndarray) -> Standardised | None:
        """None when u or y is constant on the fit part."""
        n_fit = split_index(len(y))
        mu_u, sd_u = float(np.mean(u[:n_fit])), float(np.std(u[:n_fit]))
        mu_y, sd_y = float(np.mean(y[:n_fit])), float(np.std(y[:n_fit]))
        if sd_u == 0.0 or sd_y == 0.0:
            return None
        return Standardised((u - mu_u) / sd_u, (y - mu_y) / sd_y, mu_y, sd_y, n_fit)

    def errors(self, sim: np.ndarray) -> tuple[float, float]:
        """(fit-part, held-out) RMSE of a standardised simulation, in the record's units."""
        n = self.n_fit
        return rmse(sim[:n], self.y[:n]) * self.y_std, rmse(sim[n:], self.y[n:]) * self.y_std


@dataclasses.dataclass
class PeerResult:
    structure: str = ""
    heldout_rmse: float = math.nan
    fit_rmse: float = math.nan
    reason: str = ""  # why there is no result, or a remark


CONSTANT = PeerResult(reason="input or output constant on the fit part")


# ---------------------------------------------------------------- ARX


@dataclasses.dataclass
class ArxModel:
    na: int
    nb: int
    delay: int
    a: np.ndarray  # a_1..a_na
    b: np.ndarray  # b_0..b_nb
    c: float

    def simulate(self, u: np.ndarray, y_rest: float = 0.0, u_rest: float = 0.0) -> np.ndarray:
        """Free run; before the first sample y = y_rest and u = u_rest (at rest there: in the deviations from
        that point the model starts from zero, with its constant moved accordingly)."""
        from scipy.signal import lfilter  # here: the ratchet and the table need no scipy

        den = np.concatenate(([1.0], self.a))
        num = np.concatenate((np.zeros(self.delay), self.b))
        c = self.c + u_rest * float(np.sum(self.b)) - y_rest * float(np.sum(den))
        return lfilter(num, den, u - u_rest) + lfilter([c], den, np.ones_like(u)) + y_rest


def fit_arx(u: np.ndarray, y: np.ndarray, na: int, nb: int, delay: int) -> ArxModel | None:
    """Equation-error least squares on the given (fit) samples whose regressors are all measured (from sample
    max(na, delay + nb) on). None when there are fewer such rows than unknowns."""
    first = max(na, delay + nb)
    rows = len(y) - first
    if rows <= na + nb + 2:
        return None
    cols = [-y[first - i : len(y) - i] for i in range(1, na + 1)]
    cols += [u[first - delay - j : len(u) - delay - j] for j in range(nb + 1)]
    cols.append(np.ones(rows))
    theta, *_ = np.linalg.lstsq(np.column_stack(cols), y[first:], rcond=None)
    return ArxModel(na, nb, delay, theta[:na], theta[na : na + nb + 1], float(theta[-1]))


def bounded(sim: np.ndarray | None) -> bool:
    """A standardised free run that stays finite and within DIVERGED_FACTOR of the fit part's mean."""
    return sim is not None and bool(np.all(np.isfinite(sim))) and float(np.max(np.abs(sim))) <= DIVERGED_FACTOR


def arx_peer(u: np.ndarray, y: np.ndarray) -> PeerResult:
    """The ARX structure with the lowest fit-part free-run RMSE on the standardised record (simulated from the
    record's first sample), scored on the held-out part; diverging structures are not eligible."""
    st = Standardised.of(u, y)
    if st is None:
        return CONSTANT
    best, diverged = None, 0
    for na in ARX_NA:
        for nb in ARX_NB:
            for d in ARX_DELAYS:
                m = fit_arx(st.u[: st.n_fit], st.y[: st.n_fit], na, nb, d)
                if m is None:
                    continue
                sim = m.simulate(st.u, st.y[0], st.u[0])
                if not bounded(sim):
                    diverged += 1
                    continue
                e_fit, e_held = st.errors(sim)
                if best is None or e_fit < best[0]:
                    best = (e_fit, e_held, m)
    if best is None:
        return PeerResult(reason=f"no ARX structure stays bounded ({diverged} diverged)")
    e_fit, e_held, m = best
    return PeerResult(structure=f"{m.na},{m.nb},{m.delay}", heldout_rmse=e_held, fit_rmse=e_fit,
                      reason=f"{diverged} of 48 diverged" if diverged else "")


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
        yp = [y_rest] * (n + max_lag)
        up = [u_rest] * max_lag + [float(v) for v in u]
        terms = [
            (float(coef), [(int(c) // 1000 == 1, int(c) % 1000) for c in row if c != 0])
            for coef, row in zip(self.theta, self.codes)
        ]
        for kk in range(max_lag, n + max_lag):
            acc = 0.0
            for coef, factors in terms:
                v = coef
                for is_y, lag in factors:
                    v *= yp[kk - lag] if is_y else up[kk - lag]
                acc += v
            if not math.isfinite(acc) or abs(acc) > bound:
                return None
            yp[kk] = acc
        return np.asarray(yp[max_lag:])


def fit_narx(u: np.ndarray, y: np.ndarray, lag: int, degree: int) -> NarxModel:
    """FROLS (NARMAX, AIC over the first NARX_INFO_VALUES terms, least squares) on the given (standardised)
    fit samples, ylag = xlag = lag."""
    from sysidentpy.basis_function import Polynomial
    from sysidentpy.model_structure_selection import FROLS
    from sysidentpy.parameter_estimation import LeastSquares

    model = FROLS(
        order_selection=True,
        n_info_values=NARX_INFO_VALUES,
        ylag=lag,
        xlag=lag,
        info_criteria="aic",
        estimator=LeastSquares(),
        basis_function=Polynomial(degree=degree),
        model_type="NARMAX",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(X=u.reshape(-1, 1), y=y.reshape(-1, 1))
    return NarxModel(np.asarray(model.final_model), np.asarray(model.theta).ravel())


def narx_peer(u: np.ndarray, y: np.ndarray, lags=NARX_LAGS, degrees=NARX_DEGREES) -> PeerResult:
    """The bounded NARX structure with the lowest fit-part free-run RMSE, scored on the held-out part."""
    st = Standardised.of(u, y)
    if st is None:
        return CONSTANT
    ranked, failures, diverged = [], [], 0
    tried = [(lag, degree) for degree in degrees for lag in lags]
    for lag, degree in tried:
        try:
            m = fit_narx(st.u[: st.n_fit], st.y[: st.n_fit], lag, degree)
        except Exception as e:  # noqa: BLE001 - a failing structure is reported, not fatal
            failures.append(f"{lag}/{degree}: {type(e).__name__}")
            continue
        sim = m.simulate(st.u, st.y[0], st.u[0], DIVERGED_FACTOR)
        if not bounded(sim):
            diverged += 1
            continue
        ranked.append((*st.errors(sim), f"lag {lag}, degree {degree} ({len(m.theta)} terms)"))
    if not ranked:
        why = f"all {len(tried)} structures failed ({diverged} diverged"
        return PeerResult(reason=why + (f"; {'; '.join(failures)})" if failures else ")"))
    e_fit, e_held, structure = min(ranked, key=lambda r: r[0])
    remark = f"{diverged} of {len(tried)} diverged" if diverged else ""
    if failures:
        remark += ("; " if remark else "") + f"{len(failures)} failed to fit"
    return PeerResult(structure=structure, heldout_rmse=e_held, fit_rmse=e_fit, reason=remark)


@dataclasses.dataclass
class PeerSet:
    """Both peers on a record at one rate."""

    decimate: int
    n: int
    mean_predictor: float  # the held-out RMSE of predicting the fit part's mean: the bar any model clears
    arx: PeerResult
    narx: PeerResult


def peers_at(rec: Record, factor: int) -> PeerSet:
    u, y = read_record(rec, factor)
    n_fit = split_index(len(y))
    found = []
    for peer in (arx_peer, narx_peer):
        try:
            found.append(peer(u, y))
        except Exception as e:  # noqa: BLE001 - any peer failure becomes a note
            found.append(PeerResult(reason=f"{type(e).__name__}: {e}"))
    return PeerSet(factor, len(y), rmse(y[n_fit:], np.mean(y[:n_fit])), *found)


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


def diagnose_command(binary: str, rec: Record, path: pathlib.Path, structure=None) -> list[str]:
    cmd = [binary, "diagnose", str(path), "--json"]
    if rec.decimate is not None:
        cmd += ["--decimate", str(rec.decimate)]
    cmd += ["--time-col", rec.time_col, "--u-col", rec.u_col, "--y-col", rec.y_col]
    if structure is not None:
        na, nb, d = structure
        cmd += ["--na", str(na), "--nb", str(nb), "--delay", str(d)]
    return cmd


def run_diagnose(binary: str, rec: Record, timeout: float) -> DiagnoseResult:
    """`diagnose` on the record with its settings; a failure is in the result's reason. MissingRecord when
    the record is not in place."""
    path = data_records.record_path(rec.file)
    if not pathlib.Path(binary).is_file():
        return DiagnoseResult(reason=f"{binary} not found: run `cargo build --release`")
    try:
        code, out, err, secs, mib = run_process(diagnose_command(binary, rec, path), timeout)
        chosen_by = "tool"
        if code not in (0, None) and refused_for_structure(err):
            cmd = diagnose_command(binary, rec, path, rec.fallback)
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


# ---------------------------------------------------------------- the committed numbers


def to_json(value):
    """Dataclasses as dicts, NaN as null (the file is plain JSON)."""
    if dataclasses.is_dataclass(value):
        return {k: to_json(v) for k, v in dataclasses.asdict(value).items()}
    if isinstance(value, dict):
        return {k: to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def from_json(cls, doc: dict):
    """The dataclass cls from to_json's dict (null numbers back to NaN; nested PeerResults rebuilt)."""
    kwargs = {}
    for f in dataclasses.fields(cls):
        v = doc.get(f.name)
        if f.type in ("PeerResult",):
            v = from_json(PeerResult, v or {})
        elif f.type == "float":
            v = math.nan if v is None else float(v)
        kwargs[f.name] = v
    return cls(**kwargs)


@dataclasses.dataclass
class Entry:
    """One record's committed measurement: diagnose and the peers at each rate fitted."""

    record: str
    diagnose: DiagnoseResult
    peers: list[PeerSet]

    def peers_at(self, factor: int) -> PeerSet | None:
        return next((p for p in self.peers if p.decimate == factor), None)


def load(path: pathlib.Path = MEASURED) -> dict[str, Entry]:
    if not path.is_file():
        return {}
    doc = json.loads(path.read_text())
    return {
        name: Entry(name, from_json(DiagnoseResult, e["diagnose"]), [from_json(PeerSet, p) for p in e["peers"]])
        for name, e in doc["records"].items()
    }


def save(entries: dict[str, Entry], path: pathlib.Path = MEASURED) -> None:
    order = [r.name for r in RECORDS]
    doc = {
        "about": "written by `python scripts/peer_compare.py --update` (see its help): the measured records' "
        "held-out free-run RMSE of `backlash diagnose` and of the peers, the numbers the ratchet checks",
        "records": {
            name: {
                "command": command_line(record_named(name)),
                "diagnose": to_json(entries[name].diagnose),
                "peers": to_json(entries[name].peers),
            }
            for name in order
            if name in entries
        },
    }
    path.write_text(json.dumps(doc, indent=1) + "\n")


def command_line(rec: Record) -> str:
    """The diagnose command a record is measured with, as a reader types it."""
    return " ".join(diagnose_command("backlash", rec, pathlib.Path("data") / rec.file))


def record_named(name: str) -> Record:
    return next(r for r in RECORDS if r.name == name)


def measure(rec: Record, binary: str, timeout: float, old: Entry | None, refit: bool) -> Entry:
    """diagnose on the record; the peers at the file's rate and at diagnose's, fitted unless `old` has them
    (and refit is off)."""
    print(f"{rec.name}: diagnose ...", file=sys.stderr, flush=True)
    d = run_diagnose(binary, rec, timeout)
    peers = []
    for factor in sorted({1, d.decimate}):
        kept = None if (refit or old is None) else old.peers_at(factor)
        if kept is None:
            print(f"{rec.name}: fitting the peers at decimation {factor} ...", file=sys.stderr, flush=True)
            kept = peers_at(rec, factor)
        peers.append(kept)
    return Entry(rec.name, d, peers)


def ratchet(rec: Record, committed: Entry | None, binary: str, timeout: float) -> tuple[bool, str]:
    """(passed, the line saying why): diagnose again and compare its final held-out error with the committed
    one."""
    d = run_diagnose(binary, rec, timeout)
    if d.reason:
        return False, f"{rec.name}: diagnose failed: {d.reason}"
    if committed is None or not math.isfinite(committed.diagnose.after):
        return False, f"{rec.name}: after.rmse {d.after:.6g}, but no committed number (run --update)"
    was, now = committed.diagnose.after, d.after
    rate = "" if d.decimate == committed.diagnose.decimate else (
        f"; decimation {d.decimate}, committed at {committed.diagnose.decimate}")
    change = f"after.rmse {now:.6g} against the committed {was:.6g} ({(now / was - 1) * 100:+.2f}%{rate})"
    if not now <= was * (1 + RATCHET_TOLERANCE):
        return False, f"{rec.name}: {change}: more than {RATCHET_TOLERANCE:.0%} worse"
    return True, f"{rec.name}: {change}, {d.seconds:.1f} s"


# ---------------------------------------------------------------- table


COLUMNS = [
    "record",
    "N",
    "rate (decimate)",
    "mean predictor",
    "ARX na,nb,d",
    "ARX",
    "NARX structure",
    "NARX",
    "ARX, file's rate",
    "NARX, file's rate",
    "diagnose na,nb,d",
    "linear",
    "before",
    "after",
    "after / best peer",
    "effects",
    "time [s]",
    "notes",
]


def row(entry: Entry) -> dict:
    """The table's row of a record: the peers at diagnose's rate beside it, and at the file's rate."""
    d = entry.diagnose
    at, own = entry.peers_at(d.decimate), entry.peers_at(1)
    r = {c: "" for c in COLUMNS}
    r["record"] = entry.record
    notes = [f"diagnose: {d.reason}"] if d.reason else []
    if at is not None:
        r["N"] = at.n if d.decimate == 1 or own is None else f"{at.n} ({own.n} as given)"
        r["mean predictor"] = fmt(at.mean_predictor)
        r["ARX na,nb,d"], r["ARX"] = at.arx.structure, fmt(at.arx.heldout_rmse)
        r["NARX structure"], r["NARX"] = at.narx.structure, fmt(at.narx.heldout_rmse)
        best = min(at.arx.heldout_rmse, at.narx.heldout_rmse)
        r["after / best peer"] = fmt(d.after / best, 3) if math.isfinite(best) else "n/a"
        notes += [f"{k}: {p.reason}" for k, p in (("ARX", at.arx), ("NARX", at.narx)) if p.reason]
    if own is not None and d.decimate != 1:
        r["ARX, file's rate"], r["NARX, file's rate"] = fmt(own.arx.heldout_rmse), fmt(own.narx.heldout_rmse)
    else:
        r["ARX, file's rate"] = r["NARX, file's rate"] = "same"
    r["rate (decimate)"] = f"{d.decimate} ({d.rate_by})" if d.rate_by else ""
    r["diagnose na,nb,d"] = d.structure + (" (fallback)" if d.chosen_by == "fallback" else "")
    r["linear"], r["before"], r["after"] = fmt(d.linear), fmt(d.before), fmt(d.after)
    r["effects"], r["time [s]"] = d.effects, fmt(d.seconds, 3)
    r["notes"] = "; ".join(notes)
    return r


def fmt(v: float, digits: int = 4) -> str:
    if v is None or not math.isfinite(v):
        return "n/a"
    return f"{v:.{digits}g}"


def markdown(rows: list[dict]) -> str:
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
    for r in rows:
        lines.append("| " + " | ".join(str(r[c]).replace("|", "/") for c in COLUMNS) + " |")
    return "\n".join(lines)


def absent_optional(rec: Record) -> bool:
    """A record of the optional set that is not in place (a missing record of the default set is not this)."""
    if not rec.optional:
        return False
    try:
        data_records.record_path(rec.file)
    except data_records.MissingRecord:
        return True
    return False


def in_place(chosen: list[Record], skip_absent: bool) -> list[Record]:
    """The chosen records, without the optional ones not in place when skip_absent (each skip said on
    stderr)."""
    kept = []
    for rec in chosen:
        if skip_absent and absent_optional(rec):
            print(f"skipped {rec.name}: {rec.file} is not in place (optional set: "
                  f"`{data_records.FETCH_COMMAND} --extra` fetches it)", file=sys.stderr, flush=True)
            continue
        kept.append(rec)
    return kept


def run_ratchet(chosen: list[Record], committed: dict[str, Entry], binary: str, timeout: float) -> int:
    failed = []
    for rec in chosen:
        ok, line = ratchet(rec, committed.get(rec.name), binary, timeout)
        print(("ok      " if ok else "FAILED  ") + line, flush=True)
        if not ok:
            failed.append(line)
    if failed:
        print(f"error: the ratchet failed on {len(failed)} of {len(chosen)} records (a final held-out error more "
              f"than {RATCHET_TOLERANCE:.0%} above {MEASURED.relative_to(ROOT)}):", file=sys.stderr)
        for line in failed:
            print(f"  {line}", file=sys.stderr)
        print("  if the change is meant, `python scripts/peer_compare.py --update` writes the new numbers",
              file=sys.stderr)
        return 1
    print(f"the ratchet passed on all {len(chosen)} records")
    return 0


def main(argv=None) -> int:
    names = [r.name for r in RECORDS]
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--records", nargs="+", metavar="NAME", help=f"records to run (default all: {', '.join(names)})")
    p.add_argument("--backlash", default=str(ROOT / "target" / "release" / "backlash"), help="the CLI program")
    p.add_argument("--timeout", type=float, default=120.0, help="seconds one diagnose run may take (120)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--ratchet", action="store_true",
                      help="run diagnose on every record; exit 1 where after.rmse is more than 2%% above the "
                      "committed number")
    mode.add_argument("--update", action="store_true",
                      help="run diagnose on every record and write the numbers into docs/measured_records.json")
    p.add_argument("--refit-peers", action="store_true", help="with --update: fit the peers again too")
    p.add_argument("--csv", metavar="FILE", help="also write the table as CSV")
    a = p.parse_args(argv)
    unknown = [n for n in (a.records or []) if n not in names]
    if unknown:
        p.error(f"unknown record {', '.join(unknown)}; known: {', '.join(names)}")
    chosen = [r for r in RECORDS if not a.records or r.name in a.records]
    entries = load()
    try:
        if a.ratchet:
            return run_ratchet(in_place(chosen, not a.records), entries, a.backlash, a.timeout)
        if a.update:
            for rec in in_place(chosen, not a.records):
                entries[rec.name] = measure(rec, a.backlash, a.timeout, entries.get(rec.name), a.refit_peers)
            save(entries)
    except data_records.MissingRecord as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    missing = [r.name for r in chosen if r.name not in entries]
    if missing:
        print(f"error: no committed numbers for {', '.join(missing)}: run with --update", file=sys.stderr)
        return 1
    rows = [row(entries[r.name]) for r in chosen]
    print(markdown(rows))
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
