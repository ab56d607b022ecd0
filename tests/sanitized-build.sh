# Sourced by tests/sanitize.sh and tests/tsan.sh: builds with clang++ and the sanitizers given,
# then runs either the Catch2 suites named in SUITES (each executable once, all its tests in
# one process, without building the server) or ctest with the caller's arguments.
# Usage: run_sanitized LABEL DEFAULT_BUILD_DIR SANITIZERS [ctest arguments...]
#   (BUILD_DIR overrides the build directory; the caller sets the sanitizer's *_OPTIONS.)
run_sanitized() {
  local label="$1" build="${BUILD_DIR:-$2}" sanitizers="$3"
  shift 3
  . tests/debian-packages.sh
  install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}" "${MARZIPAN_TEST_PACKAGES[@]}"
  CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DMARZIPAN_SANITIZE="$sanitizers"
  if [ -n "${SUITES:-}" ]; then
    local suites suite
    read -r -a suites <<<"$SUITES"
    cmake --build "$build" -j "$(nproc)" --target "${suites[@]/%/_tests}"
    for suite in "${suites[@]}"; do
      echo "== ${suite}_tests under $label"
      "$build/tests/${suite}_tests"
    done
    return 0
  fi
  cmake --build "$build" -j "$(nproc)"
  ctest --test-dir "$build" --output-on-failure -j "$(nproc)" "$@"
}
