#!/usr/bin/env python3
"""presence_cost: what presence costs the server, and whether an edit waits behind it.

Per server binary given (--marzipan, repeatable: "LABEL=PATH" or PATH), one `marzipan serve`
(its own process, --threads 2, no data directory) with one session (64^3 sphere) and 16
WebSocket clients in splats mode on loopback. Client 0, the editor, also edits: a radius-4 blob
by ray at the top of the sphere, add and remove alternating, 5 per second, each timed from just
before its request is written until its response, and until its splat delta (kind 2, the
response's revision) has been read. Phases alternate on each server, the same clients
throughout: "off" (edits only) and "on" (edits, and every client sending presence {brush,
camera} as notifications at 60 Hz, its brush moving). With several servers, each cycle runs
every server's off and on phases (the order reversed every other cycle) while the others idle,
so that they are compared under the same load of the machine.

The editor runs in this process, the 15 other clients in three child processes (5 each): in
one event loop, the others' reading of their presence would delay the editor's reads, and that
client-side wait would be counted as the server's edit latency; and one process for all could
not read every presence on a loaded machine, so that the server, dropping what a slow reader
has not taken (latest wins), did less work than the scenario asks (both were so until
2026-11-24). delivered_share tells how close a phase came: presence received per client per
second over the most the server may send, 15 senders x 20 per second (a little below 1 even
when all is read, as the flush timer fires a little late); a phase well below it was not
measured under the full load.

Server CPU is the server process's utime + stime over each phase (/proc/PID/stat, 10 ms ticks),
so the clients' CPU (the editor's process is reported) is not in it, though it competes for the
same cores. It does include the kernel's loopback work that a server's send does for the
receiving socket, which on a real network would be elsewhere.

Prints JSON lines: one per phase (scenario "presence_cost_phase"), then per server one
"presence_cost" line: added_cores is presence's cost, each cycle's on phase minus its off
phase, as median and range over the cycles; added_share_of_machine the same over the machine's
cores (os.cpu_count()); presence_share_of_server the added CPU as a share of the server's CPU
with presence on; sent/received are presence messages per client per second (a sender that
fell behind 60 Hz, or a reader behind the deliveries, would flatter the server); edit latencies are p50/p99 in ms over all phases
of a kind. With two servers, a last line gives the ratio of their added cores per cycle.
Usage:
  tests/bench/bench_presence.py --marzipan build/marzipan [--marzipan old=/tmp/marzipan.old]
      [--seconds 8] [--cycles 3]
Needs python3-websockets (tests/debian-packages.sh).
"""
import argparse
import asyncio
import json
import math
import multiprocessing
import os
import re
import resource
import statistics
import subprocess
import time

import websockets

CLIENTS = 16
PRESENCE_HZ = 60
EDIT_HZ = 5
OTHER_PROCESSES = 3  # the 15 other clients, 5 to a process
# What a client would receive if every delivery went out: (CLIENTS - 1) senders at 20 per second.
FULL_DELIVERY = (CLIENTS - 1) * 20


def server_cpu_seconds(pid: int) -> float:
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def own_cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def percentile(values, q):
    if not values:
        return None
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q * len(s)) - 1))]


def spread(values, digits=4):
    return {"median": round(statistics.median(values), digits), "min": round(min(values), digits),
            "max": round(max(values), digits)}


class Peer:
    def __init__(self, ws, index):
        self.ws = ws
        self.index = index
        self.presence_received = 0
        self.presence_sent = 0
        self.waiting = {}  # request id -> future of the response
        self.delta_waiting = None  # (revision, future)

    async def read(self):
        async for message in self.ws:
            if isinstance(message, str):
                if '"method":"presence"' in message:
                    self.presence_received += 1
                    continue
                m = json.loads(message)
                if "id" in m and m["id"] in self.waiting:
                    self.waiting.pop(m["id"]).set_result((time.perf_counter(), m))
            elif len(message) >= 24 and message[6] == 2 and self.delta_waiting:
                revision = int.from_bytes(message[12:20], "little")
                want, future = self.delta_waiting
                if revision >= want and not future.done():
                    future.set_result(time.perf_counter())

    async def call(self, id_, method, params):
        future = asyncio.get_running_loop().create_future()
        self.waiting[id_] = future
        await self.ws.send(json.dumps({"jsonrpc": "2.0", "id": id_, "method": method, "params": params}))
        return await asyncio.wait_for(future, 30)


async def send_presence(peer, on, stop):
    """Presence {brush, camera} at 60 Hz while on() holds, the brush moving, until stop()."""
    start = time.perf_counter()
    n = 0
    while not stop():
        n += 1
        await asyncio.sleep(max(0.0, start + n / PRESENCE_HZ - time.perf_counter()))
        if not on():
            continue
        a = (n + 7 * peer.index) / 30
        params = {"brush": {"tool": "add_blob", "radius": 6, "point": [32 + 20 * math.cos(a), 50, 32 + 20 * math.sin(a)],
                            "normal": [math.cos(a), 0.5, math.sin(a)], "active": n % 120 < 60},
                  "camera": {"eye": [32 + 90 * math.cos(a / 4), 60, 32 + 90 * math.sin(a / 4)], "target": [32, 32, 32]}}
        await peer.ws.send(json.dumps({"jsonrpc": "2.0", "method": "presence", "params": params}))
        peer.presence_sent += 1


