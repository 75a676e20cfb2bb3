"""BacklashPlant.fmu through FMPy: validation, the contract's equations, FMU state, refusals."""
import shutil
import subprocess
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

import reference
from conftest import LOG

def _vrs(path):
    md = read_model_description(path)
    return {v.name: v.valueReference for v in md.modelVariables}


@pytest.fixture(scope="module")
def unzipped(plant_fmu):
    d = extract(plant_fmu)
    yield d
    shutil.rmtree(d, ignore_errors=True)


def _slave(plant_fmu, unzipped, name="plant"):
    md = read_model_description(plant_fmu)
    s = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipped,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=name,
    )
    s.instantiate(callbacks=LOG.callbacks)
    return s


def test_validate_fmu_reports_nothing(plant_fmu):
    assert validate_fmu(plant_fmu) == []


def test_binary_exports_exactly_the_34_fmi2_functions(plant_fmu, tmp_path):
    with zipfile.ZipFile(plant_fmu) as z:
        z.extract("binaries/linux64/BacklashPlant.so", tmp_path)
    so = tmp_path / "binaries/linux64/BacklashPlant.so"
    out = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True)
    names = sorted(line.split()[-1] for line in out.stdout.splitlines() if line.split()[-1].startswith("fmi2"))
    assert len(names) == 34, names
    md = read_model_description(plant_fmu)
    assert md.fmiVersion == "2.0" and md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate


def _input_table(u, ts):
    t = np.arange(len(u)) * ts
    return np.array(list(zip(t, u)), dtype=[("time", np.float64), ("u", np.float64)])


