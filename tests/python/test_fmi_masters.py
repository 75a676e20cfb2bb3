"""Both FMUs driven as FMI masters drive them with their defaults (docs/INTERFACE.md, "What masters can expect").

Step patterns measured in the tools: the FMU Compliance Checker steps (stop - start) / 500 of the default
experiment; OMSimulator 1e-3; PyFMI 0.01 with error control halving the step; masters that keep the step in a
float32; a step of n Ts. The values at the sample instants t_k = k Ts must equal those of a run stepped by
exactly Ts, bit for bit. Also: a wrong FMU-state pointer (in a subprocess, where a crash cannot take pytest
down), percent signs in logged messages, and the packaged binaries (no debug information, no GLIBC symbol
newer than 2.17).
"""
import re
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Discard, fmi2LastSuccessfulTime

from conftest import LOG
from backlash_fmu.cosim import ESTIMATE_NAMES, _Slave, max_rel_error, paper_input, run_pair

PLANT_OUT = ["y", "w", "x"]


def start(path, name, params, stop=None):
    s = _Slave(path, name, LOG.callbacks)
    s.fmu.setupExperiment(startTime=0.0, stopTime=stop)
    s.set_start(params)
    s.fmu.enterInitializationMode()
    s.fmu.exitInitializationMode()
    return s


def vrs(slave, names):
    return [slave.vr(n) for n in names]


def plant_at_instants(plant_fmu, ts, u, points, params=None, noise=None):
    """The plant stepped through the communication points `points` (from 0). At a point that is an instant
    (index i with points[i] == the master's idea of k Ts, given by `instant_of[i]`) the master sets u(k); at
    the points in between it sets `noise` (if given), which the plant must ignore. Returns the outputs after
    each step as rows, with the sample index k the step ended at (None between instants)."""
    p = start(plant_fmu, "plant", {"Ts": ts, **(params or {})})
    try:
        rows = []
        for i in range(len(points) - 1):
            t, h = points[i], points[i + 1] - points[i]
            k = points_instant(points, ts, i)
            value = u[k] if k is not None else noise
            if value is not None:
                p.fmu.setReal(vrs(p, ["u"]), [float(value)])
            p.fmu.doStep(t, h)
            rows.append(p.fmu.getReal(vrs(p, PLANT_OUT)))
        return rows
    finally:
        p.free()


def points_instant(points, ts, i):
    """The sample index k if points[i] is the instant k Ts (within the master's rounding), else None."""
    k = round(points[i] / ts)
    return k if abs(points[i] - k * ts) <= 1e-7 * max(abs(points[i]), ts) else None


def plant_reference(plant_fmu, ts, u, params=None):
    """Outputs after each step of exactly Ts (row k: the outputs at t_{k+1})."""
    points = [k * ts for k in range(len(u) + 1)]
    return plant_at_instants(plant_fmu, ts, u, points, params)


def float_sum(h, n):
    """The master's clock: a float64 running sum of n steps of h."""
    t, out = 0.0, [0.0]
    for _ in range(n):
        t += h
        out.append(t)
    return out


def test_default_experiment_gives_the_checker_a_step_of_ts(plant_fmu, estimator_fmu):
    for path in (plant_fmu, estimator_fmu):
        md = read_model_description(path)
        ex = md.defaultExperiment
        ts = next(float(v.start) for v in md.modelVariables if v.name == "Ts")
        checker_step = (float(ex.stopTime) - float(ex.startTime)) / 500
        assert float(ex.stepSize) == ts
        assert checker_step == ts, f"{path}: the checker would step {checker_step} with Ts = {ts}"


def test_checker_default_run_of_both_fmus(plant_fmu, estimator_fmu):
    """The whole default experiment at the checker's step, both FMUs wired as a pair: no refusal."""
    md = read_model_description(plant_fmu)
    h = (float(md.defaultExperiment.stopTime) - float(md.defaultExperiment.startTime)) / 500
    u = paper_input(500, 3)
    want = run_pair(plant_fmu, estimator_fmu, u, record_every=1)
    p = start(plant_fmu, "plant", {}, stop=float(md.defaultExperiment.stopTime))
    e = start(estimator_fmu, "estimator", {}, stop=float(md.defaultExperiment.stopTime))
    try:
        rows = []
        for k in range(500):
            y = p.fmu.getReal(vrs(p, ["y"]))[0]
            p.fmu.setReal(vrs(p, ["u"]), [u[k]])
            e.fmu.setReal(vrs(e, ["u", "y"]), [u[k], y])
            p.fmu.doStep(k * h, h)
            e.fmu.doStep(k * h, h)
            rows.append(e.fmu.getReal(vrs(e, ESTIMATE_NAMES)))
        assert np.array_equal(np.array(rows), want["estimates"])
    finally:
        p.free()
        e.free()