def others_process(url, session, token, indices, on, stop, sent, received, ready):
    """Some of the other clients, in a process of their own (see the module's doc)."""

    async def run():
        peers, readers = [], []
        for i in indices:
            ws = await websockets.connect(url, max_size=None, compression=None, ping_interval=None)
            peer = Peer(ws, i)
            readers.append(asyncio.create_task(peer.read()))
            peers.append(peer)
            await peer.call(1, "session.join", {"session": session, "token": token, "view": "splats", "name": f"peer {i}"})
        senders = [asyncio.create_task(send_presence(p, lambda: on.value, lambda: stop.value)) for p in peers]
        ready.set()
        while not stop.value:
            await asyncio.sleep(0.05)
            sent.value = sum(p.presence_sent for p in peers)
            received.value = sum(p.presence_received for p in peers)
        await asyncio.gather(*senders)
        for p in peers:
            await p.ws.close()
        await asyncio.gather(*readers, return_exceptions=True)

    asyncio.run(run())


class Server:
    """One server process, its session and its clients: the editor here, the others in a child process."""

    def __init__(self, label, binary):
        self.label = label
        self.binary = binary
        self.presence_on = False
        self.stop = False
        self.next_id = 100
        self.phases = []

    async def start(self):
        self.proc = subprocess.Popen([self.binary, "serve", "--port", "0", "--threads", "2"], stdout=subprocess.PIPE,
                                     stderr=subprocess.DEVNULL, text=True)
        url = "ws" + re.search(r"listening on http(://\S+)", self.proc.stdout.readline()).group(1).rstrip("/") + "/ws"
        ws = await websockets.connect(url, max_size=None, compression=None, ping_interval=None)
        self.editor = Peer(ws, 0)
        self.reader = asyncio.create_task(self.editor.read())
        created = (await self.editor.call(1, "session.create", {"size": [64, 64, 64], "solid": "sphere", "view": "splats",
                                                                "name": "editor"}))[1]["result"]
        ctx = multiprocessing.get_context("spawn")
        self.others_on, self.others_stop = ctx.Value("b", 0, lock=False), ctx.Value("b", 0, lock=False)
        self.others, self.others_sent, self.others_received = [], [], []
        for k in range(OTHER_PROCESSES):
            sent, received, ready = ctx.Value("q", 0, lock=False), ctx.Value("q", 0, lock=False), ctx.Event()
            indices = list(range(1 + k, CLIENTS, OTHER_PROCESSES))
            process = ctx.Process(daemon=True, target=others_process,
                                  args=(url, created["session"], created["token"], indices, self.others_on, self.others_stop,
                                        sent, received, ready))
            process.start()
            if not await asyncio.get_running_loop().run_in_executor(None, ready.wait, 60):
                raise RuntimeError("the other clients did not join")
            self.others.append(process)
            self.others_sent.append(sent)
            self.others_received.append(received)
        self.sender = asyncio.create_task(send_presence(self.editor, lambda: self.presence_on, lambda: self.stop))

    def counts(self):
        """Presence sent and received so far by all clients (the others' as of their last report, <= 50 ms old)."""
        return (self.editor.presence_sent + sum(v.value for v in self.others_sent),
                self.editor.presence_received + sum(v.value for v in self.others_received))

    def set_presence(self, on):
        self.presence_on = on
        self.others_on.value = 1 if on else 0

    async def phase(self, on, seconds, cycle):
        self.set_presence(on)
        await asyncio.sleep(0.5)  # let the previous phase's traffic drain
        editor = self.editor
        sent0, received0 = self.counts()
        own0 = own_cpu_seconds()
        cpu0, wall0 = server_cpu_seconds(self.proc.pid), time.perf_counter()
        response, delta = [], []
        while time.perf_counter() - wall0 < seconds:
            self.next_id += 1
            tool = "add_blob" if len(delta) % 2 == 0 else "remove_blob"
            arrived = asyncio.get_running_loop().create_future()
            t0 = time.perf_counter()
            editor.delta_waiting = (0, arrived)
            t_resp, answer = await editor.call(self.next_id, "tool.apply", {
                "tool": tool, "radius": 4, "ray": {"origin": [32, 100, 32.5], "direction": [0, -1, 0]}})
            editor.delta_waiting = (answer["result"]["revision"], arrived)
            t_delta = await asyncio.wait_for(arrived, 30)
            response.append((t_resp - t0) * 1e3)
            delta.append((t_delta - t0) * 1e3)
            await asyncio.sleep(max(0.0, wall0 + len(delta) / EDIT_HZ - time.perf_counter()))
        wall = time.perf_counter() - wall0
        cpu = server_cpu_seconds(self.proc.pid) - cpu0
        sent1, received1 = self.counts()  # as stale as at the start: the window is the phase's
        self.set_presence(False)
        result = {"scenario": "presence_cost_phase", "server": self.label, "cycle": cycle, "presence": on,
                  "seconds": round(wall, 2), "cpu_cores": round(cpu / wall, 4),
                  "editor_process_cpu_cores": round((own_cpu_seconds() - own0) / wall, 4),
                  "presence_sent_per_client_per_s": round((sent1 - sent0) / CLIENTS / wall, 1),
                  "presence_received_per_client_per_s": round((received1 - received0) / CLIENTS / wall, 1),
                  "delivered_share": round((received1 - received0) / CLIENTS / wall / FULL_DELIVERY, 3) if on else None,
                  "edit_delta_p50_ms": round(percentile(delta, 0.5), 3), "edits": len(delta)}
        print(json.dumps(result), flush=True)
        self.phases.append({**result, "response": response, "delta": delta})

    async def close(self):
        self.stop = True
        self.others_stop.value = 1
        await self.sender
        for process in self.others:
            await asyncio.get_running_loop().run_in_executor(None, process.join, 30)
        await self.editor.ws.close()
        await asyncio.gather(self.reader, return_exceptions=True)
        self.proc.terminate()
        self.proc.wait(timeout=20)

    def added(self):
        """Each cycle's presence cost: its on phase's CPU minus its off phase's, in cores."""
        off = [p for p in self.phases if not p["presence"]]
        on = [p for p in self.phases if p["presence"]]
        return [b["cpu_cores"] - a["cpu_cores"] for a, b in zip(off, on)]

    def summary(self):
        cores = os.cpu_count()
        off = [p for p in self.phases if not p["presence"]]
        on = [p for p in self.phases if p["presence"]]
        added = self.added()
        line = {"scenario": "presence_cost", "server": self.label, "clients": CLIENTS, "presence_hz": PRESENCE_HZ,
                "edits_per_s": EDIT_HZ, "cycles": len(added), "seconds_per_phase": round(statistics.fmean(p["seconds"] for p in on), 2),
                "machine_cores": cores,
                "off_cpu_cores": spread([p["cpu_cores"] for p in off]), "on_cpu_cores": spread([p["cpu_cores"] for p in on]),
                "added_cores": spread(added), "added_share_of_machine": spread([a / cores for a in added], 4),
                "presence_share_of_server": spread([a / b["cpu_cores"] for a, b in zip(added, on)], 3)
                if all(b["cpu_cores"] for b in on) else None,
                "presence_sent_per_client_per_s": spread([p["presence_sent_per_client_per_s"] for p in on], 1),
                "presence_received_per_client_per_s": spread([p["presence_received_per_client_per_s"] for p in on], 1),
                "delivered_share": spread([p["delivered_share"] for p in on], 3),
                "editor_process_cpu_cores_on": spread([p["editor_process_cpu_cores"] for p in on], 3)}
        for kind, phases in (("off", off), ("on", on)):
            for what in ("response", "delta"):
                values = [v for p in phases for v in p[what]]
                line[f"edit_{what}_{kind}_p50_ms"] = round(percentile(values, 0.5), 3)
                line[f"edit_{what}_{kind}_p99_ms"] = round(percentile(values, 0.99), 3)
        line["date"] = time.strftime("%Y-%m-%d")
        return line


