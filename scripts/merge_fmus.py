"""Merge FMUs of one model built on several platforms into one FMU that carries every platform's binary.

    python scripts/merge_fmus.py OUT.fmu BUILT_ON_LINUX.fmu BUILT_ON_WINDOWS.fmu [...]

`cargo build --release` packages the binary of the platform it builds for (binaries/linux64/<id>.so,
binaries/win64/<id>.dll or binaries/darwin64/<id>.dylib). The inputs must describe the same model: their
modelDescription.xml and every other file outside binaries/ must be byte-identical, and a binary present in two
inputs must be identical too; otherwise nothing is written and the exit status is 1, with the file and entry
that differ named.
"""
import argparse
import pathlib
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


def write(out, entries):
    out = pathlib.Path(out)
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
    args = parser.parse_args(argv)
    try:
        entries = merge(args.inputs)
    except MergeError as e:
        print(f"merge_fmus: {e}", file=sys.stderr)
        return 1
    write(args.output, entries)
    platforms = sorted({n.split("/")[1] for n in entries if n.count("/") >= 2 and n.startswith("binaries/")})
    print(f"{args.output}: {', '.join(platforms)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
