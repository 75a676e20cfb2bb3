#!/usr/bin/env bash
# The main job on a fresh machine: set up, build both FMUs and the CLI, co-simulate plant + estimator on
# paper 000's example, print how the estimates converge, and write the plots to out/. One release build of the
# crate; the Python package's extension is compiled on top of it (no wheel: that is CI's job).
#
# --workspace: cargo unifies the dependencies' features over the packages it builds, and the extension's own
# (NumPy's ndarray, PyO3's macros) change those of dependencies the crate shares. Built for the default members
# alone, the crate would be compiled a second time by the extension's build (`maturin develop`); built with the
# extension's package, `maturin develop` finds it done and compiles only the extension again (maturin strips it,
# a profile setting of its own).
set -euo pipefail
cd "$(dirname "$0")/.."
# The build needs only zig and cargo-zigbuild from the Python environment (the FMUs' portable binary): they come
# first, and the rest (FMPy, NumPy, Matplotlib, maturin: about 20 s of pip) is installed beside the build.
bash scripts/setup.sh --linker
mkdir -p target
source scripts/background.sh
in_background target/setup-main.log bash scripts/setup.sh --main
# PyO3's build configuration for this abi3-py39 extension (python/pyo3-abi3-py39.txt, the file maturin writes for
# it), the same for both builds below: maturin keeps a PYO3_CONFIG_FILE it is given, so `maturin develop` finds
# PyO3 built by `cargo build` instead of compiling it again because the variable changed.
export PYO3_CONFIG_FILE="$PWD/python/pyo3-abi3-py39.txt" PYO3_BUILD_EXTENSION_MODULE=1
cargo build --release --workspace
await_background "setting up the Python environment (scripts/setup.sh --main)"
bash scripts/install_package.sh
.venv/bin/python scripts/paper_cosim.py "$@"
