"""The Python package as users install it (CI runs this file in a fresh virtual environment holding only the
wheel, numpy, fmpy and pytest): the API gives the program's JSON on the same records, the packaged FMUs
simulate in FMPy, diagnose names an effect, and bad arrays are refused with a message that says what is wrong.
"""
import json
import pathlib
import subprocess
import sys
import sysconfig
import threading
import time

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.validation import validate_fmu

import backlash_fmu
from backlash_fmu import cosim
from conftest import ROOT

PAPER = dict(na=2, nb=0, delay=1)


def _record(n, seed, noise_std=0.01, **plant):
    u = cosim.paper_input(n, seed)
    y = backlash_fmu.simulate(u, noise_std=noise_std, noise_seed=seed, **plant)["y"]
    return u, y


def _csv(path, u, y, time=None):
    """time = 0, 1, 2, ... unless given; numbers in their shortest exact form, so the program reads the API's
    floats."""
    time = np.arange(len(u), dtype=float) if time is None else time
    with open(path, "w") as f:
        f.write("time,u,y\n")
        for t, a, b in zip(time.tolist(), u.tolist(), y.tolist()):
            f.write(f"{t!r},{a!r},{b!r}\n")
    return str(path)


def _cli_json(cli, *args):
    out = subprocess.run([cli, *map(str, args), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _same(api, program, ignore=("file", "seconds")):
    """Equal key for key (numbers exactly), apart from the file's name and wall-clock times."""
    assert api.keys() == program.keys()
    for k in api.keys() - set(ignore):
        assert api[k] == program[k], k


def test_the_package_is_the_installed_one():
    here = pathlib.Path(backlash_fmu.__file__).resolve()
    assert ROOT / "python" not in here.parents, f"{here}: imported from the source tree, not the installation"


def test_mrgia_equals_the_program(cli, tmp_path):
    u, y = _record(3000, 1)
    data = _csv(tmp_path / "r.csv", u, y)
    for recommended in (False, True):
        api = backlash_fmu.identify_mrgia(u, y, 2, 0, 1, recommended=recommended)
        flags = ["--recommended"] if recommended else []
        _same(api, _cli_json(cli, "identify", "mrgia", data, "--na", 2, "--nb", 0, "--delay", 1, *flags))
    assert abs(api["c1"] - 0.5) < 0.05 and api["file"] is None


def test_oe_crb_and_frequency_equal_the_program(cli, tmp_path):
    u, y = _record(600, 2)
    data = _csv(tmp_path / "r.csv", u, y)
    api = backlash_fmu.identify_oe(u, y, **PAPER, target_rel=0.01)
    _same(api, _cli_json(cli, "identify", "oe", data, "--na", 2, "--nb", 0, "--delay", 1, "--target-rel", 0.01))
    assert abs(api["c2"] - 1.0) < 0.05

    bound = backlash_fmu.crb(u, snr=43.0, c1=0.4, a=[0.45, 0.55])
    program = _cli_json(cli, "crb", data, "--snr", 43, "--c1", 0.4, "--a", "0.45,0.55")
    _same(bound, program, ignore=("input",))
    assert bound["input"] == "array" and bound["truth"]["c1"] == 0.4

    t = np.arange(0, 40, 0.01)
    us = 2.0 * np.cos(1.5 * t)
    ys = backlash_fmu.simulate(us, a=[0.5], b=[0.5], c1=0.2, c2=0.2, m2=1.0)["y"]
    sine = _csv(tmp_path / "sine.csv", us, ys, time=t)
    freq = backlash_fmu.identify_frequency(t, us, ys)
    _same(freq, _cli_json(cli, "identify", "frequency", sine))
    assert freq["method"] == "frequency" and freq["degree"] >= 1


def test_diagnose_names_the_effect_the_declared_model_lacks_as_the_program_does(cli, tmp_path):
    """The plant's true delay is 3; the declared model has 1: the diagnosis says `extra-delay`."""
    u, y = _record(1500, 3, noise_std=0.02, delay=3)
    api = backlash_fmu.diagnose(u, y, **PAPER, ts=1.0, max_effects=1, time_budget=60)
    assert api["effect"]["id"] == "extra-delay", api["effect"]
    data = _csv(tmp_path / "r.csv", u, y)
    program = _cli_json(cli, "diagnose", data, "--na", 2, "--nb", 0, "--delay", 1, "--max-effects", 1,
                        "--time-budget", 60)
    _same(api, program, ignore=("file",))


@pytest.mark.parametrize("bench", [{}, dict(Ts=0.5, c1_rate=0.002, noise_phi=0.6, quant_step=0.05)])
def test_simulate_equals_the_packaged_plant_fmu_in_fmpy(bench):
    """By the FMU's names, the test bench's effects included: every parameter the FMU has."""
    fmu = backlash_fmu.fmu_path("BacklashPlant")
    assert validate_fmu(fmu) == []
    u = cosim.paper_input(500, 4)
    assert {"a", "b", "Ts", "c1_rate", "noise_phi", "quant_step", "b4_fall"} <= set(backlash_fmu.PLANT_PARAMETERS)
    params = dict(c1=0.3, c2=0.7, m2=1.2, noise_std=0.01, noise_seed=9, **bench)
    ts = bench.get("Ts", 1.0)
    api = backlash_fmu.simulate(u, a=[0.45, 0.55], b=[0.8], **params)
    inp = np.array(list(zip(ts * np.arange(500.0), u)), dtype=[("time", float), ("u", float)])
    res = simulate_fmu(fmu, stop_time=499 * ts, output_interval=ts, input=inp, start_values=params,
                       output=["x", "w", "y"])
    for name in ("x", "w", "y"):
        np.testing.assert_allclose(res[name], api[name], rtol=0, atol=1e-12, err_msg=name)


def test_record_options_units_decimate_and_progress_equal_the_program(cli, tmp_path):
    """A file named as a measured record is (`t [s],u [V],y [kN]`): the program reads it with --time-col and
    --decimate as the API reads the arrays with decimate=; diagnose reports its stages as counts."""
    u, y = _record(3000, 3, noise_std=0.02)
    data = tmp_path / "damper.csv"
    with open(data, "w") as f:
        f.write("t [s],u [V],y [kN]\n")
        for k, (a, b) in enumerate(zip(u.tolist(), y.tolist())):
            f.write(f"{0.01 * k!r},{a!r},{b!r}\n")
    stages = []
    program = _cli_json(cli, "diagnose", data, "--time-col", "t", "--decimate", 2, "--na", 2, "--nb", 0,
                        "--delay", 1, "--max-effects", 1, "--time-budget", 60)
    # The program's Ts is the median step of the decimated time column (0.02 within rounding).
    api = backlash_fmu.diagnose(u, y, **PAPER, ts=program["Ts"] / 2, max_effects=1, time_budget=60, decimate=2,
                                progress=lambda done, total: stages.append((done, total)))
    _same(api, program)
    assert api["decimate"] == 2 and abs(program["Ts"] - 0.02) < 1e-12
    _check_counts(stages)
    oe = _cli_json(cli, "identify", "oe", data, "--na", 2, "--nb", 0, "--delay", 1)
    _same(backlash_fmu.identify_oe(u, y, **PAPER), oe)
    assert oe["warnings"] == []


def test_warnings_and_the_missing_sample_period_are_told():
    u = np.full(400, 0.7)
    y = backlash_fmu.simulate(u, noise_std=0.01)["y"]
    out = backlash_fmu.identify_mrgia(u, y, 2, 0, 1)
    assert out["warnings"][0].startswith("the input is constant (0.7 in every sample)"), out["warnings"]
    u, y = _record(1500, 3, noise_std=0.02)
    out = backlash_fmu.diagnose(u, y, **PAPER, max_effects=1, time_budget=60)
    assert out["Ts"] is None and "c1_rate_per_s" in out["Ts_note"]


def test_packaged_estimator_fmu_in_a_pair_equals_identify_mrgia():
    u = cosim.paper_input(2000, 5)
    r = cosim.run_pair(backlash_fmu.fmu_path("BacklashPlant"), backlash_fmu.fmu_path("MrgiaEstimator"), u,
                       plant_start={"noise_std": 0.01, "noise_seed": 5}, checkpoints=[2000])
    assert validate_fmu(backlash_fmu.fmu_path("MrgiaEstimator")) == []
    j = backlash_fmu.identify_mrgia(u, r["y"], 2, 0, 1)
    est = dict(zip(r["names"], r["estimates"][-1]))
    api = dict(a1=j["a"][0], a2=j["a"][1], b0=j["b"][0], m2=j["m2"], c1=j["c1"], c2=j["c2"])
    for name in cosim.CHECKED:
        assert abs(api[name] - est[name]) <= 1e-12, name


def test_compensate_equals_the_program(cli, tmp_path):
    e = np.random.default_rng(5).standard_normal(6000)  # low-pass noise of std 1.5, as in docs/RESULTS.md
    r = np.empty_like(e)
    r[0] = 1.5 * e[0]
    for k in range(1, len(e)):
        r[k] = 0.9 * r[k - 1] + 1.5 * np.sqrt(1 - 0.81) * e[k]
    path = tmp_path / "reference.csv"
    with open(path, "w") as f:
        f.write("time,r\n")
        for k, x in enumerate(r.tolist()):
            f.write(f"{k},{x!r}\n")
    api = backlash_fmu.compensate(r, noise_std=0.02, wear="step", wear_ratio=0.5, memory=300)
    program = _cli_json(cli, "compensate", path, "--noise-std", 0.02, "--wear", "step", "--memory", 300)
    _same(api, program)
    assert set(api["modes"]) == {"none", "fixed", "adaptive", "no-play"}
    assert api["modes"]["adaptive"]["rmse_last_quarter"] < 0.2 * api["modes"]["fixed"]["rmse_last_quarter"]
    with pytest.raises(ValueError, match="wear 'sudden' is unknown"):
        backlash_fmu.compensate(r, wear="sudden")
    # The estimate of the sample before (a Jacobi master's loop): the program's --estimate-lag.
    lagged = backlash_fmu.compensate(r, noise_std=0.02, wear="step", memory=300, modes=["adaptive"], estimate_lag=1)
    _same(lagged, _cli_json(cli, "compensate", path, "--noise-std", 0.02, "--wear", "step", "--memory", 300,
                            "--modes", "adaptive", "--estimate-lag", 1))
    assert lagged["estimate_lag"] == 1 and lagged["modes"]["adaptive"] != api["modes"]["adaptive"]
    with pytest.raises(ValueError, match="estimate lag 2 is invalid"):
        backlash_fmu.compensate(r, estimate_lag=2)


def test_fmu_path_names_what_it_has():
    with pytest.raises(ValueError, match="unknown FMU 'Plant': the package has BacklashPlant, MrgiaEstimator, "
                                         "BacklashCompensator"):
        backlash_fmu.fmu_path("Plant")
    with pytest.raises(ValueError, match="must be 2 or 3"):
        backlash_fmu.fmu_path("BacklashPlant", fmi_version=1)
    try:
        path = backlash_fmu.fmu_path("BacklashPlant", fmi_version=3)
    except FileNotFoundError as e:
        assert "no FMI 3.0 BacklashPlant.fmu" in str(e)
    else:
        assert validate_fmu(path) == []


def _check_counts(calls):
    """The progress protocol: two integers, done never decreasing and below total until the last call, which
    has done == total."""
    assert len(calls) >= 3, calls
    assert all(isinstance(d, int) and isinstance(t, int) for d, t in calls), calls
    assert all(a[0] <= b[0] for a, b in zip(calls, calls[1:])), calls
    assert all(d < t for d, t in calls[:-1]), calls
    assert calls[-1][0] == calls[-1][1] and calls[-1][0] >= 2, calls


def test_every_long_function_calls_progress_with_done_and_total():
    """One callable serves identify_mrgia, identify_oe and diagnose alike (stages become counts)."""
    u, y = _record(3000, 3, noise_std=0.02)
    for call in (lambda p: backlash_fmu.identify_mrgia(u, y, 2, 0, 1, progress=p),
                 lambda p: backlash_fmu.identify_oe(u, y, progress=p),
                 lambda p: backlash_fmu.diagnose(u, y, **PAPER, max_effects=1, time_budget=60, progress=p)):
        calls = []
        call(lambda done, total: calls.append((done, total)))
        _check_counts(calls)


def test_progress_true_is_the_same_bar_everywhere(capsys):
    u, y = _record(3000, 3, noise_std=0.02)
    backlash_fmu.identify_mrgia(u, y, 2, 0, 1, progress=True)
    mrgia = capsys.readouterr().err
    backlash_fmu.diagnose(u, y, **PAPER, max_effects=1, time_budget=60, progress=True)
    diagnose = capsys.readouterr().err
    assert mrgia and diagnose
    with pytest.raises(ValueError, match=r"progress\(done, total\)"):
        backlash_fmu.diagnose(u, y, **PAPER, progress="yes")


@pytest.mark.parametrize("call, message", [
    (lambda u, y: backlash_fmu.identify_mrgia(u, y[:-1], 2, 0, 1),
     r"u has 400 samples and y 399: they must be the same length"),
    (lambda u, y: backlash_fmu.identify_oe(np.where(np.arange(400) == 17, np.nan, u), y, **PAPER),
     r"u\[17\] is NaN: every sample must be a finite number"),
    (lambda u, y: backlash_fmu.diagnose(u, np.where(np.arange(400) == 3, np.inf, y)),
     r"y\[3\] is inf: every sample must be a finite number"),
    (lambda u, y: backlash_fmu.diagnose(u[:50], y[:50], **PAPER),
     r"50 samples: at least 160 are needed"),
    (lambda u, y: backlash_fmu.identify_mrgia(u[:0], y[:0], 2, 0, 1),
     r"0 samples are too few: at least 1 are needed"),
    (lambda u, y: backlash_fmu.identify_mrgia(u, y, 7, 0, 1), r"na.*7.*between 0 and 4"),
    (lambda u, y: backlash_fmu.identify_oe(u, y, na=2), r"give all three of na, nb and delay"),
    (lambda u, y: backlash_fmu.simulate(np.column_stack([u, u])), r"u must be one-dimensional"),
    (lambda u, y: backlash_fmu.simulate(u, c3=1.0), r"^the plant has no parameter named c3 \(did you mean \w+\?\); "
                                                     r"its parameters are the plant FMU's: a, b, Ts, "),
    (lambda u, y: backlash_fmu.simulate(u, c1_rat=1.0), r"no parameter named c1_rat \(did you mean c1_rate\?\)"),
    (lambda u, y: backlash_fmu.simulate(u, delay=1.5), r"delay = 1.5 must be a whole number"),
    (lambda u, y: backlash_fmu.simulate(u, a=[0.1] * 5), r"a has 5 coefficients; 0 to 4 \(a1 to a4\)"),
    (lambda u, y: backlash_fmu.crb(u, snr=43.0, c1_rate=0.1), r"c1_rate is not one of its parameters"),
    (lambda u, y: backlash_fmu.diagnose(u, y, decimate=0), r"decimate must be at least 1"),
    (lambda u, y: backlash_fmu.crb(u), r"give one of noise_std and snr"),
    (lambda u, y: backlash_fmu.diagnose(u, y, time_budget=0), r"time budget 0 must be"),
])
def test_bad_arguments_raise_value_error_with_the_librarys_message(call, message):
    u, y = _record(400, 6)
    with pytest.raises(ValueError, match=message):
        call(u, y)


def test_long_calls_release_the_gil_and_report_progress():
    u, y = _record(2_000_000, 7, noise_std=0.0)
    calls = []
    t0 = time.perf_counter()
    backlash_fmu.identify_mrgia(u, y, 2, 0, 1, progress=lambda done, total: calls.append((done, total)))
    alone = time.perf_counter() - t0
    assert len(calls) == 100 and calls[-1] == (2_000_000, 2_000_000)
    assert all(a[0] < b[0] for a, b in zip(calls, calls[1:]))

    worker = threading.Thread(target=backlash_fmu.identify_mrgia, args=(u, y, 2, 0, 1))
    stamps = [time.perf_counter()]
    worker.start()
    while worker.is_alive():
        stamps.append(time.perf_counter())
    worker.join()
    gaps = np.diff(stamps)
    # Holding the GIL, the call would stop this loop for its whole duration.
    assert gaps.max() < alone / 3, (gaps.max(), alone)


def test_the_backlash_command_is_the_program(cli, tmp_path):
    command = pathlib.Path(sysconfig.get_path("scripts")) / "backlash"
    assert command.is_file(), f"{command}: the package installs no backlash command"
    help_text = subprocess.run([command, "--help"], capture_output=True, text=True, check=True).stdout
    assert "diagnose" in help_text and "identify" in help_text
    u, y = _record(800, 8)
    data = _csv(tmp_path / "r.csv", u, y)
    args = ["identify", "mrgia", data, "--na", "2", "--nb", "0", "--delay", "1", "--json"]
    mine = subprocess.run([command, *args], capture_output=True, text=True, check=True).stdout
    assert mine == subprocess.run([cli, *args], capture_output=True, text=True, check=True).stdout
    bad = subprocess.run([command, "identify", "mrgia", str(tmp_path / "missing.csv"), "--na", "2", "--nb", "0",
                          "--delay", "1"], capture_output=True, text=True)
    assert bad.returncode == 1 and "missing.csv" in bad.stderr


def test_the_study_runs_as_a_module():
    out = subprocess.run([sys.executable, "-m", "backlash_fmu.study", "--help"], capture_output=True, text=True,
                         check=True).stdout
    assert "--scheduler" in out


def test_the_readme_example_runs_as_written(capsys):
    text = (ROOT / "README.md").read_text()
    section = text[text.index("\n## Python\n"):]
    start = section.index("```python\n") + len("```python\n")
    code = section[start:section.index("```", start)]
    exec(compile(code, "README.md (Python example)", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    presence, fit = out[1].split()
    assert out[0].split()[0] == "3" and presence == "present" and float(fit) > 95.0, out
