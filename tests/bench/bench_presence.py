#!/usr/bin/env python3
"""presence_cost: what presence costs the server, and whether an edit waits behind it.

One `marzipan serve` (its own process, --threads 2, no data directory), one session (64^3
sphere) with 16 WebSocket clients in splats mode on loopback. Client 0 also edits: a radius-4
blob by ray at the top of the sphere, add and remove alternating, 5 per second, each timed from
just before its request is written until its response, and until its splat delta (kind 2, the
response's revision) has been read. Phases alternate, the same clients throughout: "off" (edits
only) and "on" (edits, and every client sending presence {brush, camera} as notifications at
60 Hz, its brush moving). Server CPU is the server process's utime + stime over each phase
(/proc/PID/stat), so the clients' own CPU (this Python process, on the same machine) is not in
it, though it competes for the same cores.

Prints JSON lines: one per phase kind with the totals over its phases ("presence": false/true;
cpu_cores = server CPU seconds per wall second; edit latencies p50/p99 in ms; presence messages
received per client per second), then one summary line with the added CPU (in cores and as a
share of the off phases' CPU) and the latency ratios. Usage:
  tests/bench/bench_presence.py --marzipan build/marzipan [--seconds 8] [--cycles 2]
Needs python3-websockets (tests/debian-packages.sh).
"""
import argparse
import asyncio
import json
import math
import os
import re
import statistics
import subprocess
import time

import websockets

CLIENTS = 16
PRESENCE_HZ = 60
EDIT_HZ = 5


def server_cpu_seconds(pid: int) -> float:
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def percentile(values, q):
    if not values:
        return None
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q * len(s)) - 1))]


class Peer:
    def __init__(self, ws, index):
        self.ws = ws
        self.index = index
        self.presence_received = 0
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


