"""Merge FMUs of one model built on several platforms into one FMU that carries every platform's binary.

    python scripts/merge_fmus.py OUT.fmu BUILT_ON_LINUX.fmu BUILT_ON_WINDOWS.fmu [...]
    python scripts/merge_fmus.py OUT.fmu IN.fmu --binary win64=backlash.dll --binary aarch64-linux=libbacklash.so

`cargo build --release` packages the binary of the platform it builds for (binaries/linux64/<id>.so,
binaries/win64/<id>.dll or binaries/darwin64/<id>.dylib). The inputs must describe the same model: their
modelDescription.xml and every other file outside binaries/ must be byte-identical, and a binary present in two
inputs must be identical too; otherwise nothing is written and the exit status is 1, with the file and entry
that differ named. `--binary FOLDER=FILE` adds a shared library built for another platform (scripts/dist.sh:
cross-compiled) as binaries/FOLDER/<modelIdentifier>.<extension of the platform>. The output's folder is
created when missing.
"""
import argparse
import pathlib
import re
import sys
import zipfile


class MergeError(Exception):
    pass


def read_entries(path):
    """The archive's files (directories left out) as {name: bytes}."""
    try:
        with zipfile.ZipFile(path) as z:
            return {i.filename: z.read(i) for i in z.infolist() if not i.is_dir()}
    except (OSError, zipfile.BadZipFile) as e:
        raise MergeError(f"{path}: cannot read it as an FMU (zip archive): {e}") from e


def merge(inputs):
    """The union of the inputs' entries, checked as the module documentation says."""
    merged, origin = {}, {}
    for path in inputs:
        entries = read_entries(path)
        if "modelDescription.xml" not in entries:
            raise MergeError(f"{path}: has no modelDescription.xml")
        for name, data in entries.items():
            if name in merged and merged[name] != data:
                what = "binary" if name.startswith("binaries/") else "file"
                raise MergeError(f"{path}: {what} {name} differs from the one in {origin[name]}")
            merged.setdefault(name, data)
            origin.setdefault(name, path)
        if not any(n.startswith("binaries/") for n in entries):
            raise MergeError(f"{path}: has no binaries/ folder")
    for name, first in origin.items():
        if not name.startswith("binaries/"):
            for path in inputs:
                if name not in read_entries(path):
                    raise MergeError(f"{path}: lacks {name}, which {first} has")
    return merged


def extension(folder):
    """The file extension of a shared library in binaries/<folder> (FMI 2.0 or 3.0 platform names)."""
    if folder.startswith("win") or folder.endswith("-windows"):
        return "dll"
    if folder.startswith("darwin") or folder.endswith("-darwin"):
        return "dylib"
    return "so"


def model_identifier(description):
    """The co-simulation modelIdentifier of a modelDescription.xml (FMI 2.0 and 3.0 name it alike)."""
    m = re.search(rb"<CoSimulation\b[^>]*\bmodelIdentifier=\"([^\"]+)\"", description)
    if not m:
        raise MergeError("modelDescription.xml has no CoSimulation modelIdentifier")
    return m.group(1).decode()


def add_binaries(entries, binaries):
    """Adds each FOLDER=FILE of `binaries` as binaries/FOLDER/<modelIdentifier>.<ext>; refuses an occupied one."""
    ident = model_identifier(entries["modelDescription.xml"])
    for spec in binaries:
        folder, sep, file = spec.partition("=")
        if not sep or not folder or "/" in folder or not file:
            raise MergeError(f"--binary {spec}: expected FOLDER=FILE, e.g. win64=backlash.dll")
        name = f"binaries/{folder}/{ident}.{extension(folder)}"
        if name in entries:
            raise MergeError(f"--binary {spec}: the inputs already have {name}")
        try:
            entries[name] = pathlib.Path(file).read_bytes()
        except OSError as e:
            raise MergeError(f"--binary {spec}: {e}") from e


def write(out, entries):
    out = pathlib.Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for name in sorted(entries):
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            if name.startswith("binaries/"):
                info.external_attr = 0o755 << 16
            z.writestr(info, entries[name])
    tmp.replace(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("output", help="the merged FMU to write")
    parser.add_argument("inputs", nargs="+", help="FMUs of the same model, each built on one platform")
    parser.add_argument("--binary", action="append", default=[], metavar="FOLDER=FILE",
                        help="add FILE as the binary of platform folder FOLDER (win64, aarch64-linux, ...)")
    args = parser.parse_args(argv)
    try:
        entries = merge(args.inputs)
        add_binaries(entries, args.binary)
    except MergeError as e:
        print(f"merge_fmus: {e}", file=sys.stderr)
        return 1
    write(args.output, entries)
    platforms = sorted({n.split("/")[1] for n in entries if n.count("/") >= 2 and n.startswith("binaries/")})
    print(f"{args.output}: {', '.join(platforms)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
