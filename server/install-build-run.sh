#!/usr/bin/env bash
# Installs what is missing (Debian 12, as root), builds the `marzipan` executable (Release, into
# build/) and runs `marzipan serve` (default http://127.0.0.1:8080) until Ctrl-C.
# Usage: bash server/install-build-run.sh [serve options]   e.g. --bind 0.0.0.0 --port 9000
# (BUILD_DIR=... to build elsewhere; `marzipan serve --help` lists the options.)
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
install_debian_packages
build="${BUILD_DIR:-build}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build "$build" -j "$(nproc)" --target marzipan
exec "$build/server/marzipan" serve "$@"
