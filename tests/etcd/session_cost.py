#!/usr/bin/python3
"""What one session holds in etcd, measured against a real etcd member and `marzipan serve
--etcd` (issue 31 item 1), and the hostile case of that issue: open strokes with full memories
while another client makes cheap edits past a snapshot.

Cases (one server and one etcd member each, on loopback ports picked free):
  typical   one editor makes EDITS journaled changes (alternating add_blob / remove_blob at one
            spot of a 64^3 sphere); after each REPORT_EVERY it prints the session's etcd keys
            and bytes (keys and values as stored: the gateway's base64 decoded) and its
            snapshot files. The peak is just before a snapshot, with two snapshots' journals.
  hostile   three clients each open a stroke (add_blob, height 1, symmetry xyz) and send 512
            dabs on the sphere's surface in two messages: 4096 remembered dab images each,
            with normals (~580 KB as JSON). The strokes stay open while a third client makes
            EDITS cheap edits. Holds when: the session keeps at most 3 snapshot files, the
            snapshot pointer moved past the first snapshot, and its pointer is under 4 KiB.

Prints one JSON line per measurement and a summary; exits 1 when the hostile case fails. Not
run by ctest (about 90 s, most of it the strokes' dabs); test_etcd_storage.cpp checks the same
against an in-memory etcd. README (Deployment, etcd) quotes its figures. Before 2026-11-29 the
hostile case left 111 snapshot files (62 MB) after 2100 edits and never moved the pointer.

Usage: session_cost.py --marzipan BIN --workdir DIR [--only typical|hostile] [--edits N]
Conventions: every wait is bounded; every process started here is killed at the end.
"""

import argparse
import asyncio
import base64
import json
import math
import os
import re
import select
import shutil
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from cluster import EtcdCluster, free_port  # noqa: E402
from rpc import Rpc  # noqa: E402

SIDE = 64
CREATE = {"size": [SIDE, SIDE, SIDE], "solid": "sphere", "view": "none"}
PREFIX = "marzipan/"


def b64(text):
    return base64.b64encode(text.encode()).decode()


def prefix_end(prefix):
    return prefix[:-1] + chr(ord(prefix[-1]) + 1)


class Setup:
    def __init__(self, marzipan, workdir):
        self.work = workdir
        shutil.rmtree(workdir, ignore_errors=True)
        os.makedirs(workdir)
        self.data = os.path.join(workdir, "data")
        self.cluster = EtcdCluster(os.path.join(workdir, "etcd"), size=1)
        self.marzipan = marzipan
        self.proc = None
        self.log_path = os.path.join(workdir, "server.stderr")

    def start(self):
        self.cluster.start()
        for _ in range(3):
            port = free_port()
            with open(self.log_path, "a") as log:
                self.proc = subprocess.Popen(
                    [self.marzipan, "serve", "--port", str(port), "--threads", "2", "--data-dir", self.data,
                     "--etcd", self.cluster.endpoints, "--max-requests-per-second", "1000000",
                     "--server-id", f"127.0.0.1:{port}"],
                    stdout=subprocess.PIPE, stderr=log, text=True,
                    env={k: v for k, v in os.environ.items() if not k.startswith("MARZIPAN_")})
            ready, _, _ = select.select([self.proc.stdout], [], [], 15)
            line = self.proc.stdout.readline() if ready else ""
            match = re.fullmatch(r"listening on http://127\.0\.0\.1:(\d+)\n", line)
            if match:
                self.port = int(match.group(1))
                return self
            self.proc.kill()
            self.proc.wait(timeout=10)
        raise AssertionError("the server did not start:\n" + self.log_tail())

    def url(self, sid=None):
        return f"ws://127.0.0.1:{self.port}/ws" + (f"?session={sid}" if sid else "")

    def etcd(self, path, body):
        m = self.cluster.members[0]
        return m.post(path, body, timeout=5)

    def held(self, sid):
        """(keys, bytes of keys and values, {kind: keys}, pointer bytes) of the session in etcd."""
        prefix = f"{PREFIX}sessions/{sid}/"
        r = self.etcd("/v3/kv/range", {"key": b64(prefix), "range_end": b64(prefix_end(prefix))})
        keys, size, kinds, pointer = 0, 0, {}, 0
        for kv in r.get("kvs", []):
            key = base64.b64decode(kv["key"])
            value = base64.b64decode(kv.get("value", ""))
            keys += 1
            size += len(key) + len(value)
            kind = key.decode()[len(prefix):].split("/")[0]
            if kind == "journal" and value.startswith(b'{"head"'):
                kind = "head"
            kinds[kind] = kinds.get(kind, 0) + 1
            if kind == "snapshot":
                pointer = len(value)
        return keys, size, kinds, pointer

    def db_size(self):
        return int(self.etcd("/v3/maintenance/status", {}).get("dbSize", 0))

    def files(self, sid):
        d = os.path.join(self.data, "sessions", sid)
        names = os.listdir(d) if os.path.isdir(d) else []
        snaps = [n for n in names if n.startswith("snapshot-")]
        return len(snaps), sum(os.path.getsize(os.path.join(d, n)) for n in names)

    def log_tail(self, lines=40):
        try:
            with open(self.log_path, errors="replace") as f:
                return "".join(f.readlines()[-lines:])
        except OSError:
            return "(no log)"

    def stop(self):
        if self.proc and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(timeout=10)
        self.cluster.stop()


