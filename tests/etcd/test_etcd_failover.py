#!/usr/bin/python3
"""Sessions owned through etcd, as processes on loopback: three etcd members (cluster.py), three
`marzipan serve --etcd ... --data-dir SHARED` behind HAProxy with docker/haproxy.cfg (only its
`server-template` line replaced by the loopback servers), and scripted clients whose every edit
is tagged (an add_blob at a position of its own), so that the recovered session can be checked
against a reference replay of exactly the acknowledged edits on a server with no storage.

Checks, in order:
  kill      SIGKILL the owner: through the proxy, another server acknowledges an edit within
            10 s (reported: takeover time); revision and digest equal the reference replay.
  restart   the killed server, started again under its name, does not load the session another
            server owns: -32015 with data.owner naming that server, also when HAProxy, with
            the server back in its rotation, sends the session's clients there.
  pause     SIGSTOP an owner past its lease; another server takes the session and acknowledges
            edits; SIGCONT the old one and send it edits on its old connection: none is
            acknowledged; the journal's tokens never decrease along its sequence keys.
  leader    SIGKILL the etcd leader during edits: the edits resume after the election
            (reported: the longest edit), nothing acknowledged is lost.
Also reported: the median and 95th percentile of an acknowledged edit's round trip through
the proxy, and marzipan_etcd_append_seconds from a server's /metrics.

Usage: test_etcd_failover.py --marzipan BIN --haproxy BIN --config docker/haproxy.cfg --workdir DIR
       [--lease-seconds N] [--only kill|pause|leader ...]
Run by ctest ("etcd: ..."). Needs Debian's /usr/bin/python3 with python3-websockets.
Conventions: every wait is bounded; every process started here is killed at the end; a failed
check raises AssertionError saying what was expected and what came. On any failure (a failed
check, a closed connection, a timeout, --time-limit reached) it prints to stdout the test's own
timed steps and the last lines of every server's, etcd member's and HAProxy's log, the servers'
lines stamped with the wall-clock time they were read at (UTC, as etcd stamps its own): a
failure seen once under CI load (a session closed with 1011, cause unknown, 2026-11-28) had
left nothing to read.
"""

import argparse
import asyncio
import base64
import json
import os
import re
import secrets
import shutil
import select
import signal
import statistics
import subprocess
import sys
import threading
import time
import traceback
import urllib.request


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from cluster import EtcdCluster, free_port  # noqa: E402
from rpc import Rpc  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "protocol", "python"))
from marzipan import Client  # noqa: E402  (this checkout's package)

SERVERS = ("s1", "s2", "s3")
LEASE_SECONDS = 3
TAKEOVER_LIMIT = 10.0  # seconds, the "within ~10 s"
HELD_ELSEWHERE = -32015
LOG_TAIL_LINES = 200
CREATE = {"size": [48, 48, 48], "solid": "sphere", "view": "none"}


def clean_env():
    return {k: v for k, v in os.environ.items() if not k.startswith("MARZIPAN_")}


def stamp():
    now = time.time()
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(now)) + ".%03d" % (int(now * 1000) % 1000)


def tail(path, label, lines):
    try:
        with open(path, errors="replace") as f:
            return "".join(f"  [{label}] {line}" for line in f.readlines()[-lines:])
    except OSError:
        return f"  [{label}] (no log at {path})\n"


def session_id():
    return secrets.token_urlsafe(16)[:22]


def edit(tag):
    """The tagged edit number `tag`: a small blob at a position of its own on the sphere."""
    return {"tool": "add_blob", "center": [8 + (tag * 7) % 32, 8 + (tag * 11) % 32, 24 + (tag % 3)], "radius": 2.5}


