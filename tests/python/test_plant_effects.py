"""BacklashPlant.fmu as a test bench: each effect of the diagnosis catalogue switched on through parameters.

Two independent checks:
- equality with a NumPy implementation of the effects written from the parameter descriptions in
  modelDescription/BacklashPlant.xml (it shares no code with the Rust library). The noise cannot be redrawn
  in NumPy (ChaCha8), so the white noise of a run with the same seed and no effects is taken from the FMU
  (y - w) and the NumPy chain turns it into what the effect makes of it;
- `backlash diagnose` names the effect in a record the FMU made, as a user building test data in their own
  co-simulation would do.
"""
import json
import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

import reference
from conftest import LOG

TS = 0.01
PAPER = dict(a=(0.45, 0.55), b=(0.8,), delay=1, m1=1.0, m2=1.5, c1=0.5, c2=1.0)


def _input(n, seed):
    a = np.sqrt(3 * 1.93)  # the paper's input: white, uniform, variance 1.93
    return np.random.default_rng(seed).uniform(-a, a, n)


def _run(plant_fmu, u, start, outputs=("x", "w", "f", "y")):
    t = np.arange(len(u)) * TS
    table = np.array(list(zip(t, u)), dtype=[("time", np.float64), ("u", np.float64)])
    res = simulate_fmu(plant_fmu, stop_time=(len(u) - 1) * TS, output_interval=TS,
                       start_values={"Ts": TS, **start}, input=table, output=list(outputs))
    assert len(res) == len(u)
    return {k: res[k] for k in outputs}


def bench(x, noise, p):
    """The effects of the XML's descriptions on the linear block's output x, with the white noise `noise`
    (sigma z(k)). Returns w (backlash output, or the slider with contact friction), f, y."""
    m1, m2, c1, c2 = p["m1"], p["m2"], p["c1"], p["c2"]
    n = len(x)
    w, f, y = np.zeros(n), np.zeros(n), np.zeros(n)
    w_prev = f_prev = n_prev = 0.0
    for k in range(n):
        t = k * TS
        g1 = c1 + p.get("c1_rate", 0.0) * t
        g2 = c2 + p.get("c2_rate", 0.0) * t
        s_up, s_dn = x[k] - g1, x[k] + g2
        upper = m1 * s_up + p.get("curve_up2", 0.0) * s_up**2 + p.get("curve_up3", 0.0) * s_up**3
        lower = m2 * s_dn + p.get("curve_down2", 0.0) * s_dn**2 + p.get("curve_down3", 0.0) * s_dn**3
        friction = p.get("friction", 0)
        ke, fp, fm = p.get("k_e", 1.0), p.get("f_plus", 1.0), p.get("f_minus", 1.0)
        if friction == 2:
            # The play inside the spring: stretch r = x - slider; force k_e m (r -/+ gap) beyond the play,
            # and the slider moves when the force would pass a slip level.
            r = x[k] - w_prev
            force = ke * m1 * (r - g1) if r > g1 else ke * m2 * (r + g2) if r < -g2 else 0.0
            if force > fp:
                fk, wk = fp, x[k] - g1 - fp / (ke * m1)
            elif force < -fm:
                fk, wk = -fm, x[k] + g2 + fm / (ke * m2)
            else:
                fk, wk = force, w_prev
        else:
            wk = upper if upper > w_prev else lower if lower < w_prev else w_prev
            fk = min(max(f_prev + ke * (wk - w_prev), -fm), fp) if friction == 1 else wk
        phi = p.get("noise_phi", 0.0)
        nk = noise[k] if k == 0 or phi == 0 else phi * n_prev + np.sqrt(1 - phi * phi) * noise[k]
        v = fk
        lo, hi, sat = p.get("sat_lo", -1.0), p.get("sat_hi", 1.0), p.get("saturation", 0)
        if sat == 2:
            v = min(max(v, lo), hi)
        v += p.get("dist_amplitude", 0.0) * np.sin(p.get("dist_omega", 0.0) * t + p.get("dist_phase", 0.0))
        v += nk
        if sat == 1:
            v = min(max(v, lo), hi)
        q, off = p.get("quant_step", 0.0), p.get("quant_offset", 0.0)
        if q:
            v = off + q * np.round((v - off) / q)
        w[k], f[k], y[k] = wk, fk, v
        w_prev, f_prev, n_prev = wk, fk, nk
    return w, f, y


