#!/usr/bin/env bash
# Set up and run every test: formatting, lints, Rust unit/property/integration tests, Python tests with FMPy, the
# Python package's manylinux2014 wheel in a fresh virtual environment, the FMUs of every platform (Windows under
# Wine, aarch64 under QEMU) and the compliance checks. Each step prints when it starts (docs/ARCHITECTURE.md,
# "Where CI time goes").
set -euo pipefail
cd "$(dirname "$0")/.."
step() { printf '== [%dm%02ds] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }
step "setup: system packages"
bash scripts/setup.sh --system
# The Python environment (pip) is made beside formatting, lints and docs, which do not use it; the release
# build waits for it (zig links the FMUs' portable binary).
mkdir -p target
setup_log=target/setup-python.log
step "setup: the Python environment (in the background: $setup_log)"
bash scripts/setup.sh --python >"$setup_log" 2>&1 &
setup_pid=$!
trap 'kill "$setup_pid" 2>/dev/null || true' EXIT
# The FMUs' binary linked against GLIBC 2.17 (packaging/build.rs), as scripts/dist.sh builds it: the same setting for
# every cargo command here, so that no step rebuilds what another built (the build script reruns when it
# changes).
export BACKLASH_FMU_PORTABLE=require
# Without the release profile's line tables (Cargo.toml; they serve profiling, and a valgrind report then names
# functions without their lines): the release build of the crate and the tests takes about 7% less CPU
# (docs/ARCHITECTURE.md, "Where CI time goes"). Every release build here, the wheel's too, sees the same setting.
export CARGO_PROFILE_RELEASE_DEBUG=false

step "cargo fmt --check"
cargo fmt --check
step "cargo clippy (the lints of Cargo.toml's [lints] table, warnings as errors), also the FMU-only library"
cargo clippy --workspace --all-targets -- -D warnings
cargo clippy --lib --no-default-features -- -D warnings
step "cargo doc (broken or private links in the documentation are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps
# With the tests and examples: the tests' dev-dependencies enable more features of shared dependencies (serde,
# libc, flate2, ...), and cargo compiles the crate's library once per set of features. Built here with the
# tests' set, the program, the tests and `cargo test` below share one build of the crate; a plain
# `cargo build --release` would compile it a second time (about a minute), so no step here runs one.
step "waiting for the Python environment"
if ! wait "$setup_pid"; then
    cat "$setup_log" >&2
    echo "setting up the Python environment failed (log above, $setup_log)" >&2
    exit 1
fi
trap - EXIT
cat "$setup_log"
step "cargo build --release --lib --bins --tests --examples (both FMUs, the CLI, the tests)"
cargo build --release --lib --bins --tests --examples
step "every platform's FMUs: scripts/dist.sh (target/dist)"
bash scripts/dist.sh
step "the manylinux2014 wheel (the one build of the Python extension), installed into .venv"
bash scripts/build_wheel.sh
.venv/bin/python -m pip install -q --disable-pip-version-check --force-reinstall --no-deps \
    target/wheels/backlash_fmu-*manylinux*.whl
step "cargo test --release"
cargo test --release
# The Python tests, and tests/cross with the compliance checks, keep one core each busy for most of their time:
# they run side by side, the Python tests' output kept in a log and printed when they end.
python_tests() {
    .venv/bin/python -m pytest -q --durations=10 tests/python --ignore=tests/python/test_api.py &&
        echo "-- the Python API tests in a fresh virtual environment holding only the wheel" &&
        rm -rf target/wheel-venv &&
        python3 -m venv target/wheel-venv &&
        target/wheel-venv/bin/python -m pip install -q --disable-pip-version-check -c tests/python/requirements.txt \
            target/wheels/backlash_fmu-*manylinux*.whl numpy fmpy pytest &&
        target/wheel-venv/bin/python -m pytest -q -p no:cacheprovider tests/python/test_api.py
}
python_log=target/python-tests.log
step "pytest, then the Python API tests in a fresh virtual environment holding only the wheel (in the background: $python_log)"
python_tests >"$python_log" 2>&1 &
python_pid=$!
trap 'kill "$python_pid" 2>/dev/null || true' EXIT
step "every platform: tests/cross on target/dist (Windows under Wine, aarch64 under QEMU)"
bash scripts/cross_test.sh --no-dist
step "compliance: valgrind, fmutool, long fuzz, 1 GB file in bounded memory"
bash scripts/compliance.sh
step "the Python tests' output ($python_log)"
python_status=0
wait "$python_pid" || python_status=$?
trap - EXIT
cat "$python_log"
if [ "$python_status" -ne 0 ]; then
    echo "the Python tests failed (exit $python_status): $python_log" >&2
    exit "$python_status"
fi
step "all tests passed"
