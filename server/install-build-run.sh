#!/usr/bin/env bash
# Installs what building and running need (Debian 12, as root; MARZIPAN_RUN_PACKAGES in
# tests/debian-packages.sh, no test tools), builds the `marzipan` executable (Release, into
# build/) and runs `marzipan serve` (default http://127.0.0.1:8080) until Ctrl-C.
#
# Sessions are kept on disk, in ${XDG_DATA_HOME:-~/.local/share}/marzipan, so that they survive
# a restart; `--data-dir DIR` (or MARZIPAN_DATA_DIR) keeps them elsewhere, and `--in-memory`
# keeps them in memory only (lost when the server stops), as `marzipan serve` itself does when
# it is given no data directory.
# Usage: bash server/install-build-run.sh [--in-memory] [serve options]   e.g. --bind 0.0.0.0 --port 9000
# (BUILD_DIR=... to build elsewhere; `marzipan serve --help` lists the options.)
set -euo pipefail
cd "$(dirname "$0")/.."
. tests/debian-packages.sh
install_debian_packages "${MARZIPAN_RUN_PACKAGES[@]}"
build="${BUILD_DIR:-build}"
# Tests off: configuring them needs Catch2, a test-only package (tests/install-build-test.sh
# turns them back on in the same build directory).
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMARZIPAN_BUILD_TESTS=OFF
cmake --build "$build" -j "$(nproc)" --target marzipan

args=()
data_dir_given=${MARZIPAN_DATA_DIR:+yes}
in_memory=""
for a in "$@"; do
  case "$a" in
    --in-memory) in_memory=yes ;;
    --data-dir | --data-dir=*) data_dir_given=yes; args+=("$a") ;;
    *) args+=("$a") ;;
  esac
done
if [ -n "$in_memory" ] && [ -n "$data_dir_given" ]; then
  echo "install-build-run.sh: --in-memory and --data-dir (or MARZIPAN_DATA_DIR) contradict each other" >&2
  exit 2
fi
if [ -z "$in_memory" ] && [ -z "$data_dir_given" ]; then
  data_dir="${XDG_DATA_HOME:-$HOME/.local/share}/marzipan"
  echo "sessions are kept in $data_dir (--data-dir DIR elsewhere, --in-memory for none)"
  args=(--data-dir "$data_dir" "${args[@]}")
fi
exec "$build/server/marzipan" serve "${args[@]}"
