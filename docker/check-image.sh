#!/usr/bin/env bash
# Builds docker/Dockerfile with podman where no registry and no Docker daemon can be reached, and
# checks that the runtime image works: a Debian 12 base made by debootstrap (--variant=minbase)
# and `podman import` stands in for debian:12 and debian:bookworm-slim; the image's file tree
# is mounted and `marzipan serve --port 0` runs in a chroot of it, as the image's user and with
# the image's environment, answers its own health check, HTTP and a WebSocket session, and on
# SIGTERM saves that session into the image's data directory and exits 0.
#
# Usage (Debian 12, as root, from anywhere):   bash docker/check-image.sh
#   JOBS=N        compile jobs inside the build (default 2)
#   FRESH=1       debootstrap a new base even when the imported one exists
#   KEEP_IMAGE=1  keep localhost/marzipan:check afterwards (default: removed)
# It prints the time of each step and the image's size. Installs podman, debootstrap, curl and
# python3-websockets when missing. Exit 0 when every check passed.
#
# Conventions: every step says what it checks on one line; a failed check prints why and exits
# 1; whatever the script started or mounted is undone on exit.
set -euo pipefail
cd "$(dirname "$0")/.."

base_image=localhost/marzipan-base:bookworm-minbase
image=localhost/marzipan:check
jobs="${JOBS:-2}"

step() {
  echo "== $* (at ${SECONDS}s)"
}
fail() {
  echo "FAILED: $*" >&2
  exit 1
}

container="" mnt="" server_pid="" work=""
cleanup() {
  if [ -n "$server_pid" ] && kill -0 "$server_pid" 2>/dev/null; then
    kill -KILL "$server_pid" 2>/dev/null || true
  fi
  if [ -n "$container" ]; then
    podman umount "$container" >/dev/null 2>&1 || true
    podman rm -f "$container" >/dev/null 2>&1 || true
  fi
  if [ "${KEEP_IMAGE:-0}" != 1 ]; then
    podman rmi -f "$image" >/dev/null 2>&1 || true
  fi
  if [ -n "$work" ]; then rm -rf "$work"; fi
}
trap cleanup EXIT

missing=()
for tool in podman debootstrap curl; do
  command -v "$tool" >/dev/null || missing+=("$tool")
