#!/usr/bin/env bash
# Runs the browser tests (every *.test.mjs here but vdb.test.mjs, which needs a server built with
# OpenVDB) the way ctest does, refusing to start without what they need rather than skipping:
# Debian's chromium, the npm dependency installed by tests/install-build-test.sh, and a built
# marzipan. ctest runs each file as its own entry; this runs the files given one after the other.
# Usage: MARZIPAN=build/server/marzipan bash tests/browser/run.sh [FILE.test.mjs ...]
#        (no FILE: all of them, as ctest runs them)
#        (MARZIPAN_BROWSER_ARTIFACTS=DIR for the screenshots; default build/browser-artifacts)
set -euo pipefail
# MARZIPAN may be relative to where this was started; it is resolved before leaving there.
if [ -n "${MARZIPAN:-}" ] && [ -x "$MARZIPAN" ]; then MARZIPAN="$(cd "$(dirname "$MARZIPAN")" && pwd)/$(basename "$MARZIPAN")"; fi
cd "$(dirname "$0")"
chromium="${CHROMIUM:-/usr/lib/chromium/chromium}"
marzipan="${MARZIPAN:-../../build/server/marzipan}"
fail() { echo "tests/browser: $*" >&2; exit 1; }
[ -x "$chromium" ] || fail "no Chromium at $chromium: apt-get install chromium (tests/debian-packages.sh lists it)"
[ -d node_modules/playwright-core ] || fail "playwright-core is not installed: npm ci --prefix tests/browser (tests/install-build-test.sh does it)"
[ -x "$marzipan" ] || fail "no marzipan executable at $marzipan: build it, or set MARZIPAN"
export MARZIPAN="$(cd "$(dirname "$marzipan")" && pwd)/$(basename "$marzipan")"
export CHROMIUM="$chromium"
if [ $# -eq 0 ]; then
  for file in *.test.mjs; do [ "$file" = vdb.test.mjs ] || set -- "$@" "$file"; done
fi
exec node --test --test-concurrency=1 "$@"
