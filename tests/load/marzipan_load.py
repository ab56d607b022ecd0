#!/usr/bin/python3
"""Load on a Marzipan server: N sculpting clients on M sessions, and optionally a client that
stops reading. Reports throughput, latency, errors and the server's memory as one JSON object.

Each session is a --size^3 solid (128^3 pig by default). Client i works in session i mod M; the first
client of a session creates it, the others join with its token, all in `splats` view, so every
client receives every splat delta of its session. Each client sculpts strokes as a pointer
drag would: stroke.begin (add_blob, remove_blob, smooth in turn, radius 4-10), stroke.dabs
messages of 1-4 `ray` dabs sweeping across the model at a steady rate (open loop: a message
is sent when it is due, whether or not the previous ones were answered), stroke.end after
1-2 s, then the next stroke. --mode web-client sculpts as the browser does instead (closed
loop, dabs spaced and picked on the client's splats: sculpt_like_web_client).

Latency of one stroke.dabs: from sending it until its response ("response"), and until the
first splat delta that shows its revision arrives ("delta", what a user sees). The server's
own view of edit latency (request arrival to response) comes from its /metrics histogram.
Server memory: VmRSS and VmHWM from /proc/PID/status every second, during and after the run.

With --marzipan BIN the tool starts `BIN serve --port 0 --threads 2` itself (and stops it; 1 with --pin);
with --url it uses a running server (--server-pid PID then gives its memory). The clients run
in several processes (--processes), each an asyncio loop, because one Python process cannot
receive the ~10,000 messages per second of 64 clients; the client side's CPU is reported so
that a saturated client is told apart from a slow server.

--pin measures capacity per server core: the server started on one core (--threads 1), the
tool and its clients on another; the report's server CPU per dab and dab->delta p50/p99 are
then the figures that count, and a pinned run fails without them. --client-bin runs the
compiled client (load_client.cpp, the same web-client strokes from the same seed) in place of
the Python client processes, which saturate their one core near 48 sculptors.

--slow-client adds one client that joins session 0 a little after the start and then stops
reading; the server should close it with 1008 "too far behind" once its queue passes
--max-queue-mb, without slowing the others or growing without bound. At the end the slow
client reads again to learn how it was closed.

Exit status: 0 when no request got an error or went unanswered, no sculpting client's
connection closed, every client saw its session's last delta and at least one dab was applied;
1 otherwise; 2 usage. Latency does not decide it: the JSON's "goals" says whether the
targets were met.

Conventions: times are time.monotonic() (system-wide on Linux, so comparable between the
processes); latencies in milliseconds, memory in MiB (2^20 bytes) and called _mb like the
server's --max-queue-mb; coordinates in vu of the session's grid, y up. Standard library,
Debian's python3-websockets and python3-numpy only: run it with /usr/bin/python3.
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import json
import math
import multiprocessing
import os
import random
import re
import resource
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import websockets

# The project's Python client package, for the frame decoder and session URLs.
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "protocol" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from marzipan.client import new_session_id, session_url  # noqa: E402
from marzipan.frames import FrameError, FrameKind, decode_frame  # noqa: E402
from marzipan.splats import SPLAT_FORMAT_VERSION  # noqa: E402
from ws_link import WsLink  # noqa: E402
from web_client_model import DAB_SPACING, MIN_DAB_SPACING, DabSpacer, SplatSurface, StrokePicker  # noqa: E402

TOOLS = ("add_blob", "remove_blob", "smooth")
GOAL_P99_MS = 50.0  # the target p99 of an edit's round trip
# web-client/net/stroke-sender.js and the browser's pointer events
WEB_CLIENT_FRAME_HZ = 60.0
WEB_CLIENT_MAX_IN_FLIGHT = 3
WEB_CLIENT_MAX_DABS = 256  # the server's default --max-dabs, which the client adopts
WEB_CLIENT_STROKE_S = 1.5  # each stroke lasts 0.8-1.2 times this
WEB_CLIENT_PAUSE_S = 0.25  # between a stroke's end and the next one's begin
# web-client/net/stroke-sender.js strokeBeginParams: add/remove blob strokes stand at a height of
# strength x half the radius (at most 16 vu; the server works a sub-step per vu), smoothing builds up.
WEB_CLIENT_HEIGHT_PER_RADIUS = 0.5
WEB_CLIENT_MAX_HEIGHT = 16.0
# Grab strokes among the web-client mode's (issue 29 section 5), with dab spacing only (their
# anchor is a point the client picked): a fifth of the strokes, each dragging its anchor this
# far in the plane facing the camera by the stroke's last pointer event, at the warps' default
# strength of 1 (web-client/ui: a warp keeps a strength of its own).
GRAB_SHARE = 0.2
GRAB_REACH = 20.0  # vu


def web_client_stroke_params(tool: str, radius: float, strength: float) -> dict:
    params = {"tool": tool, "radius": radius, "strength": strength}
    if tool in ("add_blob", "remove_blob"):
        height = strength * min(WEB_CLIENT_HEIGHT_PER_RADIUS * radius, WEB_CLIENT_MAX_HEIGHT)
        params["height"] = max(0.001, math.floor(1000 * height) / 1000)
    else:
        params["accumulate"] = True
    return params
# Deltas of a 128^3 session are tens of KiB, full buffers a few hundred; 64 MiB covers far larger grids.
MAX_MESSAGE_BYTES = 64 << 20
SETUP_TIMEOUT_S = 60.0
DRAIN_TIMEOUT_S = 10.0  # for the answers still due after the run, and then the last deltas
SLOW_CLIENT_DRAIN_S = 5.0  # reading the few MiB still in flight takes well under a second
SLOW_CLIENT_RCVBUF = 64 << 10


def percentiles(values) -> dict:
    """p50, p99 and max (nearest rank) of latencies in seconds, as milliseconds; n the count."""
    if not values:
        return {"n": 0, "p50": None, "p99": None, "max": None}
    ordered = sorted(values)

    def rank(p):
        return ordered[min(len(ordered) - 1, max(0, math.ceil(p * len(ordered)) - 1))]

    return {"n": len(ordered), "p50": round(rank(0.50) * 1e3, 2), "p99": round(rank(0.99) * 1e3, 2),
            "max": round(ordered[-1] * 1e3, 2)}


# ------------------------------------------------------------------------------------ strokes

def _normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


class Drag:
    """A pointer drag across the model seen from a random side: the screen point moves on a
    straight line across the model's middle, each pick a ray from the screen plane straight
    into the scene (an orthographic camera), as a browser client casts them."""

    def __init__(self, rng: random.Random, size: int):
        centre = [(size - 1) / 2.0] * 3
        azimuth = rng.uniform(0, 2 * math.pi)
        elevation = math.radians(rng.uniform(-15, 45))
        towards_eye = [math.cos(elevation) * math.cos(azimuth), math.sin(elevation),
                       math.cos(elevation) * math.sin(azimuth)]
        right = _normalize(_cross([0.0, 1.0, 0.0], towards_eye))
        up = _cross(towards_eye, right)
        # Within the pig's and the sphere's silhouette from most sides (both span about
        # +-0.3 N around the middle), so most picks hit; a miss just skips its dab.
        reach = 0.22 * size
        u0, u1 = (-reach, reach) if rng.random() < 0.5 else (reach, -reach)
        v0, v1 = rng.uniform(-0.12, 0.15) * size, rng.uniform(-0.12, 0.15) * size
        distance = 1.5 * size
        self._eye = [centre[i] + distance * towards_eye[i] for i in range(3)]
        self._right, self._up = right, up
        self._line = (u0, v0, u1, v1)
        self.direction = [round(-c, 4) for c in towards_eye]

    def origin(self, t: float) -> list:
        u0, v0, u1, v1 = self._line
        u, v = u0 + (u1 - u0) * t, v0 + (v1 - v0) * t
        return [self._eye[i] + u * self._right[i] + v * self._up[i] for i in range(3)]

    def ray(self, t: float) -> dict:
        return {"origin": [round(c, 2) for c in self.origin(t)], "direction": self.direction}


class WebClientStroke:
    """One stroke as the browser makes it, drawn from `rng` in a fixed order (the compiled
    client, load_client.cpp, draws the same numbers from the same seed: test_load_client.py):
    whether it is a grab, its tool's parameters (radius 4-10, strength 0.3-0.8), a Drag, its
    pointer events (`frames`, ~1.5 s at 60 Hz); pointer(k) gives the dabs pointer event k makes.
    With a dab spacing each event is picked on `surface` as it was when the stroke began, the
    hits spaced into dabs along their path and each dab put on the surface under its own
    interpolated ray (a centre); with spacing 0 each event is one `ray` dab the server picks.
    A grab (GRAB_SHARE of the strokes, with a dab spacing only) sends as its first dab the first
    point the drag picks, its anchor (protocol/PROTOCOL.md, warp strokes), then one dab per
    pointer event: the anchor moved along the drag's screen direction, GRAB_REACH vu by the
    stroke's last event."""

    def __init__(self, rng: random.Random, tool: str, size: int, surface: SplatSurface, dab_spacing: float):
        self.rng = rng
        self.grab = rng.random() < GRAB_SHARE and dab_spacing > 0
        radius, strength = round(rng.uniform(4, 10), 2), round(rng.uniform(0.3, 0.8), 2)
        self.params = {"tool": "grab", "radius": radius, "strength": 1.0} if self.grab else \
            web_client_stroke_params(tool, radius, strength)
        self.anchor = self.anchor_event = None
        self.drag = Drag(rng, size)
        self.picker = self.spacer = None
        if dab_spacing > 0:
            self.picker = StrokePicker(surface.snapshot(), self.drag.origin(0), self.drag.origin(1), self.drag.direction)
            self.spacer = DabSpacer(max(MIN_DAB_SPACING, dab_spacing * self.params["radius"]))
        self.frames = max(1, round(rng.uniform(0.8, 1.2) * WEB_CLIENT_STROKE_S * WEB_CLIENT_FRAME_HZ))

    def pointer(self, k: int) -> list:
        """The dabs of pointer event k (0 <= k < frames), in order."""
        pressure = round(self.rng.uniform(0.5, 1.0), 2)
        if self.grab:
            return self._grab_pointer(k, pressure)
        if self.spacer is None:
            return [{"ray": self.drag.ray((k + 1) / self.frames), "pressure": pressure}]
        dabs = []
        for point, dab_pressure, f in self.spacer.add(self.picker.pick(self.drag.origin((k + 1) / self.frames)),
                                                      pressure):
            if f < 1:  # between two samples: on the surface under its own ray
                point = self.picker.pick(self.drag.origin((k + f) / self.frames)) or point
            dabs.append({"center": [round(c, 4) for c in point], "pressure": round(dab_pressure, 4)})
        return dabs

    def _grab_pointer(self, k: int, pressure: float) -> list:
        if self.anchor is None:
            self.anchor = self.picker.pick(self.drag.origin((k + 1) / self.frames))
            if self.anchor is None:
                return []
            self.anchor_event = k
            point = self.anchor
        else:
            a, b = self.drag.origin(0), self.drag.origin(1)
            along = math.dist(a, b)
            reach = GRAB_REACH * (k - self.anchor_event) / max(1, self.frames - 1 - self.anchor_event)
            point = [p + reach * (y - x) / along for p, x, y in zip(self.anchor, a, b)]
        return [{"center": [round(c, 4) for c in point], "pressure": pressure}]


