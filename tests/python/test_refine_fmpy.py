"""MrgiaEstimator.fmu with `refine` in the plant + estimator pair (FMPy master of cosim.py): it converges to the
paper plant at the output-error accuracy, its standard errors are 0 during the warm-up and then those of
`identify mrgia --refine`, which gives the same numbers to 1e-12 on the same data.

Paper 000, section 4 plant, uniform white input of variance 1.93, SNR 43 (noise std = std(w) / 43).
"""
import json
import subprocess

import numpy as np

import reference
from backlash_fmu.cosim import CHECKED, PAPER_TRUTH, max_rel_error, paper_input, run_pair

WARMUP = 500  # samples of plain MRGIA before the recursion starts (identify::oe::online::WARMUP)


def _noise_std(u):
    _, w = reference.simulate(u)
    return float(np.std(w)) / 43.0


def _pair(plant_fmu, estimator_fmu, u, seed, checkpoints, **estimator_start):
    return run_pair(plant_fmu, estimator_fmu, u,
                    plant_start={"noise_std": _noise_std(u), "noise_seed": 500 + seed},
                    estimator_start={"refine": True, **estimator_start}, checkpoints=checkpoints)


def test_refine_pair_converges_with_standard_errors(plant_fmu, estimator_fmu):
    """At N = 3000, the refined estimate is within 4 of its own standard errors of the truth on every seed
    (an efficient estimator's worst of six normal errors exceeds 4 with probability 4e-4), the standard errors
    are 0 before the warm-up ends and positive after."""
    for seed in range(3):
        u = paper_input(3000, seed)
        r = _pair(plant_fmu, estimator_fmu, u, seed, [WARMUP - 1, 3000])
        cols = list(r["names"])
        se_early, se = r["std_err"][0], r["std_err"][1]
        assert np.all(se_early == 0.0), se_early
        est = r["estimates"][1]
        for name in CHECKED:
            i = cols.index(name)
            assert se[i] > 0.0, (name, se[i])
            z = abs(est[i] - PAPER_TRUTH[name]) / se[i]
            assert z < 4.0, (seed, name, est[i], se[i])
        assert max_rel_error(dict(zip(cols, est))) < 2e-2, est


def test_refine_pair_equals_the_cli(plant_fmu, estimator_fmu, cli, tmp_path):
    u = paper_input(2000, 7)
    r = _pair(plant_fmu, estimator_fmu, u, 7, [2000])
    data = tmp_path / "record.csv"
    np.savetxt(data, np.column_stack([np.arange(2000.0), u, r["y"]]), delimiter=",", header="time,u,y",
               comments="", fmt="%.17g")
    out = subprocess.run([cli, "identify", "mrgia", str(data), "--na", "2", "--nb", "0", "--delay", "1",
                          "--refine", "--json"], capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    assert j["method"] == "mrgia" and j["samples"] == 2000 and j["refine"] is True
    cli_est = dict(a1=j["a"][0], a2=j["a"][1], b0=j["b"][0], m2=j["m2"], c1=j["c1"], c2=j["c2"])
    s = j["std_err"]
    cli_se = dict(a1=s["a"][0], a2=s["a"][1], b0=s["b"][0], m2=s["m2"], c1=s["c1"], c2=s["c2"])
    cols = list(r["names"])
    for name in CHECKED:
        i = cols.index(name)
        assert abs(cli_est[name] - r["estimates"][-1][i]) <= 1e-12, (name, cli_est[name], r["estimates"][-1][i])
        assert abs(cli_se[name] - r["std_err"][-1][i]) <= 1e-12, (name, cli_se[name], r["std_err"][-1][i])
        assert cli_se[name] > 0.0