@pytest.mark.parametrize("ts, h", [(1.0, 0.02), (1.0, 1e-3), (1.0, 0.25), (0.1, 0.1 / 3), (0.5, 0.01)])
def test_plant_sub_steps_match_ts_stepping_at_the_instants(plant_fmu, ts, h):
    n = 40
    u = paper_input(n, 5)
    want = plant_reference(plant_fmu, ts, u)
    m = round(ts / h)
    points = float_sum(h, n * m)
    got = plant_at_instants(plant_fmu, ts, u, points, noise=123.0)
    at_instants = [got[i] for i in range(len(got)) if points_instant(points, ts, i + 1) is not None]
    assert np.array_equal(np.array(at_instants), np.array(want))
    # Between instants the outputs hold the last sample's values.
    for i in range(1, len(got)):
        if points_instant(points, ts, i + 1) is None:
            assert got[i] == got[i - 1], f"sub-step {i}"


def test_plant_stepped_by_n_ts_holds_the_input(plant_fmu):
    ts, n_per, steps = 0.5, 2, 60
    u = paper_input(steps, 6)
    held = np.repeat(u, n_per)
    want = plant_reference(plant_fmu, ts, held)
    points = [j * n_per * ts for j in range(steps + 1)]
    p = start(plant_fmu, "plant", {"Ts": ts})
    try:
        for j in range(steps):
            p.fmu.setReal(vrs(p, ["u"]), [u[j]])
            p.fmu.doStep(points[j], n_per * ts)
            assert p.fmu.getReal(vrs(p, PLANT_OUT)) == want[(j + 1) * n_per - 1]
    finally:
        p.free()


def pair_substeps(plant_fmu, estimator_fmu, u, ts, points):
    """The pair as a master that exchanges values at every communication point (OMSimulator, PyFMI): u(k)
    from a discrete source that changes at the instants, the plant's y copied to the estimator at every point.
    Returns the estimates at each instant the master reaches."""
    p = start(plant_fmu, "plant", {"Ts": ts})
    e = start(estimator_fmu, "estimator", {"Ts": ts})
    try:
        rows = []
        for i in range(len(points) - 1):
            t, h = points[i], points[i + 1] - points[i]
            k = int(np.floor(t / ts + 1e-7))
            y = p.fmu.getReal(vrs(p, ["y"]))[0]
            p.fmu.setReal(vrs(p, ["u"]), [u[min(k, len(u) - 1)]])
            e.fmu.setReal(vrs(e, ["u", "y"]), [u[min(k, len(u) - 1)], y])
            p.fmu.doStep(t, h)
            e.fmu.doStep(t, h)
            if points_instant(points, ts, i + 1) is not None:
                rows.append(e.fmu.getReal(vrs(e, ESTIMATE_NAMES)))
        return np.array(rows)
    finally:
        p.free()
        e.free()


def test_pair_at_quarter_ts_converges_exactly_like_the_ts_pair(plant_fmu, estimator_fmu):
    n = 3000
    u = paper_input(n, 0)
    want = run_pair(plant_fmu, estimator_fmu, u, record_every=1)["estimates"]
    got = pair_substeps(plant_fmu, estimator_fmu, u, 1.0, float_sum(0.25, 4 * n))
    assert np.array_equal(got, want)
    assert max_rel_error(got[-1]) < 1e-6


def test_pair_at_omsimulator_default_step(plant_fmu, estimator_fmu):
    n = 30
    u = paper_input(n, 1)
    want = run_pair(plant_fmu, estimator_fmu, u, record_every=1)["estimates"]
    got = pair_substeps(plant_fmu, estimator_fmu, u, 1.0, float_sum(1e-3, 1000 * n))
    assert np.array_equal(got, want)


def test_pair_under_pyfmi_error_control(plant_fmu, estimator_fmu):
    """Steps of 0.01 that the master sometimes rejects and retries at half size (state saved and restored)."""
    n, ts = 20, 1.0
    u = paper_input(n, 2)
    want = run_pair(plant_fmu, estimator_fmu, u, record_every=1)["estimates"]
    p = start(plant_fmu, "plant", {"Ts": ts})
    e = start(estimator_fmu, "estimator", {"Ts": ts})
    try:
        rows, t, step = [], 0.0, 0
        while len(rows) < n:
            k = int(np.floor(t / ts + 1e-7))
            y = p.fmu.getReal(vrs(p, ["y"]))[0]
            p.fmu.setReal(vrs(p, ["u"]), [u[k]])
            e.fmu.setReal(vrs(e, ["u", "y"]), [u[k], y])
            h = min(0.01, (k + 1) * ts - t)
            if step % 7 == 3:  # a rejected trial step: saved, tried, restored, retried at half size
                saved = [s.fmu.getFMUstate() for s in (p, e)]
                for s in (p, e):
                    s.fmu.doStep(t, h)
                for s, st in zip((p, e), saved):
                    s.fmu.setFMUstate(st)
                    s.fmu.freeFMUstate(st)
                h /= 2
            for s in (p, e):
                s.fmu.doStep(t, h)
            t += h
            step += 1
            if abs(t - round(t / ts) * ts) <= 1e-7 * max(t, ts):
                rows.append(e.fmu.getReal(vrs(e, ESTIMATE_NAMES)))
        assert np.array_equal(np.array(rows), want)
    finally:
        p.free()
        e.free()


