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
. tests/sanitized-build.sh
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
run_sanitized "ASan + UBSan" build-asan "address;undefined" "$@"