@pytest.mark.parametrize("seed", range(6))
def test_simulate_fmu_matches_independent_numpy_to_1e12(plant_fmu, seed):
    rng = np.random.default_rng(100 + seed)
    na, nb = int(rng.integers(0, 5)), int(rng.integers(0, 5))
    delay = int(rng.integers(1, 6))
    a, b = reference.random_stable_arx(rng, na, nb)
    m1, m2 = rng.uniform(0.3, 2.5, 2)
    c1, c2 = rng.uniform(0.0, 1.0, 2)
    ts = [1.0, 0.01, 0.5, 0.1, 2.0, 0.001][seed]
    n = 400
    u = rng.uniform(-3, 3, n) * np.repeat(rng.uniform(0.2, 1.5, n // 20), 20)
    start = {"Ts": ts, "na": na, "nb": nb, "delay": delay, "m1": m1, "m2": m2, "c1": c1, "c2": c2}
    start.update({f"a{i + 1}": v for i, v in enumerate(a)})
    start.update({f"b{j}": v for j, v in enumerate(b)})
    res = simulate_fmu(
        plant_fmu,
        start_time=0.0,
        stop_time=(n - 1) * ts,
        output_interval=ts,
        start_values=start,
        input=_input_table(u, ts),
        output=["x", "w", "y"],
    )
    assert len(res) == n
    x, w = reference.simulate(u, a=a, b=b, delay=delay, m1=m1, m2=m2, c1=c1, c2=c2)
    np.testing.assert_allclose(res["x"], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res["w"], w, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(res["y"], res["w"])  # no noise configured
    # The record must exercise all three regimes, or the comparison proves little.
    dw = np.diff(w)
    assert (dw > 0).any() and (dw < 0).any() and (dw == 0).any()


def test_noise_is_seeded_white_and_of_the_requested_std(plant_fmu):
    n, ts = 4000, 1.0
    u = np.random.default_rng(1).uniform(-2.4, 2.4, n)
    runs = []
    for seed in (3, 3, 4):
        res = simulate_fmu(
            plant_fmu, stop_time=(n - 1) * ts, output_interval=ts,
            start_values={"noise_std": 0.05, "noise_seed": seed},
            input=_input_table(u, ts), output=["w", "y"],
        )
        runs.append(res["y"] - res["w"])
    np.testing.assert_array_equal(runs[0], runs[1])
    assert not np.array_equal(runs[0], runs[2])
    e = runs[0]
    se = 0.05 / np.sqrt(n)
    assert abs(e.mean()) < 4 * se
    assert abs(e.std() - 0.05) < 4 * 0.05 / np.sqrt(2 * n)
    r1 = np.corrcoef(e[:-1], e[1:])[0, 1]
    assert abs(r1) < 4 / np.sqrt(n)


def _run(slave, u, ts=1.0, t0=0.0):
    vr = {"u": 2, "y": 3}
    out = []
    t = t0
    for uk in u:
        out.append(slave.getReal([vr["y"]])[0])
        slave.setReal([vr["u"]], [uk])
        slave.doStep(t, ts)
        t += ts
    return np.array(out), t


def test_fmu_state_save_step_restore_is_bit_identical(plant_fmu, unzipped):
    s = _slave(plant_fmu, unzipped)
    vr = _vrs(plant_fmu)
    s.setupExperiment(startTime=0.0)
    s.setReal([vr["noise_std"]], [0.1])
    s.enterInitializationMode()
    s.exitInitializationMode()
    u = np.random.default_rng(5).uniform(-2.4, 2.4, 300)
    _, t = _run(s, u[:100])
    state = s.getFMUstate()
    first, _ = _run(s, u[100:], t0=t)
    s.setFMUstate(state)
    second, _ = _run(s, u[100:], t0=t)
    assert first.tobytes() == second.tobytes()
    # Through the serialised form as well.
    blob = s.serializeFMUstate(state)
    s.freeFMUstate(state)
    state2 = s.deSerializeFMUstate(blob)
    s.setFMUstate(state2)
    third, _ = _run(s, u[100:], t0=t)
    assert first.tobytes() == third.tobytes()
    s.freeFMUstate(state2)
    s.terminate()
    s.freeInstance()


def test_variable_step_sizes_hold_the_input(plant_fmu, unzipped):
    """A step of n sample periods advances n samples with u held; equal to n unit steps."""
    vr = _vrs(plant_fmu)
    ts = 0.01
    u = np.random.default_rng(9).uniform(-2.4, 2.4, 60)
    sizes = np.random.default_rng(10).integers(1, 6, 60)
    # Reference: expand each held input over its samples.
    expanded = np.repeat(u, sizes)
    _, w_ref = reference.simulate(np.append(expanded, 0.0))
    s = _slave(plant_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    s.setReal([vr["Ts"]], [ts])
    s.enterInitializationMode()
    s.exitInitializationMode()
    k = 0
    for uk, n in zip(u, sizes):
        s.setReal([vr["u"]], [uk])
        s.doStep(k * ts, n * ts)
        k += n
        assert abs(s.getReal([vr["w"]])[0] - w_ref[k]) <= 1e-12
    s.terminate()
    s.freeInstance()


def _expect_error(call, *args):
    with pytest.raises(FMICallException) as e:
        call(*args)
    assert e.value.status == 3  # fmi2Error


def test_refusals_are_logged_with_the_call_and_the_state(plant_fmu, unzipped):
    log = LOG
    md = read_model_description(plant_fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="BacklashPlant", instanceName="p1")
    s.instantiate(callbacks=log.callbacks)
    _expect_error(s.doStep, 0.0, 1.0)
    assert (3, "logStatusError", "fmi2DoStep: illegal call in state 'instantiated' of instance 'p1'") in log.lines
    s.reset()
    vr = _vrs(plant_fmu)
    _expect_error(s.setReal, [vr["m2"]], [float("nan")])
    assert log.lines[-1] == (3, "logStatusError", "fmi2SetReal: 'm2' = NaN is not a finite number")
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([vr["m1"]], [1.0])
    s.setInteger([vr["na"]], [3])
    s.setReal([vr["a3"]], [0.1])
    s.exitInitializationMode()  # a consistent change of order is accepted
    s.reset()
    s.setupExperiment(startTime=0.0)
    _expect_error(s.doStep, 0.0, 1.0)
    assert "illegal call in state 'instantiated'" in log.lines[-1][2]
    s.freeInstance()


def test_illegal_call_sequences_are_errors_not_crashes(plant_fmu, unzipped):
    vr = _vrs(plant_fmu)
    s = _slave(plant_fmu, unzipped)
    # doStep before initialisation
    _expect_error(s.doStep, 0.0, 1.0)
    s.reset()
    # getReal in the instantiated state is illegal in FMI 2.0
    _expect_error(s.getReal, [vr["y"]])
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    _expect_error(s.doStep, 0.0, 1.0)
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _expect_error(s.setReal, [vr["m2"]], [2.0])  # fixed parameter after initialisation
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _expect_error(s.setReal, [vr["y"]], [1.0])  # an output
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _expect_error(s.getReal, [12345])  # unknown value reference
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _expect_error(s.doStep, 0.0, -1.0)  # a step must be > 0
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    _expect_error(s.doStep, 3.0, 1.0)  # wrong communication point
    s.reset()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.doStep(0.0, 1.0)
    s.terminate()
    _expect_error(s.doStep, 1.0, 1.0)  # after terminate
    s.freeInstance()


@pytest.mark.parametrize(
    "name,value",
    [("m1", 0.0), ("m2", -1.0), ("c1", -0.1), ("c2", float("nan")), ("a1", float("inf")),
     ("noise_std", -1.0), ("Ts", 0.0), ("na", 5), ("nb", -1), ("delay", 0)],
)
def test_bad_parameters_are_refused(plant_fmu, unzipped, name, value):
    vr = _vrs(plant_fmu)
    s = _slave(plant_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    if name in ("na", "nb", "delay"):
        _expect_error(s.setInteger, [vr[name]], [value])
    else:
        _expect_error(s.setReal, [vr[name]], [value])
    s.freeInstance()


def test_guid_mismatch_is_refused(plant_fmu, unzipped):
    s = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipped,
                  modelIdentifier="BacklashPlant", instanceName="wrong")
    with pytest.raises(Exception):
        s.instantiate()


def test_paper_003_continuous_block_and_polynomial_borders(plant_fmu):
    """linear = 1, border = 1: G(s) = 1/(s^2 + 0.6 s + 1) sampled with the input held, and straight borders
    written as polynomials. The independent check: scipy's ZOH discretisation of G turned into ARX
    coefficients, run through the NumPy reference plant with the same straight borders."""
    from scipy.signal import cont2discrete

    ts = 0.1
    numd, dend, _ = cont2discrete(([1.0], [1.0, 0.6, 1.0]), ts, method="zoh")
    numd = np.ravel(numd)
    # x(k) = -a1 x(k-1) - a2 x(k-2) + b0 u(k-1) + b1 u(k-2): numd = [0, b0, b1], dend = [1, a1, a2].
    assert abs(numd[0]) < 1e-14
    a, b = list(dend[1:]), list(numd[1:])
    m1, m2, c1, c2 = 1.2, 0.8, 0.3, 0.2
    n = 600
    u = np.random.default_rng(21).uniform(-2, 2, n) * np.repeat([0.3, 1.0, 0.6], n // 3)
    start = {"Ts": ts, "linear": 1, "num0": 1.0, "den0": 1.0, "den1": 0.6, "den2": 1.0,
             "border": 1, "fa0": -m1 * c1, "fa1": m1, "fd0": m2 * c2, "fd1": m2}
    res = simulate_fmu(plant_fmu, stop_time=(n - 1) * ts, output_interval=ts, start_values=start,
                       input=_input_table(u, ts), output=["x", "w"])
    x, w = reference.simulate(u, a=a, b=b, delay=1, m1=m1, m2=m2, c1=c1, c2=c2)
    # The borders cross at x* = (m1 c1 + m2 c2) / (m1 - m2) = 1.3: keep the check to records below it.
    assert np.max(x) < 1.3
    np.testing.assert_allclose(res["x"], x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res["w"], w, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name,value,reason", [
    ("den1", -0.6, "stable"),      # unstable G(s)
    ("num2", 1.0, "strictly proper"),  # numerator degree 2 = denominator degree
])
def test_bad_continuous_blocks_are_refused_at_exit_initialization(plant_fmu, unzipped, name, value, reason):
    vr = _vrs(plant_fmu)
    s = _slave(plant_fmu, unzipped)
    s.setupExperiment(startTime=0.0)
    s.setInteger([vr["linear"]], [1])
    s.setReal([vr["num0"], vr["den0"], vr["den1"], vr["den2"]], [1.0, 1.0, 0.6, 1.0])
    s.setReal([vr[name]], [value])
    s.enterInitializationMode()
    _expect_error(s.exitInitializationMode)
    assert reason in LOG.lines[-1][2], LOG.lines[-1]
    s.freeInstance()