class Topology:
    def __init__(self, args):
        self.args = args
        self.work = args.workdir
        self.data = os.path.join(self.work, "data")
        self.cluster = EtcdCluster(os.path.join(self.work, "etcd"), size=3)
        os.makedirs(self.data, exist_ok=True)
        self.procs = {}
        self.ports = {name: free_port() for name in SERVERS}
        self.events_path = os.path.join(self.work, "test-events.log")
        self.readers = []

    def note(self, what):
        """One timed step of the test, printed with the logs if it fails."""
        with open(self.events_path, "a") as f:
            f.write(f"{stamp()} {what}\n")

    def start_server(self, name, etcd=True):
        # The port was picked free before the etcd members started; their connections (or another
        # test's) may have taken it since (once in 50 runs under load, 2026-11-29). A first start
        # then tries another; a restart keeps its port, which is the server's name.
        first = name not in self.procs
        for attempt in range(3 if first else 1):
            if attempt > 0:
                self.ports[name] = free_port()
            proc, line = self._spawn_server(name, etcd)
            if line or proc.poll() is None or "Address already in use" not in self.log(name, 1):
                break
        match = re.fullmatch(r"listening on http://127\.0\.0\.1:(\d+)\n", line)
        assert match, f"{name}: expected 'listening on http://127.0.0.1:PORT', got {line!r}\n{self.log(name)}"
        self.ports[name] = int(match.group(1))

    def _spawn_server(self, name, etcd):
        """Starts `name` on self.ports[name]; returns the process and its first line of stdout."""
        args = [self.args.marzipan, "serve", "--port", str(self.ports[name]), "--threads", "2",
                "--max-requests-per-second", "1000000", "--server-id", self.server_id(name)]
        if etcd:
            args += ["--data-dir", self.data, "--etcd", self.cluster.endpoints,
                     "--etcd-lease-seconds", str(LEASE_SECONDS)]
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=clean_env())
        reader = threading.Thread(target=self._stamp_lines, args=(proc.stderr, self.log_path(name)), daemon=True)
        reader.start()
        self.readers.append(reader)
        self.procs[name] = proc
        self.note(f"started {name} (pid {proc.pid}, port {self.ports[name]})")
        ready, _, _ = select.select([proc.stdout], [], [], 15)
        line = proc.stdout.readline() if ready else ""
        if not line:
            try:
                proc.wait(timeout=2)
                reader.join(timeout=2)  # its last words, in its log
            except subprocess.TimeoutExpired:
                pass
        return proc, line

    def server_id(self, name):
        """What the owner keys and -32015's data.owner say: the address clients can reach."""
        return f"127.0.0.1:{self.ports[name]}"

    @staticmethod
    def _stamp_lines(stream, path):
        # marzipan's log lines carry no time; stamped here they line up with etcd's.
        with open(path, "a") as log:
            for line in stream:
                log.write(f"{stamp()} {line}")
                log.flush()

    def log_path(self, name):
        return os.path.join(self.work, f"{name}.stderr")

    def log(self, name, lines=30):
        return tail(self.log_path(name), name, lines)

    def dump_logs(self, out=sys.stdout):
        """The test's steps and the tail of every log it has, for a failure to explain itself."""
        print(f"---- test steps (UTC), {self.events_path}", file=out)
        print(tail(self.events_path, "test", LOG_TAIL_LINES), file=out)
        for name in [*SERVERS, "reference"]:
            print(f"---- marzipan {name}: last {LOG_TAIL_LINES} lines of {self.log_path(name)}", file=out)
            print(self.log(name, LOG_TAIL_LINES), file=out)
        for m in self.cluster.members:
            print(f"---- etcd {m.name} (client {m.url}): last {LOG_TAIL_LINES} lines of {m.log_path}", file=out)
            print(self.cluster.log_tail(m, LOG_TAIL_LINES), file=out)
        print("---- haproxy: last 50 lines", file=out)
        print(tail(os.path.join(self.work, "haproxy.log"), "haproxy", 50), file=out)
        out.flush()

    def start_proxy(self):
        with open(self.args.config) as f:
            lines = f.read().splitlines(keepends=True)
        template = [i for i, l in enumerate(lines) if l.strip().startswith("server-template ")]
        assert len(template) == 1, f"expected one server-template line in {self.args.config}"
        indent = lines[template[0]][: len(lines[template[0]]) - len(lines[template[0]].lstrip())]
        lines[template[0]: template[0] + 1] = [f"{indent}server {n} 127.0.0.1:{self.ports[n]}\n" for n in SERVERS]
        config = os.path.join(self.work, "haproxy.cfg")
        with open(config, "w") as f:
            f.write("".join(lines))
        self.proxy_port = free_port()
        env = clean_env()
        env.update(MARZIPAN_LB_ADDR="127.0.0.1", MARZIPAN_LB_PORT=str(self.proxy_port), MARZIPAN_LB_TLS_PORT=str(free_port()))
        with open(os.path.join(self.work, "haproxy.log"), "w") as log:
            self.procs["haproxy"] = subprocess.Popen([self.args.haproxy, "-db", "-f", config], env=env,
                                                     stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{self.proxy_port}/healthz", timeout=1) as r:
                    if r.read() == b"ok":
                        return
            except OSError:
                time.sleep(0.05)
        raise AssertionError("HAProxy did not answer within 10 s")

    def via_proxy(self, sid):
        return f"ws://127.0.0.1:{self.proxy_port}/ws?session={sid}"

    def direct(self, name, sid):
        return f"ws://127.0.0.1:{self.ports[name]}/ws?session={sid}"

    def signal(self, name, sig):
        self.note(f"{signal.Signals(sig).name} to {name}")
        self.procs[name].send_signal(sig)
        if sig == signal.SIGKILL:
            self.procs[name].wait(timeout=10)

    def stop(self):
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGCONT)
                proc.kill()
            proc.wait(timeout=10)
        self.cluster.stop()
        for reader in self.readers:
            reader.join(timeout=2)