def edit(k):
    """Journaled cheap edits: a blob added at one spot of the surface, then removed, in turn."""
    return {"tool": "add_blob" if k % 2 == 0 else "remove_blob", "center": [SIDE / 2, SIDE / 2, SIDE / 2 + 0.35 * SIDE],
            "radius": 2.5}


def report(**fields):
    print(json.dumps(fields), flush=True)


async def typical(s, edits, every):
    async with Rpc(s.url()) as rpc:
        created = await rpc.result("session.create", CREATE)
        sid = created["session"]
        base = s.db_size()
        revision = 0
        for k in range(edits):
            revision = (await rpc.result("tool.apply", edit(k)))["revision"]
            if (k + 1) % every == 0 or k + 1 == edits:
                keys, size, kinds, pointer = s.held(sid)
                snaps, file_bytes = s.files(sid)
                report(case="typical", edits=k + 1, revision=revision, etcd_keys=keys, etcd_bytes=size, kinds=kinds,
                       pointer_bytes=pointer, snapshot_files=snaps, data_bytes=file_bytes,
                       etcd_db_growth=s.db_size() - base)
    return True


def surface_dabs(count, first):
    """Dab centres `first` .. `first + count` of 512 on the sphere's surface in one octant (a
    16 x 32 grid of directions; symmetry mirrors them into the others)."""
    c, r = (SIDE - 1) / 2, 0.35 * SIDE
    dabs = []
    for k in range(first, first + count):
        theta = (k // 32 + 0.5) / 16 * math.pi / 2 * 0.9 + 0.05
        phi = (k % 32 + 0.5) / 32 * math.pi / 2 * 0.9 + 0.05
        d = (math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta))
        dabs.append({"center": [c + r * d[0], c + r * d[1], c + r * d[2]], "pressure": 1})
    return dabs


async def hostile(s, edits, every):
    ok = True
    async with Rpc(s.url()) as owner:
        created = await owner.result("session.create", CREATE)
        sid = created["session"]
        join = {"session": sid, "token": created["token"], "view": "none"}
        base = s.db_size()
        strokes = []
        for who in range(3):
            rpc = await Rpc(s.url(sid)).__aenter__()
            await rpc.result("session.join", join)
            stroke = (await rpc.result("stroke.begin", {"tool": "add_blob", "radius": 2, "strength": 1, "height": 1,
                                                       "symmetry": ["x", "y", "z"]}))["stroke"]
            for m in range(2):
                dabs = surface_dabs(256, 256 * m)
                applied = (await rpc.result("stroke.dabs", {"stroke": stroke, "dabs": dabs}, timeout=60))["applied"]
                report(case="hostile", stroke=who + 1, message=m + 1, dabs=len(dabs), applied=applied)
            strokes.append(rpc)
        t0 = time.monotonic()
        for k in range(edits):
            await owner.result("tool.apply", edit(k))
            if (k + 1) % every == 0 or k + 1 == edits:
                keys, size, kinds, pointer = s.held(sid)
                snaps, file_bytes = s.files(sid)
                report(case="hostile", edits=k + 1, seconds=round(time.monotonic() - t0, 1), etcd_keys=keys,
                       etcd_bytes=size, kinds=kinds, pointer_bytes=pointer, snapshot_files=snaps,
                       data_bytes=file_bytes, etcd_db_growth=s.db_size() - base)
        pointer_value = s.etcd("/v3/kv/range", {"key": b64(f"{PREFIX}sessions/{sid}/snapshot")}).get("kvs", [])
        current = json.loads(base64.b64decode(pointer_value[0]["value"]))["current"] if pointer_value else {}
        failures = s.log_tail(2000).count("snapshot failed")
        report(case="hostile", pointer_revision=current.get("revision"), snapshot_failures_logged=failures)
        if snaps > 3:
            print(f"FAIL hostile: {snaps} snapshot files left in the session's directory (at most 3 expected)")
            ok = False
        if not current or current.get("revision", 0) == 0:
            print("FAIL hostile: the snapshot pointer never moved past the session's first snapshot")
            ok = False
        if pointer > 4096:
            print(f"FAIL hostile: the snapshot pointer holds {pointer} bytes (at most 4096 expected)")
            ok = False
        for rpc in strokes:
            await rpc.__aexit__()
    return ok


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--marzipan", required=True)
    ap.add_argument("--workdir", required=True)
    ap.add_argument("--only", choices=["typical", "hostile"], action="append")
    ap.add_argument("--edits", type=int, default=2100)
    ap.add_argument("--every", type=int, default=500)
    args = ap.parse_args()
    cases = args.only or ["typical", "hostile"]
    ok = True
    for case in cases:
        s = Setup(args.marzipan, os.path.join(args.workdir, case)).start()
        try:
            passed = asyncio.run({"typical": typical, "hostile": hostile}[case](s, args.edits, args.every))
            print(f"{'PASS' if passed else 'FAIL'} {case}", flush=True)
            ok = ok and passed
        except Exception:
            print(s.log_tail(), file=sys.stderr)
            raise
        finally:
            s.stop()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