async def main(args):
    proc = subprocess.Popen([args.marzipan, "serve", "--port", "0", "--threads", "2"], stdout=subprocess.PIPE,
                            stderr=subprocess.DEVNULL, text=True)
    try:
        url = "ws" + re.search(r"listening on http(://\S+)", proc.stdout.readline()).group(1).rstrip("/") + "/ws"
        peers = []
        readers = []
        for i in range(CLIENTS):
            ws = await websockets.connect(url + "?session=presencebenchsession0001", max_size=None, compression=None,
                                          ping_interval=None)
            peer = Peer(ws, i)
            readers.append(asyncio.create_task(peer.read()))
            peers.append(peer)
        created = (await peers[0].call(1, "session.create", {"size": [64, 64, 64], "solid": "sphere", "view": "splats",
                                                              "session": "presencebenchsession0001", "name": "editor"}))[1]
        for p in peers[1:]:
            await p.call(1, "session.join", {"session": created["result"]["session"], "token": created["result"]["token"],
                                             "view": "splats", "name": f"peer {p.index}"})
        presence_on = False
        stop = False

        async def send_presence(peer):
            start = time.perf_counter()
            n = 0
            while not stop:
                n += 1
                await asyncio.sleep(max(0.0, start + n / PRESENCE_HZ - time.perf_counter()))
                if not presence_on:
                    continue
                a = (n + 7 * peer.index) / 30
                params = {"brush": {"tool": "add_blob", "radius": 6, "point": [32 + 20 * math.cos(a), 50, 32 + 20 * math.sin(a)],
                                    "normal": [math.cos(a), 0.5, math.sin(a)], "active": n % 120 < 60},
                          "camera": {"eye": [32 + 90 * math.cos(a / 4), 60, 32 + 90 * math.sin(a / 4)], "target": [32, 32, 32]}}
                await peer.ws.send(json.dumps({"jsonrpc": "2.0", "method": "presence", "params": params}))

        senders = [asyncio.create_task(send_presence(p)) for p in peers]
        editor = peers[0]
        next_id = 100
        results = {False: {"wall": 0.0, "cpu": 0.0, "response": [], "delta": [], "presence": 0},
                   True: {"wall": 0.0, "cpu": 0.0, "response": [], "delta": [], "presence": 0}}
        for cycle in range(args.cycles):
            for on in (False, True):
                presence_on = on
                await asyncio.sleep(0.5)  # let the previous phase's traffic drain
                received0 = sum(p.presence_received for p in peers)
                cpu0, wall0 = server_cpu_seconds(proc.pid), time.perf_counter()
                edits = 0
                while time.perf_counter() - wall0 < args.seconds:
                    next_id += 1
                    tool = "add_blob" if edits % 2 == 0 else "remove_blob"
                    delta = asyncio.get_running_loop().create_future()
                    t0 = time.perf_counter()
                    editor.delta_waiting = (0, delta)
                    t_resp, response = await editor.call(next_id, "tool.apply", {
                        "tool": tool, "radius": 4, "ray": {"origin": [32, 100, 32.5], "direction": [0, -1, 0]}})
                    editor.delta_waiting = (response["result"]["revision"], delta)
                    if response["result"]["revision"] is not None and delta.done() is False:
                        pass
                    t_delta = await asyncio.wait_for(delta, 30)
                    results[on]["response"].append((t_resp - t0) * 1e3)
                    results[on]["delta"].append((t_delta - t0) * 1e3)
                    edits += 1
                    await asyncio.sleep(max(0.0, wall0 + edits / EDIT_HZ - time.perf_counter()))
                wall = time.perf_counter() - wall0
                results[on]["wall"] += wall
                results[on]["cpu"] += server_cpu_seconds(proc.pid) - cpu0
                results[on]["presence"] += sum(p.presence_received for p in peers) - received0
        stop = True
        await asyncio.gather(*senders)
        for p in peers:
            await p.ws.close()
        await asyncio.gather(*readers, return_exceptions=True)

        lines = []
        for on in (False, True):
            r = results[on]
            line = {"scenario": "presence_cost", "presence": on, "clients": CLIENTS,
                    "presence_hz": PRESENCE_HZ if on else 0, "edits_per_s": EDIT_HZ, "seconds": round(r["wall"], 2),
                    "cpu_cores": round(r["cpu"] / r["wall"], 4),
                    "edit_response_p50_ms": round(percentile(r["response"], 0.5), 3),
                    "edit_response_p99_ms": round(percentile(r["response"], 0.99), 3),
                    "edit_delta_p50_ms": round(percentile(r["delta"], 0.5), 3),
                    "edit_delta_p99_ms": round(percentile(r["delta"], 0.99), 3),
                    "edit_delta_mean_ms": round(statistics.fmean(r["delta"]), 3), "edits": len(r["delta"]),
                    "presence_received_per_client_per_s": round(r["presence"] / CLIENTS / r["wall"], 1)}
            lines.append(line)
            print(json.dumps(line), flush=True)
        off, on = lines
        print(json.dumps({"scenario": "presence_cost_summary", "added_cpu_cores": round(on["cpu_cores"] - off["cpu_cores"], 4),
                          "added_cpu_share_of_off": round(on["cpu_cores"] / off["cpu_cores"] - 1, 3) if off["cpu_cores"] else None,
                          "delta_p50_ratio": round(on["edit_delta_p50_ms"] / off["edit_delta_p50_ms"], 3),
                          "delta_p99_ratio": round(on["edit_delta_p99_ms"] / off["edit_delta_p99_ms"], 3),
                          "response_p50_ratio": round(on["edit_response_p50_ms"] / off["edit_response_p50_ms"], 3),
                          "date": time.strftime("%Y-%m-%d")}), flush=True)
    finally:
        proc.terminate()
        proc.wait(timeout=20)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--marzipan", required=True)
    parser.add_argument("--seconds", type=float, default=8)
    parser.add_argument("--cycles", type=int, default=2)
    asyncio.run(main(parser.parse_args()))
