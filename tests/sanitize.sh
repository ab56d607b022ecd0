#!/usr/bin/env bash
# Builds everything with clang++ under AddressSanitizer + UndefinedBehaviorSanitizer and runs
# the test suite (or the ctest filter given, e.g. `-R "file|splats|mesh"`).
# Usage: bash tests/sanitize.sh [ctest arguments...]   (BUILD_DIR=... to build elsewhere)
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
MARZIPAN_PACKAGES+=(clang libclang-rt-14-dev)
install_debian_packages
build="${BUILD_DIR:-build-asan}"
CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DMARZIPAN_SANITIZE="address;undefined"
cmake --build "$build" -j "$(nproc)"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
ctest --test-dir "$build" --output-on-failure -j "$(nproc)" "$@"