class Session:
    """The acknowledged edits of one session, in order, and its secrets."""

    def __init__(self, sid):
        self.sid = sid
        self.token = None
        self.acked = []  # tags
        self.revision = 0  # after the last acknowledged edit
        self.next_tag = 0
        self.round_trips = []

    def join(self):
        return {"session": self.sid, "token": self.token, "view": "none"}

    async def apply(self, rpc):
        """Sends the next tagged edit; records it when acknowledged. Returns the reply."""
        tag = self.next_tag
        self.next_tag += 1
        t0 = time.monotonic()
        reply = await rpc.call("tool.apply", edit(tag))
        if reply[0] == "ok":
            self.round_trips.append(time.monotonic() - t0)
            self.acked.append(tag)
            # An edit that changes nothing (a blob inside the solid) leaves the revision.
            expected = self.revision + (0 if reply[1].get("roi") is None else 1)
            assert reply[1]["revision"] == expected, \
                f"edit {tag}: revision {reply[1]['revision']}, expected {expected} (each acknowledged edit once)"
            self.revision = expected
        return reply


async def reference_stats(t, tags):
    """session.stats after replaying exactly `tags` on a server without storage."""
    async with Rpc(f"ws://127.0.0.1:{t.ports['reference']}/ws") as rpc:
        ok = await rpc.call("session.create", CREATE)
        assert ok[0] == "ok", ok
        for tag in tags:
            r = await rpc.call("tool.apply", edit(tag))
            assert r[0] == "ok", r
        return (await rpc.call("session.stats", {}))[1]


async def check_against_reference(t, s, rpc, what):
    stats = await rpc.call("session.stats", {})
    assert stats[0] == "ok", stats
    expected = await reference_stats(t, s.acked)
    assert stats[1]["revision"] == s.revision == expected["revision"], \
        f"{what}: revision {stats[1]['revision']}, acknowledged {s.revision}, the reference replay {expected['revision']}"
    assert stats[1]["digest"] == expected["digest"], \
        f"{what}: digest {stats[1]['digest']}, the reference replay gives {expected['digest']}"


