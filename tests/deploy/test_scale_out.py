#!/usr/bin/python3
"""The scale-out topology of docker/compose.yaml, run natively on loopback: three `marzipan
serve` processes sharing one data directory behind HAProxy (Debian's package) with
docker/haproxy.cfg, of which only the `server-template` line is replaced by the loopback servers.
Three, not two: only with a third server does stopping one show that the hashing is consistent
(the sessions of the servers that stay up do not move).

Checks: every request that names a session (HTTP or the WebSocket /ws?session=ID) reaches the
same server, whatever the connection; sessions spread over every server; the clients of one
session meet on one server, and another server refuses it while it is loaded there (-32015,
its lease in the shared data directory); after that server stops (SIGTERM), its sessions, idle
or not, load from the shared data directory on another, while the other servers' sessions stay
where they were; a server that comes back gets back exactly the sessions it had; a session
whose server was killed (SIGKILL) loads elsewhere with its last acknowledged edit once its lease
runs out; TLS at the proxy.

Usage: test_scale_out.py --marzipan BIN --haproxy BIN --config docker/haproxy.cfg --workdir DIR
Run by ctest ("deploy: ..."). Needs Debian's /usr/bin/python3 with python3-websockets.

Conventions: every wait is bounded; every process the test starts is killed when it ends;
a failed check raises AssertionError with what was expected and what came.
"""

import argparse
import asyncio
import http.client
import json
import os
import re
import secrets
import select
import shutil
import signal
import socket
import ssl
import subprocess
import sys
import time

import websockets

