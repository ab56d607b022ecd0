# Sourced by tests/fuzz/run.sh (the gate) and tests/fuzz/explore.sh: installs what is missing,
# builds the libFuzzer targets (clang, ASan + UBSan) into $build, writes the generated seeds and
# sets what both scripts share. Expects `build` and the positional TARGET names ("$@").
#
# Inputs each target reads, all fixed by the checkout:
#   tests/fuzz/corpus/TARGET/       inputs fuzzing found that reach code the seeds do not (kept in git)
#   tests/fuzz/regressions/TARGET/  every input that ever broke the target (kept in git)
#   $build/fuzz-seeds/TARGET/       made by marzipan_fuzz_seeds from the golden vectors and the engine
. tests/debian-packages.sh
install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}" "${MARZIPAN_TEST_PACKAGES[@]}"

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
# What counts as a finding besides a crash (tests/fuzz/README.md): one allocation over 64 MB,
# 2 GB resident, one input running over 10 s.
fuzz_limits=(-rss_limit_mb=2048 -malloc_limit_mb=64 -timeout=10)

# The fixed input directories of target $1 that exist (libFuzzer refuses a missing one).
fixed_inputs() {
  local dir
  for dir in "tests/fuzz/corpus/$1" "tests/fuzz/regressions/$1" "$build/fuzz-seeds/$1"; do
    [ -d "$dir" ] && printf '%s\n' "$dir"
  done
}

# libFuzzer's -dict for target $1, when tests/fuzz/dict has one.
dict_of() {
  [ -f "tests/fuzz/dict/$1.dict" ] && printf '%s\n' "-dict=tests/fuzz/dict/$1.dict"
  return 0
}

# The results table: a line per run of a target (run_target), under this header.
row_format='%-14s %-8s %12s %8s %10s  %s\n'
table_header() { printf "$row_format" target run execs seconds exec/s result; }

# run_target TARGET RUN FLAG...: runs fuzz_TARGET with the shared limits and FLAGs, its log in
# $build/fuzz-logs/TARGET.RUN.log and what it finds in $build/fuzz-artifacts/TARGET/; prints its
# line of the table (inputs executed, seconds, rate, ok or FAILED) and, when it failed, adds
# "TARGET (RUN)" to the caller's `failed` array and prints the end of the log.
run_target() {
  local t="$1" run="$2" result=ok execs took rate
  shift 2
  local log="$build/fuzz-logs/$t.$run.log" artifacts="$build/fuzz-artifacts/$t"
  mkdir -p "$artifacts" "$build/fuzz-logs"
  "$build/tests/fuzz/fuzz_$t" "${fuzz_limits[@]}" -print_final_stats=1 -artifact_prefix="$artifacts/" "$@" \
    >"$log" 2>&1 || result=FAILED
  execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")"
  took="$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$log")"
  rate="$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")"
  printf "$row_format" "$t" "$run" "${execs:-?}" "${took:-?}" "${rate:-?}" "$result"
  if [ "$result" != ok ]; then
    failed+=("$t ($run)")
    tail -n 40 "$log"
  fi
}
