"""The Dask co-simulation study (backlash_fmu.study, `python -m backlash_fmu.study`): a LocalCluster of worker
processes gives exactly the serial table, and a cell's rows are what the reference master cosim.run_pair
reads from the same FMUs."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import reference
from backlash_fmu import study as cosim_study
from backlash_fmu.cosim import run_pair
from conftest import LOG

# In this process the FMUs log to the session's one logger (conftest.py hands it to backlash_fmu.cosim).

GRID = dict(seeds=2, ns=[300, 1000], snrs=[43.0], plants=["paper", "second-order-b"])


@pytest.fixture(scope="module")
def serial(plant_fmu, estimator_fmu):
    rows, _ = cosim_study.run_study(plant_fmu, estimator_fmu, **GRID, quiet=True)
    return rows


def test_local_cluster_gives_the_serial_table(plant_fmu, estimator_fmu, serial):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        rows, _ = cosim_study.run_study(plant_fmu, estimator_fmu, **GRID, client=client, quiet=True)
        # The tasks really ran in the two worker processes, not here.
        assert len(client.scheduler_info()["workers"]) == 2
    # 2 plants x 1 SNR x 2 seeds x 2 N x 2 methods x (6 or 7 parameters).
    assert len(serial) == 2 * 2 * 2 * (6 + 7)
    assert cosim_study.to_csv(rows) == cosim_study.to_csv(serial)


def test_cells_read_what_the_reference_master_reads(plant_fmu, estimator_fmu, serial):
    for plant, seed in [("paper", 1), ("second-order-b", 0)]:
        p = cosim_study.PLANTS[plant]
        u = cosim_study.paper_input(1000, seed)
        _, w = reference.simulate(u, a=(p["a1"], p["a2"]), b=(p["b0"], p["b1"])[: p["nb"] + 1], m2=p["m2"],
                                  c1=p["c1"], c2=p["c2"])
        noise_std = float(np.std(w)) / 43.0
        names = cosim_study.param_names(plant)
        for method, start in [("mrgia-paper", {}), ("mrgia-recommended", {"recommended": True})]:
            r = run_pair(plant_fmu, estimator_fmu, u,
                         plant_start={**cosim_study._plant_start(plant, noise_std, seed + 1_000_000)},
                         estimator_start={"na": p["na"], "nb": p["nb"], **start}, checkpoints=[300, 1000],
                         callbacks=LOG.callbacks)
            for i, n in enumerate([300, 1000]):
                mine = [x for x in serial if x[0] == plant and x[2] == n and x[3] == seed and x[5] == method]
                assert [x[6] for x in mine] == names
                assert math.isclose(mine[0][4], noise_std, rel_tol=1e-12)
                expect = [r["estimates"][i][r["names"].index(k)] for k in names]
                assert [x[8] for x in mine] == expect, (plant, method, n)
                assert all(x[9] == x[8] - x[7] and x[7] == p[x[6]] for x in mine)


def test_module_runs_serially_and_writes_its_files(plant_fmu, estimator_fmu, tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "backlash_fmu.study", "--serial", "--seeds", "2", "--ns", "100,200",
         "--plant-fmu", plant_fmu, "--estimator-fmu", estimator_fmu, "--out", tmp_path, "--json"],
        capture_output=True, text=True, check=True).stdout
    report = json.loads(out)
    assert report["runs"] == 2 and report["mode"] == "serial"
    lines = (tmp_path / "cosim_study.csv").read_text().splitlines()
    assert lines[0] == cosim_study.HEADER and len(lines) == 1 + 2 * 2 * 2 * 6
    assert (tmp_path / "cosim_study.png").stat().st_size > 10_000


def test_unknown_plant_is_refused_with_the_known_ones(plant_fmu, estimator_fmu):
    with pytest.raises(ValueError, match="unknown plant variant.*'tiny'.*known: paper, wide-gaps"):
        cosim_study.run_study(plant_fmu, estimator_fmu, 1, [100], plants=["tiny"])
