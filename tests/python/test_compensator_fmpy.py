"""The adaptive compensation loop in FMPy: BacklashPlant.fmu, MrgiaEstimator.fmu (recommended, refine, a
memory) and BacklashCompensator.fmu, the estimator's outputs connected to the compensator's inputs by name, and
the linear block's feed-forward inverse in this master (as the library's loop does it, src/compensate/adaptive.rs).
The same numbers as `backlash compensate --json` on the same reference."""
import json
import subprocess

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2Real, fmi2ValueReference, fmi2Warning
from fmpy.validation import validate_fmu

from conftest import FMU_DIR, FMU3_DIR, LOG, _need

PAPER = {"a": [0.45, 0.55], "b": [0.8], "delay": 1, "c1": 0.5, "c2": 1.0}
ESTIMATES = ["a1", "a2", "b0", "m2", "c1", "c2"]
WARMUP = 500  # the refined estimator's warm-up (src/identify/oe/online.rs), before which the loop uses theta(0)


@pytest.fixture(scope="session")
def compensator_fmu():
    return _need(FMU_DIR / "BacklashCompensator.fmu")


def _stable(poly):
    """Every root of poly (highest power first, leading 1) strictly inside the unit circle."""
    return len(poly) < 2 or bool(np.all(np.abs(np.roots(poly)) < 1.0))


def _invertible(a, b):
    """The library's `invertible`: finite, b0 away from 0, A stable, B minimum phase."""
    if not np.all(np.isfinite(a + b)) or abs(b[0]) <= 1e-6 * max(abs(x) for x in b):
        return False
    return _stable([1.0] + list(a)) and _stable([1.0] + [x / b[0] for x in b[1:]])