CASES = {
    "gap-drift": {"c1_rate": 0.05, "c2_rate": 0.03},
    "curved-borders": {"curve_up2": 0.08, "curve_up3": 0.02, "curve_down2": -0.05, "curve_down3": 0.03},
    "friction-series": {"friction": 1, "k_e": 1.5, "f_plus": 0.6, "f_minus": 0.9},
    "friction-contact": {"friction": 2, "k_e": 0.8, "f_plus": 0.7, "f_minus": 0.5},
    "periodic-disturbance": {"dist_amplitude": 0.2, "dist_omega": 31.0, "dist_phase": 0.4},
    "coloured-noise": {"noise_phi": 0.8},
    "saturation-sensor": {"saturation": 1, "sat_lo": -0.8, "sat_hi": 1.1},
    "saturation-end-stop": {"saturation": 2, "sat_lo": -0.8, "sat_hi": 1.1},
    "quantization": {"quant_step": 0.25, "quant_offset": 0.05},
    "all-sensor-effects": {"dist_amplitude": 0.1, "dist_omega": 5.0, "noise_phi": -0.4, "saturation": 1,
                           "sat_lo": -1.5, "sat_hi": 1.2, "quant_step": 0.1},
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_each_effect_matches_an_independent_numpy_bench(plant_fmu, case):
    n = 1500
    u = _input(n, 5)
    noise_std = 0.05
    base = {"noise_std": noise_std, "noise_seed": 17}
    white = _run(plant_fmu, u, base)
    noise = white["y"] - white["w"]
    assert np.std(noise) == pytest.approx(noise_std, rel=0.1)
    x_ref, _ = reference.simulate(u, **PAPER)
    np.testing.assert_allclose(white["x"], x_ref, rtol=0, atol=1e-12)
    p = {**PAPER, **CASES[case]}
    got = _run(plant_fmu, u, {**base, **CASES[case]})
    w, f, y = bench(x_ref, noise, p)
    np.testing.assert_allclose(got["w"], w, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["f"], f, rtol=0, atol=1e-9)
    # Rounding can flip a quantized value by one step where v sits on a rounding edge (noise differences
    # of 1e-16): allow a handful of such samples, nothing else.
    diff = np.abs(got["y"] - y)
    if "quant_step" in CASES[case]:
        assert np.sum(diff > 1e-9) <= 2, np.flatnonzero(diff > 1e-9)
    else:
        assert diff.max() < 1e-9
    # The effect does something (the test could fail): y differs from the plain plant's.
    assert np.max(np.abs(got["y"] - white["y"])) > 1e-3


def test_direction_dependent_block_matches_numpy(plant_fmu):
    """The falling set as the XML describes it: x(k) is the value of a1..a4, b0..b4 unless that is below
    x(k-1), then the value of a1_fall..b4_fall over the same history; the backlash after it is the plain one."""
    u = _input(1200, 8)
    start = {"direction_dependent": 1, "a1_fall": 0.2, "a2_fall": 0.1, "b0_fall": 0.5}
    got = _run(plant_fmu, u, start)
    x = np.zeros(len(u))
    for k in range(len(u)):
        def value(a, b):
            past = sum(-ai * x[k - 1 - i] for i, ai in enumerate(a) if k - 1 - i >= 0)
            return past + (b[0] * u[k - 1] if k >= 1 else 0.0)
        prev = x[k - 1] if k > 0 else 0.0
        rise = value(PAPER["a"], PAPER["b"])
        x[k] = rise if rise >= prev else value((0.2, 0.1), (0.5,))
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12)
    w, _, _ = bench(x, np.zeros(len(u)), PAPER)
    np.testing.assert_allclose(got["w"], w, rtol=0, atol=1e-12)
    # The effect does something: x differs from the plain block's.
    x_ref, _ = reference.simulate(u, **PAPER)
    assert np.max(np.abs(got["x"] - x_ref)) > 0.1


def test_polynomial_feedback_matches_numpy(plant_fmu):
    """The feedback as the XML describes it: x(k) of the ARX block gains phi(x(k-1)) +
    feedback_lag2 phi(x(k-2)), phi(x) = feedback2 x^2 + feedback3 x^3; the backlash after it is the plain one."""
    u = _input(1200, 9)
    start = {"feedback2": 0.02, "feedback3": -0.006, "feedback_lag2": 0.7}
    got = _run(plant_fmu, u, start)
    x = np.zeros(len(u))

    def phi(v):
        return 0.02 * v**2 - 0.006 * v**3

    for k in range(1, len(u)):
        past = sum(-ai * x[k - 1 - i] for i, ai in enumerate(PAPER["a"]) if k - 1 - i >= 0)
        older = phi(x[k - 2]) if k >= 2 else 0.0
        x[k] = past + PAPER["b"][0] * u[k - 1] + phi(x[k - 1]) + 0.7 * older
    np.testing.assert_allclose(got["x"], x, rtol=0, atol=1e-12)
    w, _, _ = bench(x, np.zeros(len(u)), PAPER)
    np.testing.assert_allclose(got["w"], w, rtol=0, atol=1e-12)
    # The effect does something: x differs from the plain block's.
    x_ref, _ = reference.simulate(u, **PAPER)
    assert np.max(np.abs(got["x"] - x_ref)) > 0.1


