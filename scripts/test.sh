#!/usr/bin/env bash
# Set up and run every test: formatting, lints, Rust unit/property/integration tests, Python tests with FMPy, the
# Python package's wheel in a fresh virtual environment.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

echo "== cargo fmt --check"
cargo fmt --check
echo "== cargo clippy (the lints of Cargo.toml's [lints] table, warnings as errors)"
cargo clippy --workspace --all-targets -- -D warnings
echo "== cargo doc (broken or private links in the documentation are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps
echo "== cargo build --release (both FMUs and the CLI)"
cargo build --release
echo "== cargo test --release"
cargo test --release
echo "== pytest (the package installed into .venv by setup.sh)"
.venv/bin/python -m pytest -q tests/python --ignore=tests/python/test_api.py
echo "== the wheel in a fresh virtual environment: the Python API tests against the installed package"
rm -rf target/wheel-venv
python3 -m venv target/wheel-venv
target/wheel-venv/bin/python -m pip install -q --disable-pip-version-check -c tests/python/requirements.txt \
    target/wheels/backlash_fmu-*.whl numpy fmpy pytest
target/wheel-venv/bin/python -m pytest -q -p no:cacheprovider tests/python/test_api.py
echo "== compliance: valgrind, fmutool, long fuzz, 1 GB file in bounded memory"
bash scripts/compliance.sh
