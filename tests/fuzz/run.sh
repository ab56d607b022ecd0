#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz with clang (MARZIPAN_FUZZ: ASan + UBSan) into
# their own build directory, writes the seed corpora and runs each target for a bounded time,
# one after the other, printing how many inputs each one executed.
# Usage: bash tests/fuzz/run.sh [SECONDS_PER_TARGET [TARGET...]]
#   SECONDS_PER_TARGET defaults to 10; TARGETs are names like rpc or volume_file (all if none).
#   BUILD_DIR=... builds elsewhere (default build-fuzz); corpora grow in $BUILD_DIR/fuzz-corpus.
# Exits 1 if any target crashed, reported a sanitizer error, broke an invariant, allocated
# more than 64 MB at once or ran a single input for more than 10 s; the input that did it is
# saved under $BUILD_DIR/fuzz-artifacts/TARGET/ and the end of the log is printed.
set -euo pipefail
cd "$(dirname "$0")/../.."
. tests/debian-packages.sh
install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}" "${MARZIPAN_TEST_PACKAGES[@]}"
seconds="${1:-10}"
shift || true
build="${BUILD_DIR:-build-fuzz}"

CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMARZIPAN_FUZZ=ON \
  -DMARZIPAN_BUILD_TESTS=OFF >/dev/null
cmake --build "$build" --target fuzz -j "$(nproc)"
"$build/tests/fuzz/marzipan_fuzz_seeds" tests/protocol/vectors/vectors.json "$build/fuzz-seeds"

targets=("$@")
if ((${#targets[@]} == 0)); then
  for source in tests/fuzz/fuzz_*.cpp; do
    name="$(basename "$source" .cpp)"
    targets+=("${name#fuzz_}")
  done
fi

# Leaks are findings too; halt_on_error keeps UBSan from only printing.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
failed=()
printf '%-14s %12s %8s %10s  %s\n' target execs seconds exec/s result
for t in "${targets[@]}"; do
  corpus="$build/fuzz-corpus/$t" artifacts="$build/fuzz-artifacts/$t" log="$build/fuzz-logs/$t.log"
  mkdir -p "$corpus" "$artifacts" "$(dirname "$log")"
  dict=()
  [ -f "tests/fuzz/dict/$t.dict" ] && dict=("-dict=tests/fuzz/dict/$t.dict")
  # New inputs go to the first directory, the growing corpus; the seeds are only read.
  result=ok
  "$build/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=64 -timeout=10 \
    -print_final_stats=1 -artifact_prefix="$artifacts/" "${dict[@]}" "$corpus" "$build/fuzz-seeds/$t" \
    >"$log" 2>&1 || result=FAILED
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")"
  took="$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log")"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")"
  printf '%-14s %12s %8s %10s  %s\n' "$t" "${execs:-?}" "${took:-?}" "${rate:-?}" "$result"
  if [ "$result" != ok ]; then
    failed+=("$t")
    tail -n 40 "$log"
  fi
done
if ((${#failed[@]})); then
  echo "fuzzing failed: ${failed[*]} (inputs in $build/fuzz-artifacts/)"
  exit 1
fi