# ------------------------------------------------------------------------------------ clients

class Pacer:
    """A fixed schedule from now: ticks `period` s apart until `end`, each one's lateness
    appended to `lags`; `due` is the time of the next tick."""

    def __init__(self, period: float, end: float, lags: list):
        self.period, self.end, self.lags = period, end, lags
        self.due = time.monotonic()

    async def ticks(self, count: int):
        for k in range(count):
            now = time.monotonic()
            if self.due > now:
                await asyncio.sleep(self.due - now)
                now = time.monotonic()
            if now >= self.end:
                return
            self.lags.append(now - self.due)
            yield k
            self.due += self.period


class SessionState:
    """What the clients of one session (all in one process) share."""

    def __init__(self, index: int, session_id: str):
        self.index = index
        self.id = session_id
        self.token = None
        self.created = asyncio.get_running_loop().create_future()
        self.last_revision = 0  # newest revision any of its clients' dabs made
        # The revisions its clients' dabs messages answered: one per application (the server
        # applies a stroke's queued messages as one, and they answer the same revision).
        self.dab_revisions = set()
        # Its splats as its creating client receives them (web-client mode with dab spacing):
        # the surface each stroke picks its dabs on, as a browser does.
        self.surface = SplatSurface()


class LoadClient:
    """One sculpting connection. A reader task takes every message as it arrives and stamps
    it; the sculpting task sends on its own schedule."""

    def __init__(self, index: int, session: SessionState, args: dict, stats: "WorkerStats", creator: bool):
        self.index = index
        self.creator = creator
        self.session = session
        self.args = args
        self.stats = stats
        self.rng = random.Random(args["seed"] * 100003 + index)
        self.ws = None
        self.reader = None
        self.next_id = 1
        self.pending = {}  # request id -> (method, sent at, future or None)
        # (revision, sent at, pointer times of its dabs or None) of dabs messages that applied, in order
        self.awaiting_delta = collections.deque()
        self.dab_times = {}  # request id -> pointer times of its dabs (web-client mode)
        self.last_delta_revision = 0
        self.delta_seen = None  # an asyncio.Event while someone waits for a revision
        self.closed_unexpectedly = None
        self.stroke = None  # the open stroke's id

    async def connect(self):
        self.ws = await WsLink.connect(session_url(self.args["url"], self.session.id), MAX_MESSAGE_BYTES,
                                       self.on_text, self.on_binary, SETUP_TIMEOUT_S)
        self.reader = asyncio.create_task(self.read())

    async def read(self):
        """Waits for the connection's end (its messages come to on_text and on_binary as they
        arrive) and fails whatever was waiting on it."""
        await self.ws.closed
        if not self.stats.closing:
            self.closed_unexpectedly = (self.ws.close_code, self.ws.close_reason)
            self.stats.unexpected_closes[str(self.ws.close_code)] += 1
        for method, _, future in self.pending.values():
            if future is not None and not future.done():
                future.set_exception(ConnectionError(f"connection closed during {method}"))
        if self.delta_seen is not None:
            self.delta_seen.set()

    def on_text(self, text: str, now: float):
        message = json.loads(text)
        if "id" not in message:
            method = message.get("method", "?")
            self.stats.notifications[method] += 1
            if method == "session.clients" and self.session.index == self.stats.slow_session:
                self.stats.slow_session_clients.append((now, len(message["params"]["clients"])))
            return
        entry = self.pending.pop(message["id"], None)
        if entry is None:
            self.stats.anomalies["response to no request"] += 1
            return
        method, sent, future = entry
        latency = now - sent
        dab_times = self.dab_times.pop(message["id"], None)
        error = message.get("error")
        self.stats.answered += 1
        if error is not None:
            code = str(error.get("code"))
            self.stats.errors[code] += 1
            if len(self.stats.error_samples) < 5:
                self.stats.error_samples.append({"method": method, "error": error})
            if future is not None and not future.done():
                future.set_exception(RuntimeError(f"{method}: {error.get('code')} {error.get('message')}"))
            return
        result = message["result"]
        if method == "stroke.dabs":
            self.stats.dabs_latency.append(latency)
            self.stats.dabs_sent.append(sent)
            self.stats.session_dabs_latency[self.session.index].append(latency)
            applied = result["applied"]
            self.stats.dabs_applied += applied
            if applied > 0:
                revision = result["revision"]
                self.session.last_revision = max(self.session.last_revision, revision)
                self.session.dab_revisions.add(revision)
                if self.last_delta_revision >= revision:
                    self.stats.anomalies["delta before its response"] += 1
                else:
                    self.awaiting_delta.append((revision, sent, dab_times))
        else:
            self.stats.other_latency[method].append(latency)
        if future is not None and not future.done():
            future.set_result(result)

    def on_binary(self, data: bytes, now: float):
        try:
            frame = decode_frame(data, MAX_MESSAGE_BYTES)
        except FrameError as e:
            self.stats.anomalies[f"bad frame: {e.code.value}"] += 1
            return
        if self.creator and self.args["mode"] == "web-client" and self.args["dab_spacing"] > 0 \
                and frame.kind in (FrameKind.SPLATS_FULL, FrameKind.SPLATS_DELTA):
            self.session.surface.apply(frame.payload, full=frame.kind == FrameKind.SPLATS_FULL)
        if frame.kind == FrameKind.SPLATS_FULL:
            self.stats.full_buffers += 1
            self.last_delta_revision = max(self.last_delta_revision, frame.revision)
            return
        if frame.kind != FrameKind.SPLATS_DELTA or frame.request_id != 0:
            self.stats.anomalies[f"unexpected frame kind {frame.kind}"] += 1
            return
        self.stats.deltas += 1
        self.stats.delta_bytes += len(data)
        if frame.revision <= self.last_delta_revision:
            self.stats.anomalies["delta revision did not grow"] += 1
        self.last_delta_revision = max(self.last_delta_revision, frame.revision)
        while self.awaiting_delta and self.awaiting_delta[0][0] <= frame.revision:
            _, sent, dab_times = self.awaiting_delta.popleft()
            self.stats.delta_latency.append(now - sent)
            self.stats.session_delta_latency[self.session.index].append(now - sent)
            if dab_times:
                self.stats.dab_delta_latency.extend(now - t for t in dab_times)
        if self.delta_seen is not None:
            self.delta_seen.set()

    def send(self, method: str, params: dict, want_result: bool = False, dab_times=None):
        """Sends a request; returns a future of its result when asked for, else None. dab_times:
        for stroke.dabs, when the pointer made each dab (for the dab->delta latency). Raises
        ConnectionError once the connection is closing."""
        request_id = self.next_id
        self.next_id += 1
        sent = time.monotonic()
        self.ws.send_text(json.dumps({"jsonrpc": "2.0", "id": request_id, "method": method, "params": params},
                                     separators=(",", ":")))
        future = asyncio.get_running_loop().create_future() if want_result else None
        self.pending[request_id] = (method, sent, future)
        if dab_times is not None:
            self.dab_times[request_id] = dab_times
        self.stats.sent[method] += 1
        return future

    async def call(self, method: str, params: dict):
        return await asyncio.wait_for(self.send(method, params, want_result=True), SETUP_TIMEOUT_S)

    async def enter(self):
        """Creates the session (first client) or joins it, in splats view (a full buffer follows)."""
        await self.connect()
        if self.creator:
            size = self.args["size"]
            result = await self.call("session.create", {"size": [size] * 3, "solid": self.args["solid"],
                                                        "session": self.session.id, "view": "splats",
                                                        "splats": SPLAT_FORMAT_VERSION})
            self.session.token = result["token"]
            self.session.created.set_result(None)
        else:
            await self.session.created
            await self.call("session.join", {"session": self.session.id, "token": self.session.token,
                                             "view": "splats", "splats": SPLAT_FORMAT_VERSION})

    async def sculpt(self, end: float):
        if self.args["mode"] == "web-client":
            await self.sculpt_like_web_client(end)
        else:
            await self.sculpt_open_loop(end)

    async def sculpt_like_web_client(self, end: float):
        """Strokes as the browser makes them (web-client/ui/sculpt.js) and
        web-client/net/stroke-sender.js sends them: a pointer event every display frame (60 Hz)
        for ~1.5 s, each picked on the session's splats as they were when the stroke began; the
        hits become dabs `dab_spacing` of the radius apart along their path (at least 0.25 vu),
        each put on the surface by a pick under its own interpolated ray and sent as a centre
        (web_client_model.py). With dab_spacing 0 every pointer event is one `ray` dab instead,
        picked by the server. Dabs queue until stroke.begin has answered, then every frame and
        every answer sends all that wait as one stroke.dabs, unless WEB_CLIENT_MAX_IN_FLIGHT
        messages are unanswered, in which case they wait and merge into a later message.
        stroke.end follows once the queue is empty and nothing is in flight; the next stroke
        starts after a short pause (pointer up, move, down)."""
        loop = asyncio.get_running_loop()
        stroke_number = 0
        while time.monotonic() < end:
            tool = TOOLS[(self.index + stroke_number) % len(TOOLS)]
            stroke_number += 1
            # The browser picks a stroke's dabs on its splats as they were at the press.
            plan = WebClientStroke(self.rng, tool, self.args["size"], self.session.surface, self.args["dab_spacing"])
            self.stats.stroke_tools[plan.params["tool"]] += 1
            queue = []  # (dab, pointer time)
            in_flight = 0
            stroke = None
            failed = False  # stroke.begin or a stroke.dabs failed: the stroke is abandoned
            idle = asyncio.Event()  # set whenever nothing is in flight
            idle.set()

            def answered(future):
                nonlocal in_flight, failed
                in_flight -= 1
                if future.cancelled() or future.exception() is not None:
                    failed = True
                    queue.clear()
                flush()

            def begun_done(future):
                nonlocal stroke, failed
                if future.cancelled() or future.exception() is not None:
                    failed = True
                    queue.clear()
                else:
                    stroke = future.result()["stroke"]
                    flush()

            def flush():
                nonlocal in_flight
                while stroke is not None and queue and in_flight < WEB_CLIENT_MAX_IN_FLIGHT \
                        and self.closed_unexpectedly is None:
                    batch = queue[:WEB_CLIENT_MAX_DABS]
                    del queue[:WEB_CLIENT_MAX_DABS]
                    in_flight += 1
                    idle.clear()
                    self.stats.dabs_per_message.append(len(batch))
                    try:
                        future = self.send("stroke.dabs", {"stroke": stroke, "dabs": [d for d, _ in batch]},
                                           want_result=True, dab_times=[t for _, t in batch])
                    except ConnectionError:
                        in_flight -= 1
                        break  # the reader sees the close and ends the stroke
                    future.add_done_callback(answered)
                if in_flight == 0:
                    idle.set()

            begun = loop.create_task(self.call("stroke.begin", plan.params))
            begun.add_done_callback(begun_done)
            pacer = Pacer(1.0 / WEB_CLIENT_FRAME_HZ, end, self.stats.send_lag)
            async for k in pacer.ticks(plan.frames):
                self.stats.pointer_events += 1
                dabs = plan.pointer(k)
                if not failed:
                    now = time.monotonic()
                    queue.extend((dab, now) for dab in dabs)
                flush()
            # The stroke's id from the awaited answer itself: when stroke.begin finished before
            # this await, begun_done is only scheduled, and the loop below, whose idle.wait()
            # returns at once while nothing is in flight, would never let it run.
            try:
                stroke = (await begun)["stroke"]
            except (RuntimeError, ConnectionError, asyncio.TimeoutError):
                failed = True  # counted as an error by the reader
                queue.clear()
            while (queue or in_flight) and self.closed_unexpectedly is None:
                flush()
                await idle.wait()
            if self.closed_unexpectedly is not None:
                return
            if stroke is not None:
                self.send("stroke.end", {"stroke": stroke})
            await asyncio.sleep(WEB_CLIENT_PAUSE_S)

    async def sculpt_open_loop(self, end: float):
        rate = self.args["rate"]
        period = 1.0 / rate
        stroke_number = 0
        while time.monotonic() < end:
            tool = TOOLS[(self.index + stroke_number) % len(TOOLS)]
            stroke_number += 1
            params = {"tool": tool, "radius": round(self.rng.uniform(4, 10), 2),
                      "strength": round(self.rng.uniform(0.3, 0.8), 2)}
            begun = self.send("stroke.begin", params, want_result=True)
            self.stroke = (await begun)["stroke"]
            drag = Drag(self.rng, self.args["size"])
            messages = max(1, round(self.rng.uniform(1.0, 2.0) * rate))
            pacer = Pacer(period, end, self.stats.send_lag)
            async for k in pacer.ticks(messages):
                count = self.rng.randint(1, 4)
                dabs = [{"ray": drag.ray((k + (j + 1) / count) / messages),
                         "pressure": round(self.rng.uniform(0.5, 1.0), 2)} for j in range(count)]
                self.send("stroke.dabs", {"stroke": self.stroke, "dabs": dabs})
            # The pointer is released one period after its last move, so that a client sends
            # `rate` messages a second over whole strokes, short ones too.
            await asyncio.sleep(max(0.0, min(pacer.due, end) - time.monotonic()))
            self.send("stroke.end", {"stroke": self.stroke})
            self.stroke = None

    async def answered(self, deadline: float) -> bool:
        """Waits until every request sent was answered (the reader pops them)."""
        while self.pending and self.closed_unexpectedly is None and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
        return not self.pending

    async def saw_revision(self, revision: int, deadline: float) -> bool:
        self.delta_seen = asyncio.Event()
        while self.last_delta_revision < revision and self.closed_unexpectedly is None:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            self.delta_seen.clear()
            try:
                await asyncio.wait_for(self.delta_seen.wait(), remaining)
            except asyncio.TimeoutError:
                break
        return self.last_delta_revision >= revision