def test_float32_steps_match_ts_stepping(plant_fmu, estimator_fmu):
    """h = float32(0.1) = 0.10000000149, summed in float64: one sample per step, the Ts values."""
    n, ts = 2000, 0.1
    h = float(np.float32(ts))
    assert h != ts
    u = paper_input(n, 4)
    want = run_pair(plant_fmu, estimator_fmu, u, ts=ts, record_every=1)["estimates"]
    points = float_sum(h, n)
    got = pair_substeps(plant_fmu, estimator_fmu, u, ts, points)
    assert len(got) == n
    assert np.array_equal(got, want)


def test_estimator_step_over_several_instants_is_discarded_at_the_first(estimator_fmu):
    """Ts = 0.5 with the default experiment's step 1: the estimator answers fmi2Discard and stops at t = 0.5."""
    e = start(estimator_fmu, "estimator", {"Ts": 0.5})
    try:
        e.fmu.setReal(vrs(e, ["u", "y"]), [1.0, 0.0])
        with pytest.raises(FMICallException) as info:
            e.fmu.doStep(0.0, 1.0)
        assert info.value.status == fmi2Discard
        assert e.fmu.getRealStatus(fmi2LastSuccessfulTime) == 0.5
        status, category, message = LOG.lines[-1]
        assert (status, category) == (fmi2Discard, "logStatusDiscard")
        assert "at most 1" in message and "t = 0.5" in message
        e.fmu.terminate()
    finally:
        e.free()


WRONG_POINTER = r"""
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
class Callbacks(ctypes.Structure):
    _fields_ = [("logger", ctypes.c_void_p), ("allocate", ctypes.c_void_p), ("free", ctypes.c_void_p),
                ("step_finished", ctypes.c_void_p), ("env", ctypes.c_void_p)]
lib.fmi2Instantiate.restype = ctypes.c_void_p
lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p,
                                ctypes.POINTER(Callbacks), ctypes.c_int, ctypes.c_int]
cb = Callbacks()
c = ctypes.c_void_p(lib.fmi2Instantiate(b"x", 1, sys.argv[2].encode(), None, ctypes.byref(cb), 0, 0))
assert c.value
for f in (lib.fmi2EnterInitializationMode, lib.fmi2ExitInitializationMode):
    assert f(c) == 0
state = ctypes.c_void_p()
assert lib.fmi2GetFMUstate(c, ctypes.byref(state)) == 0
# fmusim 0.0.39: the state itself where its address is expected.
print("value", lib.fmi2FreeFMUstate(c, state))
print("reset", lib.fmi2Reset(c))
print("address", lib.fmi2FreeFMUstate(c, ctypes.byref(state)), state.value)
lib.fmi2FreeInstance(c)
"""


@pytest.mark.parametrize("which", ["plant", "estimator"])
def test_state_passed_instead_of_its_address_does_not_crash(plant_fmu, estimator_fmu, tmp_path, which):
    path = plant_fmu if which == "plant" else estimator_fmu
    md = read_model_description(path)
    with zipfile.ZipFile(path) as z:
        so = z.extract(f"binaries/linux64/{md.coSimulation.modelIdentifier}.so", tmp_path)
    r = subprocess.run([sys.executable, "-c", WRONG_POINTER, so, md.guid], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:3] == ["value 3", "reset 0", "address 0 None"]


def test_percent_signs_in_messages_reach_the_logger_intact(plant_fmu):
    name = "plant 100% %s %d"
    p = start(plant_fmu, name, {})
    try:
        with pytest.raises(FMICallException):
            p.fmu.doStep(7.0, 1.0)
        status, category, message = LOG.lines[-1]
        assert category == "logStatusError"
        assert "currentCommunicationPoint 7 is not the instance's time 0" in message
        p.fmu.reset()
        with pytest.raises(FMICallException):
            p.fmu.exitInitializationMode()
        assert f"'{name}'" in LOG.lines[-1][2]
    finally:
        p.free()


def glibc_versions(so):
    out = subprocess.run(["objdump", "-T", so], capture_output=True, text=True, check=True).stdout
    return sorted({tuple(int(x) for x in v.split(".")) for v in re.findall(r"GLIBC_([0-9.]+)", out)})


@pytest.mark.parametrize("which", ["plant", "estimator"])
def test_packaged_binary_is_stripped_and_needs_glibc_2_17_at_most(plant_fmu, estimator_fmu, tmp_path, which):
    path = plant_fmu if which == "plant" else estimator_fmu
    md = read_model_description(path)
    with zipfile.ZipFile(path) as z:
        so = z.extract(f"binaries/linux64/{md.coSimulation.modelIdentifier}.so", tmp_path)
    sections = subprocess.run(["readelf", "-S", "-W", so], capture_output=True, text=True, check=True).stdout
    assert ".debug_" not in sections, "debug information in the FMU's binary"
    assert ".symtab" not in sections, "the FMU's binary is not stripped"
    newest = glibc_versions(so)[-1]
    assert newest <= (2, 17), f"needs GLIBC {'.'.join(map(str, newest))}: build with scripts/setup.sh's zig"
