#!/usr/bin/env bash
# Mutation samples of the FMI boundary (src/fmi, src/fmi2, src/fmi3, src/fmus), of src/diagnose/effects and of
# src/identify/mrgia.rs with cargo-mutants 27, a shard at a time: a mutant is caught when a test fails, missed
# when all pass, unviable when it does not compile.
#
#   scripts/mutants.sh list           every mutant of the boundary, per file (nothing is built)
#   scripts/mutants.sh state          every mutant of the FMU-state checks (src/fmi/fmu_state.rs: check_layer,
#                                     the header, the model's sample count)
#   scripts/mutants.sh shard K N      shard K of N (0-based) of the whole boundary, round-robin over the list
#                                     of mutants (file by file), so that a shard samples every file
#   scripts/mutants.sh effects K N    shard K of N of src/diagnose/effects (about 1060 mutants; N = 30 runs
#                                     about 35), against the tests that cover it: the effects' unit tests
#                                     (`diagnose::effects`) and the bench's tests of each effect's draw
#                                     (`diagnose::bench::draw_tests`, `curved_border_draws`) and the decision's
#                                     tests, which read each effect's structure penalty, under a second
#   scripts/mutants.sh mrgia K N      shard K of N of src/identify/mrgia.rs without the state checks that
#                                     `TryFrom<MrgiaState>` selects (about 220 mutants; N = 7 runs about 31),
#                                     against the library's `mrgia` unit tests (under a second)
#
# Tests (the faster subset that covers the boundary, release build, filters `fmi`, `fmus::` and
# `fmu_compensator::`): the library's unit tests of the FMI layers (`fmi::`, `fmi2::`, `fmi3::`: the state
# checks, the state tables) and of the FMUs' models (`fmus::`: the seam, each model's settings and outputs)
# and the integration tests of the FMI layers (tests/fmi_*.rs, tests/fmi3_exports.rs: forged states, the state
# machine, timing, threads, the exports; tests/fmu_compensator.rs: the compensator's warnings and refusals
# through the FMI 2.0 exports) with the two call-sequence fuzzers cut to FMI_FUZZ_CALLS / FMI3_FUZZ_CALLS
# calls per FMU (default 3000 each, against 120,000 and 20,000 in the full test run). `state` runs only the
# unit tests (`--lib`, `fmi::`), which test those checks directly. Left out: tests/fmu_import.rs (the packaged .fmu
# through another importer: BACKLASH_FMU=never packages nothing; its tests' names contain `fmi`, so `shard`
# skips `fmu_import::`, else cargo-mutants' baseline test fails in a fresh tree), tests/fmu_memory.rs, the CLI, Python and
# cross tests.
#
# `--in-place` mutates the working tree's files (each restored after its mutant): do not edit or commit
# while it runs. The release profile is made incremental for the run (CARGO_PROFILE_RELEASE_INCREMENTAL), so
# that a mutant recompiles only the code it changed; the first mutant pays for one full build of the crate.
# Results: mutants.out/ (outcomes.json, caught.txt, missed.txt, unviable.txt, timeout.txt).
#
# CPU: on a busy 2-core machine a mutant costs 1-4 minutes; keep a run to ~20-40 mutants (`list` gives the
# total), never the whole boundary at once.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! cargo mutants --version 2>/dev/null | grep -q '^cargo-mutants 27'; then
    cargo install cargo-mutants --locked --version '^27'
fi

export BACKLASH_FMU=never CARGO_PROFILE_RELEASE_INCREMENTAL=true
export FMI_FUZZ_CALLS=${FMI_FUZZ_CALLS:-3000}
export FMI3_FUZZ_CALLS=${FMI3_FUZZ_CALLS:-3000}
files=(-f 'src/fmi/*.rs' -f 'src/fmi2/*.rs' -f 'src/fmi3/*.rs' -f 'src/fmus/*.rs')
run() {
    cargo mutants --in-place --profile release --timeout 300 --build-timeout 900 "$@"
}

case "${1:-}" in
list)
    cargo mutants --list "${files[@]}" | cut -d: -f1 | sort | uniq -c
    ;;
state)
    run -f src/fmi/fmu_state.rs --re 'check_layer|check_header|check_model_samples' -C --lib -- fmi::
    ;;
shard)
    [ $# -eq 3 ] || { echo "usage: $0 shard K N" >&2; exit 2; }
    run "${files[@]}" --sharding round-robin --shard "$2/$3" \
        -C --lib -C --test=integration -- -- fmi fmus:: fmu_compensator:: --skip fmu_import::
    ;;
effects)
    [ $# -eq 3 ] || { echo "usage: $0 effects K N" >&2; exit 2; }
    # Several filters: after a second `--` they go to the test binary (`cargo test` takes one).
    run -f 'src/diagnose/effects/*.rs' -f 'src/diagnose/effects/**/*.rs' --sharding round-robin \
        --shard "$2/$3" -C --lib -- -- diagnose::effects diagnose::bench::draw_tests curved_border_draws \
        diagnose::search::decision
    ;;
mrgia)
    [ $# -eq 3 ] || { echo "usage: $0 mrgia K N" >&2; exit 2; }
    run -f src/identify/mrgia.rs --exclude-re 'TryFrom<MrgiaState>' --sharding round-robin \
        --shard "$2/$3" -C --lib -- mrgia
    ;;
*)
    sed -n '2,37p' "$0" >&2
    exit 2
    ;;
esac
