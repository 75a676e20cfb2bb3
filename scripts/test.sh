#!/usr/bin/env bash
# Set up and run every test: formatting, lints, Rust unit/property/integration tests, Python tests with FMPy, the
# Python package's manylinux2014 wheel in a fresh virtual environment, the FMUs of every platform (Windows under
# Wine, aarch64 under QEMU) and the compliance checks. Each step prints when it starts (docs/ARCHITECTURE.md,
# "Where CI time goes").
set -euo pipefail
cd "$(dirname "$0")/.."
step() { printf '== [%dm%02ds] %s\n' $((SECONDS / 60)) $((SECONDS % 60)) "$*"; }
# A run needs about 4.5 GB of disk (target/ and .venv/ at their largest, with the tests' temporary files).
step "disk: $(df -h --output=avail . | tail -1 | tr -d ' ') free here"
step "setup: system packages"
bash scripts/setup.sh --system
# The measured records the tests read (data/*/README.md): copied from BACKLASH_FETCH_FROM when set (.ci/run sets
# it), otherwise downloaded from their sources at pinned commits; every sha256 checked (quick when in place).
step "the measured records: scripts/fetch_data.py${BACKLASH_FETCH_FROM:+ --from $BACKLASH_FETCH_FROM}"
python3 scripts/fetch_data.py ${BACKLASH_FETCH_FROM:+--from "$BACKLASH_FETCH_FROM"}
# The Python environment (pip) is made beside formatting, lints and docs, which do not use it; the release
# build waits for it (zig links the FMUs' portable binary).
mkdir -p target
source scripts/background.sh
step "setup: the Python environment (in the background: target/setup-python.log)"
in_background target/setup-python.log bash scripts/setup.sh --python
# The FMUs' binary linked against GLIBC 2.17 (packaging/build.rs), as scripts/dist.sh builds it: the same setting for
# every cargo command here, so that no step rebuilds what another built (the build script reruns when it
# changes).
export BACKLASH_FMU_PORTABLE=require

step "cargo fmt --check"
cargo fmt --check
# Lints and docs with the release profile: their build scripts and procedural macros are then the release build's
# own, compiled and run once (about 40 s less and half a gigabyte less of target/ than with the dev profile; no
# code here depends on debug_assertions).
step "cargo clippy (the lints of Cargo.toml's [lints] table, warnings as errors), also the FMU-only library"
cargo clippy --release --workspace --all-targets -- -D warnings
cargo clippy --release --lib --no-default-features -- -D warnings
step "cargo doc (broken or private links in the documentation are errors)"
RUSTDOCFLAGS="-D warnings" cargo doc --release --no-deps
step "waiting for the Python environment"
await_background "setting up the Python environment"
# `reusing_release_build <command...>` runs the command and fails if it compiled a second copy of a crate that the
# tests' build has (cargo compiles a crate once per set of features, and names each copy by a hash): the wheel's
# build is meant to compile only what the extension adds, PyO3 and NumPy's bindings, and reuse every other
# dependency (python/Cargo.toml, `shared-build`, says how and which crates).
rlibs() { find target/release/deps -name 'lib*.rlib' -printf '%f\n' | sort; }
crate_of() { sed 's/^lib\(.*\)-[0-9a-f]*\.rlib$/\1/' | sort -u; }
tests_crates() { cargo tree -p backlash-fmu -e normal,dev --prefix none --format '{lib}' | sed 's/ (\*)$//' | sort -u; }
reusing_release_build() {
    local before again
    before=$(rlibs)
    "$@"
    again=$(comm -12 <(tests_crates) <(comm -13 <(echo "$before") <(rlibs) | crate_of))
    if [ -n "$again" ]; then
        echo "error: \`$*\` compiled again, with other features, what the tests' build had compiled:" $again >&2
        echo "       add the features that differ to python/Cargo.toml's shared-build (cargo tree -e features -i <crate>)" >&2
        exit 1
    fi
}
# With the tests and examples: the tests' dev-dependencies enable more features of shared dependencies (serde,
# libc, flate2, ...), and cargo compiles the crate's library once per set of features. Built here with the
# tests' set, the program, the tests and `cargo test` below share one build of the crate; a plain
# `cargo build --release` would compile it a second time (about a minute), so no step here runs one.
step "cargo build --release --lib --bins --tests --examples (both FMUs, the CLI, the tests)"
cargo build --release --lib --bins --tests --examples
# The ratchet: `backlash diagnose` on every measured record with its committed settings; fails where a final
# held-out error is more than 2% above docs/measured_records.json (`--update` there writes new numbers).
step "the ratchet: diagnose on the nine measured records against docs/measured_records.json"
.venv/bin/python scripts/peer_compare.py --ratchet
step "every platform's FMUs: scripts/dist.sh (target/dist)"
bash scripts/dist.sh
step "the manylinux2014 wheel (the one build of the Python extension, on the build above), installed into .venv"
reusing_release_build bash scripts/build_wheel.sh
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
step "pytest, then the Python API tests in a fresh virtual environment holding only the wheel (in the background: target/python-tests.log)"
in_background target/python-tests.log python_tests
step "every platform: tests/cross on target/dist (Windows under Wine, aarch64 under QEMU)"
bash scripts/cross_test.sh --no-dist
step "compliance: valgrind, fmutool, long fuzz, 1 GB file in bounded memory"
bash scripts/compliance.sh
step "the Python tests' output (target/python-tests.log)"
await_background "the Python tests"
step "all tests passed (target/ $(du -sh target | cut -f1), .venv/ $(du -sh .venv | cut -f1))"