class SlowClient:
    """Joins a busy session in splats view, then stops reading: websockets stops taking bytes
    off the socket once one message waits unread (max_queue=1) and its small read buffer is
    full, so the server's writes to it back up into its queue."""

    def __init__(self, session: SessionState, args: dict):
        self.session = session
        self.args = args
        self.report = {"session": session.index}

    async def run(self, join_at: float, end: float):
        await asyncio.sleep(max(0.0, join_at - time.monotonic()))
        await self.session.created
        ws = await websockets.connect(session_url(self.args["url"], self.session.id), max_size=MAX_MESSAGE_BYTES,
                                      ping_interval=None, compression=None, max_queue=1, read_limit=1 << 12,
                                      open_timeout=SETUP_TIMEOUT_S)
        # A small receive buffer keeps the backlog in the server's queue, the bound under test,
        # rather than in this socket's (loopback autotunes it to megabytes).
        ws.transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, SLOW_CLIENT_RCVBUF)
        await ws.send(json.dumps({"jsonrpc": "2.0", "id": 1, "method": "session.join",
                                  "params": {"session": self.session.id, "token": self.session.token,
                                             "view": "splats"}}))
        while True:
            message = await asyncio.wait_for(ws.recv(), SETUP_TIMEOUT_S)
            answer = json.loads(message) if isinstance(message, str) else {}
            if answer.get("id") == 1:
                if "error" in answer:
                    raise RuntimeError(f"session.join: {answer['error']}")
                break
        self.report["joined_at_s"] = round(time.monotonic() - self.args["t0"], 3)
        await asyncio.sleep(max(0.0, end - time.monotonic()))
        # Reading again shows how the server ended the connection: the close frame comes after
        # whatever was still in flight when it gave up on this client.
        read_bytes = 0
        deadline = time.monotonic() + SLOW_CLIENT_DRAIN_S
        try:
            while time.monotonic() < deadline:
                message = await asyncio.wait_for(ws.recv(), deadline - time.monotonic())
                read_bytes += len(message)
        except (websockets.exceptions.ConnectionClosed, asyncio.TimeoutError):
            pass
        self.report.update(read_after_resuming_mb=round(read_bytes / 2**20, 2), close_code=ws.close_code,
                           close_reason=ws.close_reason)
        if ws.close_code is None:
            await ws.close()


