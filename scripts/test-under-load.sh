#!/usr/bin/env bash
# make test-under-load (issue 20): `make test` while busy loops occupy every core of a 2-core host.
# Bounded: the load processes and the test run each carry a time limit, and the load is stopped
# by PID on exit, failure or interrupt (trap), so nothing is left spinning.
set -u
cd "$(dirname "$0")/.."
LOAD_PROCS=${LOAD_PROCS:-2}           # issue 20: two busy-loop processes, one per core
LIMIT_S=${TEST_UNDER_LOAD_LIMIT_S:-1800}   # CI budget is 10 min idle; 30 min caps a loaded run
PYTHON=${PYTHON:-python3}
pids=()

stop_load() {
    for pid in "${pids[@]}"; do
        kill "$pid" 2>/dev/null
    done
    for pid in "${pids[@]}"; do
        wait "$pid" 2>/dev/null
    done
    pids=()
}
trap stop_load EXIT
trap 'stop_load; exit 130' INT TERM

for _ in $(seq "$LOAD_PROCS"); do
    timeout "$((LIMIT_S + 60))" "$PYTHON" -c 'while True: pass' &
    pids+=("$!")
done
echo "test-under-load: $LOAD_PROCS busy loops (pids ${pids[*]}), then make test" >&2
start=$(date +%s)
timeout "$LIMIT_S" make --no-print-directory test
status=$?
echo "test-under-load: make test exit $status after $(( $(date +%s) - start )) s under load" >&2
exit "$status"
