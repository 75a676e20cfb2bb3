#!/usr/bin/env bash
# Compliance checks that `cargo test` and `pytest` do not run by default (CI calls this after
# scripts/test.sh, which builds the FMUs):
#
# 1. valgrind memcheck over the FMI layer (scripts/leak_check.sh): thousands of instantiate / initialise /
#    step / FMU-state / free cycles on both FMUs, and a short fuzz run; "definitely lost: 0 bytes".
# 2. fmu-manipulation-toolbox (`fmutool -input X.fmu -check`) on both FMUs: no ERROR or WARNING line.
#    Uses $FMUTOOL if set, else the package in .venv (installed there, pinned, when missing), else a venv
#    of its own under the target directory.
# 3. A long strict fuzz run (FMI_FUZZ_CALLS per FMU, default 1,000,000): every invariant holds.
# 4. `backlash identify mrgia --plot` on a generated 1 GB file (~37e6 rows, written under the target
#    directory and deleted afterwards; no --trace: its bounded memory is checked on 2e6 rows by
#    tests/cli_hostile.rs): peak RSS and time printed, and the run fails if the peak RSS exceeds 64 MiB
#    (tests/cli_hostile.rs, one_gigabyte_file_in_bounded_memory). The file size
#    can be changed with BACKLASH_LARGE_BYTES.
#
# Environment: CARGO_TARGET_DIR (as cargo), BACKLASH_FMU_DIR (where the .fmu files are, default
# target/fmu), FMI_LEAK_CYCLES, FMI_LEAK_FUZZ_CALLS, FMI_FUZZ_CALLS, FMUTOOL, BACKLASH_LARGE_BYTES.
set -euo pipefail
cd "$(dirname "$0")/.."
start=$SECONDS

target=${CARGO_TARGET_DIR:-target}
fmu_dir=${BACKLASH_FMU_DIR:-target/fmu}
if [ ! -f "$fmu_dir/BacklashPlant.fmu" ] || [ ! -f "$fmu_dir/MrgiaEstimator.fmu" ]; then
    echo "== cargo build --release (the FMUs are missing from $fmu_dir)"
    cargo build --release
fi

failed=()
step() { # title, then the command
    local title=$1
    shift
    local t0=$SECONDS
    echo
    echo "== $title"
    if "$@"; then
        echo "-- $title: ok ($((SECONDS - t0)) s)"
    else
        echo "-- $title: FAILED ($((SECONDS - t0)) s)"
        failed+=("$title")
    fi
}

# ---------------------------------------------------------------------------------------------- 1. valgrind
step "valgrind memcheck (scripts/leak_check.sh)" bash scripts/leak_check.sh

# ------------------------------------------------------------------------------- 2. fmu-manipulation-toolbox
FMUTOOL_PIN="fmu-manipulation-toolbox==2.0"
fmutool_cmd() {
    if [ -n "${FMUTOOL:-}" ]; then
        echo "$FMUTOOL"
        return
    fi
    local py
    if [ -x .venv/bin/python ]; then
        py=.venv/bin/python
    else
        py="$target/compliance-venv/bin/python"
        [ -x "$py" ] || python3 -m venv "$target/compliance-venv" >&2
    fi
    if ! "$py" -c "import fmu_manipulation_toolbox" 2>/dev/null; then
        "$py" -m pip install -q --disable-pip-version-check "$FMUTOOL_PIN" >&2
    fi
    echo "$(dirname "$py")/fmutool"
}

fmutool_check() {
    local tool status=0
    tool=$(fmutool_cmd)
    "$tool" -h >/dev/null 2>&1 || { echo "fmutool not runnable: $tool" >&2; return 1; }
    for name in BacklashPlant MrgiaEstimator BacklashCompensator; do
        local out rc=0
        out=$("$tool" -input "$fmu_dir/$name.fmu" -check 2>&1) || rc=$?
        # Without the colour codes.
        out=$(printf '%s\n' "$out" | sed 's/\x1b\[[0-9;]*m//g')
        printf '%s\n' "$out" | grep -E "Checks|compliant|semantic error" | sed "s/^/   $name: /"
        if [ "$rc" != 0 ] || printf '%s\n' "$out" | grep -qE '^(ERROR|WARNING|CRITICAL)'; then
            echo "fmutool -check $name: exit $rc" >&2
            printf '%s\n' "$out" | grep -E '^(ERROR|WARNING|CRITICAL)' >&2 || true
            status=1
        fi
        printf '%s\n' "$out" | grep -q "seems to be compliant with FMI-2.0" || status=1
    done
    return "$status"
}
step "fmu-manipulation-toolbox: fmutool -check" fmutool_check

# --------------------------------------------------------------------------------------------- 3. long fuzz
step "long fuzz run" bash -c 'set -o pipefail; FMI_FUZZ_CALLS=${FMI_FUZZ_CALLS:-1000000} cargo test --release \
    --test integration -- --exact fmi_fuzz::random_call_sequences_over_both_fmus --nocapture 2>&1 |
    grep -E "^(fuzz:|known FMI|panics caught|test result|fuzz invariant)"; exit ${PIPESTATUS[0]}'

# ------------------------------------------------------------------------------------------ 4. large file
step "identify mrgia on a 1 GB file (peak RSS <= 64 MiB)" bash -c 'set -o pipefail; cargo test --release \
    --test cli_hostile -- --ignored --exact one_gigabyte_file_in_bounded_memory --nocapture 2>&1 |
    grep -E "^identify mrgia|test result|panicked|peak RSS"; exit ${PIPESTATUS[0]}'

echo
if ((${#failed[@]})); then
    echo "compliance: FAILED: ${failed[*]} ($((SECONDS - start)) s)"
    exit 1
fi
echo "compliance: all passed ($((SECONDS - start)) s)"