def test_effects_off_is_the_plain_plant(plant_fmu):
    """Neutral settings (zero amplitude and rates, saturation limits far outside the signal) give the plain
    plant bit for bit."""
    u = _input(800, 6)
    base = {"noise_std": 0.05, "noise_seed": 3}
    plain = _run(plant_fmu, u, base)
    neutral = _run(plant_fmu, u, {**base, "saturation": 1, "sat_lo": -1e6, "sat_hi": 1e6,
                                  "curve_up2": 0.0, "dist_omega": 3.0})
    for k in ("x", "w", "f", "y"):
        np.testing.assert_array_equal(plain[k], neutral[k])
    np.testing.assert_array_equal(plain["f"], plain["w"])


def _slave(plant_fmu, unzipped):
    md = read_model_description(plant_fmu)
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="BacklashPlant",
                  instanceName="bench")
    s.instantiate(callbacks=LOG.callbacks)
    return s, {v.name: v.valueReference for v in md.modelVariables}


@pytest.mark.parametrize("name,value", [("friction", 3), ("saturation", -1), ("direction_dependent", 2)])
def test_out_of_range_switches_are_refused_when_set(plant_fmu, name, value):
    from fmpy import extract
    import shutil

    d = extract(plant_fmu)
    try:
        s, vr = _slave(plant_fmu, d)
        s.setupExperiment(startTime=0.0)
        with pytest.raises(Exception):
            s.setInteger([vr[name]], [value])
        assert name in LOG.lines[-1][2], LOG.lines[-1]
        s.freeInstance()
    finally:
        shutil.rmtree(d, ignore_errors=True)


@pytest.mark.parametrize("name,value", [("k_e", 0.0), ("noise_phi", 1.0), ("noise_phi", -1.0)])
def test_bench_values_outside_the_declared_range_are_refused_when_set(plant_fmu, name, value):
    """The declared range is the accepted one: k_e >= 1e-12, |noise_phi| <= 0.999999."""
    from fmpy import extract
    import shutil

    d = extract(plant_fmu)
    try:
        s, vr = _slave(plant_fmu, d)
        s.setupExperiment(startTime=0.0)
        with pytest.raises(Exception):
            s.setReal([vr[name]], [value])
        assert name in LOG.lines[-1][2], LOG.lines[-1]
        s.reset()
        s.setReal([vr[name]], [0.999999 if name == "noise_phi" else 1e-12])
        s.freeInstance()
    finally:
        shutil.rmtree(d, ignore_errors=True)


@pytest.mark.parametrize("ints,reals,reason", [
    ({"saturation": 1}, {"sat_lo": 2.0, "sat_hi": 1.0}, "sat_lo"),
    ({"border": 1}, {"fa1": 1.0, "fd1": 1.0, "c1_rate": 0.1}, "c1_rate"),
    ({"border": 1, "friction": 2}, {"fa1": 1.0, "fd1": 1.0}, "contact friction"),
    ({"friction": 2}, {"curve_up2": 0.1}, "curved borders"),
    ({"direction_dependent": 1}, {"a1_fall": 1.5, "b0_fall": 0.8}, "a1_fall"),
])
def test_inconsistent_bench_parameters_are_refused_at_exit_initialization(plant_fmu, ints, reals, reason):
    from fmpy import extract
    import shutil

    d = extract(plant_fmu)
    try:
        s, vr = _slave(plant_fmu, d)
        s.setupExperiment(startTime=0.0)
        if ints:
            s.setInteger([vr[k] for k in ints], list(ints.values()))
        if reals:
            s.setReal([vr[k] for k in reals], list(reals.values()))
        s.enterInitializationMode()
        with pytest.raises(Exception):
            s.exitInitializationMode()
        assert reason in LOG.lines[-1][2], LOG.lines[-1]
        s.freeInstance()
    finally:
        shutil.rmtree(d, ignore_errors=True)