async def join_until_acked(t, s, url, limit):
    """Joins (again and again) at url and sends the next edit until one is acknowledged;
    returns (seconds it took, the connection)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit:
        rpc = None
        try:
            rpc = await Rpc(url).__aenter__()
            joined = await rpc.call("session.join", s.join(), timeout=5)
            if joined[0] == "ok":
                reply = await s.apply(rpc)
                if reply[0] == "ok":
                    return time.monotonic() - t0, rpc
        except (ConnectionError, OSError, asyncio.TimeoutError):
            pass
        if rpc is not None:
            await rpc.__aexit__()
        await asyncio.sleep(0.1)
    raise AssertionError(f"no edit of session {s.sid} acknowledged at {url} within {limit} s")


async def check_kill_and_restart(t, report):
    s = Session(session_id())
    async with Rpc(t.via_proxy(s.sid)) as rpc:
        created = await rpc.call("session.create", dict(CREATE, session=s.sid))
        assert created[0] == "ok", created
        s.token = created[1]["token"]
        owner = rpc.server
        t.note(f"kill: session {s.sid} created on {owner}")
        assert owner in SERVERS, f"X-Marzipan-Server {owner!r}"
        for _ in range(20):
            assert (await s.apply(rpc))[0] == "ok"
    t.signal(owner, signal.SIGKILL)
    took, rpc = await join_until_acked(t, s, t.via_proxy(s.sid), TAKEOVER_LIMIT)
    report["takeover_seconds_after_sigkill"] = round(took, 2)
    new_owner = rpc.server
    t.note(f"kill: {new_owner} acknowledged an edit after {took:.2f} s")
    assert new_owner != owner, f"the killed {owner} answered"
    for _ in range(10):
        assert (await s.apply(rpc))[0] == "ok"
    await check_against_reference(t, s, rpc, "after SIGKILL of the owner")
    report["edit_round_trip_ms"] = {
        "median": round(1000 * statistics.median(s.round_trips), 2),
        "p95": round(1000 * sorted(s.round_trips)[int(0.95 * len(s.round_trips))], 2), "edits": len(s.round_trips)}

    # The killed server comes back under its name: it must not load what new_owner owns.
    t.start_server(owner)
    async with Rpc(t.direct(owner, s.sid)) as other:
        refused = await other.call("session.join", s.join())
        assert refused[0] == "error" and refused[1] == HELD_ELSEWHERE, f"restarted {owner}: {refused}"
        expected = t.server_id(new_owner)
        assert refused[2] and refused[2].get("owner") == expected, f"data.owner {refused[2]}, expected {expected}"
    # The Python client follows data.owner when asked to, and joins there.
    async with Client.connect(f"ws://127.0.0.1:{t.ports[owner]}/ws", session=s.sid) as py:
        joined = await py.join(s.sid, s.token, follow_owner=True)
        assert joined["revision"] == s.revision, f"joined at the owner at revision {joined['revision']}"
        assert py.url.startswith(f"ws://{expected}/"), py.url
        await py.leave()
    # Back in HAProxy's rotation, the restarted server is where the ring sends this session
    # again, and refuses it while new_owner holds it (README, "Another server's session": the
    # moved sessions stay with their new owner until it unloads them). What `leader` must wait
    # out before it relies on the proxy reaching an owner.
    report["restarted_server_in_rotation_seconds"] = round(await wait_in_rotation(t, owner, TAKEOVER_LIMIT), 2)
    async with Rpc(t.via_proxy(s.sid)) as again:
        refused = await again.call("session.join", s.join())
        assert again.server == owner and refused[0] == "error" and refused[1] == HELD_ELSEWHERE, \
            f"through the proxy with {owner} back: {again.server} answered {refused}"
        assert refused[2] and refused[2].get("owner") == expected, f"data.owner {refused[2]}, expected {expected}"
    assert (await s.apply(rpc))[0] == "ok"
    await rpc.__aexit__()
    return s


async def wait_in_rotation(t, name, limit):
    """Waits until HAProxy sends requests to `name` again (requests without ?session= go round
    robin over the servers it deems up); returns the seconds it took."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit:
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{t.proxy_port}/healthz", timeout=1) as r:
                if r.headers.get("X-Marzipan-Server") == name:
                    return time.monotonic() - t0
        except OSError:
            pass
        await asyncio.sleep(0.1)
    raise AssertionError(f"HAProxy sent no request to {name} within {limit} s")


def journal_tokens(t, sid):
    """(seq, token) of every journal key of sid in etcd, in key order."""
    prefix = f"marzipan/sessions/{sid}/journal/".encode()
    end = prefix[:-1] + bytes([prefix[-1] + 1])
    m = next(m for m in t.cluster.members if m.alive())
    kvs = m.post("/v3/kv/range", {"key": base64.b64encode(prefix).decode(),
                                  "range_end": base64.b64encode(end).decode()}).get("kvs", [])
    return [(int(base64.b64decode(kv["key"])[len(prefix):], 16), json.loads(base64.b64decode(kv["value"]))["token"])
            for kv in kvs]


