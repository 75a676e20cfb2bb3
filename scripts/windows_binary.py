#!/usr/bin/env python3
"""What a Windows binary made here needs, read from the file with x86_64-w64-mingw32-objdump: the DLLs it imports
(those every Windows from 10 on has, and any other), and whether it carries debug information. Shared by
tests/cross/test_dist.py (the FMU DLL) and by `scripts/build_wheel.sh --windows` (the win_amd64 wheel: its
extension module and the DLLs in the FMUs it carries):

    python scripts/windows_binary.py --wheel target/wheels/backlash_fmu-*-win_amd64.whl
"""
import argparse
import pathlib
import re
import subprocess
import sys
import tempfile
import zipfile

# DLLs that come with every Windows from 10 on (the API sets, api-ms-win-*, resolve inside Windows itself).
SYSTEM_DLLS = {"kernel32.dll", "ntdll.dll", "msvcrt.dll", "userenv.dll", "ws2_32.dll", "advapi32.dll",
               "bcrypt.dll", "bcryptprimitives.dll", "ucrtbase.dll", "shell32.dll", "ole32.dll"}
# What a CPython extension module may import besides: the stable ABI's DLL, which every CPython 3 on Windows has.
PYTHON_DLLS = {"python3.dll"}


def pe_imports(path):
    """(objdump's private headers, the imported DLLs' names in lower case)."""
    dump = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(path)], capture_output=True, text=True,
                          check=True).stdout
    return dump, {m.lower() for m in re.findall(r"DLL Name: (\S+)", dump)}


def foreign_imports(dlls, also=frozenset()):
    """The DLLs of `dlls` that Windows does not have (beyond `also`, which the caller's host provides)."""
    return {d for d in dlls if d not in SYSTEM_DLLS and d not in also and not d.startswith("api-ms-win-")}


def debug_sections(path):
    """Section names of debug information or a symbol table in the binary."""
    heads = subprocess.run(["x86_64-w64-mingw32-objdump", "-h", str(path)], capture_output=True, text=True,
                           check=True).stdout
    return sorted(set(re.findall(r"\s(\.debug_\w+|\.symtab)\s", heads)))


def wheel_problems(wheel):
    """What is wrong with a win_amd64 wheel of the package: sentences, none if it is right."""
    problems = []
    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        ext = [n for n in names if n.endswith(".pyd")]
        if ext != ["backlash_fmu/_backlash.pyd"]:
            problems.append(f"extension modules {ext}, expected backlash_fmu/_backlash.pyd")
        binaries = []
        for fmu in ("fmu/BacklashPlant", "fmu/MrgiaEstimator", "fmu/BacklashCompensator", "fmu3/BacklashPlant",
                    "fmu3/MrgiaEstimator", "fmu3/BacklashCompensator"):
            name = f"backlash_fmu/{fmu}.fmu"
            folder = "win64" if fmu.startswith("fmu/") else "x86_64-windows"
            if name not in names:
                problems.append(f"no {name}")
                continue
            with zipfile.ZipFile(z.open(name)) as f:
                dll = f"binaries/{folder}/{fmu.split('/')[1]}.dll"
                if dll not in f.namelist():
                    problems.append(f"{name} has no {dll}")
                    continue
                binaries.append((f"{name}:{dll}", f.read(dll), frozenset()))
        for n in ext:
            binaries.append((n, z.read(n), PYTHON_DLLS))
        for i, (label, data, also) in enumerate(binaries):
            path = pathlib.Path(tmp) / f"{i}.dll"
            path.write_bytes(data)
            _, dlls = pe_imports(path)
            if "kernel32.dll" not in dlls:
                problems.append(f"{label}: not a Windows DLL (no KERNEL32 import)")
            if foreign := foreign_imports(dlls, also):
                problems.append(f"{label} needs {sorted(foreign)}, which Windows does not have")
            if debug := debug_sections(path):
                problems.append(f"{label} carries debug information or symbols: {debug}")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--wheel", required=True, help="a win_amd64 wheel of backlash-fmu")
    args = ap.parse_args()
    problems = wheel_problems(args.wheel)
    for p in problems:
        print(f"{args.wheel}: {p}", file=sys.stderr)
    if problems:
        sys.exit(1)
    print(f"{args.wheel}: the extension and the four FMU DLLs import only Windows' own DLLs (and python3.dll), "
          "no debug information")


if __name__ == "__main__":
    main()
