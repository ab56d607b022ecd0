"""What the durability tests share: `marzipan serve` processes, a reference server that keeps a
twin of the session in memory, and a seeded editing workload.

The twin is how "the right digest" is known for every revision, including one whose response was
lost: every edit the durable server acknowledges is replayed on a second `marzipan serve`
without --data-dir, and the two must agree on result, revision and digest; after a crash or a
refused write, the recovered session must equal the twin (plus the in-flight edit, when the
crash test finds it applied). Digests of the durable side come from its own session.changed
notifications, so a wrong digest is caught there and not taken on trust from the twin.

Conventions: every wait is bounded; every process started here is killed when its test ends
(Server.stop in a finally); a failed check raises AssertionError saying what was expected and
what came; randomness comes only from the random.Random the caller seeds; coordinates in vu of
the session's grid (PROTOCOL.md).
"""

import asyncio
import os
import queue
import random
import re
import resource
import signal
import subprocess
import sys
import threading
import time
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "protocol", "python"))

from marzipan import Client  # noqa: E402  (the path above makes this checkout's package importable)
from marzipan import tools as registry  # noqa: E402
from marzipan.rpc import ConnectionClosed, RpcError  # noqa: E402

STORAGE_FAILED = -32000  # PROTOCOL.md: a change that could not be journaled is refused with it
HELD_ELSEWHERE = -32015
NOTHING_TO_UNDO = -32012
STORAGE_MESSAGE = "could not be stored"  # hub.cpp's persist(): what a refused write says
REQUEST_TIMEOUT = 20.0  # seconds; an edit of these small grids takes milliseconds
# The methods that may change the volume; one did when its result's roi is not null (undo and
# redo have none: they always change).
CHANGES = {"tool.apply", "stroke.dabs", "volume.morph", "history.undo", "history.redo", "volume.load"}


class Server:
    """One `marzipan serve --port 0` process; its stderr is kept (printed when a check fails).

    `fsize` sets RLIMIT_FSIZE on the process right after it starts, before any session exists
    (the server writes no file until a session is created or loaded): preexec_fn is not safe
    once this process has threads, and it has (the log readers). Only the soft limit, which is
    the one enforced: lift_fsize() raises it again, which a hard limit would forbid."""

    def __init__(self, binary, name, data_dir=None, server_id=None, fsize=None, threads=2):
        self.name = name
        # The client sends one request at a time as fast as answers come, above the default
        # per-connection rate on a fast machine: a -32005 would be a false failure here.
        args = [binary, "serve", "--port", "0", "--threads", str(threads), "--max-requests-per-second", "1000000"]
        if data_dir is not None:
            args += ["--data-dir", str(data_dir)]
        if server_id is not None:
            args += ["--server-id", server_id]
        self.log = []
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
        if fsize is not None:
            resource.prlimit(self.proc.pid, resource.RLIMIT_FSIZE, (fsize, resource.RLIM_INFINITY))
        lines = queue.Queue()
        threading.Thread(target=self._pump, args=(self.proc.stdout, lines), daemon=True).start()
        threading.Thread(target=self._pump, args=(self.proc.stderr, None), daemon=True).start()
        try:
            first = lines.get(timeout=15)
        except queue.Empty:
            first = None
        match = re.match(r"listening on http://127\.0\.0\.1:(\d+)", first or "")
        if not match:
            self.stop()
            raise AssertionError(f"{name}: expected 'listening on http://127.0.0.1:PORT', got {first!r}; "
                                 f"log:\n{self.log_text()}")
        self.port = int(match.group(1))
        self.url = f"ws://127.0.0.1:{self.port}/ws"

    def _pump(self, stream, lines):
        for line in stream:
            if lines is not None:
                lines.put(line)
            else:
                self.log.append(line.rstrip("\n"))
        if lines is not None:
            lines.put(None)

    def log_text(self):
        return "\n".join(f"  [{self.name}] {line}" for line in self.log[-80:])

    def lift_fsize(self):
        resource.prlimit(self.proc.pid, resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))

    def alive(self):
        return self.proc.poll() is None

    def healthy(self):
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{self.port}/healthz", timeout=5) as r:
                return r.status == 200 and r.read() == b"ok"
        except OSError:
            return False

    def kill(self):
        """SIGKILL: the process gets no chance to snapshot, release leases or flush anything."""
        if self.alive():
            self.proc.send_signal(signal.SIGKILL)
        return self.proc.wait(timeout=15)

    def terminate(self):
        """SIGTERM, the orderly stop; returns the exit status."""
        if self.alive():
            self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=60)

    def stop(self):
        if self.alive():
            self.proc.kill()
        self.proc.wait(timeout=15)


async def connect(server, session=None):
    return await Client.connect(server.url, session=session, request_timeout=REQUEST_TIMEOUT)


