"""Where scripts/dist.sh leaves the release FMUs, for the tests beside this file (pytest puts this folder on
sys.path)."""
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
DIST = ROOT / "target" / "dist"


def dist_fmu(version, model):
    """target/dist/fmi<version>/<model>.fmu; the test fails (not skips) when dist.sh has not made it."""
    path = DIST / f"fmi{version}" / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `bash scripts/dist.sh` first")
    return path
