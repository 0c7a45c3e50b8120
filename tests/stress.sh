#!/usr/bin/env bash
# Run the tests that use worker pools, threads, background work or kills many times, with one core busy,
# and count the runs that failed: a test that fails one run in twenty fails CI.
#
#   tests/stress.sh [-n RUNS] [--idle] [TEST_FILE_OR_NODE ...]
#
# Defaults: 20 runs of the parallel and background tests, with one busy loop beside them (as a loaded CI
# machine). --idle runs without the busy loop. Each run is a fresh pytest process. Exits 1 when a run failed
# and keeps the failing runs' output in stress-logs/ (printed at the end).
set -u
cd "$(dirname "$0")/.."
runs=20 busy=1 tests=()
while [ $# -gt 0 ]; do
  case "$1" in
    -n) runs="$2"; shift 2 ;;
    --idle) busy=0; shift ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    *) tests+=("$1"); shift ;;
  esac
done
[ ${#tests[@]} -gt 0 ] || tests=(tests/test_background.py tests/test_parallel_lost.py tests/test_quiet_faults.py
                                  tests/test_runner_start.py tests/test_cli_exit.py)
py=.venv/bin/python
[ -x "$py" ] || py=python3
loop_pid=""
if [ "$busy" = 1 ]; then
  "$py" -c 'while True: pass' &
  loop_pid=$!
fi
trap '[ -n "$loop_pid" ] && kill "$loop_pid" 2>/dev/null' EXIT
mkdir -p stress-logs
ok=0 bad=0
for i in $(seq 1 "$runs"); do
  log="stress-logs/run-$i.log"
  if "$py" -m pytest -q -p no:cacheprovider "${tests[@]}" >"$log" 2>&1; then
    ok=$((ok + 1)); rm -f "$log"
  else
    bad=$((bad + 1)); echo "run $i failed: $(grep -E '^(FAILED|ERROR)' "$log" | head -3 | tr '\n' ' ')"
  fi
done
echo "stress ($([ "$busy" = 1 ] && echo 'one core busy' || echo idle), $runs runs of ${tests[*]}): $ok passed, $bad failed"
[ "$bad" = 0 ] && rmdir stress-logs 2>/dev/null
[ "$bad" = 0 ]
