"""The fleet (backlash_fmu.fleet, `python -m backlash_fmu.fleet`): a LocalCluster of two worker processes
writes the serial table byte for byte (but for the wall times), a refused record is a row with the program's
message and does not stop the others, and the Parquet file holds the CSV's rows."""
import json
import subprocess
import sys

import numpy as np
import pytest

from backlash_fmu import fleet, simulate

COLUMNS_BUT_TIME = [c for c in fleet.COLUMNS if c != "seconds"]


def _record(path, seed, n=1500, **params):
    a = np.sqrt(3 * 1.93)
    u = np.random.default_rng(seed).uniform(-a, a, n)
    y = simulate(u, noise_std=0.04, noise_seed=seed, **params)["y"]
    t = np.arange(n) * 0.01
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="time,u,y", comments="", fmt="%.17g")


@pytest.fixture(scope="module")
def fleet_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    _record(d / "a_paper.csv", 1)
    _record(d / "b_wide.csv", 2, c1=1.0, c2=2.0)
    # Line 4, column 3 is not a number: refused with the file, line and column.
    (d / "c_broken.csv").write_text("time,u,y\n0,1,2\n0.01,1,2\n0.02,1,oops\n")
    _record(d / "d_nb1.csv", 4, b=[0.8, 0.4])
    (d / "notes.txt").write_text("not a record\n")
    return d


@pytest.fixture(scope="module")
def serial(fleet_dir):
    return fleet.run([fleet_dir])


def test_a_folder_is_its_csv_files_and_a_refused_record_is_a_row(fleet_dir, serial):
    assert [r["file"] for r in serial] == [str(fleet_dir / f) for f in
                                           ("a_paper.csv", "b_wide.csv", "c_broken.csv", "d_nb1.csv")]
    broken = serial[2]
    assert "c_broken.csv" in broken["error"] and "line 4" in broken["error"], broken["error"]
    assert broken["na"] is None and broken["effects"] is None
    for r in serial[:2] + serial[3:]:
        assert r["error"] == "", r["error"]
        assert r["before_rmse"] > 0 and r["after_rmse"] > 0 and r["linear_rmse"] > 0 and r["seconds"] > 0
    # The rows are the command's answers.
    out = subprocess.run([sys.executable, "-m", "backlash_fmu._cli", "diagnose", serial[3]["file"], "--json"],
                         capture_output=True, text=True, check=True)
    j = json.loads(out.stdout)
    assert (serial[3]["na"], serial[3]["nb"], serial[3]["delay"]) == (j["na"], j["nb"], j["delay"])
    assert serial[3]["effects"] == "+".join(e["id"] for e in j["effects"])
    assert serial[3]["after_rmse"] == j["after"]["rmse"]


def test_a_local_cluster_writes_the_serial_table(fleet_dir, serial, tmp_path):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        rows = fleet.run([fleet_dir], client)
        assert len(client.scheduler_info()["workers"]) == 2
    assert fleet.to_csv(rows, COLUMNS_BUT_TIME) == fleet.to_csv(serial, COLUMNS_BUT_TIME)
    csv_path, parquet_path = fleet.write(rows, tmp_path / "out" / "fleet")
    import pyarrow.parquet as pq

    table = pq.read_table(parquet_path).to_pylist()
    assert [list(r) for r in table] == [list(fleet.COLUMNS)] * len(rows)
    assert fleet.to_csv(table) == csv_path.read_text() == fleet.to_csv(rows)


def test_the_command_writes_both_files(fleet_dir, tmp_path):
    prefix = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "backlash_fmu.fleet", str(fleet_dir / "a_paper.csv"),
                           str(fleet_dir / "c_broken.csv"), "--out", str(prefix), "--workers", "1", "--quiet"],
                          capture_output=True, text=True, check=True)
    assert "2 records (1 refused)" in done.stderr
    lines = (tmp_path / "run.csv").read_text().splitlines()
    assert lines[0] == ",".join(fleet.COLUMNS) and len(lines) == 3
    assert (tmp_path / "run.parquet").stat().st_size > 0
    (tmp_path / "empty").mkdir()
    bad = subprocess.run([sys.executable, "-m", "backlash_fmu.fleet", str(tmp_path / "empty"), "--out",
                          str(prefix)], capture_output=True, text=True)
    assert bad.returncode == 2 and "no record" in bad.stderr
