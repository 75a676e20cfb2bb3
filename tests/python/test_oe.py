"""`backlash identify oe`, `backlash crb` and `backlash study` through the command line, checked against the
independent NumPy plant of reference.py (model output, Fisher information by finite differences)."""
import json
import pathlib
import statistics
import subprocess
import sys
import time

import numpy as np
import pytest

import reference

ROOT = pathlib.Path(__file__).resolve().parents[2]
TRUTH = dict(a=[0.45, 0.55], b=[0.8], m2=1.5, c1=0.5, c2=1.0)
NAMES = ["a1", "a2", "b0", "m2", "c1", "c2"]


def paper_record(n, seed, snr=43.0):
    rng = np.random.default_rng(seed)
    amp = np.sqrt(3 * 1.93)
    u = rng.uniform(-amp, amp, n)
    _, w = reference.simulate(u)
    std = w.std() / snr
    return u, w + std * rng.standard_normal(n), std


def write_csv(path, u, y=None):
    with open(path, "w") as f:
        f.write("time,u" + (",y" if y is not None else "") + "\n")
        for k in range(len(u)):
            row = [repr(0.01 * k), repr(float(u[k]))] + ([repr(float(y[k]))] if y is not None else [])
            f.write(",".join(row) + "\n")


def flat(obj):
    return list(obj["a"]) + list(obj["b"]) + [obj["m2"], obj["c1"], obj["c2"]]


def w_of(u, theta):
    _, w = reference.simulate(u, a=theta[:2], b=theta[2:3], delay=1, m2=theta[3], c1=theta[4], c2=theta[5])
    return w


def fd_jacobian(u, theta):
    cols = []
    for i, t in enumerate(theta):
        h = 1e-7 * max(abs(t), 0.1)
        tp, tm = list(theta), list(theta)
        tp[i] += h
        tm[i] -= h
        cols.append((w_of(u, tp) - w_of(u, tm)) / (2 * h))
    return np.column_stack(cols)


