#!/usr/bin/env bash
# Runs validate.test.mjs and colors.test.mjs the way ctest does, refusing to start without what
# they need rather than skipping: the npm packages of package-lock.json (the validator, and the
# independent glTF and PLY readers that check vertex colours) installed by
# tests/install-build-test.sh, and a built marzipan.
# Usage: MARZIPAN=build/server/marzipan bash tests/gltf/run.sh
set -euo pipefail
cd "$(dirname "$0")"
marzipan="${MARZIPAN:-../../build/server/marzipan}"
fail() { echo "tests/gltf: $*" >&2; exit 1; }
for package in gltf-validator @gltf-transform/core @loaders.gl/core @loaders.gl/ply; do
  [ -d "node_modules/$package" ] || fail "$package is not installed: npm ci --prefix tests/gltf (tests/install-build-test.sh does it)"
done
[ -x "$marzipan" ] || fail "no marzipan executable at $marzipan: build it, or set MARZIPAN"
export MARZIPAN="$(cd "$(dirname "$marzipan")" && pwd)/$(basename "$marzipan")"
exec node --test validate.test.mjs colors.test.mjs
