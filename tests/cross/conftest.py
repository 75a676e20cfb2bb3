"""Fixtures of the cross-platform tests: a scratch folder and a Wine prefix of their own."""
import os
import shutil

import pytest

from dist_fmus import WINE, kill_wine, run

HERE = os.path.dirname(os.path.abspath(__file__))


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("cross")


@pytest.fixture(scope="session")
def wine_env(work):
    """A Wine prefix of its own with the ProcessPrng shim as C:\\windows\\system32\\bcryptprimitives.dll.

    Wine 8.0 lacks bcryptprimitives.dll, which Rust's standard library imports (every Windows from 10 on has it);
    the shim (prng_shim.c) goes into this prefix only, never into an FMU. Every Wine process of the prefix is
    killed at the end of the session."""
    if not os.access(WINE, os.X_OK):
        pytest.fail(f"{WINE} is missing (apt-get install wine64)")
    prefix = work / "wineprefix"
    env = dict(os.environ, WINEPREFIX=str(prefix), WINEDEBUG="-all", WINEDLLOVERRIDES="mscoree,mshtml=")
    run([WINE, "wineboot", "--init"], env=env)
    shim = work / "bcryptprimitives.dll"
    run(["x86_64-w64-mingw32-gcc", "-O2", "-shared", "-static-libgcc", "-o", str(shim),
         os.path.join(HERE, "prng_shim.c"), os.path.join(HERE, "prng_shim.def"), "-ladvapi32"])
    shutil.copy(shim, prefix / "drive_c" / "windows" / "system32" / "bcryptprimitives.dll")
    yield env
    kill_wine(env)