SERVERS = ("s1", "s2", "s3")
SESSIONS = 60  # random ids routed; every server gets some unless the hash is badly broken
LEASE_SECONDS = 30  # a killed server's lease on its sessions runs out after this (hub.cpp)
HELD_ELSEWHERE = -32015


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# Waits for something the servers or HAProxy do on their own timers (health checks every 2 s,
# --idle-session-seconds 1): 30 s, so that a loaded machine running them late does not fail a
# wait that normally ends within a few seconds.
def wait_until(what, predicate, timeout=30.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        result = predicate()
        if result:
            return result
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


def clean_env():
    """This environment without MARZIPAN_* settings, which would change what the test starts."""
    return {k: v for k, v in os.environ.items() if not k.startswith("MARZIPAN_")}


def session_id():
    """An id as clients propose them: 22 base64url characters."""
    return secrets.token_urlsafe(16)[:22]


class Topology:
    """The servers and HAProxy, started from the given config; stop() ends them all."""

    def __init__(self, args):
        self.args = args
        self.work = args.workdir
        shutil.rmtree(self.work, ignore_errors=True)
        self.data = os.path.join(self.work, "data")
        os.makedirs(self.data)
        self.procs = {}
        self.ports = {}

    def start_server(self, name, port=0):
        with open(os.path.join(self.work, f"{name}.stderr"), "a") as log:
            proc = subprocess.Popen(
                [self.args.marzipan, "serve", "--port", str(port), "--threads", "2", "--data-dir", self.data,
                 "--idle-session-seconds", "1"],
                stdout=subprocess.PIPE, stderr=log, text=True, env=clean_env())
        self.procs[name] = proc
        ready, _, _ = select.select([proc.stdout], [], [], 10)
        line = proc.stdout.readline() if ready else ""
        match = re.fullmatch(r"listening on http://127\.0\.0\.1:(\d+)\n", line)
        assert match, f"{name}: expected 'listening on http://127.0.0.1:PORT' within 10 s, got {line!r}"
        self.ports[name] = int(match.group(1))

    def write_config(self):
        """docker/haproxy.cfg with its server-template line replaced by SERVERS on loopback."""
        with open(self.args.config) as f:
            text = f.read()
        lines = text.splitlines(keepends=True)
        template = [i for i, l in enumerate(lines) if l.strip().startswith("server-template ")]
        assert len(template) == 1, f"expected one server-template line in {self.args.config}"
        indent = lines[template[0]][: len(lines[template[0]]) - len(lines[template[0]].lstrip())]
        lines[template[0]: template[0] + 1] = [
            f"{indent}server {name} 127.0.0.1:{self.ports[name]}\n" for name in SERVERS]
        path = os.path.join(self.work, "haproxy.cfg")
        with open(path, "w") as f:
            f.write("".join(lines))
        return path

    def start_proxy(self, name="haproxy", tls_cert=None):
        """HAProxy on loopback; with tls_cert, its TLS frontend too. Returns (port, TLS port)."""
        config = self.write_config()
        port, tls_port = free_port(), free_port()
        env = clean_env()
        env.update(MARZIPAN_LB_ADDR="127.0.0.1", MARZIPAN_LB_PORT=str(port), MARZIPAN_LB_TLS_PORT=str(tls_port))
        if tls_cert:
            env["MARZIPAN_TLS_CERT"] = tls_cert
        check = subprocess.run([self.args.haproxy, "-c", "-f", config], env=env, capture_output=True, text=True)
        assert check.returncode == 0, f"haproxy -c refused the config:\n{check.stdout}{check.stderr}"
        with open(os.path.join(self.work, f"{name}.log"), "w") as log:
            self.procs[name] = subprocess.Popen([self.args.haproxy, "-db", "-f", config], env=env,
                                                stdout=log, stderr=subprocess.STDOUT)
        if name == "haproxy":
            self.proxy_port = port
            wait_until("HAProxy to answer", lambda: self.try_get("/healthz"))
        return port, tls_port

    def proxy_log_has(self, text, name="haproxy"):
        with open(os.path.join(self.work, f"{name}.log")) as f:
            return text in f.read()

    def try_get(self, target):
        try:
            return self.get(target)
        except OSError:
            return None

    def get(self, target, connection=None):
        """GET through the proxy; (status, body, the server that answered)."""
        conn = connection or http.client.HTTPConnection("127.0.0.1", self.proxy_port, timeout=5)
        try:
            conn.request("GET", target)
            reply = conn.getresponse()
            body = reply.read()
            return reply.status, body, reply.getheader("X-Marzipan-Server")
        finally:
            if connection is None:
                conn.close()

    def metric(self, name, series):
        """One series of the server's own /metrics, asked directly (not through the proxy)."""
        conn = http.client.HTTPConnection("127.0.0.1", self.ports[name], timeout=5)
        try:
            conn.request("GET", "/metrics")
            text = conn.getresponse().read().decode()
        finally:
            conn.close()
        match = re.search(r"^" + re.escape(series) + r" (\d+)$", text, re.M)
        assert match, f"{name}: no {series} in /metrics"
        return int(match.group(1))

    def static_requests(self, name):
        return self.metric(name, 'marzipan_http_requests_total{path="static"}')

    def stop_server(self, name):
        proc = self.procs.pop(name)
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(timeout=15)
        assert status == 0, f"{name} exited {status} after SIGTERM"

    def kill_server(self, name):
        proc = self.procs.pop(name)
        proc.kill()
        proc.wait(timeout=15)

    def stop(self):
        for proc in self.procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            if proc.stdout:
                proc.stdout.close()
        self.procs.clear()


def check_http_routing(t):
    """Requests naming a session reach one server, over fresh and shared connections."""
    ids = [session_id() for _ in range(SESSIONS)]
    owner = {}
    for sid in ids:
        status, _, server = t.get(f"/index.html?session={sid}")
        assert status == 200, f"GET /index.html?session={sid}: status {status}"
        assert server in SERVERS, f"X-Marzipan-Server {server!r}"
        owner[sid] = server
    spread = {s: sum(1 for v in owner.values() if v == s) for s in SERVERS}
    assert all(spread.values()), f"{SESSIONS} sessions left a server out: {spread}"

    # Again, in another order, interleaved on one keep-alive connection: the proxy balances
    # each request, not each connection.
    conn = http.client.HTTPConnection("127.0.0.1", t.proxy_port, timeout=5)
    try:
        for sid in reversed(ids):
            for target in (f"/?session={sid}", f"/healthz?session={sid}&x=1", f"/index.html?v=2&session={sid}"):
                status, _, server = t.get(target, conn)
                assert status == 200 and server == owner[sid], \
                    f"{target}: server {server} status {status}, expected {owner[sid]}"
    finally:
        conn.close()

    # The servers' own counters agree with the header: ten requests of one session, ten more
    # static requests on its server and none on the others.
    sid = ids[0]
    before = {name: t.static_requests(name) for name in SERVERS}
    for _ in range(10):
        assert t.get(f"/index.html?session={sid}")[0] == 200
    served = {name: t.static_requests(name) - before[name] for name in SERVERS}
    assert served == {name: 10 if name == owner[sid] else 0 for name in SERVERS}, \
        f"ten requests of a session routed to {owner[sid]} were served as {served}"
    print(f"ok: {SESSIONS} sessions routed consistently over HTTP {spread}")
    return owner


def check_failover_routing(t, owner):
    """With one server stopped, only its sessions move; back, it gets them all back."""
    stopped = "s1"
    t.stop_server(stopped)
    moved = [sid for sid, s in owner.items() if s == stopped]
    # Judged once HAProxy's health checks took the server out of the ring, not while it only
    # retries its requests elsewhere.
    wait_until(f"HAProxy to mark {stopped} down", lambda: t.proxy_log_has(f"marzipan/{stopped} is DOWN"))
    now = {}
    for sid in owner:
        status, _, now[sid] = t.get(f"/index.html?session={sid}")
        assert status == 200 and now[sid] in SERVERS and now[sid] != stopped, \
            f"session {sid} of {owner[sid]}: status {status} from {now[sid]}"
    stayed = {sid: s for sid, s in owner.items() if s != stopped}
    assert all(now[sid] == s for sid, s in stayed.items()), \
        f"sessions of servers still up moved: {[sid for sid, s in stayed.items() if now[sid] != s]}"
    print(f"ok: after {stopped} stopped, its {len(moved)} sessions went to "
          f"{sorted(set(now[sid] for sid in moved))}; none of the other {len(stayed)} moved")

    # Back on its old port, it gets back exactly the sessions it had: the ring depends on the
    # servers' names, not on what happened meanwhile.
    t.start_server(stopped, port=t.ports[stopped])

    def as_before():
        return all(t.get(f"/index.html?session={sid}")[2] == s for sid, s in owner.items())

    wait_until(f"{stopped} to serve its sessions again", as_before, timeout=40)
    print(f"ok: {stopped} restarted serves its {len(moved)} sessions again, the others kept theirs")


class Client:
    """One WebSocket client through the proxy (or `direct` to one server), JSON-RPC with view
    "none" (no binary frames)."""

    def __init__(self, t, sid, direct=None):
        port = t.ports[direct] if direct else t.proxy_port
        self.url = f"ws://127.0.0.1:{port}/ws?session={sid}"
        self.next_id = 1
        self.notifications = []

    async def __aenter__(self):
        self.ws = await asyncio.wait_for(websockets.connect(self.url, max_size=None), 10)
        self.server = self.ws.response_headers.get("X-Marzipan-Server")
        return self

    async def __aexit__(self, *exc):
        await self.ws.close()

    async def call(self, method, params):
        """The result, or ("error", code) for an error response."""
        rid = self.next_id
        self.next_id += 1
        await self.ws.send(json.dumps({"jsonrpc": "2.0", "id": rid, "method": method, "params": params}))
        while True:
            message = await asyncio.wait_for(self.ws.recv(), 10)
            if isinstance(message, bytes):
                continue
            reply = json.loads(message)
            if reply.get("id") != rid:
                self.notifications.append(reply)
                continue
            if "error" in reply:
                return ("error", reply["error"]["code"])
            return reply["result"]


def ids_routed_to(t, server, count=1):
    """`count` new session ids that the proxy routes to `server`."""
    ids = []
    for _ in range(1000):
        sid = session_id()
        if t.get(f"/healthz?session={sid}")[2] == server:
            ids.append(sid)
            if len(ids) == count:
                return ids
    raise AssertionError(f"1000 random session ids gave {len(ids)} routed to {server}, not {count}")


async def check_websocket_sessions(t):
    """Clients of a session meet on its server; a stopped server's sessions load elsewhere."""
    home = "s2"
    idle_sid, busy_sid = ids_routed_to(t, home, 2)
    edit = {"tool": "csg_add", "shape": "sphere", "center": [16, 26, 16], "radius": 4}
    state = {}
    for sid in (idle_sid, busy_sid):
        async with Client(t, sid) as a:
            assert a.server == home, f"the WebSocket of session {sid} went to {a.server}, not {home}"
            created = await a.call("session.create", {"size": [32, 32, 32], "solid": "sphere", "session": sid,
                                                      "view": "none"})
            assert isinstance(created, dict) and created["session"] == sid, f"session.create: {created}"
            applied = await a.call("tool.apply", edit)
            assert isinstance(applied, dict) and applied["revision"] == created["revision"] + 1, f"tool.apply: {applied}"
            stats = await a.call("session.stats", {})
            state[sid] = (created["token"], stats["revision"], stats["digest"])
            # More clients of the session, each on its own connection: all on the same server,
            # all in the same session.
            for n in range(3):
                async with Client(t, sid) as b:
                    assert b.server == home, f"client {n} of session {sid} went to {b.server}, not {home}"
                    joined = await b.call("session.join", {"session": sid, "token": created["token"], "view": "none"})
                    assert isinstance(joined, dict), f"session.join on the session's own server: {joined}"
                    assert (joined["revision"], joined["digest"]) == state[sid][1:], f"session.join: {joined}"
            # What the routing spares clients: another server, asked directly, refuses a
            # session loaded here, by its lease in the shared data directory.
            for other in set(SERVERS) - {home}:
                async with Client(t, sid, direct=other) as x:
                    refused = await x.call("session.join", {"session": sid, "token": created["token"], "view": "none"})
                    assert refused == ("error", HELD_ELSEWHERE), f"session.join of {sid} directly at {other}: {refused}"
    print(f"ok: two sessions and their clients all on {home}; the other servers refuse them (-32015)")

    # Both idle now (--idle-session-seconds 1): once their server saved and unloaded them, they
    # are only in the shared data dir, and no server holds their lease.
    wait_until(f"{home} to unload its idle sessions", lambda: t.metric(home, "marzipan_sessions") == 0)
    for sid in (idle_sid, busy_sid):
        files = os.listdir(os.path.join(t.data, "sessions", sid))
        assert "session.json" in files and any(f.startswith("snapshot-") for f in files), f"{sid} has {files}"
        assert "lease" not in files, f"{sid} unloaded, but its lease is still there"

    # The busy one: a client edits it and is still in it when its server gets SIGTERM, so
    # only the save on SIGTERM carries that edit to the next server.
    async with Client(t, busy_sid) as c:
        assert c.server == home
        joined = await c.call("session.join", {"session": busy_sid, "token": state[busy_sid][0], "view": "none"})
        assert isinstance(joined, dict), f"session.join: {joined}"
        applied = await c.call("tool.apply", dict(edit, center=[16, 6, 16]))
        assert isinstance(applied, dict), f"tool.apply: {applied}"
        stats = await c.call("session.stats", {})
        assert stats["digest"] != state[busy_sid][2], "the second edit left the volume as it was"
        state[busy_sid] = (state[busy_sid][0], stats["revision"], stats["digest"])
        await asyncio.get_running_loop().run_in_executor(None, t.stop_server, home)
        try:
            await asyncio.wait_for(c.ws.recv(), 10)
        except websockets.ConnectionClosed as closed:
            assert closed.code == 1001, f"closed with {closed.code} when {home} stopped, not 1001"
        else:
            raise AssertionError(f"the client of {busy_sid} stayed open after {home} stopped")
    wait_until(f"HAProxy to mark {home} down", lambda: t.proxy_log_has(f"marzipan/{home} is DOWN"))

    for sid, why in ((idle_sid, "unloaded for idleness"), (busy_sid, "edited until SIGTERM")):
        async with Client(t, sid) as d:
            assert d.server in SERVERS and d.server != home, f"session {sid} after {home} stopped: {d.server}"
            joined = await d.call("session.join", {"session": sid, "token": state[sid][0], "view": "none"})
            assert isinstance(joined, dict), f"session.join of {sid} on {d.server}: {joined}"
            assert (joined["revision"], joined["digest"]) == state[sid][1:], \
                f"{sid} loaded on {d.server} with revision {joined['revision']} digest {joined['digest']}, " \
                f"saved as {state[sid][1:]}"
            print(f"ok: a session {why} on {home} loads on {d.server} from the shared data dir, "
                  "same revision and digest")


async def check_killed_server(t):
    """A server killed with a client in its session: nothing saved on the way out, but every
    acknowledged edit is in the session's journal, and the session loads on another server once
    the dead server's lease has run out; until then that server answers -32015."""
    up = [name for name in SERVERS if name in t.procs]
    victim = up[0]
    sid = ids_routed_to(t, victim)[0]
    async with Client(t, sid) as a:
        assert a.server == victim
        created = await a.call("session.create", {"size": [32, 32, 32], "solid": "torus", "session": sid, "view": "none"})
        assert isinstance(created, dict), f"session.create: {created}"
        applied = await a.call("tool.apply", {"tool": "csg_subtract", "shape": "box", "center": [16, 16, 16], "radius": 5})
        assert isinstance(applied, dict), f"tool.apply: {applied}"
        stats = await a.call("session.stats", {})
        t.kill_server(victim)
    killed_at = time.monotonic()
    wait_until(f"HAProxy to mark {victim} down", lambda: t.proxy_log_has(f"marzipan/{victim} is DOWN"))
    refusals = 0
    while True:
        async with Client(t, sid) as d:
            assert d.server in up and d.server != victim, f"session {sid} after {victim} was killed: {d.server}"
            joined = await d.call("session.join", {"session": sid, "token": created["token"], "view": "none"})
        if isinstance(joined, dict):
            break
        assert joined == ("error", HELD_ELSEWHERE), f"session.join of {sid} on {d.server}: {joined}"
        refusals += 1
        assert time.monotonic() - killed_at < LEASE_SECONDS + 10, f"{sid} still held {LEASE_SECONDS + 10} s after the kill"
        await asyncio.sleep(1)
    assert (joined["revision"], joined["digest"]) == (stats["revision"], stats["digest"]), \
        f"{sid} loaded on {d.server} at revision {joined['revision']} digest {joined['digest']}, " \
        f"acknowledged {stats['revision']} {stats['digest']}"
    print(f"ok: {victim} killed: its session loads on {d.server} {time.monotonic() - killed_at:.0f} s later "
          f"({refusals} joins refused with -32015 meanwhile), its edit intact")


async def check_tls(t):
    """The same config with MARZIPAN_TLS_CERT: https and wss end at the proxy, which routes
    them like plain requests; plain HTTP is redirected there, /healthz excepted."""
    cert_dir = os.path.join(t.work, "certs")
    os.makedirs(cert_dir)
    key, cert, pem = (os.path.join(cert_dir, n) for n in ("key.pem", "cert.pem", "marzipan.pem"))
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1", "-subj", "/CN=localhost",
                    "-addext", "subjectAltName=IP:127.0.0.1", "-keyout", key, "-out", cert],
                   check=True, capture_output=True)
    with open(pem, "w") as out:
        for part in (cert, key):
            with open(part) as f:
                out.write(f.read())
    port, tls_port = t.start_proxy("haproxy-tls", tls_cert=pem)
    context = ssl.create_default_context(cafile=cert)

    def https_get(target):
        conn = http.client.HTTPSConnection("127.0.0.1", tls_port, timeout=5, context=context)
        try:
            conn.request("GET", target)
            reply = conn.getresponse()
            return reply.status, reply.read(), reply.getheader("X-Marzipan-Server")
        finally:
            conn.close()

    def plain_get(target):
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
        try:
            conn.request("GET", target)
            reply = conn.getresponse()
            reply.read()
            return reply.status, reply.getheader("Location")
        finally:
            conn.close()

    def answers():
        try:
            return https_get("/healthz")[0] == 200
        except OSError:
            return False

    wait_until("HAProxy's TLS frontend to answer", answers)
    up = [name for name in SERVERS if name in t.procs]
    for name in set(SERVERS) - set(up):
        wait_until(f"the second HAProxy to mark {name} down",
                   lambda: t.proxy_log_has(f"marzipan/{name} is DOWN", "haproxy-tls"))
    sid = ids_routed_to(t, up[0])[0]
    status, body, server = https_get(f"/index.html?session={sid}")
    assert status == 200 and server == up[0], f"https GET of session {sid}: {status} from {server}, not {up[0]}"
    assert plain_get(f"/?session={sid}") == (308, f"https://127.0.0.1:{port}/?session={sid}"), \
        f"plain GET /: {plain_get('/')}"
    assert plain_get("/healthz")[0] == 200, "plain /healthz should stay open for probes"

    url = f"wss://127.0.0.1:{tls_port}/ws?session={sid}"
    async with websockets.connect(url, ssl=context) as ws:
        server = ws.response_headers.get("X-Marzipan-Server")
        assert server == up[0], f"wss of session {sid} went to {server}, not {up[0]}"
        await ws.send(json.dumps({"jsonrpc": "2.0", "id": 1, "method": "session.create",
                                  "params": {"size": [16, 16, 16], "solid": "box", "session": sid, "view": "none"}}))
        reply = json.loads(await asyncio.wait_for(ws.recv(), 10))
        assert reply.get("result", {}).get("session") == sid, f"session.create over wss: {reply}"
    print(f"ok: TLS at the proxy: https and wss of session {sid} reach {up[0]}, plain HTTP redirects")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--marzipan", required=True)
    parser.add_argument("--haproxy", required=True)
    parser.add_argument("--config", required=True)
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args()
    t = Topology(args)
    try:
        for name in SERVERS:
            t.start_server(name)
        t.start_proxy()
        owner = check_http_routing(t)
        check_failover_routing(t, owner)
        asyncio.run(check_websocket_sessions(t))
        asyncio.run(check_killed_server(t))
        asyncio.run(check_tls(t))
    finally:
        t.stop()
    print("scale-out topology: all checks passed")


if __name__ == "__main__":
    sys.exit(main())
