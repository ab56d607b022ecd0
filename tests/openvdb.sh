#!/usr/bin/env bash
# The OpenVDB configuration (-DMARZIPAN_WITH_OPENVDB=ON, Debian's libopenvdb-dev from the TEST
# package list) in its own build directory, sharing ccache with the default build: builds only
# what the .vdb tests need and runs only those (the engine's .vdb files, the hub's volume.save /
# volume.load as .vdb, batch --out/--load x.vdb, the Python client's .vdb round trip, and the web
# client's Save .vdb / Load .vdb in Chromium, tests/browser/vdb.test.mjs).
# Usage: bash tests/openvdb.sh   (BUILD_DIR=... to build elsewhere; default build-vdb)
set -euo pipefail
cd "$(dirname "$0")/.."
build="${BUILD_DIR:-build-vdb}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMARZIPAN_BUILD_TESTS=ON -DMARZIPAN_WITH_OPENVDB=ON >/dev/null
cmake --build "$build" -j "$(nproc)" --target openvdb_tests service_tests cli_tests marzipan
ctest --test-dir "$build" --output-on-failure -j "$(nproc)" -R '^(openvdb:|service:.*(\.vdb|format)|cli:.*\.vdb)'
MARZIPAN_BIN="$PWD/$build/server/marzipan" /usr/bin/python3 tests/protocol/python/test_client_server.py \
  AgainstServer.test_vdb_files_round_trip_where_the_server_has_openvdb_and_are_refused_elsewhere
MARZIPAN_BIN="$PWD/$build/server/marzipan" /usr/bin/python3 tests/protocol/python/test_cli.py \
  AgainstServer.test_out_vdb_writes_an_openvdb_file_or_says_the_server_has_no_openvdb
MARZIPAN="$PWD/$build/server/marzipan" bash tests/browser/run.sh vdb.test.mjs
