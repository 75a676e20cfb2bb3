# Sourced by scripts/main.sh and scripts/test.sh: one step at a time in the background, beside the script's own.
#
# `in_background <log> <command...>` starts the command with its output in the log; it is killed if the script
# ends first. `await_background <what>` waits for it, prints its log, and ends the script with the command's exit
# status if it failed.
in_background() {
    background_log=$1
    shift
    "$@" >"$background_log" 2>&1 &
    background_pid=$!
    trap 'kill "$background_pid" 2>/dev/null || true' EXIT
}

await_background() {
    local status=0
    wait "$background_pid" || status=$?
    trap - EXIT
    cat "$background_log"
    if [ "$status" -ne 0 ]; then
        echo "$1 failed (exit $status; its output above, in $background_log)" >&2
        exit "$status"
    fi
}
