#!/usr/bin/env bash
# Installs what is missing (Debian 12, as root), configures, builds and runs every test.
# Usage: bash tests/install-build-test.sh   (BUILD_DIR=... to build elsewhere)
set -euo pipefail
cd "$(dirname "$0")/.."

# Seconds per stage, printed at the end (also when a stage fails, which is then marked): the
# command must stay under 20 min on the 2-core CI machines, and this shows where it goes.
stage_names=() stage_seconds=() stage_name="" stage_started=$SECONDS
stage() {
  if [ -n "$stage_name" ]; then
    stage_names+=("$stage_name")
    stage_seconds+=($((SECONDS - stage_started)))
  fi
  stage_name="${1:-}" stage_started=$SECONDS
}
print_stages() {
  local status=$? i
  [ -z "$stage_name" ] || stage_names+=("$stage_name (failed)") stage_seconds+=($((SECONDS - stage_started)))
  echo "== seconds per stage (load average at the end: $(cut -d' ' -f1-3 /proc/loadavg))"
  for i in "${!stage_names[@]}"; do printf '%-28s %6d s\n' "${stage_names[$i]}" "${stage_seconds[$i]}"; done
  printf '%-28s %6d s\n' total "$SECONDS"
  return "$status"
}
trap print_stages EXIT

stage "install packages"
. tests/debian-packages.sh
install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}" "${MARZIPAN_TEST_PACKAGES[@]}"
stage "npm"
# ---- Web client (tests/browser) ----------------------------------------------------------------
# The browser tests' one npm dependency, playwright-core (pinned by tests/browser/package-lock.json);
# reinstalled only when the lock file is newer than what node_modules holds.
if [ ! -f tests/browser/node_modules/.package-lock.json ] ||
   [ tests/browser/package-lock.json -nt tests/browser/node_modules/.package-lock.json ]; then
  npm ci --prefix tests/browser --no-audit --no-fund
fi
# ---- end of Web client --------------------------------------------------------------------------
# ---- glTF validator (tests/gltf) -------------------------------------------------------------------
# The Khronos glTF validator and the glTF and PLY readers that check exported colours (glTF
# Transform, loaders.gl), pinned by tests/gltf/package-lock.json, reinstalled like the above.
if [ ! -f tests/gltf/node_modules/.package-lock.json ] ||
   [ tests/gltf/package-lock.json -nt tests/gltf/node_modules/.package-lock.json ]; then
  npm ci --prefix tests/gltf --no-audit --no-fund
fi
# ---- end of glTF validator ---------------------------------------------------------------------------
build="${BUILD_DIR:-build}"
# ccache (the compiler launcher, CMakeLists.txt) keys an object on the compiler's command line
# or preprocessed output, both of which name this checkout's absolute path, and with -g (the
# clang sanitizer and fuzz builds) on the build directory too: a clean clone elsewhere, as in CI,
# found nothing in a warm cache and compiled all four builds anew. With paths under the checkout
# made relative and the build directory left out of the key, a fresh clone anywhere reuses what
# an earlier one compiled; the debug info of such an object names the build directory it was
# first compiled in (only the directory; the file and line are this checkout's).
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}" CCACHE_NOHASHDIR="${CCACHE_NOHASHDIR:-1}"
stage "configure + build"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMARZIPAN_BUILD_TESTS=ON
cmake --build "$build" -j "$(nproc)"
stage "ctest"
ctest --test-dir "$build" --output-on-failure -j "$(nproc)"

# ---- OpenVDB (tests/openvdb.sh) --------------------------------------------------------------
# The optional .vdb build (-DMARZIPAN_WITH_OPENVDB=ON) in its own directory, sharing ccache with
# the build above: only the targets the .vdb tests need, then only those tests. Measured
# 2026-11-24 on this 2-core VM at load 5-7: 34 s when the six files that see OpenVDB are
# unchanged (every object from ccache), up to 92 s more when all six must be compiled again.
stage "OpenVDB build + tests"
BUILD_DIR="${build}-vdb" bash tests/openvdb.sh
# ---- end of OpenVDB --------------------------------------------------------------------------

# ---- Hostile input (tests/sanitize.sh, tests/fuzz) -------------------------------------------
# The engine and protocol suites under ASan + UBSan, then the fuzz gate: every fuzz target over
# its checked-in corpus, every past finding and a short run with a fixed seed, so that the same
# checkout passes or fails the same way every time. The whole suite under ASan + UBSan is
# `bash tests/sanitize.sh`, under TSan `bash tests/tsan.sh`; open-ended fuzzing with random seeds
# is `bash tests/fuzz/explore.sh 300` (tests/fuzz/README.md).
stage "sanitizer build + tests"
SUITES="engine protocol" BUILD_DIR="${build}-asan" bash tests/sanitize.sh
stage "fuzz"
BUILD_DIR="${build}-fuzz" bash tests/fuzz/run.sh
stage
# ---- end of Hostile input --------------------------------------------------------------------
