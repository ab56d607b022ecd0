#!/usr/bin/env bash
# Builds everything with clang++ under ThreadSanitizer and runs the test suite (or the ctest
# filter given, e.g. `-R "service|net"`): the thread pool, copy-on-write volumes read on other
# threads, sessions and the server's I/O threads.
# Usage: bash tests/tsan.sh [ctest arguments...]   (BUILD_DIR=... to build elsewhere)
#        SUITES="service net" bash tests/tsan.sh
#   builds only those Catch2 suites (tests/AREA) and runs each executable once, all its tests
#   in one process: the hub, sessions on the worker pool and the server's I/O threads.
# TSan slows the engine about 12 times: on a busy machine the longest engine tests (mean
# curvature flow: 28 s in Release, 330 s under TSan, both on a loaded 2-core machine) can pass
# ctest's 600 s limit when two run at once; run them alone then, e.g. `-R "curvature"`.
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/sanitized-build.sh
# halt_on_error: a race fails its test instead of only printing a report.
export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1
run_sanitized "TSan" build-tsan "thread" "$@"