async def main(args):
    servers = []
    for i, spec in enumerate(args.marzipan):
        label, path = spec.split("=", 1) if "=" in spec else (f"{i}:{os.path.basename(spec)}", spec)
        servers.append(Server(label, path))
    try:
        for s in servers:
            await s.start()
        for cycle in range(args.cycles):
            for s in (servers if cycle % 2 == 0 else servers[::-1]):
                for on in (False, True):
                    await s.phase(on, args.seconds, cycle)
    finally:
        for s in servers:
            if hasattr(s, "sender"):
                await s.close()
            elif hasattr(s, "proc"):
                s.proc.terminate()
                s.proc.wait(timeout=20)
    summaries = [s.summary() for s in servers]
    for line in summaries:
        print(json.dumps(line), flush=True)
    if len(servers) == 2:
        a, b = servers
        ratios = [y / x for x, y in zip(a.added(), b.added()) if x > 0]
        print(json.dumps({"scenario": "presence_cost_compare", "servers": [a.label, b.label],
                          "added_cores_ratio": spread(ratios, 3) if ratios else None,
                          "date": time.strftime("%Y-%m-%d")}), flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--marzipan", required=True, action="append", help="a server binary, PATH or LABEL=PATH (repeatable)")
    parser.add_argument("--seconds", type=float, default=8)
    parser.add_argument("--cycles", type=int, default=3)
    asyncio.run(main(parser.parse_args()))
