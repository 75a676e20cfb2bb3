#!/usr/bin/env bash
# Set up and run every test: formatting, lints, Rust unit/property/integration tests, Python tests with FMPy.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

echo "== cargo fmt --check"
cargo fmt --check
echo "== cargo clippy (the lints of Cargo.toml's [lints] table, warnings as errors)"
cargo clippy --all-targets -- -D warnings
echo "== cargo doc (broken or private links in the documentation are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps
echo "== cargo build --release (both FMUs and the CLI)"
cargo build --release
echo "== cargo test --release"
cargo test --release
echo "== pytest"
.venv/bin/python -m pytest -q tests/python
echo "== compliance: valgrind, fmutool, long fuzz, 1 GB file in bounded memory"
bash scripts/compliance.sh
