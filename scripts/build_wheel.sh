#!/usr/bin/env bash
# Build the portable wheel of the Python package backlash-fmu, linked with zig against GLIBC 2.17, checked with
# auditwheel. Leaves target/wheels/backlash_fmu-<version>-cp39-abi3-manylinux_2_17_x86_64.manylinux2014_x86_64.whl
# and prints its path and size.
#
# manylinux2014: the extension (which carries the `backlash` program) links nothing of the system but the C
# library: the plots' text is drawn by plotters' pure-Rust ab_glyph path with the font inside the binary
# (src/report/plot.rs), not through fontconfig and freetype. The FMUs inside are GLIBC 2.17 too. Needs the tools
# of scripts/setup.sh (maturin, ziglang, cargo-zigbuild, auditwheel in .venv).
#
# --windows: the win_amd64 wheel instead (target/wheels/backlash_fmu-<version>-cp39-abi3-win_amd64.whl), cross-built
# here with the mingw-w64 linker and rustup's x86_64-pc-windows-gnu standard library; PyO3 writes the python3.dll
# import library itself (its generate-import-lib feature), so no Windows Python is needed to link. The FMUs inside
# carry the Windows DLL only (the wheel is for Windows). Checked with scripts/windows_binary.py: the extension and
# the FMU DLLs import only DLLs every Windows 10+ has (and python3.dll), no debug information. It cannot be
# imported here (no Windows CPython from the package registries this machine reaches), and CI does not build it
# (a second whole-crate build for Windows). Its own target directory, target/win-wheel: a cross build's packaging
# step writes the FMUs to <target>/fmu, which must not replace the Linux ones in target/fmu.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$PWD/.venv/bin:$PATH"
if [ "${1:-}" = --windows ]; then
    command -v maturin >/dev/null || { echo "error: maturin is missing: run scripts/setup.sh" >&2; exit 1; }
    bash scripts/apt_install.sh gcc-mingw-w64-x86-64 binutils-mingw-w64-x86-64
    if ! rustup target add x86_64-pc-windows-gnu >/dev/null 2>&1; then
        echo "error: rustup cannot add x86_64-pc-windows-gnu here; the Windows wheel needs it" >&2
        exit 1
    fi
    rm -f target/wheels/backlash_fmu-*-win_amd64.whl
    CARGO_TARGET_DIR="$PWD/target/win-wheel" maturin build --release --strip --target x86_64-pc-windows-gnu \
        --features pyo3/generate-import-lib --out target/wheels --quiet
    wheel=$(ls target/wheels/backlash_fmu-*-win_amd64.whl)
    python scripts/windows_binary.py --wheel "$wheel"
    echo "$wheel $(stat -c %s "$wheel") bytes"
    exit 0
fi
rm -f target/wheels/backlash_fmu-*manylinux*.whl
for tool in maturin auditwheel patchelf python-zig cargo-zigbuild; do
    command -v "$tool" >/dev/null || { echo "error: $tool is missing: run scripts/setup.sh" >&2; exit 1; }
done
# One release build of the extension (and, through the build script of backlash-fmu-packaging, of the FMUs it
# carries). Not `maturin --zig`: that builds for an explicit --target, in a target directory of its own, and so
# compiles the crate and every dependency again beside the release build. Here zig links the extension's crate
# alone (a rustc flag for that crate), and the build reuses the release build's dependencies: after CI's build of
# the tests it compiles only PyO3, NumPy's bindings and the extension (python/Cargo.toml, `shared-build`).
TAG=manylinux_2_17
maturin build --release --compatibility "$TAG" --features shared-build --out target/wheels --quiet \
    -- -C linker="$PWD/scripts/zig_cc_glibc217.sh"
wheel=$(ls target/wheels/backlash_fmu-*manylinux*.whl)
# The FMUs must be inside, and the wheel must keep its manylinux promise.
python - "$wheel" <<'PY'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
missing = [m for m in ("BacklashPlant", "MrgiaEstimator", "BacklashCompensator") if f"backlash_fmu/fmu/{m}.fmu" not in names]
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
