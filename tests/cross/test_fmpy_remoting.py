"""FMPy's own Wine remoting on the FMI 2.0 FMUs' Windows binary: `simulate_fmu(..., remote_platform='win64')`.

FMPy (0.3.32) starts its win64 server (`wine64 server_tcp.exe MODEL.dll LOCKFILE`) and talks to it over TCP on
rpclib's fixed port 8080; it has no remoting for FMI 3.0. The plant (paper 000's input, with measurement noise)
and the estimator (fed the Linux plant's u and y) must give the same bits as FMPy on the Linux binary.

Two things make this work under Wine, and a hard time limit keeps a failure from hanging CI:
- FMPy calls `wine64` from PATH; Debian keeps it in /usr/lib/wine, so a folder with a link to it goes first on
  PATH. The Wine prefix is the tests' own, with the ProcessPrng shim (conftest.py).
- The server quits when it can open the client's lock file (a file from tempnam(), in TMPDIR): on Windows the
  client holds it open without sharing, but a Linux client's POSIX lock means nothing to Wine, so the server,
  seeing the path as Z:\\tmp\\..., opened it half a second after start and stopped while the client waited for
  an answer that never came: the hang of the first version of this test. Here TMPDIR is a folder whose name
  holds '?', a character Windows paths cannot contain: the server cannot open the lock file and runs until the
  client kills it in fmi2FreeInstance. The FMU itself is extracted elsewhere (Python's tempfile), where the
  server can load the DLL.
"""
import json
import os
import signal
import socket
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from dist_fmus import WINE, dist_fmu, kill_wine, paper_input
from fmpy_remote import simulate

HERE = os.path.dirname(os.path.abspath(__file__))
N = 1000
TIME_LIMIT = 180  # seconds for one remote simulation (it takes a few)
RPC_PORT = 8080  # rpclib's default, fixed in FMPy's remoting client and server
EST_OUTPUTS = ["a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e"]


def windows_only(fmu, out):
    """A copy of the FMU without its Linux binary (FMPy remotes only a platform the FMU lacks on this host)."""
    with zipfile.ZipFile(fmu) as z, zipfile.ZipFile(out, "w") as copy:
        for info in z.infolist():
            if not info.filename.startswith("binaries/") or info.filename.startswith("binaries/win64"):
                copy.writestr(info, z.read(info))
    return out


def port_is_free(port):
    """No program listens on the port (connections of an earlier run waiting out TIME_WAIT do not count)."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


@pytest.fixture(scope="module")
def remote_env(work, wine_env):
    """The environment for FMPy's client: wine64 on PATH, TMPDIR a folder Wine cannot name."""
    bin_dir = work / "fmpy-bin"
    bin_dir.mkdir()
    (bin_dir / "wine64").symlink_to(WINE)
    lock_dir = work / "lock?dir"
    lock_dir.mkdir()
    return {**wine_env, "PATH": f"{bin_dir}{os.pathsep}{os.environ['PATH']}", "TMPDIR": str(lock_dir)}


def run_remote(job, env, tmp_path):
    """fmpy_remote.py on the job in a session of its own; killed with every Wine process after TIME_LIMIT."""
    if not port_is_free(RPC_PORT):
        pytest.fail(f"port {RPC_PORT} is in use: FMPy's remoting server needs it")
    job_file, out, log = tmp_path / "job.json", tmp_path / "out.npy", tmp_path / "remote.log"
    job_file.write_text(json.dumps(job))
    with open(log, "w") as log_file:
        proc = subprocess.Popen([sys.executable, os.path.join(HERE, "fmpy_remote.py"), str(job_file), str(out)],
                                env=env, cwd=tmp_path, stdout=log_file, stderr=subprocess.STDOUT,
                                start_new_session=True)
        try:
            code = proc.wait(timeout=TIME_LIMIT)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            code = f"killed after {TIME_LIMIT} s"
        finally:
            kill_wine(env)  # FMPy's server runs in a session of its own; a failed client leaves it behind
    if code != 0:
        pytest.fail(f"FMPy's remoting failed ({code}):\n{log.read_text()[-4000:]}")
    return np.load(out)


def job(fmu, extract_dir, inputs, outputs, start_values, remote_platform):
    return {"fmu": str(fmu), "remote_platform": remote_platform, "extract_dir": str(extract_dir),
            "stop_time": N - 1, "start_values": start_values, "outputs": outputs,
            "input": {"time": list(np.arange(N, dtype=float)), **{k: list(map(float, v)) for k, v in inputs.items()}}}


def same_bits(linux, windows, names):
    for name in names:
        a, b = linux[name], windows[name]
        assert len(a) == len(b) == N, (name, len(a), len(b))
        differ = np.flatnonzero(a.view(np.uint64) != b.view(np.uint64))
        assert differ.size == 0, f"{name} differs from step {differ[0]}: {b[differ[0]]!r} vs {a[differ[0]]!r}"


def test_fmpy_runs_the_windows_binary_through_wine_with_the_linux_bits(work, remote_env, tmp_path):
    extract = tmp_path / "extract"
    extract.mkdir()
    u = paper_input(N)
    plant, est = dist_fmu(2, "BacklashPlant"), dist_fmu(2, "MrgiaEstimator")
    noise = {"noise_std": 0.02, "noise_seed": 7}

    linux_plant = simulate(job(plant, extract, {"u": u}, ["y", "w"], noise, None))
    (tmp_path / "plant").mkdir()
    win_plant = run_remote(job(windows_only(plant, tmp_path / "plant.fmu"), extract, {"u": u}, ["y", "w"], noise,
                               "win64"), remote_env, tmp_path / "plant")
    same_bits(linux_plant, win_plant, ["y", "w"])
    assert np.std(linux_plant["y"] - linux_plant["w"]) > 0.01, "the noise reached y"

    fed = {"u": u, "y": linux_plant["y"]}
    linux_est = simulate(job(est, extract, fed, EST_OUTPUTS, {}, None))
    (tmp_path / "est").mkdir()
    win_est = run_remote(job(windows_only(est, tmp_path / "est.fmu"), extract, fed, EST_OUTPUTS, {}, "win64"),
                         remote_env, tmp_path / "est")
    same_bits(linux_est, win_est, EST_OUTPUTS)