# Records made by the FMU, diagnosed by the CLI: the declared model is always the paper's (na 2, nb 0,
# delay 1). Magnitudes inside the ranges of src/diagnose/bench.rs.
DIAGNOSED = {
    "gap-drift": {"c1_rate": 0.3 / 30.0, "c2_rate": 0.6 / 30.0},  # gaps +60 % over 3000 samples of 0.01 s
    "curved-borders": {"curve_up2": 0.1, "curve_up3": 0.04, "curve_down2": -0.12, "curve_down3": 0.05},
    "extra-delay": {"delay": 3},
    "linear-order": {"nb": 1, "b1": 0.4},
    "coloured-noise": {"noise_phi": 0.8, "noise_std": 0.1},
    "saturation": {"saturation": 1, "sat_lo": -1.2, "sat_hi": 1.6},
    "periodic-disturbance": {"dist_amplitude": 0.06, "dist_omega": 70.0, "dist_phase": 1.0},
    "quantization": {"quant_step": 0.3, "noise_std": 0.02},
    "friction": {"friction": 1, "k_e": 1.0, "f_plus": 0.9, "f_minus": 0.9},
    # While x falls the poles are 0.55 times the rising ones (a_i times 0.55^i), b0 keeps the static gain.
    "direction-dependent": {"direction_dependent": 1, "a1_fall": 0.45 * 0.55, "a2_fall": 0.55 * 0.55**2,
                            "b0_fall": 0.8 * (1 + 0.45 * 0.55 + 0.55 * 0.55**2) / 2.0},
}


@pytest.mark.parametrize("effect", sorted(DIAGNOSED))
def test_diagnose_names_the_effect_the_fmu_was_given(plant_fmu, cli, tmp_path, effect):
    n = 3000
    u = _input(n, 40)
    start = {"noise_std": 0.04, "noise_seed": 9, **DIAGNOSED[effect]}
    got = _run(plant_fmu, u, start, outputs=("y",))
    path = tmp_path / f"{effect}.csv"
    t = np.arange(n) * TS
    np.savetxt(path, np.column_stack([t, u, got["y"]]), delimiter=",", header="time,u,y", comments="",
               fmt="%.17g")
    out = subprocess.run([cli, "diagnose", str(path), "--na", "2", "--nb", "0", "--delay", "1", "--json"],
                         capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    assert j["effect"]["id"] == effect, j["effect"]
    # The loop goes on after the first effect: on a single-effect record it adds nothing else.
    assert [e["id"] for e in j["effects"]] == [effect], j["effects"]
    one_step = j["after"].get("one_step")
    if one_step is not None:
        # A noise model leaves the simulation (and its free-run error) as it was; it is judged, and its gain
        # reported, by one-step prediction.
        assert j["after"]["rmse"] == j["before"]["rmse"]
        assert one_step["after"] < one_step["before"]
    else:
        assert j["after"]["rmse"] < j["before"]["rmse"]


# Several effects at once, made by the FMU: the loop names each one present and no other, and every step
# lowers the held-out error (a noise model: its one-step prediction error).
COMBINED = [
    ("gap-drift", "quantization"),
    ("friction", "coloured-noise"),
    ("extra-delay", "saturation"),
    ("curved-borders", "periodic-disturbance"),
    ("gap-drift", "saturation", "periodic-disturbance"),
]


@pytest.mark.parametrize("effects", COMBINED, ids=["+".join(c) for c in COMBINED])
def test_diagnose_names_every_effect_of_a_combined_record(plant_fmu, cli, tmp_path, effects):
    n = 3000
    u = _input(n, 41)
    start = {"noise_std": 0.04, "noise_seed": 11}
    for e in effects:
        start.update(DIAGNOSED[e])
    got = _run(plant_fmu, u, start, outputs=("y",))
    path = tmp_path / "combined.csv"
    t = np.arange(n) * TS
    np.savetxt(path, np.column_stack([t, u, got["y"]]), delimiter=",", header="time,u,y", comments="",
               fmt="%.17g")
    out = subprocess.run([cli, "diagnose", str(path), "--na", "2", "--nb", "0", "--delay", "1", "--json"],
                         capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    named = [e["id"] for e in j["effects"]]
    assert sorted(named) == sorted(effects), (named, j["stopped"])
    assert j["effect"]["id"] == named[0]
    before = j["before"]["rmse"]
    for step in j["effects"]:
        assert step["before_rmse"] == before
        if step.get("one_step"):
            assert step["one_step"]["after"] < step["one_step"]["before"]
        else:
            assert step["after_rmse"] < before
        before = step["after_rmse"]
    assert j["after"]["rmse"] == j["effects"][-1]["after_rmse"]