done
/usr/bin/python3 -c 'import websockets' 2>/dev/null || missing+=(python3-websockets)
if ((${#missing[@]})); then
  [ "$(id -u)" -eq 0 ] || fail "needs ${missing[*]} (apt-get install ${missing[*]}) and root"
  step "installing ${missing[*]}"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
[ "$(id -u)" -eq 0 ] || fail "debootstrap, chroot and podman's storage need root"
work="$(mktemp -d /var/tmp/marzipan-check.XXXXXX)"

if [ "${FRESH:-0}" = 1 ] || ! podman image exists "$base_image"; then
  step "debootstrap --variant=minbase bookworm, podman import as $base_image"
  debootstrap --variant=minbase bookworm "$work/rootfs" http://deb.debian.org/debian >"$work/debootstrap.log" 2>&1 \
    || { tail -20 "$work/debootstrap.log" >&2; fail "debootstrap"; }
  # Like the registry's images: no package lists or downloaded packages in the base.
  rm -rf "$work/rootfs/var/lib/apt/lists/"* "$work/rootfs/var/cache/apt/"*
  tar -C "$work/rootfs" -c . | podman import --quiet --change 'CMD ["/bin/bash"]' - "$base_image" >/dev/null
  rm -rf "$work/rootfs"
else
  step "reusing $base_image (FRESH=1 makes a new one)"
fi

step "podman build --isolation chroot (JOBS=$jobs)"
build_start=$SECONDS
# --format docker keeps HEALTHCHECK, which the OCI image format has no field for; --layers=false
# leaves no intermediate images (the build stage's is near 1 GB) behind.
podman build --isolation chroot --format docker --pull=never --layers=false \
  --build-arg BUILD_BASE="$base_image" --build-arg RUNTIME_BASE="$base_image" --build-arg JOBS="$jobs" \
  --ignorefile docker/Dockerfile.dockerignore -f docker/Dockerfile -t "$image" . >"$work/build.log" 2>&1 \
  || { tail -40 "$work/build.log" >&2; fail "podman build (log above)"; }
build_seconds=$((SECONDS - build_start))
echo "built in ${build_seconds}s"

step "image configuration"
inspect() { podman image inspect --format "$1" "$image"; }
size_bytes="$(inspect '{{.Size}}')"
echo "image size: $((size_bytes / 1000000)) MB (the base alone: $(($(podman image inspect --format '{{.Size}}' "$base_image") / 1000000)) MB)"
[ "$(inspect '{{.Config.User}}')" = marzipan ] || fail "the image does not run as the user marzipan"
inspect '{{json .Config.ExposedPorts}}' | grep -q '"8080/tcp"' || fail "8080/tcp is not exposed"
inspect '{{json .Config.Volumes}}' | grep -q '"/var/lib/marzipan"' || fail "/var/lib/marzipan is not a volume"
inspect '{{json .Config.Healthcheck}}' | grep -q 'healthcheck' || fail "no HEALTHCHECK running marzipan healthcheck"
[ "$(inspect '{{.Config.StopSignal}}')" = SIGTERM ] || fail "the stop signal is not SIGTERM"
mapfile -t image_env < <(inspect '{{range .Config.Env}}{{println .}}{{end}}' | sed '/^$/d')
for setting in MARZIPAN_BIND=0.0.0.0 MARZIPAN_PORT=8080 MARZIPAN_DATA_DIR=/var/lib/marzipan; do
  printf '%s\n' "${image_env[@]}" | grep -qx "$setting" || fail "the image's environment lacks $setting"
done

step "the runtime tree: no compiler, every library found"
container="$(podman create "$image")"
mnt="$(podman mount "$container")"
[ -x "$mnt/usr/local/bin/marzipan" ] || fail "no /usr/local/bin/marzipan"
for tool in g++ cc cmake curl; do
  [ ! -e "$mnt/usr/bin/$tool" ] || fail "the runtime image has /usr/bin/$tool"
done
[ ! -d "$mnt/usr/include/boost" ] || fail "the runtime image has Boost's headers"
[ -f "$mnt/opt/marzipan/web-client/index.html" ] || fail "no web-client/index.html"
for f in protocol/js/*.js; do
  cmp -s "$f" "$mnt/opt/marzipan/$f" || fail "the image's /opt/marzipan/$f differs from the checkout's"
done
if chroot "$mnt" /usr/bin/ldd /usr/local/bin/marzipan | grep 'not found'; then fail "missing shared libraries"; fi
uid="$(awk -F: '$1 == "marzipan" { print $3 ":" $4 }' "$mnt/etc/passwd")"
[ -n "$uid" ] && [ "${uid%%:*}" != 0 ] || fail "no non-root user marzipan in /etc/passwd"
data_owner="$(stat -c %u:%g "$mnt/var/lib/marzipan")"
[ "$data_owner" = "$uid" ] || fail "/var/lib/marzipan belongs to $data_owner, not marzipan ($uid)"

# Runs a command in the image's tree as its user, with only the image's environment.
in_image() {
  env -i "${image_env[@]}" chroot --userspec="$uid" "$mnt" "$@"
}

step "marzipan serve --port 0 in a chroot of the image"
env -i "${image_env[@]}" chroot --userspec="$uid" "$mnt" /usr/local/bin/marzipan serve --port 0 \
  >"$work/serve.out" 2>"$work/serve.err" &
server_pid=$!
port=""
for _ in $(seq 100); do
  port="$(sed -n 's|^listening on http://0\.0\.0\.0:\([0-9][0-9]*\)$|\1|p' "$work/serve.out")"
  [ -n "$port" ] && break
  kill -0 "$server_pid" 2>/dev/null || { cat "$work/serve.err" >&2; fail "marzipan serve exited"; }
  sleep 0.1
done
[ -n "$port" ] || fail "marzipan serve printed no 'listening on http://0.0.0.0:PORT' within 10 s"
echo "listening on port $port"

step "marzipan healthcheck (as the image's HEALTHCHECK runs it)"
start_ms=$(date +%s%3N)
env -i "${image_env[@]}" MARZIPAN_PORT="$port" chroot --userspec="$uid" "$mnt" /usr/local/bin/marzipan healthcheck \
  || fail "marzipan healthcheck on a serving server"
echo "healthy, in $(($(date +%s%3N) - start_ms)) ms"
in_image /usr/local/bin/marzipan healthcheck --url "http://127.0.0.1:$port/healthz" >/dev/null \
  || fail "marzipan healthcheck --url"
curl -fsS --max-time 5 "http://127.0.0.1:$port/" | cmp -s - web-client/index.html \
  || fail "GET / is not web-client/index.html"
echo "GET / is web-client/index.html"
curl -fsS --max-time 5 "http://127.0.0.1:$port/protocol/js/frames.js" | cmp -s - protocol/js/frames.js \
  || fail "GET /protocol/js/frames.js is not protocol/js/frames.js"
echo "GET /protocol/js/frames.js is protocol/js/frames.js"

step "a WebSocket session in the image's server"
session="$(/usr/bin/python3 - "$port" <<'PY'
import asyncio, json, sys, websockets

async def main(port):
    async with websockets.connect(f"ws://127.0.0.1:{port}/ws", max_size=None) as ws:
        async def call(i, method, params):
            await ws.send(json.dumps({"jsonrpc": "2.0", "id": i, "method": method, "params": params}))
            while True:
                m = await asyncio.wait_for(ws.recv(), 10)
                if isinstance(m, str) and json.loads(m).get("id") == i:
                    return json.loads(m)["result"]
        created = await call(1, "session.create", {"size": [32, 32, 32], "solid": "sphere", "view": "none"})
        await call(2, "tool.apply", {"tool": "csg_add", "shape": "box", "center": [16, 26, 16], "radius": 3})
        print(created["session"])

asyncio.run(main(int(sys.argv[1])))
PY
)" || fail "a WebSocket session (session.create, tool.apply)"
echo "session $session created and edited"

step "SIGTERM stops it gracefully"
kill -TERM "$server_pid"
status=0
for _ in $(seq 100); do
  kill -0 "$server_pid" 2>/dev/null || break
  sleep 0.1
done
kill -0 "$server_pid" 2>/dev/null && fail "still running 10 s after SIGTERM"
wait "$server_pid" || status=$?
server_pid=""
[ "$status" = 0 ] || fail "exit status $status after SIGTERM, not 0"
if in_image /usr/local/bin/marzipan healthcheck --url "http://127.0.0.1:$port/healthz" 2>/dev/null; then
  fail "healthcheck passed with the server stopped"
fi
echo "exited 0; the health check now fails, as it should"
saved="$mnt/var/lib/marzipan/sessions/$session"
[ -s "$saved/session.json" ] && compgen -G "$saved/snapshot-*.mzv" >/dev/null \
  || fail "the session was not saved to /var/lib/marzipan on SIGTERM (no session.json and snapshot)"
[ ! -e "$saved/lease" ] || fail "the session's lease was not released on SIGTERM"
[ -z "$(find "$saved" ! -user "${uid%%:*}")" ] || fail "files of the saved session do not belong to marzipan"
echo "the session was saved to /var/lib/marzipan/sessions/$session by marzipan, its lease released"

echo "PASSED in ${SECONDS}s (podman build ${build_seconds}s); image $((size_bytes / 1000000)) MB"