def changed(step, result):
    """Whether an acknowledged step changed the volume (and a session.changed follows)."""
    return step.method in CHANGES and result.get("roi", "none given") is not None


async def changed_digest(client, revision):
    """The digest in this client's session.changed for `revision` (each edit is followed by
    one, after its response); None when the connection closed first (a kill)."""
    while True:
        try:
            update = await client.next_update(timeout=REQUEST_TIMEOUT)
        except asyncio.TimeoutError:
            raise AssertionError(f"no session.changed for revision {revision} within {REQUEST_TIMEOUT} s") from None
        if update is None:
            return None
        if getattr(update, "method", None) == "session.changed" and update.params["revision"] == revision:
            return update.params["digest"]


class Step:
    """One request of the workload. `stroke` marks params that name the open stroke: each side
    has its own stroke ids, filled in when the step is sent."""

    def __init__(self, method, params=None, upload=None, stroke=False):
        self.method = method
        self.params = params or {}
        self.upload = upload
        self.stroke = stroke

    def describe(self):
        params = dict(self.params)
        if self.upload is not None:
            params["<upload bytes>"] = len(self.upload)
        return f"{self.method} {params}"


class Outcome:
    """What the durable server answered to one step: `result` (acknowledged), `error`
    (refused: an RpcError) or neither (the connection died first: in flight)."""

    def __init__(self, result=None, error=None, digest=None):
        self.result = result
        self.error = error
        self.digest = digest