class _Fmu:
    def __init__(self, path, name, start):
        self.md = read_model_description(path)
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.types = {v.name: v.type for v in self.md.modelVariables}
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=extract(path),
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate(callbacks=LOG.callbacks)
        self.fmu.setupExperiment(startTime=0.0)
        for k, v in start.items():
            if self.types[k] == "Boolean":
                self.fmu.setBoolean([self.vr[k]], [bool(v)])
            elif self.types[k] == "Integer":
                self.fmu.setInteger([self.vr[k]], [int(v)])
            else:
                self.fmu.setReal([self.vr[k]], [float(v)])
        self.fmu.enterInitializationMode()
        self.fmu.exitInitializationMode()

    def get(self, names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def set(self, values):
        self.fmu.setReal([self.vr[n] for n in values], [float(x) for x in values.values()])


def run_loop(plant_fmu, estimator_fmu, compensator_fmu, r, noise_std, ramp, memory):
    """The adaptive loop of the library (adaptive.rs) with the three FMUs; returns y."""
    n, d = len(r), PAPER["delay"]
    plant = _Fmu(plant_fmu, "plant", {"noise_std": noise_std, "noise_seed": 0})
    est = _Fmu(estimator_fmu, "estimator", {"recommended": True, "refine": True, "rho_min": 1.0 / memory})
    comp = _Fmu(compensator_fmu, "compensator", {})
    a, b = [0.0, 0.0], [1.0]  # the estimator's theta(0): x(k) = u(k - d)
    x_hist, u_hist = [0.0] * 4, [0.0] * 4
    y = np.empty(n)
    for k in range(n):
        f = 1.0 + ramp * k / n
        plant.set({"c1": PAPER["c1"] * f, "c2": PAPER["c2"] * f})
        a1, a2, b0, m2, c1, c2 = est.get(ESTIMATES)
        warm = k < WARMUP
        if not warm and _invertible([a1, a2], [b0]):
            a, b = [a1, a2], [b0]
        rk = r[min(k + d, n - 1)]
        comp.set({"r": rk, "m2": m2, "c1": c1, "c2": c2})
        # During the estimator's warm-up the compensator runs but its v is not used (adaptive.rs).
        v = rk if warm else comp.get(["v"])[0]
        acc = v
        for i, ai in enumerate(a):
            acc += ai * x_hist[i]
        for j, bj in enumerate(b[1:], start=1):
            acc -= bj * u_hist[j - 1]
        uk = acc / b[0]
        x_hist, u_hist = [v] + x_hist[:-1], [uk] + u_hist[:-1]
        y[k] = plant.get(["y"])[0]
        plant.set({"u": uk})
        est.set({"u": uk, "y": y[k]})
        for s in (plant, est, comp):
            s.fmu.doStep(k * 1.0, 1.0)  # FMPy raises above fmi2Warning
    for s in (plant, est, comp):
        s.fmu.terminate()
        s.fmu.freeInstance()
    return y


def test_the_compensator_fmus_validate():
    for folder in (FMU_DIR, FMU3_DIR):
        assert validate_fmu(_need(folder / "BacklashCompensator.fmu")) == []


def write_reference(path, n):
    """The loops' reference: low-pass noise of std 1.5 (AR(1), pole 0.9, seed 5), written as `time,r` to
    `path`; returns it."""
    e = np.random.default_rng(5).standard_normal(n)
    r = np.empty(n)
    r[0] = 1.5 * e[0]
    for k in range(1, n):
        r[k] = 0.9 * r[k - 1] + 1.5 * np.sqrt(1 - 0.81) * e[k]
    np.savetxt(path, np.column_stack([np.arange(n, dtype=float), r]), delimiter=",", header="time,r",
               comments="", fmt="%.17g")
    return r


def test_the_fmu_loop_gives_the_library_loops_numbers(plant_fmu, estimator_fmu, compensator_fmu, cli, tmp_path):
    n, noise, memory = 3000, 0.02, 500
    path = tmp_path / "reference.csv"
    r = write_reference(path, n)
    out = subprocess.run([cli, "compensate", str(path), "--noise-std", str(noise), "--wear", "ramp",
                          "--wear-ratio", "0.5", "--memory", str(memory), "--modes", "adaptive", "--json"],
                         capture_output=True, text=True, check=True)
    lib = json.loads(out.stdout)["modes"]["adaptive"]
    y = run_loop(plant_fmu, estimator_fmu, compensator_fmu, r, noise, 0.5, memory)
    rmse = float(np.sqrt(np.mean((y - r) ** 2)))
    q = n - n // 4
    last = float(np.sqrt(np.mean((y[q:] - r[q:]) ** 2)))
    assert abs(rmse - lib["rmse"]) <= 1e-9 * lib["rmse"], (rmse, lib["rmse"])
    assert abs(last - lib["rmse_last_quarter"]) <= 1e-9 * lib["rmse_last_quarter"], (last, lib)


def test_a_degenerate_estimate_answers_warning_and_a_log_line(compensator_fmu):
    comp = _Fmu(compensator_fmu, "degenerate", {})
    LOG.lines.clear()
    comp.fmu.setDebugLogging(True, [])
    comp.set({"r": 1.0, "m2": -1.0})
    vr, value = (fmi2ValueReference * 1)(comp.vr["v"]), (fmi2Real * 1)()
    # FMPy's wrapper returns the status (it raises only above fmi2Warning).
    assert comp.fmu.fmi2GetReal(comp.fmu.component, vr, 1, value) == fmi2Warning
    assert np.isfinite(value[0])
    assert any("m2 = -1 is not a positive number" in m for _, _, m in LOG.lines), LOG.lines
    assert np.isfinite(comp.get(["v"])[0])
    comp.fmu.terminate()
    comp.fmu.freeInstance()


def test_fmi2_and_fmi3_invert_the_backlash_exactly_in_fmpys_simulate_fmu():
    """FMPy's own master (simulate_fmu, one step of Ts per sample): the backlash of v is r at every sample, and
    the FMI 3.0 variant gives the same v."""
    from fmpy import simulate_fmu

    rng = np.random.default_rng(3)
    n = 200
    names = [("time", float), ("r", float), ("m2", float), ("c1", float), ("c2", float)]
    signals = np.array([(k, x, 1.5, 0.5, 1.0) for k, x in enumerate(rng.uniform(-2, 2, n))], dtype=names)
    runs = [simulate_fmu(_need(folder / "BacklashCompensator.fmu"), input=signals, stop_time=n - 1,
                         step_size=1.0, output_interval=1.0, output=["r", "v", "w"])
            for folder in (FMU_DIR, FMU3_DIR)]
    for res in runs:
        w = 0.0
        for r, v in zip(res["r"], res["v"]):
            # The backlash of the paper (m1 1, m2 1.5, c1 0.5, c2 1) on v from w.
            w = v - 0.5 if v > w + 0.5 else 1.5 * (v + 1.0) if v < w / 1.5 - 1.0 else w
            assert abs(w - r) < 1e-9, (r, v, w)
    assert np.array_equal(runs[0]["v"], runs[1]["v"])


def test_fmi3_a_degenerate_estimate_answers_warning_and_a_log_line():
    from fmpy.fmi3 import FMU3Slave, fmi3Float64, fmi3ValueReference, fmi3Warning

    from conftest import LOG3

    path = _need(FMU3_DIR / "BacklashCompensator.fmu")
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=extract(path),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="degenerate3")
    fmu.instantiate(loggingOn=True, logMessage=LOG3.record)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    LOG3.lines.clear()
    fmu.setFloat64([vr["r"], vr["m2"]], [1.0, -1.0])
    refs, value = (fmi3ValueReference * 1)(vr["v"]), (fmi3Float64 * 1)()
    assert fmu.fmi3GetFloat64(fmu.component, refs, 1, value, 1) == fmi3Warning
    # No valid estimate yet: the identity's inverse, v = r.
    assert value[0] == 1.0
    assert any(c == "logStatusWarning" and "m2 = -1 is not a positive number" in m for _, c, m in LOG3.lines)
    fmu.terminate()
    fmu.freeInstance()
