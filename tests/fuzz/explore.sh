#!/usr/bin/env bash
# Open-ended fuzzing, outside the test command: each target in turn for SECONDS with a random
# seed, from the checked-in inputs (tests/fuzz/setup.sh) and what earlier explorations found in
# $BUILD_DIR/fuzz-corpus/TARGET. What to do with its results is in tests/fuzz/README.md: a
# finding goes into tests/fuzz/regressions/TARGET/ with its fix, and --merge keeps the inputs
# that reach new code in tests/fuzz/corpus/TARGET/.
# Usage: bash tests/fuzz/explore.sh [SECONDS_PER_TARGET [TARGET...]]   (default 60 s, all targets)
#        bash tests/fuzz/explore.sh --merge [TARGET...]
#   BUILD_DIR=... builds elsewhere (default build-fuzz).
# Exits 1 if any target found something; the input is in $BUILD_DIR/fuzz-artifacts/TARGET/.
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${BUILD_DIR:-build-fuzz}"
merge=false seconds=60
if [ "${1:-}" = --merge ]; then
  merge=true
  shift
elif [ $# -gt 0 ]; then
  seconds="$1"
  shift
fi
. tests/fuzz/setup.sh

if $merge; then
  # Only explored inputs that reach code the checked-in and generated inputs do not are kept:
  # libFuzzer merges them into a copy of those, and what is new in the copy is added.
  mkdir -p "$build/fuzz-logs"
  for t in "${targets[@]}"; do
    [ -d "$build/fuzz-corpus/$t" ] || continue
    known="$build/fuzz-merge/$t"
    rm -rf "$known" && mkdir -p "$known" "tests/fuzz/corpus/$t"
    mapfile -t inputs < <(fixed_inputs "$t")
    for dir in "${inputs[@]}"; do cp -- "$dir"/* "$known"/ 2>/dev/null || true; done
    before="$(ls "$known")"
    "$build/tests/fuzz/fuzz_$t" "${fuzz_limits[@]}" -merge=1 "$known" "$build/fuzz-corpus/$t" \
      >"$build/fuzz-logs/$t.merge.log" 2>&1
    added=0
    for f in "$known"/*; do
      grep -qxF -- "$(basename "$f")" <<<"$before" && continue
      cp -- "$f" "tests/fuzz/corpus/$t/"
      added=$((added + 1))
    done
    echo "$t: $added inputs added to tests/fuzz/corpus/$t"
  done
  rm -rf "$build/fuzz-merge"
  exit 0
fi

failed=()
table_header
for t in "${targets[@]}"; do
  corpus="$build/fuzz-corpus/$t"
  mkdir -p "$corpus"
  mapfile -t inputs < <(fixed_inputs "$t")
  mapfile -t dict < <(dict_of "$t")
  # New inputs go to the first directory, the growing corpus; the fixed inputs are only read.
  run_target "$t" explore -max_total_time="$seconds" "${dict[@]}" "$corpus" "${inputs[@]}"
done
if ((${#failed[@]})); then
  echo "exploration found: ${failed[*]} (inputs in $build/fuzz-artifacts/; each goes into tests/fuzz/regressions/TARGET/ with its fix)"
  exit 1
fi
