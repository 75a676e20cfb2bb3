"""The wear monitor of MrgiaEstimator.fmu in co-simulation (FMPy master of cosim.py), FMI 2.0 and 3.0: the plant
FMU's gaps grow by 50% at sample 5000 (a wear step set with `plant_events`); the estimator FMU with `monitor`
on raises `wear_alarm` after the step and never before, and `wear_onset` lies within the measured delay of the
true time. The program and the Python function give the same alarm on the same record.

Paper 000, section 4 plant, uniform white input of variance 1.93, SNR 20 (noise std = std(w) / 20).
"""
import json
import subprocess

import numpy as np
import pytest

import backlash_fmu as bf
import reference
from backlash_fmu.cosim import paper_input, run_pair

STEP = 5000
N = 8000
WEAR = ("play", "play_se", "wear_statistic", "wear_alarm", "wear_onset")


def _noise_std(u):
    _, w = reference.simulate(u)
    return float(np.std(w)) / 20.0


def _pair(plant, estimator, seed, monitor=True, step=True, estimator_events=None, **estimator_start):
    u = paper_input(N, seed)
    events = {STEP: {"c1": 0.75, "c2": 1.5}} if step else None
    start = {"monitor": True, **estimator_start} if monitor else {"refine": True, **estimator_start}
    r = run_pair(plant, estimator, u, plant_start={"noise_std": _noise_std(u), "noise_seed": 900 + seed},
                 estimator_start=start, plant_events=events, estimator_outputs=WEAR,
                 estimator_events=estimator_events)
    return u, r


def _check_alarm(r):
    alarm = r["outputs"]["wear_alarm"]
    samples = r["samples"]
    # Outputs after sample count s are those after samples 0..s-1: the step acts from sample STEP on.
    assert not alarm[samples <= STEP].any(), samples[alarm][:5]
    assert alarm[-1]
    first = samples[np.argmax(alarm)] - 1  # the sample that raised it
    delay = first - STEP
    onset = r["outputs"]["wear_onset"][-1]
    assert 0 <= delay < 1000, delay
    assert abs(onset - STEP) <= delay, (onset, delay)
    assert np.all(r["outputs"]["wear_onset"][~alarm] == 0.0)
    stat = r["outputs"]["wear_statistic"]
    assert stat[samples - 1 == first][0] == 0.0 or stat.max() > 0.0
    return first, onset


@pytest.mark.parametrize("version", [2, 3])
def test_alarm_after_a_wear_step_never_before(version, request):
    plant = request.getfixturevalue("plant_fmu" if version == 2 else "plant_fmu3")
    estimator = request.getfixturevalue("estimator_fmu" if version == 2 else "estimator_fmu3")
    for seed in range(2):
        _, r = _pair(plant, estimator, seed)
        _check_alarm(r)
        play = r["outputs"]["play"]
        assert abs(play[STEP - 1] - 1.5) < 0.05, play[STEP - 1]


@pytest.mark.parametrize("version", [2, 3])
def test_wear_reset_clears_the_latched_alarm(version, request):
    """The input `wear_reset`, true for one sample, clears wear_alarm and wear_onset at that sample."""
    plant = request.getfixturevalue("plant_fmu" if version == 2 else "plant_fmu3")
    estimator = request.getfixturevalue("estimator_fmu" if version == 2 else "estimator_fmu3")
    _, r = _pair(plant, estimator, 0)
    first, _ = _check_alarm(r)
    k = first + 20
    _, again = _pair(plant, estimator, 0, estimator_events={k: {"wear_reset": True}, k + 1: {"wear_reset": False}})
    alarm, samples = again["outputs"]["wear_alarm"], again["samples"]
    assert alarm[samples == k].all()  # latched until the reset sample
    assert not alarm[samples == k + 1].any()  # outputs after sample k: cleared
    assert again["outputs"]["wear_onset"][samples == k + 1][0] == 0.0


def test_no_alarm_without_a_step_and_monitor_leaves_estimates(plant_fmu, estimator_fmu):
    """Unchanged plant: no alarm at the default period; the estimates equal those of `refine` alone (the
    monitor only reads the estimator), and with the monitor off its outputs stay 0."""
    _, on = _pair(plant_fmu, estimator_fmu, 5, step=False)
    assert not on["outputs"]["wear_alarm"].any()
    assert on["outputs"]["wear_statistic"].max() < 1.0
    _, off = _pair(plant_fmu, estimator_fmu, 5, monitor=False, step=False)
    assert np.array_equal(on["estimates"], off["estimates"])
    assert np.array_equal(on["std_err"], off["std_err"])
    assert not off["outputs"]["wear_alarm"].any()
    assert np.all(off["outputs"]["wear_statistic"] == 0.0)
    assert np.all(off["outputs"]["wear_onset"] == 0.0)


def test_cli_and_python_give_the_fmu_alarm(plant_fmu, estimator_fmu, cli, tmp_path):
    u, r = _pair(plant_fmu, estimator_fmu, 1)
    first, onset = _check_alarm(r)
    data = tmp_path / "record.csv"
    np.savetxt(data, np.column_stack([np.arange(float(N)), u, r["y"]]), delimiter=",", header="time,u,y",
               comments="", fmt="%.17g")
    png = tmp_path / "monitor.png"
    out = subprocess.run([cli, "monitor", str(data), "--na", "2", "--nb", "0", "--delay", "1", "--json",
                          "--plot", str(png)], capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    assert j["alarms"][0]["time"] == first and j["alarms"][0]["onset"] == onset
    assert png.stat().st_size > 10_000
    py = bf.monitor(u, r["y"], 2, 0, 1)
    for key in ("alarms", "play", "play_se", "samples"):
        assert py[key] == j[key], key
    a = j["alarms"][0]
    assert a["play_before"] < a["play_after"]
    assert abs(a["play_after"] - 2.25) < 4 * a["play_after_se"] + 0.05, a
    assert abs(j["play"] - r["outputs"]["play"][-1]) < 1e-12
