#!/usr/bin/env bash
# The whole test suite, run N times while two CPU hogs keep both cores busy (run by hand).
#
#     bash benchmarks/loaded_suite.sh [RUNS]        # default 10; run from a checkout with .venv set up
#
# Prints one line per run (wall time, pytest's closing line) and the pass count. The suite
# must pass every run: a test that asserts wall-clock behaviour would fail here. Logs are
# kept in test-artifacts/loaded/.
set -uo pipefail
cd "$(dirname "$0")/.."
runs=${1:-10}
logs=test-artifacts/loaded
mkdir -p "$logs"
hogs=()
for _ in 1 2; do
    python3 -c "while True: pass" &
    hogs+=($!)
done
trap 'kill "${hogs[@]}" 2>/dev/null' EXIT
passed=0
for ((k = 1; k <= runs; k++)); do
    began=$(date +%s)
    .venv/bin/python -m pytest -q -p no:cacheprovider > "$logs/run-$k.log" 2>&1
    status=$?
    took=$(( $(date +%s) - began ))
    [ "$status" -eq 0 ] && passed=$((passed + 1))
    echo "run $k: exit $status in ${took} s: $(tail -n 1 "$logs/run-$k.log")"
done
echo "$passed of $runs runs passed, with two CPU hogs on $(nproc) cores"
[ "$passed" -eq "$runs" ]
