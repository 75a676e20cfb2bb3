#!/usr/bin/env bash
# Set up and run every test: formatting, lints, Rust unit/property/integration tests, Python tests with FMPy, the
# Python package's wheel in a fresh virtual environment.
set -euo pipefail
cd "$(dirname "$0")/.."
# Each step's start, in minutes and seconds since this script started (where CI time goes).
step() { printf '== [%dm%02ds] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }
step "setup (system packages, the Python environment, the wheel)"
bash scripts/setup.sh

step "cargo fmt --check"
cargo fmt --check
step "cargo clippy (the lints of Cargo.toml's [lints] table, warnings as errors)"
cargo clippy --workspace --all-targets -- -D warnings
step "cargo doc (broken or private links in the documentation are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps
step "cargo build --release (both FMUs and the CLI)"
cargo build --release
step "cargo test --release"
cargo test --release
step "pytest (the package installed into .venv by setup.sh)"
.venv/bin/python -m pytest -q --durations=10 tests/python --ignore=tests/python/test_api.py
step "the wheel in a fresh virtual environment: the Python API tests against the installed package"
rm -rf target/wheel-venv
python3 -m venv target/wheel-venv
target/wheel-venv/bin/python -m pip install -q --disable-pip-version-check -c tests/python/requirements.txt \
    target/wheels/backlash_fmu-*.whl numpy fmpy pytest
target/wheel-venv/bin/python -m pytest -q -p no:cacheprovider tests/python/test_api.py
step "compliance: valgrind, fmutool, long fuzz, 1 GB file in bounded memory"
bash scripts/compliance.sh
step "all tests passed"
