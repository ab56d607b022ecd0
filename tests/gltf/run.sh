#!/usr/bin/env bash
# Runs validate.test.mjs the way ctest does, refusing to start without what it needs rather
# than skipping: the npm validator installed by tests/install-build-test.sh and a built marzipan.
# Usage: MARZIPAN=build/server/marzipan bash tests/gltf/run.sh
set -euo pipefail
cd "$(dirname "$0")"
marzipan="${MARZIPAN:-../../build/server/marzipan}"
fail() { echo "tests/gltf: $*" >&2; exit 1; }
[ -d node_modules/gltf-validator ] || fail "gltf-validator is not installed: npm ci --prefix tests/gltf (tests/install-build-test.sh does it)"
[ -x "$marzipan" ] || fail "no marzipan executable at $marzipan: build it, or set MARZIPAN"
export MARZIPAN="$(cd "$(dirname "$marzipan")" && pwd)/$(basename "$marzipan")"
exec node --test validate.test.mjs