async def check_pause(t, report):
    s = Session(session_id())
    old, new = "s2", "s3"
    stale = await Rpc(t.direct(old, s.sid)).__aenter__()
    created = await stale.call("session.create", dict(CREATE, session=s.sid))
    assert created[0] == "ok", created
    s.token = created[1]["token"]
    t.note(f"pause: session {s.sid} created on {old}")
    for _ in range(10):
        assert (await s.apply(stale))[0] == "ok"
    t.signal(old, signal.SIGSTOP)
    t0 = time.monotonic()
    took, rpc = await join_until_acked(t, s, t.direct(new, s.sid), LEASE_SECONDS + TAKEOVER_LIMIT)
    report["takeover_seconds_after_sigstop"] = round(took, 2)
    t.note(f"pause: {new} acknowledged an edit after {took:.2f} s")
    for _ in range(5):
        assert (await s.apply(rpc))[0] == "ok"
    # Well past the lease, then the old owner wakes up and is sent edits on its old connection.
    await asyncio.sleep(max(0.0, LEASE_SECONDS + 0.5 - (time.monotonic() - t0)))
    t.signal(old, signal.SIGCONT)
    acknowledged_by_stale = 0
    for k in range(5):
        try:
            reply = await stale.call("tool.apply", edit(1000 + k), timeout=10)
        except (ConnectionError, asyncio.TimeoutError):
            break
        if reply[0] == "ok":
            acknowledged_by_stale += 1
    await stale.__aexit__()
    assert acknowledged_by_stale == 0, f"the resumed {old} acknowledged {acknowledged_by_stale} edits"
    for _ in range(5):
        assert (await s.apply(rpc))[0] == "ok"
    await check_against_reference(t, s, rpc, "after SIGSTOP/SIGCONT of the owner")
    await rpc.__aexit__()
    tokens = journal_tokens(t, s.sid)
    assert tokens, "no journal keys in etcd"
    seqs = [seq for seq, _ in tokens]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), f"journal keys not contiguous: {seqs}"
    assert all(a[1] <= b[1] for a, b in zip(tokens, tokens[1:])), f"a token decreases along the journal: {tokens}"
    assert len({tok for _, tok in tokens}) == 2, f"expected the records of two owners: {tokens}"


async def check_etcd_leader_kill(t, report):
    # The session is created and then joined again through the proxy, which reaches its owner
    # only while HAProxy's ring stays as it is. A server stopped by `pause` (or restarted by
    # `kill`) may still be out of the rotation: a session created meanwhile lands elsewhere, and
    # once that server is back the ring sends every rejoin to it, refused with -32015 while the
    # owner holds the session (see `restart`). That failed this check once in about a dozen
    # runs (2026-11-24/25: 242 rejoins in 30 s, each refused by the returned server).
    t0 = time.monotonic()
    for name in SERVERS:
        await wait_in_rotation(t, name, TAKEOVER_LIMIT)
    report["all_servers_in_rotation_before_leader_seconds"] = round(time.monotonic() - t0, 2)
    s = Session(session_id())
    async with Rpc(t.via_proxy(s.sid)) as rpc:
        created = await rpc.call("session.create", dict(CREATE, session=s.sid))
        assert created[0] == "ok", created
        s.token = created[1]["token"]
        t.note(f"leader: session {s.sid} created on {rpc.server}")
        for _ in range(10):
            assert (await s.apply(rpc))[0] == "ok"
        leader = t.cluster.leader()
        assert leader is not None, "no etcd leader"
        t.note(f"leader: SIGKILL to etcd {leader.name}, the leader")
        t.cluster.kill(leader)
        t0 = time.monotonic()
        refused = 0
        while True:
            reply_ok = False
            try:
                reply = await s.apply(rpc)
            except ConnectionError:
                break
            if reply[0] == "ok":
                reply_ok = True
                break
            refused += 1
            assert time.monotonic() - t0 < TAKEOVER_LIMIT, f"edits still refused {TAKEOVER_LIMIT} s after the leader died"
        report["first_edit_after_etcd_leader_kill_seconds"] = round(time.monotonic() - t0, 2)
        report["edits_refused_during_election"] = refused
        t.note(f"leader: {refused} edits refused, then {'one acknowledged' if reply_ok else 'the connection closed'}")
    # Whether the session stayed or had to be joined again, every acknowledged edit is there.
    # Not a takeover (the owner kept its session): the time is reported. The owner may have
    # refused an edit and closed the session while the election held its keep-alive up past
    # the TTL (etcd kept the lease); every rejoin then got that refused journal back, each edit
    # refused, while the lease lived (seen 2026-11-25 under load; EtcdStorage::acquire now
    # claims such a session afresh, tests/service/test_etcd_storage.cpp).
    took, rpc = await join_until_acked(t, s, t.via_proxy(s.sid), TAKEOVER_LIMIT)
    report["rejoin_after_etcd_leader_kill_seconds"] = round(took, 2)
    t.note(f"leader: rejoined on {rpc.server} after {took:.2f} s")
    for _ in range(5):
        assert (await s.apply(rpc))[0] == "ok"
    await check_against_reference(t, s, rpc, "after the etcd leader was killed")
    await rpc.__aexit__()