class Mirror:
    """The durable session and its twin on the reference server, edited in lock step.

    `revision`/`digest` are the last acknowledged ones; `history` maps every acknowledged
    revision to its digest. Each side's open stroke id is kept: the workload's stroke steps
    name the stroke by role, not by number. Once the two are known to differ (lose_twin), the
    durable side goes on alone, its digests from its own notifications: what it acknowledges
    after a failed check must still survive a restart.

    `history_cut`: the durable session was recovered (session_store.hpp): its undo history
    reaches back only to the last snapshot, undo or redo in its journal, while the twin keeps
    all of it. From then on can_undo/can_redo are not compared, and an
    undo or redo the durable side refuses with -32012 is not asked of the twin; every undo or
    redo it does carry out still must match the twin's digest."""

    def __init__(self, durable, reference, revision, digest):
        self.durable = durable
        self.reference = reference
        self.revision = revision
        self.digest = digest
        self.history = {revision: digest}
        self.stroke_durable = None
        self.stroke_reference = None
        self.saved = []  # .mzv files from volume.save, for later volume.load
        self.latencies = []  # seconds from request to response on the durable server
        self.twin_lost = False
        self.history_cut = False
        self.acknowledged = 0
        self.refused = 0

    def _params(self, step, stroke):
        params = dict(step.params)
        if step.stroke:
            params["stroke"] = stroke if stroke is not None else 1_000_000  # no such stroke: both refuse
        return params

    async def send_durable(self, step):
        """Sends one step to the durable server only; never raises for the server's answers."""
        started = time.monotonic()
        try:
            result, frame = await self.durable.call(step.method, self._params(step, self.stroke_durable),
                                                    upload=step.upload)
        except RpcError as e:
            return Outcome(error=e)
        except ConnectionClosed:
            return Outcome()
        self.latencies.append(time.monotonic() - started)
        if step.method == "stroke.begin":
            self.stroke_durable = result["stroke"]
        elif step.method == "stroke.end":
            self.stroke_durable = None
        if step.method == "volume.save":
            self.saved.append(bytes(frame.payload))
        digest = None
        if changed(step, result):
            digest = await changed_digest(self.durable, result["revision"])
        return Outcome(result=result, digest=digest)

    async def mirror(self, step, outcome):
        """Replays an acknowledged (or found-applied) step on the twin and checks that both
        agree; returns the twin's digest of the new revision."""
        try:
            result, frame = await self.reference.call(step.method, self._params(step, self.stroke_reference),
                                                      upload=step.upload)
        except RpcError as e:
            raise AssertionError(f"{step.describe()}: the durable server acknowledged {outcome.result}, "
                                 f"the reference refused it: {e.code} {e.message}") from None
        if step.method == "stroke.begin":
            self.stroke_reference = result["stroke"]
        elif step.method == "stroke.end":
            self.stroke_reference = None
        for key in self._compared(("revision", "roi", "applied", "hit", "can_undo", "can_redo")):
            if outcome.result is not None and key in result and outcome.result.get(key) != result[key]:
                raise AssertionError(f"{step.describe()}: {key} {outcome.result.get(key)} on the durable server, "
                                     f"{result[key]} on the reference")
        if not changed(step, result):
            return None
        return await changed_digest(self.reference, result["revision"])

    def _compared(self, keys):
        return [k for k in keys if not (self.history_cut and k in ("can_undo", "can_redo"))]

    def lose_twin(self):
        self.twin_lost = True
        self.stroke_reference = None

    async def step(self, step):
        """Sends a step to the durable server and, when it is acknowledged, to the twin; returns
        the Outcome. A refusal is checked against the twin unless it is a storage failure
        (-32000), which the twin cannot have."""
        outcome = await self.send_durable(step)
        if outcome.result is not None:
            await self.acknowledge(step, outcome)
        elif outcome.error is not None and outcome.error.code == STORAGE_FAILED:
            self.refused += 1
            await self.end_reference_stroke()
        elif outcome.error is not None and not self.twin_lost:
            if not (self.history_cut and outcome.error.code == NOTHING_TO_UNDO):
                await self.expect_same_refusal(step, outcome.error)
        return outcome

    async def acknowledge(self, step, outcome):
        self.acknowledged += 1
        revision = outcome.result.get("revision") if isinstance(outcome.result, dict) else None
        if self.twin_lost:
            if outcome.digest is not None:
                self.revision, self.digest = revision, outcome.digest
                self.history[revision] = outcome.digest
            return
        twin = await self.mirror(step, outcome)
        if twin is None or revision is None:
            return
        if outcome.digest is not None and outcome.digest != twin:
            raise AssertionError(f"{step.describe()}: revision {revision} has digest {outcome.digest} on the "
                                 f"durable server, {twin} on the reference (same edits, same order)")
        self.revision = revision
        self.digest = twin
        self.history[revision] = twin

    async def expect_same_refusal(self, step, error):
        try:
            result, _ = await self.reference.call(step.method, self._params(step, self.stroke_reference),
                                                  upload=step.upload)
        except RpcError as e:
            if e.code != error.code:
                raise AssertionError(f"{step.describe()}: refused with {error.code} by the durable server, "
                                     f"{e.code} by the reference") from None
            return
        raise AssertionError(f"{step.describe()}: refused by the durable server ({error.code} {error.message}), "
                             f"acknowledged by the reference ({result})")

    async def adopt(self, step, revision, digest):
        """The durable server recovered `revision` = the last acknowledged one + 1: the step whose
        response the crash swallowed was applied and journaled. The twin applies it too and must
        land on exactly that revision and digest."""
        try:
            result, _ = await self.reference.call(step.method, self._params(step, self.stroke_reference),
                                                  upload=step.upload)
        except RpcError as e:
            raise AssertionError(f"recovered revision {revision}, one past the last acknowledged, but the in-flight "
                                 f"{step.describe()} is refused by the reference: {e.code} {e.message}") from None
        if step.method == "stroke.begin":
            self.stroke_reference = result["stroke"]
        elif step.method == "stroke.end":
            self.stroke_reference = None
        if result.get("revision") != revision:
            raise AssertionError(f"recovered revision {revision}, but the in-flight {step.describe()} takes the "
                                 f"reference to revision {result.get('revision')}")
        twin = await changed_digest(self.reference, revision)
        if twin != digest:
            raise AssertionError(f"recovered revision {revision} has digest {digest}; the in-flight "
                                 f"{step.describe()} gives {twin} on the reference")
        self.revision = revision
        self.digest = digest
        self.history[revision] = digest

    async def end_reference_stroke(self):
        """The durable session lost its open stroke (a restart or a rolled-back write ends every
        stroke, folding its dabs into one undo step): the twin ends its own the same way."""
        if self.stroke_reference is not None and not self.twin_lost:
            await self.reference.call("stroke.end", {"stroke": self.stroke_reference})
            self.stroke_reference = None
        self.stroke_durable = None

    async def compare_state(self, what):
        """session.stats of both sides: revision, digest, can_undo and can_redo must agree."""
        durable, _ = await self.durable.call("session.stats", {})
        if self.twin_lost:
            twin = {"revision": self.revision, "digest": self.digest, "can_undo": durable["can_undo"],
                    "can_redo": durable["can_redo"]}
        else:
            twin, _ = await self.reference.call("session.stats", {})
        for key in self._compared(("revision", "digest", "can_undo", "can_redo")):
            if durable[key] != twin[key]:
                raise AssertionError(f"{what}: {key} is {durable[key]} on the durable server, {twin[key]} on the "
                                     f"reference (last acknowledged revision {self.revision})")
        return durable

    async def walk_back(self, steps, what):
        """Undoes up to `steps` steps on both sides comparing digests at each: the history
        survived too, not only the newest volume. Then redoes them all, back where it was."""
        undone = 0
        if self.twin_lost:
            return undone
        for _ in range(steps):
            outcome = await self.step(Step("history.undo"))
            if outcome.result is None:
                break
            undone += 1
        for _ in range(undone):
            await self.step(Step("history.redo"))
        await self.compare_state(f"{what}, after {undone} undos and as many redos")
        return undone


