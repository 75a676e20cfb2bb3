"""The FMI 3.0 FMUs (target/fmu3) through FMPy: validation, exports, the plant bit for bit against the FMI 2.0
plant and the NumPy reference, FMU state, refusals, and the pair through FMU3Slave."""
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

import reference
from conftest import LOG3
from backlash_fmu.cosim import _callbacks, _Slave, max_rel_error, paper_input, run_pair

# Every function of the standard's fmi3Functions.h: the common and co-simulation functions, and those of model
# exchange and scheduled execution (answering "not provided"), since FMPy loads all of them whatever the interface.
FMI3_EXPORTS = sorted(
    ["fmi3GetVersion", "fmi3SetDebugLogging", "fmi3InstantiateModelExchange", "fmi3InstantiateCoSimulation",
     "fmi3InstantiateScheduledExecution", "fmi3FreeInstance", "fmi3EnterInitializationMode",
     "fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3Terminate", "fmi3Reset"]
    + [f"fmi3{d}{t}" for d in ("Get", "Set") for t in ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16",
                                                      "Int32", "UInt32", "Int64", "UInt64", "Boolean", "String",
                                                      "Binary", "Clock")]
    + ["fmi3GetNumberOfVariableDependencies", "fmi3GetVariableDependencies", "fmi3GetFMUState",
       "fmi3SetFMUState", "fmi3FreeFMUState", "fmi3SerializedFMUStateSize", "fmi3SerializeFMUState",
       "fmi3DeserializeFMUState", "fmi3GetDirectionalDerivative", "fmi3GetAdjointDerivative",
       "fmi3EnterConfigurationMode", "fmi3ExitConfigurationMode", "fmi3GetIntervalDecimal",
       "fmi3GetIntervalFraction", "fmi3GetShiftDecimal", "fmi3GetShiftFraction", "fmi3SetIntervalDecimal",
       "fmi3SetIntervalFraction", "fmi3SetShiftDecimal", "fmi3SetShiftFraction", "fmi3EvaluateDiscreteStates",
       "fmi3UpdateDiscreteStates", "fmi3EnterStepMode", "fmi3GetOutputDerivatives", "fmi3DoStep"]
    + ["fmi3EnterContinuousTimeMode", "fmi3CompletedIntegratorStep", "fmi3SetTime", "fmi3SetContinuousStates",
       "fmi3GetContinuousStateDerivatives", "fmi3GetEventIndicators", "fmi3GetContinuousStates",
       "fmi3GetNominalsOfContinuousStates", "fmi3GetNumberOfEventIndicators", "fmi3GetNumberOfContinuousStates",
       "fmi3ActivateModelPartition"]
)


def test_both_fmi3_fmus_validate(plant_fmu3, estimator_fmu3):
    for path in (plant_fmu3, estimator_fmu3):
        assert validate_fmu(path) == [], path
        md = read_model_description(path)
        assert md.fmiVersion == "3.0" and md.coSimulation is not None and md.modelExchange is None


def test_fmi3_descriptions_carry_the_fmi2_variables(plant_fmu, plant_fmu3, estimator_fmu, estimator_fmu3):
    """Same names, value references, causalities, starts; Real -> Float64, Integer -> Int32; plus 'time'."""
    types = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}
    for two, three in ((plant_fmu, plant_fmu3), (estimator_fmu, estimator_fmu3)):
        md2, md3 = read_model_description(two), read_model_description(three)
        assert md3.instantiationToken == md2.guid
        v3 = {v.name: v for v in md3.modelVariables}
        assert v3.pop("time").causality == "independent"
        assert sorted(v3) == sorted(v.name for v in md2.modelVariables)
        for v in md2.modelVariables:
            w = v3[v.name]
            assert (w.valueReference, w.causality, w.variability, w.start, w.min, w.max, types[v.type]) == (
                v.valueReference, v.causality, v.variability, v.start, v.min, v.max, w.type), v.name


def test_binary_exports_exactly_the_fmi3_functions(plant_fmu3, tmp_path):
    with zipfile.ZipFile(plant_fmu3) as z:
        z.extract("binaries/x86_64-linux/BacklashPlant.so", tmp_path)
    so = tmp_path / "binaries/x86_64-linux/BacklashPlant.so"
    out = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True)
    names = [line.split()[-1] for line in out.stdout.splitlines()]
    assert len(FMI3_EXPORTS) == 75
    assert sorted(n for n in names if n.startswith("fmi3")) == FMI3_EXPORTS
    # One shared library serves both versions: the FMI 2.0 exports are there too.
    assert len([n for n in names if n.startswith("fmi2")]) == 34


