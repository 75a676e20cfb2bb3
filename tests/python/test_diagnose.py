"""`backlash diagnose` from outside: records simulated here with numpy (an implementation of the contract's
plant that shares no code with the Rust one), and the measured friction damper brfd (found by
scripts/data_records.py)."""
import json
import subprocess

import numpy as np
import pytest
from data_records import record_path


def plant(u, noise_std, seed, clip=None):
    """Paper 000's plant: x(k) = -0.45 x(k-1) - 0.55 x(k-2) + 0.8 u(k-1), backlash m1 = 1, m2 = 1.5,
    c1 = 0.5, c2 = 1, white noise on the output; optionally the measured value clipped to `clip`."""
    n = len(u)
    x = np.zeros(n)
    w = np.zeros(n)
    for k in range(n):
        x[k] = (-0.45 * x[k - 1] if k >= 1 else 0) + (-0.55 * x[k - 2] if k >= 2 else 0) + (
            0.8 * u[k - 1] if k >= 1 else 0
        )
        prev = w[k - 1] if k else 0.0
        if x[k] > prev + 0.5:
            w[k] = x[k] - 0.5
        elif x[k] < prev / 1.5 - 1.0:
            w[k] = 1.5 * (x[k] + 1.0)
        else:
            w[k] = prev
    y = w + noise_std * np.random.default_rng(seed).standard_normal(n)
    if clip is not None:
        y = np.clip(y, *clip)
    return y


def record(tmp_path, name, u, y):
    path = tmp_path / name
    t = np.arange(len(u)) * 0.01
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="time,u,y", comments="", fmt="%.17g")
    return path


def diagnose(cli, path, *extra):
    out = subprocess.run(
        [cli, "diagnose", str(path), "--na", "2", "--nb", "0", "--delay", "1", "--json", *extra],
        capture_output=True,
        text=True,
        check=True,
    )
    lines = [l for l in out.stdout.splitlines() if l.strip()]
    assert len(lines) == 1, "--json prints exactly one JSON object"
    return json.loads(lines[0])


def paper_input(n, seed):
    a = np.sqrt(3 * 1.93)
    return np.random.default_rng(seed).uniform(-a, a, n)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_clean_records_are_null(cli, tmp_path, seed):
    u = paper_input(3000, 100 + seed)
    y = plant(u, 0.03, seed)
    j = diagnose(cli, record(tmp_path, "clean.csv", u, y))
    assert j["effect"]["id"] is None
    assert j["after"]["rmse"] == j["before"]["rmse"]
    assert j["before"]["rmse"] < 0.04


def test_saturation_is_named(cli, tmp_path):
    u = paper_input(3000, 7)
    y0 = plant(u, 0.0, 0)
    lo, hi = np.quantile(y0, [0.08, 0.92])
    y = plant(u, 0.03, 7, clip=(lo, hi))
    j = diagnose(cli, record(tmp_path, "clipped.csv", u, y))
    assert j["effect"]["id"] == "saturation"
    assert isinstance(j["effect"]["pointed_by"], str)
    assert j["after"]["rmse"] < 0.5 * j["before"]["rmse"]
    p = j["effect"]["parameters"]
    assert abs(p["hi"] - hi) < 0.05 and abs(p["lo"] - lo) < 0.05


def test_measured_friction_damper(cli, tmp_path):
    """The command of docs/RESULTS.md: the winner is friction and it at least halves the held-out RMSE."""
    out = subprocess.run(
        [
            cli, "diagnose", str(record_path("brfd/char_0.5Hz_36lb_1in.csv")), "--na", "0", "--nb", "0",
            "--delay", "1",
            "--decimate", "16", "--time-col", "t", "--json", "--report", str(tmp_path / "report"),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    j = json.loads(out.stdout)
    assert j["effect"]["id"] == "friction"
    assert j["after"]["rmse"] <= 0.5 * j["before"]["rmse"]
    assert (tmp_path / "report" / "report.md").exists()
    assert (tmp_path / "report" / "evidence.png").stat().st_size > 1000


def test_bad_file_is_refused_with_its_name(cli, tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,u\n0,1\n1,2\n")
    out = subprocess.run([cli, "diagnose", str(path), "--na", "1", "--nb", "0", "--delay", "1", "--json"],
                         capture_output=True, text=True)
    assert out.returncode != 0
    assert out.stdout == ""
    assert "bad.csv" in out.stderr and "'y'" in out.stderr
