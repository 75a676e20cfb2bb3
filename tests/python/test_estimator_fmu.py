"""MrgiaEstimator.fmu on its own through FMPy: validation, FMU state mid-run, refusals."""
import shutil

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

import reference
from conftest import LOG

EST = ["a1", "a2", "b0", "m2", "c1", "c2"]


@pytest.fixture(scope="module")
def unzipped(estimator_fmu):
    d = extract(estimator_fmu)
    yield d
    shutil.rmtree(d, ignore_errors=True)


def _vrs(path):
    return {v.name: v.valueReference for v in read_model_description(path).modelVariables}


def _slave(path, unzipped, name="est"):
    md = read_model_description(path)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="MrgiaEstimator", instanceName=name)
    s.instantiate(callbacks=LOG.callbacks)
    return s


def _data(n, seed=0):
    u = np.random.default_rng(seed).uniform(-np.sqrt(3 * 1.93), np.sqrt(3 * 1.93), n)
    _, w = reference.simulate(u)
    return u, w


def _feed(s, vr, u, y, k0=0):
    est = []
    for k in range(len(u)):
        s.setReal([vr["u"], vr["y"]], [u[k], y[k]])
        s.doStep(float(k0 + k), 1.0)
        est.append(s.getReal([vr[n] for n in EST] + [vr["y_hat"], vr["e"]]))
    return np.array(est)


def test_validate_fmu_reports_nothing(estimator_fmu):
    assert validate_fmu(estimator_fmu) == []


def test_defaults_are_the_papers_settings(estimator_fmu):
    md = read_model_description(estimator_fmu)
    start = {v.name: v.start for v in md.modelVariables if v.causality == "parameter"}
    assert start["P0"] == "1000000.0" or float(start["P0"]) == 1e6
    assert float(start["rho_exp"]) == 0.25
    assert float(start["rho_min"]) == 0.0
    assert float(start["Sigma0"]) == 1.0
    assert start["recommended"] in ("false", False)
    assert start["refine"] in ("false", False)
    assert start["monitor"] in ("false", False)
    assert float(start["wear_ratio"]) == 0.1
    assert float(start["alarm_period"]) == 1e6
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    estimates = {"a1", "a2", "a3", "a4", "b0", "b1", "b2", "b3", "b4", "m2", "c1", "c2"}
    wear = {"play", "play_se", "wear_statistic", "wear_alarm", "wear_onset"}
    assert outputs == estimates | {f"{n}_se" for n in estimates} | {"y_hat", "e", "updating"} | wear


def test_fmu_state_mid_run_is_bit_identical(estimator_fmu, unzipped):
    vr = _vrs(estimator_fmu)
    u, y = _data(1200, seed=3)
    s = _slave(estimator_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _feed(s, vr, u[:400], y[:400])
    state = s.getFMUstate()
    first = _feed(s, vr, u[400:], y[400:], k0=400)
    s.setFMUstate(state)
    second = _feed(s, vr, u[400:], y[400:], k0=400)
    assert first.tobytes() == second.tobytes()
    blob = s.serializeFMUstate(state)
    s.freeFMUstate(state)
    # A truncated or corrupted state is refused with fmi2Error, not a crash.
    with pytest.raises(FMICallException):
        s.deSerializeFMUstate(blob[: len(blob) // 2])
    assert "truncated or corrupted" in LOG.lines[-1][2]
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    restored = s.deSerializeFMUstate(blob)
    s.setFMUstate(restored)
    third = _feed(s, vr, u[400:], y[400:], k0=400)
    assert first.tobytes() == third.tobytes()
    s.freeFMUstate(restored)
    s.freeInstance()


def test_a_plant_state_is_refused_by_the_estimator(estimator_fmu, plant_fmu, unzipped):
    pdir = extract(plant_fmu)
    try:
        md = read_model_description(plant_fmu)
        p = FMU2Slave(guid=md.guid, unzipDirectory=pdir, modelIdentifier="BacklashPlant", instanceName="p")
        p.instantiate(callbacks=LOG.callbacks)
        p.setupExperiment(startTime=0.0)
        p.enterInitializationMode()
        p.exitInitializationMode()
        blob = p.serializeFMUstate(p.getFMUstate())
        p.freeInstance()
        s = _slave(estimator_fmu, unzipped)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        with pytest.raises(FMICallException):
            s.deSerializeFMUstate(blob)
        assert "belongs to another FMU" in LOG.lines[-1][2]
        s.freeInstance()
    finally:
        shutil.rmtree(pdir, ignore_errors=True)


def test_one_sample_per_step(estimator_fmu, unzipped):
    vr = _vrs(estimator_fmu)
    s = _slave(estimator_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    s.setReal([vr["Ts"]], [0.01])
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.doStep(0.0, 0.01)
    with pytest.raises(FMICallException) as info:
        s.doStep(0.01, 0.02)  # reaches t = 0.02 and 0.03: cut at 0.02
    assert info.value.status == 2  # fmi2Discard
    assert "takes at most 1 per step, so it stopped at t = 0.02" in LOG.lines[-1][2]
    assert s.getRealStatus(2) == 0.02  # fmi2LastSuccessfulTime
    s.freeInstance()


@pytest.mark.parametrize(
    "name,value",
    [("P0", 0.0), ("rho_exp", 1.5), ("rho_min", 1.0), ("eps", -1.0), ("Sigma0", float("nan")), ("c_init", float("inf"))],
)
def test_bad_settings_are_refused(estimator_fmu, unzipped, name, value):
    vr = _vrs(estimator_fmu)
    s = _slave(estimator_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    with pytest.raises(FMICallException):
        s.setReal([vr[name]], [value])
    assert LOG.lines[-1][0] == 3 and f"'{name}'" in LOG.lines[-1][2]
    s.freeInstance()


def test_nan_inputs_are_refused_mid_run(estimator_fmu, unzipped):
    vr = _vrs(estimator_fmu)
    s = _slave(estimator_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.setReal([vr["u"], vr["y"]], [0.5, 0.1])
    s.doStep(0.0, 1.0)
    with pytest.raises(FMICallException):
        s.setReal([vr["y"]], [float("nan")])
    assert LOG.lines[-1] == (3, "logStatusError", "fmi2SetReal: 'y' = NaN is not a finite number")
    s.freeInstance()