def _plant_run(path, u, ts, substeps, start):
    """Drive the plant (either FMI version, through cosim's _Slave) over u with `substeps` equal steps per
    sample; return x, w, y read at every sample instant t_k, before u(k) is set."""
    s = _Slave(path, "plant", _callbacks(None))
    try:
        f = s.fmu
        f.setupExperiment(startTime=0.0)
        s.set_start({"Ts": ts, **start})
        f.enterInitializationMode()
        f.exitInitializationMode()
        out_vr, u_vr = [s.vr("x"), s.vr("w"), s.vr("y")], [s.vr("u")]
        rows, t, h = [], 0.0, ts / substeps
        for uk in u:
            rows.append(f.getReal(out_vr))
            f.setReal(u_vr, [float(uk)])
            for _ in range(substeps):
                f.doStep(t, h)
                t += h
        f.terminate()
        return np.array(rows)
    finally:
        s.free()


@pytest.mark.parametrize("seed, ts, substeps", [(0, 1.0, 1), (1, 0.01, 3), (2, 0.5, 4)])
def test_plant_fmi3_equals_fmi2_bit_for_bit_and_numpy_to_1e12(plant_fmu, plant_fmu3, seed, ts, substeps):
    rng = np.random.default_rng(300 + seed)
    na, nb, delay = int(rng.integers(1, 5)), int(rng.integers(0, 4)), int(rng.integers(1, 4))
    a, b = reference.random_stable_arx(rng, na, nb)
    m1, m2 = rng.uniform(0.3, 2.5, 2)
    c1, c2 = rng.uniform(0.0, 1.0, 2)
    start = {"na": na, "nb": nb, "delay": delay, "m1": m1, "m2": m2, "c1": c1, "c2": c2}
    start.update({f"a{i + 1}": v for i, v in enumerate(a)})
    start.update({f"b{j}": v for j, v in enumerate(b)})
    u = rng.uniform(-3, 3, 300)
    two = _plant_run(plant_fmu, u, ts, substeps, start)
    three = _plant_run(plant_fmu3, u, ts, substeps, start)
    np.testing.assert_array_equal(three, two)
    x, w = reference.simulate(u, a=a, b=b, delay=delay, m1=m1, m2=m2, c1=c1, c2=c2)
    np.testing.assert_allclose(three[:, 0], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(three[:, 1], w, rtol=0, atol=1e-12)
    dw = np.diff(w)
    assert (dw > 0).any() and (dw < 0).any() and (dw == 0).any()


def test_simulate_fmu_fmi3_equals_fmi2(plant_fmu, plant_fmu3):
    """FMPy's own FMI 3.0 master (simulate_fmu), with input interpolation and noise: the same bits as FMI 2.0."""
    u = np.random.default_rng(0).uniform(-2.4, 2.4, 1000)
    inp = np.array(list(zip(np.arange(1000.0), u)), dtype=[("time", float), ("u", float)])
    kw = dict(stop_time=999, output_interval=1, input=inp, start_values={"c1": 0.3, "noise_std": 0.01},
              output=["x", "w", "y"])
    r2, r3 = simulate_fmu(plant_fmu, **kw), simulate_fmu(plant_fmu3, **kw)
    assert len(r3) == 1000
    for k in ("x", "w", "y"):
        np.testing.assert_array_equal(r3[k], r2[k], err_msg=k)


@pytest.fixture
def slave3(plant_fmu3):
    md = read_model_description(plant_fmu3)
    d = extract(plant_fmu3)
    s = FMU3Slave(guid=md.instantiationToken, unzipDirectory=d, modelIdentifier="BacklashPlant",
                  instanceName="plant3")
    s.instantiate(logMessage=LOG3.record)
    yield s
    s.freeInstance()
    shutil.rmtree(d, ignore_errors=True)


def test_fmu_state_get_set_serialize_is_bit_identical(slave3):
    s = slave3
    s.enterInitializationMode(startTime=0.0)
    s.setFloat64([40], [0.1])  # noise_std: the generator's state is part of the FMU state
    s.exitInitializationMode()

    def run(t0, n):
        out = []
        for k in range(n):
            s.setFloat64([2], [np.sin(0.3 * (t0 + k))])
            s.doStep(t0 + k, 1.0)
            out.append(s.getFloat64([3, 0]))  # y and the independent variable time
        return out

    run(0.0, 20)
    state = s.getFMUState()
    first = run(20.0, 30)
    s.setFMUState(state)
    assert run(20.0, 30) == first
    assert first[-1][1] == 50.0
    blob = s.serializeFMUState(state)
    s.freeFMUState(state)
    restored = s.deserializeFMUState(blob)
    s.setFMUState(restored)
    assert run(20.0, 30) == first
    s.freeFMUState(restored)
    s.terminate()


def test_refusals_are_errors_with_a_reason(slave3):
    s = slave3
    LOG3.lines.clear()
    with pytest.raises(FMICallException):
        s.getFloat32([1])
    assert "no Float32 variable" in LOG3.lines[-1][2]
    s.reset()
    s.enterInitializationMode(startTime=0.0)
    with pytest.raises(FMICallException):
        s.getFloat64([3], nValues=2)
    assert "nValues = 2 but nValueReferences = 1" in LOG3.lines[-1][2]
    s.reset()
    with pytest.raises(FMICallException):
        s.doStep(0.0, 1.0)  # before initialization
    assert "illegal call in state 'instantiated'" in LOG3.lines[-1][2]
    s.reset()
    with pytest.raises(FMICallException):
        s.enterEventMode()
    assert "hasEventMode" in LOG3.lines[-1][2]


def test_event_mode_and_model_exchange_are_refused_at_instantiation(plant_fmu3):
    md = read_model_description(plant_fmu3)
    d = extract(plant_fmu3)
    try:
        s = FMU3Slave(guid=md.instantiationToken, unzipDirectory=d, modelIdentifier="BacklashPlant",
                      instanceName="p")
        LOG3.lines.clear()
        with pytest.raises(Exception, match="Failed to instantiate"):
            s.instantiate(eventModeUsed=True, logMessage=LOG3.record)
        assert "eventModeUsed is true" in LOG3.lines[-1][2]
    finally:
        shutil.rmtree(d, ignore_errors=True)


def test_estimator_step_over_two_samples_is_discarded_at_the_first(estimator_fmu3):
    md = read_model_description(estimator_fmu3)
    d = extract(estimator_fmu3)
    s = FMU3Slave(guid=md.instantiationToken, unzipDirectory=d, modelIdentifier="MrgiaEstimator",
                  instanceName="e")
    try:
        s.instantiate(logMessage=LOG3.record)
        s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        LOG3.lines.clear()
        with pytest.raises(FMICallException, match="status 2"):
            s.doStep(0.0, 2.0)
        assert "so it stopped at t = 1 (the last successful time)" in LOG3.lines[-1][2]
        assert s.getFloat64([0]) == [1.0]
        s.terminate()
    finally:
        s.freeInstance()
        shutil.rmtree(d, ignore_errors=True)


def test_noise_free_pair_converges_through_fmu3slave(plant_fmu3, estimator_fmu3):
    u = paper_input(3000, 0)
    r = run_pair(plant_fmu3, estimator_fmu3, u, checkpoints=[3000])
    err = max_rel_error(r["estimates"][-1])
    assert err < 1e-6, f"max relative error {err:.3e} at N = 3000"


def test_noisy_pair_fmi3_equals_fmi2_bit_for_bit(plant_fmu, estimator_fmu, plant_fmu3, estimator_fmu3):
    """SNR 43 (the pair tests' noise): the FMI 3.0 pair's estimates are the FMI 2.0 pair's, so every statistic
    of test_pair_fmpy.py holds for both."""
    u = paper_input(2000, 4)
    _, w = reference.simulate(u)
    start = {"noise_std": float(np.std(w)) / 43.0, "noise_seed": 1004}
    r2 = run_pair(plant_fmu, estimator_fmu, u, plant_start=start, record_every=100)
    r3 = run_pair(plant_fmu3, estimator_fmu3, u, plant_start=start, record_every=100)
    for key in ("y", "estimates", "y_hat", "e", "updating"):
        np.testing.assert_array_equal(r3[key], r2[key], err_msg=key)
