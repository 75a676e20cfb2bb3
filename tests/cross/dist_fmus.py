"""What the tests beside this file share (pytest puts this folder on sys.path): where scripts/dist.sh leaves the
release FMUs, and how a tool is run (with a time limit, its output in the failure)."""
import os
import pathlib
import subprocess

import numpy as np

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DIST = ROOT / "target" / "dist"
PAPER_INPUT_VARIANCE = 1.93  # paper 000, section 4 (src/identify/mrgia/study.rs)
# Debian keeps wine64 in /usr/lib/wine, off PATH.
WINE = os.environ.get("WINE64", "/usr/lib/wine/wine64")


def dist_fmu(version, model):
    """target/dist/fmi<version>/<model>.fmu; the test fails (not skips) when dist.sh has not made it."""
    path = DIST / f"fmi{version}" / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `bash scripts/dist.sh` first")
    return path


def run(cmd, timeout=600, **kw):
    """Runs cmd; a failure or a timeout fails the test with the end of its output."""
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, **kw)
    if out.returncode != 0:
        pytest.fail(f"{cmd[0]} failed ({out.returncode}):\n{out.stdout[-2000:]}\n{out.stderr[-4000:]}")
    return out


def paper_input(n):
    """n samples of paper 000's input: white, uniform, variance 1.93 (seed 0)."""
    amp = np.sqrt(3 * PAPER_INPUT_VARIANCE)
    return np.random.default_rng(0).uniform(-amp, amp, n)


def kill_wine(env):
    """Ends every process of the Wine prefix in env and its wineserver (exit status 1: none was running)."""
    server = os.path.join(os.path.dirname(WINE), "wineserver")
    subprocess.run([server if os.access(server, os.X_OK) else "wineserver", "-k"], env=env, timeout=60,
                   capture_output=True)