class WorkerStats:
    def __init__(self, sessions, slow_session):
        self.closing = False
        # When the session with the slow client changed its list of clients, and how many it had:
        # the server drops a client from its session when it gives up on it.
        self.slow_session = slow_session
        self.slow_session_clients = []
        self.sent = collections.Counter()
        self.answered = 0
        self.errors = collections.Counter()
        self.error_samples = []
        self.notifications = collections.Counter()
        self.anomalies = collections.Counter()
        self.unexpected_closes = collections.Counter()
        self.dabs_latency = []
        self.dabs_sent = []  # when each of dabs_latency's messages was sent
        self.delta_latency = []
        self.dab_delta_latency = []  # web-client mode: pointer event until the delta showing its dab
        self.dabs_per_message = []  # web-client mode
        self.pointer_events = 0  # web-client mode
        self.stroke_tools = collections.Counter()  # web-client mode: strokes begun, by tool
        self.session_dabs_latency = {s: [] for s in sessions}
        self.session_delta_latency = {s: [] for s in sessions}
        self.other_latency = collections.defaultdict(list)
        self.send_lag = []
        self.loop_lag = []
        self.dabs_applied = 0
        self.deltas = 0
        self.delta_bytes = 0
        self.full_buffers = 0


async def measure_loop_lag(stats: WorkerStats, end: float):
    """How late a 10 ms timer fires: the event loop's backlog, i.e. whether this process keeps up."""
    while time.monotonic() < end:
        due = time.monotonic() + 0.01
        await asyncio.sleep(0.01)
        stats.loop_lag.append(time.monotonic() - due)


