#!/usr/bin/env bash
# Memory check of the FMI layer under valgrind memcheck.
#
# 1. tests/fmi_threads.rs `leak_cycles` (ignored in a plain `cargo test`): FMI_LEAK_CYCLES (default 2000)
#    cycles per FMU of instantiate / refused instantiate / logging / initialise / step / get-set /
#    get-overwrite-serialise-deserialise-set-free FMU state / refused calls / reset / terminate / free, on
#    both FMUs, in-process through the exported C functions.
# 2. tests/fmi_fuzz.rs with a small budget (FMI_LEAK_FUZZ_CALLS per FMU, default 4000; 0 skips it): random
#    call sequences with NULL pointers, bad sizes, corrupted states... under memcheck, for invalid reads and
#    writes as much as for leaks.
# 3. tests/fmi3_exports.rs, the FMI 3.0 exports: the state table (every function in every state, both FMUs)
#    and random call sequences (FMI3_LEAK_FUZZ_CALLS per FMU, default 2000; 0 skips the FMI 3.0 run).
#
# Passes when memcheck reports no error and "definitely lost: 0 bytes" (or no leak at all) for each.
# Needs valgrind (Debian: apt-get install valgrind). Builds the test binaries in release (no line tables: a
# report names functions, not lines); set CARGO_TARGET_DIR to use another target directory.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v valgrind >/dev/null; then
    echo "leak_check: valgrind is not installed (apt-get install valgrind)" >&2
    exit 1
fi

cycles=${FMI_LEAK_CYCLES:-2000}
fuzz_calls=${FMI_LEAK_FUZZ_CALLS:-4000}
fmi3_calls=${FMI3_LEAK_FUZZ_CALLS:-2000}
export FMI_LEAK_CYCLES=$cycles FMI_FUZZ_CALLS=$fuzz_calls FMI3_FUZZ_CALLS=$fmi3_calls
logdir=$(mktemp -d)
trap 'rm -rf "$logdir"' EXIT

# The test binary of one integration test target, built in release.
test_binary() {
    cargo test --release --no-run --test "$1" --message-format=json 2>/dev/null |
        sed -n 's/.*"executable":"\([^"]*\/'"$1"'-[^"]*\)".*/\1/p' | tail -n 1
}

status=0
run() { # name, then the command
    local name=$1
    shift
    local log="$logdir/$name.log"
    local t0=$SECONDS
    echo "== valgrind memcheck: $name"
    if ! valgrind --tool=memcheck --leak-check=full --show-leak-kinds=definite \
        --errors-for-leak-kinds=definite --error-exitcode=1 --log-file="$log" "$@" >"$logdir/$name.out" 2>&1; then
        echo "leak_check: $name FAILED (memcheck errors or a failing test)" >&2
        tail -n 40 "$logdir/$name.out" >&2 || true
        cat "$log" >&2
        status=1
        return
    fi
    # The summary lines, as valgrind prints them.
    grep -E "ERROR SUMMARY|definitely lost|indirectly lost|possibly lost|still reachable|All heap blocks were freed|total heap usage" "$log" |
        sed 's/^==[0-9]*== */   /'
    if ! grep -qE "definitely lost: 0 bytes|All heap blocks were freed" "$log"; then
        echo "leak_check: $name: no 'definitely lost: 0 bytes' in the valgrind summary" >&2
        status=1
    fi
    echo "   ($((SECONDS - t0)) s)"
}

bin=$(test_binary integration)
[ -x "$bin" ] || { echo "leak_check: cannot find the integration test binary" >&2; exit 1; }
echo "leak_cycles: $cycles cycles per FMU"
run leak_cycles \
    "$bin" --ignored --exact fmi_threads::leak_cycles --test-threads=1

if [ "$fuzz_calls" != 0 ]; then
    echo "fuzz: $fuzz_calls calls per FMU"
    run fuzz \
        "$bin" --exact fmi_fuzz::random_call_sequences_over_both_fmus --test-threads=1
fi

if [ "$fmi3_calls" != 0 ]; then
    echo "FMI 3.0: state table, and $fmi3_calls random calls per FMU"
    run fmi3 \
        "$bin" --exact fmi3_exports::every_call_in_every_state_follows_the_table \
        fmi3_exports::random_call_sequences_over_both_fmus \
        --test-threads=1
fi

if [ "$status" = 0 ]; then
    echo "leak_check: OK"
fi
exit "$status"
