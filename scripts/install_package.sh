#!/usr/bin/env bash
# Install the Python package backlash_fmu into .venv for this checkout (`maturin develop --release`): the pure
# Python modules and the extension, built on the same release build of the crate as `cargo build --release`
# (only the extension crate is compiled on top, and PyO3 unless the build had maturin's PyO3 configuration:
# scripts/main.sh gives both the same), with the FMUs that build packaged. The portable
# wheel is scripts/build_wheel.sh's job (CI), not the main job's.
set -euo pipefail
cd "$(dirname "$0")/.."
VIRTUAL_ENV="$PWD/.venv" .venv/bin/maturin develop --release --quiet
