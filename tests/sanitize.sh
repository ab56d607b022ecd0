#!/usr/bin/env bash
# Builds everything with clang++ under AddressSanitizer + UndefinedBehaviorSanitizer and runs
# the test suite (or the ctest filter given, e.g. `-R "file|splats|mesh"`).
# Usage: bash tests/sanitize.sh [ctest arguments...]   (BUILD_DIR=... to build elsewhere)
#        SUITES="engine protocol" bash tests/sanitize.sh
#   builds only those Catch2 suites (tests/AREA) and runs each executable once, all its tests
#   in one process: the decoders of untrusted bytes and the engine behind them, without
#   building the server. CI runs this form (tests/install-build-test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}" "${MARZIPAN_TEST_PACKAGES[@]}"
build="${BUILD_DIR:-build-asan}"
CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DMARZIPAN_SANITIZE="address;undefined"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
if [ -n "${SUITES:-}" ]; then
  read -r -a suites <<<"$SUITES"
  cmake --build "$build" -j "$(nproc)" --target "${suites[@]/%/_tests}"
  for suite in "${suites[@]}"; do
    echo "== ${suite}_tests under ASan + UBSan"
    "$build/tests/${suite}_tests"
  done
  exit 0
fi
cmake --build "$build" -j "$(nproc)"
ctest --test-dir "$build" --output-on-failure -j "$(nproc)" "$@"
