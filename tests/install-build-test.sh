#!/usr/bin/env bash
# Installs what is missing (Debian 12, as root), configures, builds and runs every test.
# Usage: bash tests/install-build-test.sh   (BUILD_DIR=... to build elsewhere)
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
install_debian_packages
# The browser tests' one npm dependency, playwright-core (pinned by tests/browser/package-lock.json);
# reinstalled only when the lock file is newer than what node_modules holds.
if [ ! -f tests/browser/node_modules/.package-lock.json ] ||
   [ tests/browser/package-lock.json -nt tests/browser/node_modules/.package-lock.json ]; then
  npm ci --prefix tests/browser --no-audit --no-fund
fi
build="${BUILD_DIR:-build}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$(nproc)"
ctest --test-dir "$build" --output-on-failure -j "$(nproc)"
