"""Shared fixtures: where the built FMUs and the CLI are."""
import os
import pathlib
import sys

import pytest

from backlash_fmu import cosim

ROOT = pathlib.Path(__file__).resolve().parents[2]
# The scripts' modules (data_records: where the measured records are) are importable by the tests.
sys.path.insert(0, str(ROOT / "scripts"))
FMU_DIR = pathlib.Path(os.environ.get("BACKLASH_FMU_DIR", ROOT / "target" / "fmu"))
FMU3_DIR = pathlib.Path(os.environ.get("BACKLASH_FMU3_DIR", ROOT / "target" / "fmu3"))
CLI = pathlib.Path(os.environ.get("BACKLASH_CLI", ROOT / "target" / "release" / "backlash"))


class Log:
    """Records what the FMUs log.

    fmpy formats the variadic C message in a native proxy that keeps ONE global pointer to the last Python
    logger registered; a logger that is garbage-collected leaves that pointer dangling. So the tests share
    this one instance for the whole session (LOG below) and pass its callbacks to every FMU they instantiate.
    """

    def __init__(self):
        from ctypes import byref

        from fmpy.fmi2 import defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
        from fmpy.logging import addLoggerProxy

        self.lines = []
        self._fn = fmi2CallbackLoggerTYPE(self._record)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._fn
        self.callbacks.allocateMemory = defaultCallbacks.allocateMemory
        self.callbacks.freeMemory = defaultCallbacks.freeMemory
        addLoggerProxy(byref(self.callbacks))

    def _record(self, env, name, status, category, message):
        self.lines.append((status, category.decode(), message.decode()))


LOG = Log()
# The package's co-simulation helpers instantiate their FMUs with this logger too (one per process).
cosim.use_callbacks(LOG.callbacks)


class Log3:
    """Records what FMI 3.0 FMUs log: pass `LOG3.record` as FMU3Slave.instantiate's logMessage (fmpy keeps the
    ctypes callback with the slave; FMI 3.0 messages are plain text, no variadic format)."""

    def __init__(self):
        self.lines = []

    def record(self, env, status, category, message):
        self.lines.append((status, category.decode(), message.decode()))


LOG3 = Log3()


def _need(path):
    if not path.exists():
        pytest.fail(f"{path} is missing: run `cargo build --release` first")
    return str(path)


@pytest.fixture(scope="session")
def plant_fmu():
    return _need(FMU_DIR / "BacklashPlant.fmu")


@pytest.fixture(scope="session")
def estimator_fmu():
    return _need(FMU_DIR / "MrgiaEstimator.fmu")


@pytest.fixture(scope="session")
def plant_fmu3():
    return _need(FMU3_DIR / "BacklashPlant.fmu")


@pytest.fixture(scope="session")
def estimator_fmu3():
    return _need(FMU3_DIR / "MrgiaEstimator.fmu")


@pytest.fixture(scope="session")
def cli():
    return _need(CLI)