class Workload:
    """A seeded editing gesture generator over a grid of `dims`: brushes by centre and by ray,
    CSG, strokes with and without symmetry (one request per dab batch), morphology, global
    smoothing, undo/redo, volume.save and a later volume.load of a saved file."""

    # The tools applied by centre or ray with a radius and strength, and stroked: the registry's
    # surface-speed tools.
    TOOLS = tuple(t["name"] for t in registry.TOOLS if t["kind"] == "surface_speed" and t["strokes"])

    def __init__(self, rng: random.Random, dims, mirror: Mirror):
        self.rng = rng
        self.dims = dims
        self.mirror = mirror

    def _point(self, margin=0.25):
        return [round(self.rng.uniform(margin * n, (1 - margin) * n), 3) for n in self.dims]

    def _ray(self):
        centre = [n / 2 for n in self.dims]
        direction = [self.rng.uniform(-1, 1) for _ in range(3)]
        if all(abs(d) < 1e-3 for d in direction):
            direction = [0.0, 0.0, 1.0]
        reach = 2 * max(self.dims)
        origin = [round(c - reach * d, 3) for c, d in zip(centre, direction)]
        target = self._point(0.35)
        return {"origin": origin, "direction": [round(t - o, 3) for t, o in zip(target, origin)]}

    def _dab(self):
        dab = {"ray": self._ray()} if self.rng.random() < 0.5 else {"center": self._point()}
        if self.rng.random() < 0.5:
            dab["pressure"] = round(self.rng.uniform(0.2, 1.0), 3)
        return dab

    def gesture(self, allow_load=True, allow_history=True):
        """The next gesture: a list of Steps sent one after the other. Without history, no
        undo/redo (whose step files are the largest writes) and no volume.load."""
        r = self.rng.random() if allow_history else self.rng.uniform(0.0, 0.66)
        if r < 0.30:
            params = {"tool": self.rng.choice(self.TOOLS), "radius": round(self.rng.uniform(2, 6), 3),
                      "strength": round(self.rng.uniform(0.2, 1.0), 3)}
            if self.rng.random() < 0.5:
                params["ray"] = self._ray()
            else:
                params["center"] = self._point()
            return [Step("tool.apply", params)]
        if r < 0.52:
            symmetry = [a for a in "xyz" if self.rng.random() < 0.35]
            begin = {"tool": self.rng.choice(self.TOOLS), "radius": round(self.rng.uniform(2, 5), 3),
                     "strength": round(self.rng.uniform(0.2, 1.0), 3)}
            if symmetry:
                begin["symmetry"] = symmetry
            steps = [Step("stroke.begin", begin)]
            for _ in range(self.rng.randint(1, 4)):
                dabs = [self._dab() for _ in range(self.rng.randint(1, 6))]
                steps.append(Step("stroke.dabs", {"dabs": dabs}, stroke=True))
            steps.append(Step("stroke.end", {}, stroke=True))
            return steps
        if r < 0.58:
            shape = self.rng.choice(("sphere", "box", "cylinder"))
            params = {"tool": self.rng.choice(("csg_add", "csg_subtract")), "shape": shape,
                      "center": self._point(), "radius": round(self.rng.uniform(1.5, 4), 3)}
            if shape == "cylinder":
                params["axis"] = self.rng.choice("xyz")
            return [Step("tool.apply", params)]
        if r < 0.64:
            return [Step("volume.morph", {"kind": self.rng.choice(("erode", "dilate", "open", "close")),
                                          "radius": round(self.rng.uniform(0.3, 1.2), 3)})]
        if r < 0.66:
            return [Step("tool.apply", {"tool": "smooth", "global": True, "iterations": self.rng.randint(1, 2),
                                        "strength": round(self.rng.uniform(0.3, 1.0), 3)})]
        if r < 0.80:
            return [Step("history.undo")]
        if r < 0.90:
            return [Step("history.redo")]
        if r < 0.95 or not allow_load or not self.mirror.saved:
            return [Step("volume.save")]
        data = self.rng.choice(self.mirror.saved)
        return [Step("volume.load", {"bytes": len(data)}, upload=data)]


def session_dir(data_dir, session):
    return os.path.join(str(data_dir), "sessions", session)


def listing(directory):
    """{name: content} of the files directly in a directory, for before/after checks."""
    out = {}
    for name in sorted(os.listdir(directory)):
        path = os.path.join(directory, name)
        if os.path.isfile(path):
            with open(path, "rb") as f:
                out[name] = f.read()
    return out


def new_session_id(rng: random.Random):
    alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_"
    return "".join(rng.choice(alphabet) for _ in range(22))
