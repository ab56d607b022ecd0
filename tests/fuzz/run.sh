#!/usr/bin/env bash
# The fuzz gate of the test command: deterministic, so that it passes or fails the same way on
# every run of the same checkout. For each target (tests/fuzz/README.md):
#   replay  every checked-in input: tests/fuzz/corpus/TARGET, tests/fuzz/regressions/TARGET and
#           the generated seeds, each executed once (-runs=0);
#   seeded  a short fuzzing run from those same inputs with a fixed seed and a fixed number of
#           inputs (-seed, -runs), so that it explores the same mutations every time; what it
#           adds to the corpus goes to a scratch directory emptied before each run.
# A new random discovery cannot fail it; an old finding, or a change that breaks a decoder on
# the fixed inputs or the seeded path, always does. Open-ended fuzzing is tests/fuzz/explore.sh.
# Usage: bash tests/fuzz/run.sh [TARGET...]   (targets are names like rpc or volume_file; all if none)
#   BUILD_DIR=... builds elsewhere (default build-fuzz); MARZIPAN_FUZZ_SEED (default 1) and
#   MARZIPAN_FUZZ_RUNS (inputs of the seeded run, default 20000) change the seeded run.
# Exits 1 if any run crashed, reported a sanitizer error, broke an invariant, allocated more than
# 64 MB at once or ran a single input for more than 10 s; the input that did it is saved under
# $BUILD_DIR/fuzz-artifacts/TARGET/ and the end of the log is printed.
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${BUILD_DIR:-build-fuzz}"
seed="${MARZIPAN_FUZZ_SEED:-1}"
runs="${MARZIPAN_FUZZ_RUNS:-20000}"
. tests/fuzz/setup.sh

failed=()
table_header
for t in "${targets[@]}"; do
  scratch="$build/fuzz-gate-scratch/$t"
  mapfile -t inputs < <(fixed_inputs "$t")
  mapfile -t dict < <(dict_of "$t")
  run_target "$t" replay -runs=0 "${inputs[@]}"
  rm -rf "$scratch" && mkdir -p "$scratch"
  run_target "$t" seeded -seed="$seed" -runs="$runs" "${dict[@]}" "$scratch" "${inputs[@]}"
done
rm -rf "$build/fuzz-gate-scratch"
if ((${#failed[@]})); then
  echo "fuzzing failed: ${failed[*]} (inputs in $build/fuzz-artifacts/; a finding goes into tests/fuzz/regressions/TARGET/ with its fix)"
  exit 1
fi