async def worker_main(spec: dict, conn, start_event, start_time) -> dict:
    args = spec["args"]
    stats = WorkerStats([s["index"] for s in spec["sessions"]], spec.get("slow_session"))
    sessions = {s["index"]: SessionState(s["index"], s["id"]) for s in spec["sessions"]}
    clients = [LoadClient(c, sessions[s["index"]], args, stats, creator=(c == s["clients"][0]))
               for s in spec["sessions"] for c in s["clients"]]
    failures = []
    try:
        await asyncio.gather(*(c.enter() for c in clients))
    except Exception as e:  # noqa: BLE001  reported to the parent, which fails the run
        conn.send(("failed", f"setup: {e!r}"))
        return {}
    conn.send(("ready", None))
    await asyncio.get_running_loop().run_in_executor(None, start_event.wait)
    t0 = start_time.value
    end = t0 + args["duration"]
    cpu0, wall0, wait0 = resource.getrusage(resource.RUSAGE_SELF), time.monotonic(), runqueue_wait_s("self")
    slow = None
    tasks = [asyncio.create_task(measure_loop_lag(stats, end))]
    if spec.get("slow_session") is not None:
        slow = SlowClient(sessions[spec["slow_session"]], dict(args, t0=t0))
        tasks.append(asyncio.create_task(slow.run(t0 + min(2.0, args["duration"] / 4), end)))
    outcomes = await asyncio.gather(*(c.sculpt(end) for c in clients), return_exceptions=True)
    for client, outcome in zip(clients, outcomes):
        if isinstance(outcome, BaseException):
            failures.append(f"client {client.index}: {outcome!r}")
    deadline = time.monotonic() + DRAIN_TIMEOUT_S
    answered = await asyncio.gather(*(c.answered(deadline) for c in clients))
    unanswered = sum(len(c.pending) for c, ok in zip(clients, answered) if not ok)
    deadline = time.monotonic() + DRAIN_TIMEOUT_S
    saw = await asyncio.gather(*(c.saw_revision(c.session.last_revision, deadline) for c in clients))
    for c, ok in zip(clients, saw):
        if not ok:
            failures.append(f"client {c.index}: last delta seen at revision {c.last_delta_revision}, "
                            f"session {c.session.index} reached {c.session.last_revision}")
    drained = time.monotonic()
    cpu1, wait1 = resource.getrusage(resource.RUSAGE_SELF), runqueue_wait_s("self")
    answered_in_run, sent_in_run = stats.answered, dict(stats.sent)
    for outcome in await asyncio.gather(*tasks, return_exceptions=True):
        if isinstance(outcome, BaseException):
            failures.append(f"slow client: {outcome!r}")
    # What the sessions hold after the run (volume and undo history), to explain the server's RSS.
    session_stats = []
    for c in clients:
        if c.creator and c.closed_unexpectedly is None:
            try:
                stats_result = await c.call("session.stats", {})
                session_stats.append({k: stats_result[k] for k in ("revision", "memory_bytes", "history_bytes")})
            except (RuntimeError, ConnectionError, asyncio.TimeoutError) as e:
                failures.append(f"session.stats of session {c.session.index}: {e!r}")
    if slow is not None and "joined_at_s" in slow.report:
        joined = t0 + slow.report["joined_at_s"]
        after = [(t, n) for t, n in stats.slow_session_clients if t >= joined - 0.5]
        peak = max((n for _, n in after), default=None)
        dropped = next((t for t, n in after if peak is not None and n < peak), None)
        slow.report["dropped_from_session_after_s"] = None if dropped is None else round(dropped - t0, 2)
    stats.closing = True
    for c in clients:
        await c.ws.close()
        await c.reader
    return {
        "clients": len(clients),
        "cpu_s": (cpu1.ru_utime + cpu1.ru_stime) - (cpu0.ru_utime + cpu0.ru_stime),
        "wall_s": drained - wall0,
        "runqueue_wait_s": None if wait0 is None or wait1 is None else wait1 - wait0,
        "drained_at": drained,
        "sent": sent_in_run, "answered": answered_in_run, "unanswered": unanswered,
        "errors": dict(stats.errors), "error_samples": stats.error_samples,
        "notifications": dict(stats.notifications), "anomalies": dict(stats.anomalies),
        "unexpected_closes": dict(stats.unexpected_closes), "failures": failures,
        "dabs_latency": stats.dabs_latency, "dabs_sent": stats.dabs_sent, "delta_latency": stats.delta_latency,
        "dab_delta_latency": stats.dab_delta_latency, "dabs_per_message": stats.dabs_per_message,
        "pointer_events": stats.pointer_events, "stroke_tools": dict(stats.stroke_tools),
        "session_dabs_latency": stats.session_dabs_latency, "session_delta_latency": stats.session_delta_latency,
        "other_latency": dict(stats.other_latency), "send_lag": stats.send_lag, "loop_lag": stats.loop_lag,
        "dabs_applied": stats.dabs_applied, "deltas": stats.deltas, "delta_bytes": stats.delta_bytes,
        "full_buffers": stats.full_buffers, "slow_client": slow.report if slow else None,
        "session_stats": session_stats,
        "dab_applications": sum(len(s.dab_revisions) for s in sessions.values()),
    }


def worker_entry(spec: dict, conn, start_event, start_time):
    """A client process: its sessions' clients on one asyncio loop; the result goes back on conn."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    if spec["client_cpus"]:
        os.sched_setaffinity(0, spec["client_cpus"])
    try:
        result = asyncio.run(worker_main(spec, conn, start_event, start_time))
        if result:
            conn.send(("result", result))
    except Exception as e:  # noqa: BLE001  reported to the parent, which fails the run
        conn.send(("failed", repr(e)))
    finally:
        conn.close()


# ------------------------------------------------------------------------------ the server side

class ServerProcess:
    """`marzipan serve` started by the tool; its stderr lines are kept with their arrival time."""

    def __init__(self, binary: str, threads: int, max_queue_mb, extra, cpus=None):
        command = [binary, "serve", "--port", "0", "--threads", str(threads)]
        if max_queue_mb is not None:
            command += ["--max-queue-mb", str(max_queue_mb)]
        # Every client comes from 127.0.0.1: lift the per-address bounds (issue 12) so that they
        # measure the server, not its defence against one address.
        command += ["--max-connections-per-address", "100000", "--max-creates-per-address-per-minute", "100000"]
        command += extra
        env = {k: v for k, v in os.environ.items() if not k.startswith("MARZIPAN_")}
        try:
            # Pinned before exec, so that every thread it starts inherits the core.
            self.proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                         preexec_fn=(lambda: os.sched_setaffinity(0, cpus)) if cpus else None)
        except OSError as e:
            raise RuntimeError(f"cannot start {binary}: {e.strerror}") from None
        self.log = []
        threading.Thread(target=self._keep_log, daemon=True).start()
        line = self.proc.stdout.readline()
        match = re.fullmatch(r"listening on http://(\S+):(\d+)\n", line)
        if not match:
            self.stop()
            raise RuntimeError(f"{binary} serve: expected 'listening on http://HOST:PORT', got {line!r}; "
                               f"stderr: {''.join(l for _, l in self.log[-5:])}")
        self.url = f"ws://{match.group(1)}:{match.group(2)}/ws"
        self.pid = self.proc.pid

    def _keep_log(self):
        for line in self.proc.stderr:
            self.log.append((time.monotonic(), line.rstrip("\n")))

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode


def runqueue_wait_s(pid) -> float | None:
    """Seconds the threads of process `pid` ("self" too) have spent runnable but waiting for a
    core (/proc/PID/task/TID/schedstat, second field): on a shared machine, the latency that
    is nobody's work. None where the kernel keeps no schedstat."""
    total = 0
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/schedstat") as f:
                total += int(f.read().split()[1])
    except (OSError, IndexError, ValueError):
        return None
    return total / 1e9


