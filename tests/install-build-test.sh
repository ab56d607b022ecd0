#!/usr/bin/env bash
# Installs what is missing (Debian 12, as root), configures, builds and runs every test.
# Usage: bash tests/install-build-test.sh   (BUILD_DIR=... to build elsewhere)
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
install_debian_packages
build="${BUILD_DIR:-build}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$(nproc)"
ctest --test-dir "$build" --output-on-failure -j "$(nproc)"