def run(cli, *args, check=True):
    p = subprocess.run([cli, *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        pytest.fail(f"{args} failed: {p.stderr}")
    return p


@pytest.fixture(scope="module")
def paper_fit(cli, tmp_path_factory):
    u, y, std = paper_record(3000, 11)
    path = tmp_path_factory.mktemp("oe") / "paper.csv"
    write_csv(path, u, y)
    res = path.with_name("residuals.csv")
    out = json.loads(
        run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--json", "--residuals", res).stdout
    )
    return u, y, std, path, res, out


def test_json_has_the_contract_keys_and_the_estimate_is_accurate(paper_fit):
    u, y, std, _, _, out = paper_fit
    for key in ["method", "a", "b", "m1", "m2", "c1", "c2", "samples", "std_err"]:
        assert key in out, key
    assert out["method"] == "oe" and out["m1"] == 1.0 and out["samples"] == 3000
    assert len(out["a"]) == 2 and len(out["b"]) == 1
    assert set(out["std_err"]) == {"a", "b", "m2", "c1", "c2"}
    assert len(out["std_err"]["a"]) == 2 and len(out["std_err"]["b"]) == 1
    est, se = np.array(flat(out)), np.array(flat(out["std_err"]))
    truth = np.array(flat(TRUTH))
    assert np.all(se > 0)
    # Every parameter within 4.5 standard errors of the truth (a 1-in-10^5 event per parameter otherwise).
    assert np.all(np.abs(est - truth) <= 4.5 * se), (est, se)
    assert abs(out["sigma"] / std - 1) < 0.1
    assert out["converged"]


def test_model_output_equals_the_independent_simulation(paper_fit):
    u, y, _, _, res, out = paper_fit
    data = np.genfromtxt(res, delimiter=",", names=True)
    assert list(data.dtype.names) == ["time", "u", "y", "y_oe", "e_oe", "y_start"]
    w = w_of(u, flat(out))
    np.testing.assert_allclose(data["y_oe"], w, atol=1e-9)
    np.testing.assert_allclose(data["e_oe"], y - w, atol=1e-9)
    assert abs(np.sum((y - w) ** 2) - out["cost"]) <= 1e-9 * out["cost"]


def test_standard_errors_equal_the_fisher_information_by_finite_differences(paper_fit):
    u, y, _, _, _, out = paper_fit
    theta = flat(out)
    jac = fd_jacobian(u, theta)
    s2 = np.sum((y - w_of(u, theta)) ** 2) / (len(u) - 6)
    se = np.sqrt(np.diag(s2 * np.linalg.inv(jac.T @ jac)))
    np.testing.assert_allclose(flat(out["std_err"]), se, rtol=1e-4)
    cov = np.array(out["covariance"]).reshape(6, 6)
    np.testing.assert_allclose(cov, s2 * np.linalg.inv(jac.T @ jac), rtol=1e-3, atol=1e-12)


def test_human_output_shows_plus_minus(cli, paper_fit):
    path = paper_fit[3]
    out = run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--target-rel", "1e-4").stdout
    for name in NAMES:
        assert f"{name:>3} = " in out
    assert out.count("+/-") >= 6
    assert "samples for a relative std <= 1e-4" in out


def test_planning_scales_as_one_over_sqrt_n(cli, paper_fit):
    path, out = paper_fit[3], paper_fit[5]
    plan = json.loads(
        run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--json", "--target-rel", 1e-4).stdout
    )["plan"]
    est, se = np.array(flat(out)), np.array(flat(out["std_err"]))
    want = np.ceil(3000 * (se / (np.abs(est) * 1e-4)) ** 2)
    got = np.array([plan["samples"][n] for n in NAMES])
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1)
    assert plan["samples_all"] == int(got.max())


def test_unexcited_record_is_refused(cli, tmp_path):
    path = tmp_path / "still.csv"
    write_csv(path, np.zeros(400), np.zeros(400))
    p = run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--json", check=False)
    assert p.returncode != 0 and p.stdout == ""
    assert "does not excite" in p.stderr and "still.csv" in p.stderr


def test_bad_file_is_refused_with_its_name(cli, tmp_path):
    path = tmp_path / "noy.csv"
    write_csv(path, np.ones(50))
    p = run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--json", check=False)
    assert p.returncode != 0 and p.stdout == ""
    assert "noy.csv" in p.stderr and "y" in p.stderr


def test_crb_command_equals_the_numpy_bound(cli, tmp_path):
    u, _, _ = paper_record(2000, 5)
    path = tmp_path / "input.csv"
    write_csv(path, u)
    out = json.loads(run(cli, "crb", path, "--noise-std", 0.02, "--json", "--target-rel", 1e-3).stdout)
    assert out["method"] == "crb" and out["samples"] == 2000
    jac = fd_jacobian(u, flat(TRUTH))
    want = 0.02 * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    np.testing.assert_allclose(flat(out["std"]), want, rtol=1e-4)
    rel = want / np.abs(flat(TRUTH))
    assert out["plan"]["samples_all"] == int(np.ceil(2000 * (rel.max() / 1e-3) ** 2))
    # --snr derives the noise from the noise-free output on this input.
    snr = json.loads(run(cli, "crb", path, "--snr", 43, "--json").stdout)
    assert abs(snr["noise_std"] - w_of(u, flat(TRUTH)).std() / 43) < 1e-12
    # The paper input needs no file.
    paper = json.loads(run(cli, "crb", "--paper-input", 3000, "--snr", 43, "--json").stdout)
    assert paper["samples"] == 3000 and paper["input"].startswith("paper input")


def test_identify_oe_is_fast(cli, paper_fit):
    path = paper_fit[3]
    times = []
    for _ in range(7):
        t0 = time.perf_counter()
        run(cli, "identify", "oe", path, "--na", 2, "--nb", 0, "--delay", 1, "--json")
        times.append(time.perf_counter() - t0)
    assert statistics.median(times) < 0.1, times


def test_study_command_writes_its_files(cli, tmp_path):
    out = json.loads(run(cli, "study", "--seeds", 3, "--ns", "300,1000", "--json", "--out", tmp_path).stdout)
    assert {s["method"] for s in out["stats"]} == {"mrgia-paper", "mrgia-recommended", "refine", "oe", "crb"}
    assert out["names"] == NAMES
    for name in ["oe_study.png", "oe_study.csv", "oe_study.json"]:
        assert (tmp_path / name).stat().st_size > 100


def test_benchmark_script_agrees_with_scipy(cli):
    p = subprocess.run(
        [sys.executable, ROOT / "scripts" / "oe_benchmark.py", "--cli", cli, "--repeat", "3", "--scipy-repeat", "1",
         "--json"],
        capture_output=True, text=True,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    report = json.loads(p.stdout)
    assert report["same_optimum"] and report["cli_seconds_median"] < 0.1