class ProcessSampler:
    """VmRSS, VmHWM, CPU seconds and run-queue wait of the server's process, once a second in a thread."""

    def __init__(self, pid):
        self.pid = pid
        self.samples = []  # (monotonic time, rss MiB, hwm MiB, cpu s, run-queue wait s or None)
        self._stop = threading.Event()
        self._thread = None

    def sample(self):
        if self.pid is None:
            return None
        try:
            with open(f"/proc/{self.pid}/status") as f:
                fields = dict(line.split(":", 1) for line in f if ":" in line)
            with open(f"/proc/{self.pid}/stat") as f:
                stat = f.read().rsplit(")", 1)[1].split()
        except OSError:
            return None
        if "VmRSS" not in fields:
            return None  # exited: a zombie has no memory lines
        cpu = (int(stat[11]) + int(stat[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
        kib = lambda name: int(fields[name].split()[0]) / 1024  # noqa: E731
        entry = (time.monotonic(), kib("VmRSS"), kib("VmHWM"), cpu, runqueue_wait_s(self.pid))
        self.samples.append(entry)
        return entry

    def start(self):
        def loop():
            while not self._stop.wait(1.0):
                self.sample()

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()

    def stop(self):
        self._stop.set()
        if self._thread:
            self._thread.join()


def scrape_edit_latency(url: str):
    """The server's marzipan_edit_latency_seconds histogram from /metrics: {le: cumulative count}."""
    http = re.sub(r"^ws", "http", url.split("/ws")[0]) + "/metrics"
    try:
        with urllib.request.urlopen(http, timeout=5) as response:
            text = response.read().decode()
    except OSError:
        return None
    buckets = {}
    for match in re.finditer(r'^marzipan_edit_latency_seconds_bucket\{le="([^"]+)"\} (\d+)$', text, re.M):
        buckets[match.group(1)] = int(match.group(2))
    return buckets


def histogram_summary(before, after):
    """Edits of the run per server-side latency bucket, and p50/p99 as the bucket bounds they fall in."""
    if before is None or after is None:
        return None
    bounds = list(after)
    counts = {le: after[le] - before.get(le, 0) for le in bounds}
    total = counts.get("+Inf", 0)
    summary = {"edits": total, "cumulative": counts}
    for name, p in (("p50_at_most_ms", 0.5), ("p99_at_most_ms", 0.99)):
        bound = next((le for le in bounds if total and counts[le] >= p * total), None)
        if bound == "+Inf":
            summary[name] = f"over {round(float(bounds[-2]) * 1e3)}"
        else:
            summary[name] = None if bound is None else round(float(bound) * 1e3, 1)
    return summary


# ---------------------------------------------------------------------------------------- run

def plan(args):
    """Session ids, clients per session, and which process hosts which sessions (a session's
    clients always share a process, so its token never crosses a process boundary)."""
    sessions = [{"index": s, "id": new_session_id(), "clients": []} for s in range(args.sessions)]
    for c in range(args.clients):
        sessions[c % args.sessions]["clients"].append(c)
    processes = args.processes or min(args.sessions, max(1, math.ceil(args.clients / 16)))
    processes = max(1, min(processes, args.sessions))
    specs = [{"sessions": [s for s in sessions if s["index"] % processes == p]} for p in range(processes)]
    return specs


def receive(conn, timeout: float, what: str):
    """The next message of a client process; a process that died or hangs fails the run."""
    try:
        if conn.poll(timeout):
            return conn.recv()
    except (EOFError, OSError):
        raise RuntimeError(f"a client process ended before it could {what}") from None
    raise RuntimeError(f"a client process did not {what} within {timeout:.0f} s")


def pinned_cpus(args):
    """--pin: (the server's core, the clients' cores) of the cores this process may use, the
    first for the server and the second for every client process; (None, None) without --pin."""
    if not args.pin:
        return None, None
    cores = sorted(os.sched_getaffinity(0))
    if len(cores) < 2:
        raise RuntimeError(f"--pin needs two cores, this process may use {cores}")
    return {cores[0]}, {cores[1]}


class CompiledClients:
    """The sculpting clients in one process of the compiled load client (load_client.cpp), in
    place of the Python client processes: it sets its sessions up and prints "ready", starts on
    a line "start T0" (T0 in time.monotonic()'s clock, the same CLOCK_MONOTONIC as its
    steady_clock) and prints its result as the Python workers return theirs, one JSON line."""

    def __init__(self, binary: str, url: str, specs: list, args, cpus):
        sessions = sorted((s for spec in specs for s in spec["sessions"]), key=lambda s: s["index"])
        command = [binary, "--url", url, "--clients", str(args.clients), "--sessions", ",".join(s["id"] for s in sessions),
                   "--size", str(args.size), "--solid", args.solid, "--seed", str(args.seed),
                   "--duration", str(args.duration), "--dab-spacing", str(args.dab_spacing)]
        try:
            self.proc = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                         preexec_fn=(lambda: os.sched_setaffinity(0, cpus)) if cpus else None)
        except OSError as e:
            raise RuntimeError(f"cannot start {binary}: {e.strerror}") from None
        self.lines = []
        self.arrived = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            with self.arrived:
                self.lines.append(line)
                self.arrived.notify_all()
        with self.arrived:
            self.lines.append(None)
            self.arrived.notify_all()

    def receive(self, timeout: float, what: str):
        with self.arrived:
            if not self.arrived.wait_for(lambda: self.lines, timeout):
                raise RuntimeError(f"the compiled client did not {what} within {timeout:.0f} s")
            line = self.lines.pop(0)
        if line is None:
            raise RuntimeError(f"the compiled client ended (status {self.proc.wait()}) before it could {what}")
        if line.strip() == "ready":
            return "ready", None
        result = json.loads(line)
        for key in ("session_dabs_latency", "session_delta_latency"):  # JSON's keys are strings
            result[key] = {int(k): v for k, v in result[key].items()}
        return "result", result

    def start(self, t0: float):
        self.proc.stdin.write(f"start {t0!r}\n")
        self.proc.stdin.flush()

    def stop(self):
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()


def run(args) -> tuple[dict, int]:
    server_cpus, client_cpus = pinned_cpus(args)
    if client_cpus:
        os.sched_setaffinity(0, client_cpus)  # this process, its sampler and whatever it starts
    server = ServerProcess(args.marzipan, args.threads, args.max_queue_mb, args.server_arg, server_cpus) \
        if args.marzipan else None
    url = server.url if server else args.url
    sampler = ProcessSampler(server.pid if server else args.server_pid)
    specs = plan(args)
    shared = {"url": url, "size": args.size, "solid": args.solid, "rate": args.rate, "duration": args.duration,
              "seed": args.seed, "mode": args.mode, "dab_spacing": args.dab_spacing}
    if args.slow_client:
        specs[0]["slow_session"] = 0
    context = multiprocessing.get_context("spawn")
    start_event, start_time = context.Event(), context.Value("d", 0.0)
    workers = []
    compiled = None
    try:
        if args.client_bin:
            compiled = CompiledClients(args.client_bin, url, specs, args, client_cpus)
            receivers = [compiled.receive]
        else:
            for spec in specs:
                parent_end, child_end = context.Pipe(duplex=False)
                proc = context.Process(target=worker_entry,
                                       args=(dict(spec, args=shared, client_cpus=client_cpus), child_end, start_event,
                                             start_time), daemon=True)
                proc.start()
                child_end.close()
                workers.append((proc, parent_end))
            receivers = [lambda timeout, what, conn=conn: receive(conn, timeout, what) for _, conn in workers]
        failures = []
        for receiver in receivers:
            kind, detail = receiver(SETUP_TIMEOUT_S + 30, "set up its sessions")
            if kind != "ready":
                raise RuntimeError(f"a client process failed: {detail}")
        idle = sampler.sample()
        metrics_before = scrape_edit_latency(url)
        load_before = os.getloadavg()
        sampler.start()
        start_time.value = t0 = time.monotonic() + 0.2
        start_event.set()
        if compiled:
            compiled.start(t0)
        results = []
        for receiver in receivers:
            kind, detail = receiver(args.duration + 2 * DRAIN_TIMEOUT_S + SLOW_CLIENT_DRAIN_S + 60, "finish")
            if kind != "result":
                failures.append(f"client process: {detail}")
            else:
                results.append(detail)
        for proc, _ in workers:
            proc.join(30)
        load_after = os.getloadavg()
        metrics_after = scrape_edit_latency(url)
        # The clients are gone, the sessions stay loaded (until --idle-session-seconds): the
        # memory the server keeps after the load.
        time.sleep(1.0)
        sampler.stop()
        final = sampler.sample()
    finally:
        for proc, _ in workers:
            if proc.is_alive():
                proc.kill()
        if compiled:
            compiled.stop()
        server_status = server.stop() if server else None
    return report(args, specs, results, failures, sampler, idle, final, t0, load_before, load_after,
                  histogram_summary(metrics_before, metrics_after), server, server_status,
                  {"server_cpus": sorted(server_cpus), "client_cpus": sorted(client_cpus)} if args.pin else None)


def merged(results, key):
    out = []
    for r in results:
        out.extend(r[key])
    return out


def counter_sum(results, key):
    total = collections.Counter()
    for r in results:
        total.update(r[key])
    return dict(total)


def report(args, specs, results, failures, sampler, idle, final, t0, load_before, load_after, server_hist,
           server, server_status, pinned) -> tuple[dict, int]:
    failures = failures + [f for r in results for f in r["failures"]]
    drained = max((r["drained_at"] for r in results), default=t0)
    wall = max(drained - t0, 1e-9)
    answered = sum(r["answered"] for r in results)
    sent = counter_sum(results, "sent")
    errors = counter_sum(results, "errors")
    unexpected = counter_sum(results, "unexpected_closes")
    unanswered = sum(r["unanswered"] for r in results)
    dabs_applied = sum(r["dabs_applied"] for r in results)
    client_cpu = sum(r["cpu_s"] for r in results)
    during = [s for s in sampler.samples if s[0] >= t0]
    rss_max = max((s[1] for s in during), default=None)
    server_cpu = server_cpu_s = server_wait = None
    if during and idle:
        last = max((s for s in during if s[0] <= drained), key=lambda s: s[0], default=during[-1])
        server_cpu_s = last[3] - idle[3]
        server_cpu = round(server_cpu_s / max(last[0] - idle[0], 1e-9), 2)
        if last[4] is not None and idle[4] is not None:
            server_wait = round((last[4] - idle[4]) / max(last[0] - idle[0], 1e-9), 2)
    client_waits = [r["runqueue_wait_s"] for r in results]
    client_wait = None if None in client_waits or not results else round(sum(client_waits) / wall, 2)
    dabs_messages = len(merged(results, "dabs_latency"))
    # CPU per stroke.dabs message on each side: what the machine's cores can sustain, whatever
    # else was running (the latencies depend on that, these hardly do).
    per_message = lambda cpu: None if cpu is None or not dabs_messages else round(cpu / dabs_messages * 1e3, 2)  # noqa: E731
    slow = next((r["slow_client"] for r in results if r["slow_client"]), None)
    if slow is not None and server is not None:
        # The server logs the close once the write in flight is done, i.e. after the client
        # reads again; dropped_from_session_after_s tells when it gave up on the client.
        closes = [(t, line) for t, line in server.log if "too far behind" in line]
        slow["close_logged_after_s"] = round(closes[0][0] - t0, 2) if closes else None
        slow["server_log"] = closes[0][1] if closes else None
    per_session = []
    for spec in specs:
        for s in spec["sessions"]:
            dabs = [x for r in results for x in r["session_dabs_latency"].get(s["index"], [])]
            deltas = [x for r in results for x in r["session_delta_latency"].get(s["index"], [])]
            per_session.append({"session": s["index"], "clients": len(s["clients"]),
                                "response_ms": percentiles(dabs), "delta_ms": percentiles(deltas)})
    per_session.sort(key=lambda s: s["session"])
    response = percentiles(merged(results, "dabs_latency"))
    # p99 and max of the responses per second of the run, to tell a spike from a steady tail.
    by_second = collections.defaultdict(list)
    for sent_at, latency in zip(merged(results, "dabs_sent"), merged(results, "dabs_latency")):
        by_second[int(sent_at - t0)].append(latency)
    seconds = [percentiles(by_second[i]) for i in range(max(by_second, default=-1) + 1)]
    delta = percentiles(merged(results, "delta_latency"))
    dab_delta = percentiles(merged(results, "dab_delta_latency"))
    dabs_per_message = merged(results, "dabs_per_message")
    dabs_sent = sum(dabs_per_message)
    pointer_events = sum(r["pointer_events"] for r in results)
    applications = sum(r["dab_applications"] for r in results)
    other = {}
    for r in results:
        for method, values in r["other_latency"].items():
            other.setdefault(method, []).extend(values)
    mb = lambda v: None if v is None else round(v, 1)  # noqa: E731
    out = {
        "clients": args.clients,
        "sessions": args.sessions,
        "size": args.size,
        "solid": args.solid,
        "mode": args.mode,
        "rate_per_client": args.rate if args.mode == "open-loop" else None,
        "dab_spacing": args.dab_spacing if args.mode == "web-client" else None,
        "processes": 1 if args.client_bin else len(specs),
        "client": "compiled" if args.client_bin else "python",
        "server_threads": args.threads if args.marzipan else None,
        "pinned": pinned,
        "duration_s": args.duration,
        "elapsed_s": round(wall, 2),
        "requests": {"sent": sum(sent.values()), "answered": answered, "unanswered": unanswered, "by_method": sent},
        "errors": errors,
        "error_samples": [e for r in results for e in r["error_samples"]][:5],
        "unexpected_closes": unexpected,
        "anomalies": counter_sum(results, "anomalies"),
        "failures": failures[:20],
        "throughput_req_s": round(answered / wall, 1),
        "dabs_messages_per_s": round(dabs_messages / wall, 1),
        "dabs_applied": dabs_applied,
        "dabs_applied_per_s": round(dabs_applied / wall, 1),
        "dabs_per_message": None if not dabs_per_message else
        {"mean": round(dabs_sent / len(dabs_per_message), 2), "max": max(dabs_per_message)},
        "pointer_events": pointer_events if args.mode == "web-client" else None,
        "strokes_by_tool": counter_sum(results, "stroke_tools") if args.mode == "web-client" else None,
        "dabs_per_pointer_event": round(dabs_sent / pointer_events, 3) if args.mode == "web-client" and pointer_events else None,
        "dab_applications": applications,
        "dabs_per_application": None if not applications else round(dabs_applied / applications, 2),
        "latency_ms": {"response": response, "delta": delta, "dab_delta": dab_delta,
                       "response_p99_by_second": [s["p99"] for s in seconds],
                       "response_max_by_second": [s["max"] for s in seconds],
                       "other": {m: percentiles(v) for m, v in sorted(other.items())}},
        "server_edit_latency": server_hist,
        "deltas_received": sum(r["deltas"] for r in results),
        "delta_mb_received": round(sum(r["delta_bytes"] for r in results) / 2**20, 1),
        "full_buffers_received": sum(r["full_buffers"] for r in results),
        "notifications": counter_sum(results, "notifications"),
        "per_session": per_session,
        "server": {
            "pid": sampler.pid,
            "rss_mb_idle": mb(idle[1]) if idle else None,
            "rss_mb_max": mb(rss_max),
            "rss_mb_final": mb(final[1]) if final else None,
            "hwm_mb": mb(final[2]) if final else None,
            "rss_mb_series": [round(s[1], 1) for s in during],
            "sessions_memory_mb": mb(sum(x["memory_bytes"] for r in results for x in r["session_stats"]) / 2**20),
            "sessions_history_mb": mb(sum(x["history_bytes"] for r in results for x in r["session_stats"]) / 2**20),
            "cpu_cores": server_cpu,
            "cpu_ms_per_dabs_message": per_message(server_cpu_s),
            "cpu_ms_per_dab_applied": None if server_cpu_s is None or not dabs_applied else
            round(server_cpu_s / dabs_applied * 1e3, 3),
            "cpu_ms_per_application": None if server_cpu_s is None or not applications else
            round(server_cpu_s / applications * 1e3, 2),
            "runqueue_wait_s_per_s": server_wait,
            "exit_status": server_status,
        },
        "client_side": {
            "cpu_s": round(client_cpu, 2),
            "cpu_cores": round(client_cpu / wall, 2),
            "cpu_cores_per_process": [round(r["cpu_s"] / max(r["wall_s"], 1e-9), 2) for r in results],
            "cpu_ms_per_dabs_message": per_message(client_cpu),
            "runqueue_wait_s_per_s": client_wait,
            "send_lag_ms": percentiles(merged(results, "send_lag")),
            "loop_lag_ms": percentiles(merged(results, "loop_lag")),
        },
        "load_average": {"before": [round(x, 2) for x in load_before], "after": [round(x, 2) for x in load_after]},
        "slow_client": slow,
        "goals": {"zero_errors": not errors and not unexpected and not unanswered and not failures,
                  "p99_target_ms": GOAL_P99_MS,
                  "p99_response_met": response["p99"] is not None and response["p99"] < GOAL_P99_MS,
                  "p99_delta_met": delta["p99"] is not None and delta["p99"] < GOAL_P99_MS,
                  "p99_dab_delta_met": None if args.mode != "web-client" else
                  dab_delta["p99"] is not None and dab_delta["p99"] <= GOAL_P99_MS},
    }
    # The slow client's close is expected and not counted: only the sculpting clients' are.
    ok = (not errors and not unexpected and not unanswered and not failures and dabs_applied > 0
          and server_status in (None, 0))
    if pinned:
        # The capacity figures are what a pinned run is for: a run that could not measure them failed.
        missing = [name for name, value in (("server CPU per dab", out["server"]["cpu_ms_per_dab_applied"]),
                                            ("dab->delta p99", dab_delta["p99"] if args.mode == "web-client" else 0),
                                            ("client CPU", out["client_side"]["cpu_cores"] if results else None))
                   if value is None]
        if missing:
            out["failures"].append("missing figures: " + ", ".join(missing))
            ok = False
    return out, 0 if ok else 1


def summary(out: dict) -> str:
    r, d, s, c = out["latency_ms"]["response"], out["latency_ms"]["delta"], out["server"], out["client_side"]
    pace = (f"at {out['rate_per_client']} dab messages/s each" if out["mode"] == "open-loop" else
            "like the web client (60 Hz pointer, "
            + (f"dabs {out['dab_spacing']} of the radius apart" if out["dab_spacing"] else "a ray dab per pointer event")
            + f" ({out['dabs_per_pointer_event']} per event), <= 3 messages in flight)")
    lines = [
        f"{out['clients']} clients on {out['sessions']} sessions of {out['size']}^3 {out['solid']}, "
        f"{out['duration_s']} s {pace}, {out['processes']} client processes",
        f"requests {out['requests']['answered']} answered ({out['throughput_req_s']}/s), "
        f"{out['dabs_applied']} dabs applied ({out['dabs_applied_per_s']}/s), errors {out['errors'] or 0}, "
        f"unexpected closes {out['unexpected_closes'] or 0}, unanswered {out['requests']['unanswered']}",
        f"stroke.dabs response p50 {r['p50']} / p99 {r['p99']} / max {r['max']} ms; "
        f"its splat delta p50 {d['p50']} / p99 {d['p99']} / max {d['max']} ms ({out['deltas_received']} deltas)",
        *([f"dab->delta p50 {dd['p50']} / p99 {dd['p99']} / max {dd['max']} ms over {dd['n']} dabs, "
           f"{out['dabs_per_message']['mean']} dabs per message, {out['dabs_per_application']} per application"]
          if (dd := out["latency_ms"]["dab_delta"])["n"] and out["dabs_per_message"] else []),
        f"server RSS idle {s['rss_mb_idle']} MiB, max {s['rss_mb_max']}, final {s['rss_mb_final']} "
        f"(undo history {s['sessions_history_mb']})",
        f"CPU: server {s['cpu_cores']} cores ({s['cpu_ms_per_dabs_message']} ms per dabs message, "
        f"{s['cpu_ms_per_dab_applied']} per dab applied, {s['cpu_ms_per_application']} per application), clients "
        f"{c['cpu_cores']} cores ({c['cpu_ms_per_dabs_message']} ms; per process {c['cpu_cores_per_process']}), "
        f"client loop lag p99 {c['loop_lag_ms']['p99']} ms",
        f"waiting for a core (s per s): server {s['runqueue_wait_s_per_s']}, clients {c['runqueue_wait_s_per_s']}",
        *([f"pinned: server on cores {out['pinned']['server_cpus']} (--threads {out['server_threads']}), "
           f"{out['client']} clients on {out['pinned']['client_cpus']}: server {s['cpu_cores']} of its core, "
           f"{s['cpu_ms_per_dab_applied']} ms CPU per dab; dab->delta p50 {out['latency_ms']['dab_delta']['p50']} / "
           f"p99 {out['latency_ms']['dab_delta']['p99']} ms; clients {c['cpu_cores']} of theirs"]
          if out["pinned"] else []),
        f"load average before {out['load_average']['before'][0]}, after {out['load_average']['after'][0]}",
    ]
    if out["slow_client"]:
        sc = out["slow_client"]
        lines.append(f"slow client in session {sc['session']}: joined at {sc.get('joined_at_s')} s, dropped from "
                     f"its session at {sc.get('dropped_from_session_after_s')} s, closed {sc.get('close_code')} "
                     f"{sc.get('close_reason')!r}")
    if out["failures"]:
        lines.append("failures: " + "; ".join(out["failures"][:3]))
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    target = p.add_mutually_exclusive_group(required=True)
    target.add_argument("--marzipan", help="the marzipan binary: the tool starts and stops its own server")
    target.add_argument("--url", help="a running server's WebSocket URL (ws://HOST:PORT/ws)")
    p.add_argument("--server-pid", type=int, help="with --url: the server's pid, for its memory and CPU")
    p.add_argument("--clients", type=int, default=64, help="sculpting clients (default %(default)s)")
    p.add_argument("--sessions", type=int, default=16, help="sessions (default %(default)s)")
    p.add_argument("--duration", type=float, default=60.0, help="seconds of sculpting (default %(default)s)")
    p.add_argument("--mode", choices=("open-loop", "web-client"), default="open-loop",
                   help="open-loop: stroke.dabs at --rate whatever happens; web-client: a 60 Hz pointer whose "
                        "picks are spaced into dabs as the browser does, merged into messages, at most 3 in "
                        "flight (default %(default)s)")
    p.add_argument("--dab-spacing", type=float, default=DAB_SPACING,
                   help="web-client: dabs this fraction of the brush radius apart along the picked path, as the "
                        "browser spaces them (web-client/ui/sculpt.js); 0: one `ray` dab per pointer event "
                        "(default %(default)s)")
    p.add_argument("--rate", type=float, default=20.0,
                   help="open-loop: stroke.dabs messages per second per client (default %(default)s)")
    p.add_argument("--size", type=int, default=128, help="grid side of each session (default %(default)s)")
    p.add_argument("--solid", default="pig", choices=("pig", "sphere"), help="starting solid (default %(default)s)")
    p.add_argument("--processes", type=int, default=0,
                   help="client processes, 0 = one per 16 clients, at most one per session (default %(default)s)")
    p.add_argument("--slow-client", action="store_true", help="add a client in session 0 that stops reading")
    p.add_argument("--threads", type=int,
                   help="--threads of the server started (default 2, with --pin 1: the server has one core)")
    p.add_argument("--pin", action="store_true",
                   help="capacity per server core: the server started on the first core this process may use, "
                        "every client process on the second")
    p.add_argument("--client-bin",
                   help="web-client mode: the compiled load client (build/tests/load/marzipan-load-client) "
                        "instead of the Python client processes")
    p.add_argument("--max-queue-mb", type=int, help="--max-queue-mb of the server started (default: the server's)")
    p.add_argument("--server-arg", action="append", default=[], help="a further argument for `marzipan serve`")
    p.add_argument("--seed", type=int, default=1, help="seed of the strokes (default %(default)s)")
    p.add_argument("--json", help="write the JSON object to this file instead of stdout")
    args = p.parse_args(argv)
    if args.clients < args.sessions or args.sessions < 1:
        p.error("need at least one session and one client per session")
    if args.rate <= 0 or args.duration <= 0:
        p.error("--rate and --duration must be positive")
    if not 0 <= args.dab_spacing <= 4:
        p.error("--dab-spacing must be in [0, 4]")
    if args.marzipan is None and (args.max_queue_mb is not None or args.server_arg or args.pin):
        p.error("--max-queue-mb, --server-arg and --pin need --marzipan")
    if args.client_bin and (args.mode != "web-client" or args.slow_client):
        p.error("--client-bin sculpts like the web client (--mode web-client), without --slow-client")
    if args.threads is None:
        args.threads = 1 if args.pin else 2
    try:
        out, status = run(args)
    except RuntimeError as e:
        print(f"marzipan_load: {e}", file=sys.stderr)
        return 1
    text = json.dumps(out, separators=(",", ":"))
    if args.json:
        Path(args.json).write_text(text + "\n")
    else:
        print(text)
    print(summary(out), file=sys.stderr)
    if status:
        print("marzipan_load: FAILED (errors, unexpected closes, unanswered requests, missing deltas, "
              "or no dab applied)", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
