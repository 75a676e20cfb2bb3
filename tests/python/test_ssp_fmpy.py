"""target/ssp/BacklashIdentification.ssp (cargo build --release) in FMPy's SSP master, `simulate_ssp`: the pair
plant -> estimator of paper 000's example as one system, its input `u` driving both units.

How FMPy exchanges (fmpy/ssp/simulation.py, measured below): in each step it sets every unit's inputs from
the connectors, steps every unit, then passes every connection at once, the system's input among them. So the
system input set at t_k reaches the units' `u` only in the step from t_{k+1}: the pair runs on the input one
sample late, and the plant's `y(k)`, produced by the step to t_k, reaches the estimator in the same pass as
the `u(k)` it belongs to. Plant and estimator stay aligned: the estimator's `delay` is the plant's.
"""
import pathlib

import numpy as np
import pytest
from fmpy.ssp.simulation import simulate_ssp
from fmpy.ssp.ssd import read_ssd

import backlash_fmu
from backlash_fmu.cosim import CHECKED, PAPER_TRUTH, max_rel_error, paper_input
from conftest import ROOT

SSP = ROOT / "target" / "ssp" / "BacklashIdentification.ssp"


@pytest.fixture(scope="module")
def ssp():
    if not SSP.exists():
        pytest.fail(f"{SSP} is missing: run `cargo build --release` first")
    return str(SSP)


def _run(ssp, u):
    n = len(u)
    return simulate_ssp(ssp, stop_time=float(n), step_size=1.0, input={"u": lambda t: u[int(round(t))]})


def test_the_system_binds_paper_000s_example(ssp):
    system = read_ssd(ssp).system
    assert [c.name for c in system.connectors if c.kind == "input"] == ["u"]
    outputs = {c.name for c in system.connectors if c.kind == "output"}
    assert set(CHECKED) <= outputs and {"y_hat", "e", "updating"} <= outputs
    values = {}
    for element in system.elements:
        for binding in element.parameterBindings:
            for pset in binding.parameterValues:
                values.update({(element.name, p.name): float(p.value) for p in pset.parameters})
    for name in ("a1", "a2", "b0", "m2", "c1", "c2"):
        assert values[("BacklashPlant", name)] == PAPER_TRUTH[name], name
    assert values[("BacklashPlant", "m1")] == 1.0 and values[("BacklashPlant", "noise_std")] == 0.0
    for unit in ("BacklashPlant", "MrgiaEstimator"):
        assert [values[(unit, k)] for k in ("Ts", "na", "nb", "delay")] == [1.0, 2.0, 0.0, 1.0], unit
    starts = {(c.startElement, c.startConnector, c.endElement, c.endConnector) for c in system.connections}
    assert {(None, "u", "BacklashPlant", "u"), (None, "u", "MrgiaEstimator", "u"),
            ("BacklashPlant", "y", "MrgiaEstimator", "y")} <= starts


@pytest.mark.parametrize("seed", [0, 1])
def test_the_estimates_converge_as_in_the_pair_tests(ssp, seed):
    """As test_pair_fmpy's noise-free pair: every estimate within 1e-6 of the truth after 3000 samples."""
    r = _run(ssp, paper_input(3000, seed))
    err = max_rel_error({name: r[name][-1] for name in CHECKED})
    assert err < 1e-6, f"seed {seed}: max relative error {err:.3e} at N = 3000"


def test_fmpy_passes_the_input_one_step_late_and_keeps_the_pair_aligned(ssp):
    """Row k of the result holds the connectors after the pass of the step from t_k: both units' `u` is the
    system input of t_k, which they step on from t_{k+1}; the estimator's `y` is the plant's output after
    the step to t_{k+1}. The plant alone on the input delayed by one sample gives the same y, so the
    estimator gets the pair (u(k), y(k)) of one plant sample in the same step."""
    f = paper_input(400, 5)
    r = _run(ssp, f)
    n = len(r)
    np.testing.assert_array_equal(r["MrgiaEstimator.u"], f[:n])
    np.testing.assert_array_equal(r["BacklashPlant.u"], f[:n])
    late = np.concatenate([[0.0], f])  # what the plant steps on: u_plant(k) = f(t_{k-1}), 0 at t_0
    y = backlash_fmu.simulate(late)["y"]
    np.testing.assert_allclose(r["MrgiaEstimator.y"], y[1:n + 1], rtol=0, atol=1e-12)
    # Not one sample more: the plant on the undelayed input does not match.
    y_now = backlash_fmu.simulate(f)["y"]
    assert np.max(np.abs(r["MrgiaEstimator.y"][:-1] - y_now[1:n])) > 0.1
