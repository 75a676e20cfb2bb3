"""The release FMUs of scripts/dist.sh on every platform they carry, run where each platform's binary runs.

`bash scripts/cross_test.sh` builds target/dist and runs this file. The same C master (master.c) is compiled for
x86_64 Linux (gcc), Windows (mingw-w64; run under Wine, with the ProcessPrng shim of prng_shim.c in the Wine
prefix, since Wine 8.0 lacks bcryptprimitives.dll) and aarch64 Linux (zig cc; run under qemu-aarch64 with
Debian's arm64 C library). It drives plant and estimator in a loop on paper 000's example (3000 samples,
noise-free and at SNR 43) through the FMI 2.0 and the FMI 3.0 exports, saves, serialises and restores both
FMU states half way and replays the second half, and makes two bad calls. Every platform must print the same
bits as x86_64 Linux.
"""
import pathlib
import shutil
import struct
import sys
import zipfile
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from dist_fmus import WINE, dist_fmu, paper_input, run

HERE = pathlib.Path(__file__).resolve().parent
ARM_SYSROOT = "/usr/aarch64-linux-gnu"
N = 3000
EST_OUTPUTS = ["a1", "a2", "b0", "m2", "c1", "c2", "y_hat", "e"]

# platform -> (FMI 2.0 folder or None, FMI 3.0 folder, how to run the master)
PLATFORMS = {
    "x86_64-linux": ("linux64", "x86_64-linux"),
    "x86_64-windows": ("win64", "x86_64-windows"),
    "aarch64-linux": (None, "aarch64-linux"),
}


def description(version, model):
    with zipfile.ZipFile(dist_fmu(version, model)) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def token(root):
    return root.get("guid") or root.get("instantiationToken")


def vrs(root):
    """Value reference of each variable by name (FMI 2.0 ScalarVariable or FMI 3.0 typed elements)."""
    found = {}
    for el in root.find("ModelVariables"):
        found[el.get("name")] = el.get("valueReference")
    return found


@pytest.fixture(scope="session")
def masters(work, wine_env):
    """platform -> (command prefix to run the master, the platform's library extracted from the plant FMU)."""
    src = str(HERE / "master.c")
    flags = ["-std=c11", "-O2", "-Wall", "-Wextra", "-Werror"]
    run(["gcc", *flags, "-o", str(work / "master"), src, "-ldl"])
    run(["x86_64-w64-mingw32-gcc", *flags, "-static-libgcc", "-o", str(work / "master.exe"), src])
    zig = [sys.executable, "-m", "ziglang", "cc", "-target", "aarch64-linux-gnu.2.17"]
    run([*zig, *flags, "-o", str(work / "master_aarch64"), src, "-ldl"])
    libs = {}
    with zipfile.ZipFile(dist_fmu(3, "BacklashPlant")) as z:
        for platform, (_, folder3) in PLATFORMS.items():
            ext = "dll" if folder3.endswith("windows") else "so"
            lib = work / f"{platform}.{ext}"
            lib.write_bytes(z.read(f"binaries/{folder3}/BacklashPlant.{ext}"))
            libs[platform] = lib
    qemu = shutil.which("qemu-aarch64-static") or pytest.fail("qemu-aarch64-static is missing")
    return {
        "x86_64-linux": ([str(work / "master")], libs["x86_64-linux"], None),
        "x86_64-windows": ([WINE, str(work / "master.exe")], libs["x86_64-windows"], wine_env),
        "aarch64-linux": ([qemu, "-L", ARM_SYSROOT, str(work / "master_aarch64")], libs["aarch64-linux"], None),
    }


@pytest.fixture(scope="session")
def input_file(work):
    u = paper_input(N)
    path = work / "u.bin"
    path.write_bytes(struct.pack(f"<{N}d", *u))
    return path


def bits(x):
    return f"{struct.unpack('<Q', struct.pack('<d', x))[0]:016x}"


def run_master(masters, input_file, platform, version, noise_std):
    prefix, lib, env = masters[platform]
    plant, est = description(version, "BacklashPlant"), description(version, "MrgiaEstimator")
    pv, ev = vrs(plant), vrs(est)
    args = [str(lib), str(version), token(plant), token(est), str(input_file), bits(noise_std), "7",
            pv["u"], pv["y"], pv["w"], pv["noise_std"], pv["noise_seed"], ev["u"], ev["y"],
            *[ev[name] for name in EST_OUTPUTS]]
    out = run([*prefix, *args], env=env)
    lines = out.stdout.splitlines()
    rows = [ln for ln in lines if ln[:1].isdigit()]
    tail = [ln for ln in lines if not ln[:1].isdigit()]
    return rows, tail, out.stderr


def column(rows, i):
    return np.array([struct.unpack(">d", bytes.fromhex(r.split()[1 + i]))[0] for r in rows])  # hex of the bits


@pytest.fixture(scope="session")
def runs(masters, input_file):
    """(platform, version, snr) -> (rows, tail lines, log text); SNR 43: noise std = std(w) / 43, from Linux."""
    results = {}
    for version in (2, 3):
        for platform in PLATFORMS:
            results[platform, version, None] = run_master(masters, input_file, platform, version, 0.0)
        w = column(results["x86_64-linux", version, None][0], 1)
        for platform in PLATFORMS:
            results[platform, version, 43] = run_master(masters, input_file, platform, version, np.std(w) / 43)
    return results


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("snr", [None, 43])
@pytest.mark.parametrize("platform", ["x86_64-windows", "aarch64-linux"])
def test_pair_gives_the_linux_bits(runs, platform, version, snr):
    linux, other = runs["x86_64-linux", version, snr], runs[platform, version, snr]
    assert len(linux[0]) == N
    first = next((i for i, (a, b) in enumerate(zip(linux[0], other[0])) if a != b), None)
    assert first is None, f"{platform} differs from x86_64 Linux from step {first}: {other[0][first]} vs {linux[0][first]}"
    assert other[1][0] == linux[1][0], "the serialised FMU states differ from Linux's"


@pytest.mark.parametrize("snr", [None])
def test_the_pair_converges_and_fmi2_equals_fmi3(runs, snr):
    rows2, rows3 = runs["x86_64-linux", 2, snr][0], runs["x86_64-linux", 3, snr][0]
    assert rows2 == rows3
    truth = [0.45, 0.55, 0.8, 1.5, 0.5, 1.0]  # a1, a2, b0, m2, c1, c2 of paper 000's example
    est = [column(rows2, 2 + i)[-1] for i in range(len(truth))]
    tol = 1e-6 if snr is None else 0.1
    assert np.max(np.abs(np.subtract(est, truth)) / np.abs(truth)) < tol, est


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("platform", list(PLATFORMS))
def test_state_replay_and_bad_calls(runs, platform, version):
    _, tail, log = runs[platform, version, 43]
    assert tail[0].endswith("replayed steps differing: 0"), tail[0]
    assert tail[1] == "bad value reference: status 3, log lines 1", tail[1]
    assert tail[2] == "negative step: status 3, log lines 1", tail[2]
    assert "2147483647" in log and "fmi" in log, log[-2000:]
