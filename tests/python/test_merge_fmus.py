"""scripts/merge_fmus.py on archives made here: a plant FMU as packaged for another platform (its binary
renamed to binaries/win64/BacklashPlant.dll, as a Windows build would package it) merged with the Linux one."""
import subprocess
import sys
import zipfile

import numpy as np
from fmpy import simulate_fmu

from conftest import ROOT

SCRIPT = ROOT / "scripts" / "merge_fmus.py"


def repackage(src, dst, rename):
    """A copy of the FMU `src` with entries renamed by `rename(name) -> name`."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            if not info.is_dir():
                zout.writestr(rename(info.filename), zin.read(info))
    return dst


def merge(out, *inputs):
    return subprocess.run([sys.executable, str(SCRIPT), str(out), *map(str, inputs)], capture_output=True,
                          text=True, timeout=120)


def windows_copy(fmu, tmp_path, model):
    return repackage(fmu, tmp_path / f"{model}-win64.fmu",
                     lambda n: n.replace("linux64/", "win64/").replace(f"{model}.so", f"{model}.dll"))


def test_merged_fmu_carries_both_platforms_and_still_runs(plant_fmu, tmp_path):
    win = windows_copy(plant_fmu, tmp_path, "BacklashPlant")
    out = tmp_path / "BacklashPlant.fmu"
    r = merge(out, plant_fmu, win)
    assert r.returncode == 0, r.stderr
    assert "linux64, win64" in r.stdout
    with zipfile.ZipFile(out) as z, zipfile.ZipFile(plant_fmu) as orig:
        names = set(z.namelist())
        assert {"binaries/linux64/BacklashPlant.so", "binaries/win64/BacklashPlant.dll",
                "modelDescription.xml"} <= names
        assert z.read("modelDescription.xml") == orig.read("modelDescription.xml")
        assert z.read("binaries/linux64/BacklashPlant.so") == orig.read("binaries/linux64/BacklashPlant.so")
    a = simulate_fmu(str(plant_fmu), stop_time=20, output=["y"])
    b = simulate_fmu(str(out), stop_time=20, output=["y"])
    assert np.array_equal(a["y"], b["y"])


def test_different_models_are_refused(plant_fmu, estimator_fmu, tmp_path):
    out = tmp_path / "mixed.fmu"
    r = merge(out, plant_fmu, windows_copy(estimator_fmu, tmp_path, "MrgiaEstimator"))
    assert r.returncode == 1
    assert "modelDescription.xml differs" in r.stderr
    assert not out.exists()


def test_conflicting_binaries_are_refused(plant_fmu, tmp_path):
    other = tmp_path / "other.fmu"
    with zipfile.ZipFile(plant_fmu) as zin, zipfile.ZipFile(other, "w") as zout:
        for info in zin.infolist():
            if not info.is_dir():
                data = zin.read(info)
                zout.writestr(info.filename, data + b"\0" if info.filename.endswith(".so") else data)
    r = merge(tmp_path / "out.fmu", plant_fmu, other)
    assert r.returncode == 1
    assert "binary binaries/linux64/BacklashPlant.so differs" in r.stderr


def test_binary_option_adds_a_platform_in_a_new_folder(plant_fmu, tmp_path):
    """`--binary FOLDER=FILE` (scripts/dist.sh) names the file after the modelIdentifier and the platform's
    extension; the output's folder is created; an occupied folder or a malformed spec is refused."""
    dll = tmp_path / "backlash.dll"
    dll.write_bytes(b"MZ not really a DLL")
    out = tmp_path / "new" / "folder" / "BacklashPlant.fmu"
    r = subprocess.run([sys.executable, str(SCRIPT), str(out), str(plant_fmu), "--binary", f"win64={dll}"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    with zipfile.ZipFile(out) as z:
        assert z.read("binaries/win64/BacklashPlant.dll") == dll.read_bytes()
    for spec, words in [(f"linux64={dll}", "already have binaries/linux64/BacklashPlant.so"),
                        ("win64", "expected FOLDER=FILE")]:
        bad = tmp_path / "bad.fmu"
        r = subprocess.run([sys.executable, str(SCRIPT), str(bad), str(plant_fmu), "--binary", spec],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 1 and words in r.stderr, r.stderr
        assert not bad.exists()
