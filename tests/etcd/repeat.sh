#!/bin/bash
# Runs the etcd fail-over test (test_etcd_failover.py) RUNS times in a row, optionally with every
# core kept busy by stress-ng, and records each run's outcome; a failure that happens once in
# dozens of runs under CI load is found and explained this way (issue 28 item 4).
#
# Usage: tests/etcd/repeat.sh BUILD_DIR OUT_DIR [RUNS=50] [--load]
#   BUILD_DIR   a build with the marzipan target (BUILD_DIR/server/marzipan)
#   OUT_DIR     created; gets results.tsv (run, pass/FAIL, seconds, UTC start), each run's output
#               as run-N.out, and for a failed run its whole work directory (every server's and
#               etcd member's log) as run-N/
#   --load      stress-ng --cpu N (N = nproc) for the whole loop, stopped at the end
# The marzipan binary is copied into OUT_DIR first, so that a rebuild meanwhile does not change
# what is tested. Exit status: 0 when every run passed.
set -u
build=${1:?usage: repeat.sh BUILD_DIR OUT_DIR [RUNS] [--load]}
out=${2:?usage: repeat.sh BUILD_DIR OUT_DIR [RUNS] [--load]}
runs=${3:-50}
load=${4:-}
here=$(cd "$(dirname "$0")" && pwd)
source_dir=$(cd "$here/../.." && pwd)

mkdir -p "$out"
cp "$build/server/marzipan" "$out/marzipan"
: > "$out/results.tsv"
stress_pid=
if [ "$load" = "--load" ]; then
  stress-ng --cpu "$(nproc)" --quiet > "$out/stress-ng.log" 2>&1 &
  stress_pid=$!
fi
stop_load() { [ -n "$stress_pid" ] && kill "$stress_pid" 2> /dev/null && wait "$stress_pid" 2> /dev/null; }
trap stop_load EXIT

failures=0
for n in $(seq 1 "$runs"); do
  work="$out/run-$n"
  started=$(date -u +%H:%M:%S)
  t0=$(date +%s.%N)
  # ctest's limit for this test (tests/CMakeLists.txt), as a backstop to the test's own.
  timeout -s KILL 120 env PYTHONDONTWRITEBYTECODE=1 /usr/bin/python3 "$here/test_etcd_failover.py" \
    --marzipan "$out/marzipan" --haproxy /usr/sbin/haproxy --config "$source_dir/docker/haproxy.cfg" \
    --workdir "$work" > "$out/run-$n.out" 2>&1
  rc=$?
  seconds=$(echo "$(date +%s.%N) - $t0" | bc)
  if [ $rc -eq 0 ]; then
    result=pass
    rm -rf "$work"
  else
    result=FAIL
    failures=$((failures + 1))
  fi
  printf '%s\t%s\t%.1f\t%s\n' "$n" "$result" "$seconds" "$started" | tee -a "$out/results.tsv"
done
echo "$runs runs, $failures failed${load:+ (under stress-ng)}" | tee -a "$out/results.tsv"
[ $failures -eq 0 ]