def etcd_append_metric(t, name):
    with urllib.request.urlopen(f"http://127.0.0.1:{t.ports[name]}/metrics", timeout=5) as r:
        text = r.read().decode()
    total = re.search(r"^marzipan_etcd_append_seconds_sum (\S+)$", text, re.M)
    count = re.search(r"^marzipan_etcd_append_seconds_count (\S+)$", text, re.M)
    assert total and count, "no marzipan_etcd_append_seconds in /metrics"
    n = float(count.group(1))
    return {"server": name, "transactions": int(n), "mean_ms": round(1000 * float(total.group(1)) / n, 2) if n else None}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--marzipan", required=True)
    parser.add_argument("--haproxy", required=True)
    parser.add_argument("--config", required=True)
    parser.add_argument("--workdir", required=True)
    parser.add_argument("--lease-seconds", type=int, default=3,
                        help="the servers' --etcd-lease-seconds (3 here to keep the test short; 5 is the default)")
    parser.add_argument("--only", choices=["kill", "pause", "leader"], action="append",
                        help="run only these checks (default: all)")
    parser.add_argument("--time-limit", type=float, default=110,
                        help="seconds before the test gives up and prints its logs (below ctest's TIMEOUT 120, "
                             "which would kill it silently)")
    args = parser.parse_args()
    global LEASE_SECONDS
    LEASE_SECONDS = args.lease_seconds
    shutil.rmtree(args.workdir, ignore_errors=True)
    os.makedirs(args.workdir)
    t = Topology(args)
    report = {}

    def out_of_time(signum, frame):
        raise TimeoutError(f"the test ran past its --time-limit of {args.time_limit:.0f} s")

    signal.signal(signal.SIGALRM, out_of_time)
    signal.setitimer(signal.ITIMER_REAL, args.time_limit)
    failed = True
    try:
        t.cluster.start()
        for name in SERVERS:
            t.start_server(name)
        t.ports["reference"] = free_port()
        t.start_server("reference", etcd=False)
        t.start_proxy()
        only = set(args.only or ["kill", "pause", "leader"])
        if "kill" in only:
            asyncio.run(check_kill_and_restart(t, report))
        if "pause" in only:
            asyncio.run(check_pause(t, report))
        if "leader" in only:
            asyncio.run(check_etcd_leader_kill(t, report))
        report["etcd_append"] = [etcd_append_metric(t, n) for n in SERVERS if t.procs[n].poll() is None]
        print(json.dumps(report))
        failed = False
        return 0
    except BaseException as e:
        t.note(f"failed: {type(e).__name__}: {(str(e).splitlines() or [''])[0]}")
        print("FAILED; what was measured until then: " + json.dumps(report), flush=True)
        traceback.print_exc(file=sys.stdout)
        return 1
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        try:
            t.stop()
        finally:
            if failed:
                t.dump_logs()


if __name__ == "__main__":
    sys.exit(main())
