"""An asyncio client of a Marzipan server (protocol/PROTOCOL.md is the contract).

One Client owns one WebSocket to `ws://HOST:PORT/ws?session=ID`. A background task reads every
message: responses resolve the request that waits for them, binary frames that answer a request
(they arrive before its response and carry its id) are handed to it with the response, and
notifications and pushed frames (request id 0) go to the update queue that `updates()` reads.

Conventions: coordinates and lengths in vu of the session's grid, y up; binary integers
little-endian (frames.py); request ids are integers in [1, 2^32 - 1]; results are the server's
JSON objects as dicts; binary answers are bytes. Errors from the server raise an RpcError
subclass named after its code (rpc.py), a closed socket raises ConnectionClosed, a message that
breaks the contract raises ProtocolError. Needs websockets 10.4 or later (Debian 12's
python3-websockets).
"""

from __future__ import annotations

import asyncio
import collections
import os
import secrets
import urllib.parse

import websockets

from .frames import FrameError, FrameKind, decode_frame, encode_frame
from .rpc import (
    ConnectionClosed,
    MarzipanError,
    Notification,
    ProtocolError,
    RequestIds,
    SessionHeldElsewhere,
    encode_request,
    error_from_response,
    parse_message,
)
from .splats import decode_splats

# websockets refuses incoming messages over 1 MiB by default; the server sends frames (up to
# 4096 x 4096 PNGs), meshes and volume files far larger, up to its max_binary_bytes (256 MiB by
# default) and beyond for meshes. 1 GiB covers them; a larger file needs a larger max_size.
DEFAULT_MAX_MESSAGE_BYTES = 1 << 30
# Updates the client keeps while nobody reads them; beyond this the oldest are dropped and
# counted in Client.dropped_updates.
DEFAULT_MAX_UPDATES = 4096

# The binary frame kinds that may answer each binary-answered method.
_ANSWER_KINDS = {
    "render.frame": {"jpeg": FrameKind.FRAME_JPEG, "png": FrameKind.FRAME_PNG},
    "mesh.export": {"stl": FrameKind.MESH_STL, "obj": FrameKind.MESH_OBJ, "ply": FrameKind.MESH_PLY,
                    "glb": FrameKind.MESH_GLB},
}
_SESSION_ID_CHARS = 22  # 132 random bits in base64url, as PROTOCOL.md proposes


class ConnectFailed(MarzipanError):
    """The WebSocket could not be opened (no server, or the handshake was refused)."""


def new_session_id() -> str:
    """22 random base64url characters: an id for session.create to propose."""
    return secrets.token_urlsafe(_SESSION_ID_CHARS * 3 // 4)[:_SESSION_ID_CHARS]


def session_url(url: str, session: str) -> str:
    """`url` as a WebSocket URL of the /ws endpoint with `?session=` set.

    Accepts ws://, wss://, http:// and https:// (mapped to ws and wss); an empty path or "/"
    becomes /ws, any other path is kept.
    """
    parts = urllib.parse.urlsplit(url)
    scheme = {"http": "ws", "https": "wss"}.get(parts.scheme, parts.scheme)
    if scheme not in ("ws", "wss"):
        raise ValueError(f"{url!r} is not a ws://, wss://, http:// or https:// URL")
    path = parts.path if parts.path not in ("", "/") else "/ws"
    query = [(k, v) for k, v in urllib.parse.parse_qsl(parts.query) if k != "session"]
    query.append(("session", session))
    return urllib.parse.urlunsplit((scheme, parts.netloc, path, urllib.parse.urlencode(query), ""))


def _point(value, what: str) -> list:
    seq = list(value)
    if len(seq) != 3:
        raise ValueError(f"{what} needs 3 coordinates, got {len(seq)}")
    return seq


def _ray(value) -> dict:
    """A ray param from {"origin", "direction"} or an (origin, direction) pair."""
    if isinstance(value, dict):
        return value
    origin, direction = value
    return {"origin": _point(origin, "ray origin"), "direction": _point(direction, "ray direction")}


def _dab(value) -> dict:
    """A dab from a dict ({"center" | "ray", "pressure"?}) or a bare centre [x, y, z]."""
    if isinstance(value, dict):
        dab = dict(value)
        if "ray" in dab:
            dab["ray"] = _ray(dab["ray"])
        return dab
    return {"center": _point(value, "dab centre")}


def _color(value, what: str) -> list:
    """[r, g, b] (three integers 0..255, which the server checks) as a list."""
    seq = list(value)
    if len(seq) != 3:
        raise ValueError(f"{what} needs 3 channels [r, g, b], got {len(seq)}")
    return seq


def _without_none(**params) -> dict:
    return {k: v for k, v in params.items() if v is not None}


class _Pending:
    __slots__ = ("method", "future", "frame", "kinds")

    def __init__(self, method: str, future: asyncio.Future, kinds):
        self.method = method
        self.future = future
        self.frame = None
        self.kinds = kinds  # frame kinds that may answer it; None: no binary answer


class _Connect:
    """What Client.connect returns: await it for a Client, or use it as `async with`."""

    def __init__(self, factory):
        self._factory = factory
        self._client = None

    def __await__(self):
        return self._factory().__await__()

    async def __aenter__(self) -> "Client":
        self._client = await self._factory()
        return self._client

    async def __aexit__(self, *exc):
        await self._client.close()


class Client:
    """A connection to a Marzipan server. Make one with `await Client.connect(url)`."""

    def __init__(self, url: str, route: str, max_size: int | None, max_updates: int,
                 request_timeout: float | None, open_timeout: float | None):
        self.url = url
        self.max_size = max_size
        self.request_timeout = request_timeout
        self.open_timeout = open_timeout
        self.dropped_updates = 0
        # What the server told about the session this connection is in (None when in none).
        self.session = None
        self.token = None
        self.view_token = None
        self.client_id = None
        self.read_only = None
        self.limits = {}
        self.protocol = None
        self.base_color = None  # [r, g, b] of unpainted clay, from session.create/join (protocol 1.7)
        self.revision = None  # the newest revision seen in a result, notification or frame
        # The other clients' newest presence by client id ({client, name, color, brush?,
        # camera?}), kept from `presence` notifications; a client is removed on its `gone`.
        self.others: dict[int, dict] = {}
        self._route = route  # the session id in the connection's URL
        self._route_used = False  # a session was created or joined under _route
        self._ws = None
        self._reader = None
        self._ids = RequestIds()
        self._pending: dict[int, _Pending] = {}
        self._send_lock = asyncio.Lock()
        self._updates = collections.deque()
        self._max_updates = max_updates
        self._updates_changed = asyncio.Event()
        self._closed: ConnectionClosed | None = None

    # ----------------------------------------------------------------------------- connecting

    @classmethod
    def connect(cls, url: str, *, session: str | None = None, max_size: int | None = DEFAULT_MAX_MESSAGE_BYTES,
                max_updates: int = DEFAULT_MAX_UPDATES, request_timeout: float | None = None,
                open_timeout: float | None = 10) -> _Connect:
        """Opens `url` (ws://HOST:PORT, or its /ws path) with `?session=` set to `session`, the
        session to join, or to a new random id that create_session will propose.

        `max_size` bounds one incoming message (None: no bound); `request_timeout` bounds the
        wait for each response in seconds (None: wait as long as the server works).
        """

        async def make() -> Client:
            client = cls(url, session or new_session_id(), max_size, max_updates, request_timeout, open_timeout)
            await client._open()
            return client

        return _Connect(make)

    async def _open(self):
        target = session_url(self.url, self._route)
        try:
            ws = await websockets.connect(
                target,
                max_size=self.max_size,
                open_timeout=self.open_timeout,
                # The server pings every ping_seconds and websockets answers; client pings would
                # only add a way to close during a long edit.
                ping_interval=None,
                # Frames are JPEG/PNG already; deflating them costs CPU on both sides for nothing.
                compression=None,
            )
        except websockets.exceptions.InvalidStatusCode as e:
            raise ConnectFailed(f"{target}: the server answered HTTP {e.status_code}, not a WebSocket") from None
        except (OSError, asyncio.TimeoutError, websockets.exceptions.InvalidHandshake) as e:
            raise ConnectFailed(f"{target}: {e}") from None
        self._ws = ws
        self._closed = None
        self._reader = asyncio.create_task(self._read(ws))

    async def _reopen(self, route: str):
        """Reconnects under another session id, for create and join: a load balancer routes
        on it. Only done outside a session, where a connection has no state to lose."""
        await self._shutdown()
        self._route = route
        self._route_used = False
        await self._open()

    async def _shutdown(self):
        ws, reader = self._ws, self._reader
        self._ws = self._reader = None
        if ws is not None:
            await ws.close()
        if reader is not None:
            await reader
        self._fail_pending(ConnectionClosed(1000, "closed by the client"))

    async def close(self):
        """Closes the connection (the server treats it as session.leave); idempotent."""
        await self._shutdown()
        self._set_closed(ConnectionClosed(1000, "closed by the client"))

    async def __aenter__(self):
        return self

    async def __aexit__(self, *exc):
        await self.close()

    @property
    def closed(self) -> bool:
        return self._closed is not None

    # --------------------------------------------------------------------------------- reading

    async def _read(self, ws):
        failure = None
        try:
            async for message in ws:
                if isinstance(message, str):
                    self._on_text(message)
                else:
                    self._on_binary(message)
        except websockets.exceptions.ConnectionClosed:
            pass
        except Exception as e:  # noqa: BLE001  a broken contract (or a bug here): no reply will come
            failure = e if isinstance(e, ProtocolError) else ProtocolError(f"reading the server's messages: {e!r}")
            await ws.close(1002, "protocol error")
        if ws is not self._ws:
            return  # a deliberate shutdown or reopen: it settles the pending requests itself
        closed = ConnectionClosed(ws.close_code or 1006, ws.close_reason or "")
        self._fail_pending(failure or closed)
        self._set_closed(closed)

    def _on_text(self, text: str):
        message = parse_message(text)
        if isinstance(message, Notification):
            if message.method == "session.changed":
                self._see_revision(message.params.get("revision"))
            elif message.method == "presence":
                self._see_presence(message.params)
            self._push(message)
            return
        if message.id is None:
            # The server could not read one of our requests' ids: it cannot say which one.
            error = error_from_response(message.error)
            self._fail_pending(error)
            return
        pending = self._pending.pop(message.id, None)
        if pending is None or pending.future.done():
            return  # its waiter was cancelled (a timeout): the answer has nobody to go to
        if message.error is not None:
            if pending.frame is not None:
                pending.future.set_exception(
                    ProtocolError(f"{pending.method}: an error response after a binary answer"))
            else:
                pending.future.set_exception(error_from_response(message.error, pending.method))
            return
        result = message.result
        if isinstance(result, dict):
            self._see_revision(result.get("revision"))
        if pending.kinds is None or pending.method == "volume.load":
            pending.future.set_result((result, None))
            return
        frame = pending.frame
        if frame is None:
            pending.future.set_exception(ProtocolError(f"{pending.method}: response without its binary frame"))
        elif isinstance(result, dict) and result.get("bytes") not in (None, len(frame.payload)):
            pending.future.set_exception(ProtocolError(
                f"{pending.method}: the response says {result.get('bytes')} bytes, the frame holds "
                f"{len(frame.payload)}"))
        else:
            pending.future.set_result((result, frame))

    def _on_binary(self, data: bytes):
        try:
            frame = decode_frame(data)
        except FrameError as e:
            raise ProtocolError(f"bad binary frame from the server: {e} ({e.code.value})") from None
        if frame.kind == FrameKind.VOLUME_UPLOAD:
            raise ProtocolError("the server sent a frame of kind 9 (volume upload)")
        self._see_revision(frame.revision)
        if frame.request_id == 0:
            self._push(frame)
            return
        pending = self._pending.get(frame.request_id)
        if pending is None or pending.future.done():
            return  # its waiter gave up; the frame has nobody to go to
        if pending.kinds is None or frame.kind not in pending.kinds:
            raise ProtocolError(f"{pending.method}: answered by a binary frame of kind {frame.kind}")
        if pending.frame is not None:
            raise ProtocolError(f"{pending.method}: two binary frames answer request {frame.request_id}")
        pending.frame = frame

    def _see_presence(self, params: dict):
        client = params.get("client")
        if not isinstance(client, int) or isinstance(client, bool):
            raise ProtocolError(f"a presence notification without a client id: {params!r}")
        if params.get("gone"):
            self.others.pop(client, None)
        else:
            self.others[client] = params

    def _see_revision(self, revision):
        if isinstance(revision, int) and not isinstance(revision, bool):
            self.revision = revision if self.revision is None else max(self.revision, revision)

    def _fail_pending(self, error: Exception):
        pending, self._pending = self._pending, {}
        for p in pending.values():
            if not p.future.done():
                p.future.set_exception(error)

    # --------------------------------------------------------------------------------- updates

    def _push(self, update):
        if len(self._updates) >= self._max_updates:
            self._updates.popleft()
            self.dropped_updates += 1
        self._updates.append(update)
        self._updates_changed.set()

    def _set_closed(self, closed: ConnectionClosed):
        if self._closed is None:
            self._closed = closed
        self._updates_changed.set()

    async def next_update(self, timeout: float | None = None):
        """The oldest update not yet taken: a rpc.Notification (session.changed,
        session.clients, ...) or a frames.Frame pushed with request id 0 (splat buffers, frames).
        None once the connection is closed and every update was taken; raises
        asyncio.TimeoutError after `timeout` seconds without one."""

        async def wait():
            while not self._updates:
                if self._closed is not None:
                    return None
                self._updates_changed.clear()
                await self._updates_changed.wait()
            return self._updates.popleft()

        return await asyncio.wait_for(wait(), timeout)

    async def updates(self):
        """`async for update in client.updates()`: every update in arrival order, until the
        connection closes. Kinds as in next_update."""
        while True:
            update = await self.next_update()
            if update is None:
                return
            yield update

    # -------------------------------------------------------------------------------- requests

    def _check_open(self):
        if self._closed is not None:
            raise ConnectionClosed(self._closed.code, self._closed.reason)
        if self._ws is None:
            raise ConnectionClosed(1000, "closed by the client")

    async def call(self, method: str, params: dict | None = None, *, upload: bytes | None = None):
        """Sends one request and returns (result, frame): `frame` is the binary frame that
        answered it (binary-answered methods), else None. `upload` is the payload of the kind-9
        frame that volume.load sends right after its request."""
        self._check_open()
        kinds = None
        if method in ("render.frame", "mesh.export"):
            kinds = set(_ANSWER_KINDS[method].values())
        elif method == "splats.get":
            kinds = {FrameKind.SPLATS_FULL}
        elif method == "volume.save":
            kinds = {FrameKind.VOLUME_FILE, FrameKind.VOLUME_VDB}
        elif method == "volume.load":
            kinds = set()
        request_id = self._ids.take(self._pending)
        text = encode_request(method, params, request_id)
        future = asyncio.get_running_loop().create_future()
        self._pending[request_id] = _Pending(method, future, kinds)
        try:
            async with self._send_lock:
                # volume.load's upload must be the very next message of the connection.
                await self._ws.send(text)
                if upload is not None:
                    await self._ws.send(encode_frame(FrameKind.VOLUME_UPLOAD, request_id, 0, upload))
        except websockets.exceptions.ConnectionClosed:
            self._pending.pop(request_id, None)
            raise ConnectionClosed(self._ws.close_code or 1006, self._ws.close_reason or "") from None
        try:
            return await asyncio.wait_for(asyncio.shield(future), self.request_timeout)
        finally:
            if not future.done():
                self._pending.pop(request_id, None)
                future.cancel()

    async def _result(self, method: str, params: dict | None = None) -> dict:
        result, _ = await self.call(method, params)
        return result

    async def notify(self, method: str, params: dict | None = None):
        """Sends a client notification: a request without id that the server carries out
        without any answer, not even an error (PROTOCOL.md), e.g. stroke.dabs at pointer rate."""
        self._check_open()
        async with self._send_lock:
            await self._ws.send(encode_request(method, params, None))

    # -------------------------------------------------------------------------------- sessions

    def _remember_session(self, result: dict):
        self.session = result.get("session")
        self.client_id = result.get("client")
        self.read_only = result.get("read_only")
        self.limits = result.get("limits", {})
        self.protocol = result.get("protocol")
        self.base_color = result.get("base_color")
        self._see_revision(result.get("revision"))
        if "token" in result:
            self.token = result["token"]
            self.view_token = result.get("view_token")
        self._route_used = True

    async def create_session(self, size, solid: str, *, session: str | None = None, view: str = "none",
                             protocol: int | None = 1, name: str | None = None, base_color=None,
                             splats: int | None = 2) -> dict:
        """session.create: a new session of `size` = [nx, ny, nz] voxels (or one int for a cube)
        holding `solid` (empty sphere box torus cylinder dumbbell pig). Proposes `session`, or
        the id this connection was opened with; outside a session, a connection whose id was
        used already reconnects under a new one first. `view` "none" (default here: updates
        carry notifications only) or "splats" (a full splat buffer follows, deltas after every
        change). `name`: the display name the others see (protocol 1.2; default "Sculptor N").
        `base_color`: [r, g, b] (0..255, sRGB), the colour of clay nothing has painted (protocol
        1.7; default the clay colour [221, 181, 155]). `splats`: the splat buffer version this
        client reads (2, with colour and mask, by default; None: the server's default, 1).
        Returns the result: session, token, view_token, client, size, revision, base_color,
        clients, ..."""
        if isinstance(size, int):
            size = [size, size, size]
        if self.session is None:
            wanted = session or (new_session_id() if self._route_used else self._route)
            if wanted != self._route:
                await self._reopen(wanted)
        params = _without_none(size=list(size), solid=solid, session=session or self._route,
                               protocol=protocol, view=view, name=name,
                               base_color=_color(base_color, "base_color") if base_color is not None else None,
                               splats=splats)
        result = await self._result("session.create", params)
        self._remember_session(result)
        return result

    async def join(self, session: str, token: str, *, view: str = "none", protocol: int | None = 1,
                   follow_owner: bool = False, name: str | None = None, splats: int | None = 2) -> dict:
        """session.join with the edit or the view token; reconnects under `session` first when
        this connection was opened for another id (the load balancer routes on it).
        `follow_owner`: on -32015 naming the owning server (servers sharing etcd), reconnect to
        it directly and join there once; only where clients can reach the servers themselves."""
        if self.session is None and session != self._route:
            await self._reopen(session)
        params = _without_none(session=session, token=token, protocol=protocol, view=view, name=name, splats=splats)
        try:
            result = await self._result("session.join", params)
        except SessionHeldElsewhere as e:
            if not follow_owner or e.owner is None:
                raise
            parts = urllib.parse.urlsplit(self.url)
            self.url = urllib.parse.urlunsplit((parts.scheme, e.owner, parts.path, parts.query, ""))
            await self._reopen(session)
            result = await self._result("session.join", params)
        self._remember_session(result)
        if result.get("read_only"):
            self.token, self.view_token = None, token
        else:
            self.token = token
        return result

    async def leave(self) -> dict:
        result = await self._result("session.leave", {})
        self.others = {}
        self.session = self.client_id = self.read_only = None
        self.token = self.view_token = None
        return result

    async def stats(self) -> dict:
        """session.stats: inside_volume (vu^3), surface_area (vu^2), components, bounds,
        gradient_error {max, mean, voxels}, digest, revision, memory and history bytes, ..."""
        return await self._result("session.stats", {})

    # ---------------------------------------------------------------------------------- edits

    async def apply(self, tool, *, ray=None, **fields) -> dict:
        """tool.apply: `tool` is a name (add_blob, smooth, csg_add, ...) with the operation's
        fields as keywords (center=[x, y, z], radius=8, strength=1, shape=..., global_=True for
        global smoothing, ...), or a whole operation object {"tool": ...}. `ray` = (origin,
        direction) centres the tool where the ray first meets the surface. Returns {revision,
        roi, hit?}."""
        params = dict(tool) if isinstance(tool, dict) else {"tool": tool}
        if "global_" in fields:
            fields["global"] = fields.pop("global_")
        params.update(fields)
        if ray is not None:
            params["ray"] = _ray(ray)
        return await self._result("tool.apply", params)

    async def apply_op(self, op: dict) -> dict:
        """One line of an ops file as `marzipan batch` reads it: "tool" objects go to tool.apply,
        {"op": "morph", ...} to volume.morph, {"op": "smooth", ...} to tool.apply as
        {"tool": "smooth", "global": true, ...}, which PROTOCOL.md defines as the same,
        {"op": "mask", "action": A} to mask.A, and a stroke line {"stroke": {stroke.begin's
        params}, "dabs": [...]} (warp, paint and mask tools) is one whole stroke (stroke())."""
        if "stroke" in op and "op" not in op and "tool" not in op:
            # stroke.begin's params as the line gives them: the server checks (and names) them.
            stroke = (await self._result("stroke.begin", op["stroke"]))["stroke"]
            return await self._whole_stroke(stroke, op.get("dabs", []))
        if "op" not in op or "tool" in op:
            return await self.apply(op)
        rest = {k: v for k, v in op.items() if k != "op"}
        if op["op"] == "mask" and set(rest) == {"action"} and rest["action"] in ("clear", "invert", "fill"):
            return await self._result("mask." + rest["action"], {})
        if op["op"] == "morph":
            return await self._result("volume.morph", rest)
        if op["op"] == "smooth":
            return await self.apply({"tool": "smooth", **rest, "global": rest.get("global", True)})
        # Anything else is the server's to refuse, with its own message.
        return await self.apply(op)

    async def cancel(self) -> bool:
        """op.cancel: stops this connection's long request in progress (global smoothing,
        morphology, a stroke.dabs message), which then fails with Cancelled and changes nothing.
        Needs a second task: the request waits for its own answer. True when one was running.
        Its op.progress notifications ({"request": id, "fraction": 0..1}) arrive as updates."""
        return (await self._result("op.cancel"))["cancelled"]

    async def morph(self, kind: str, radius: float) -> dict:
        """volume.morph: erode, dilate, open or close with a sphere of `radius` vu."""
        return await self._result("volume.morph", {"kind": kind, "radius": radius})

    async def begin_stroke(self, tool: str, *, radius: float | None = None, strength: float | None = None,
                           symmetry=None, accumulate: bool | None = None, height: float | None = None,
                           volume: float | None = None, direction=None, color=None, hardness: float | None = None,
                           erase: bool | None = None) -> int:
        """stroke.begin of any tool that strokes (marzipan.tools: add_blob, inflate, clay, flatten,
        crease, grab, ...); accumulate=True makes every stroke.dabs add (build-up) instead of only
        what exceeds the stroke's earlier dabs (protocol 1.1). height (vu, protocol 1.4; the tools
        whose parameters list it: add_blob, remove_blob, inflate, clay; at most half the radius,
        not with accumulate): the stroke moves the surface by at most this, however often it
        passes. volume (elastic_grab, 0..0.5) and direction ([x, y, z]: twist, scale, pinch) are
        the warp tools' (PROTOCOL.md, warp strokes; see warp()); color ([r, g, b] 0..255: paint),
        hardness (0 to below 1: paint, mask) and erase (mask) the paint tools' (paint(), mask())."""
        result = await self._result("stroke.begin", _without_none(
            tool=tool, radius=radius, strength=strength, symmetry=list(symmetry) if symmetry else None,
            accumulate=accumulate, height=height, volume=volume,
            direction=_point(direction, "direction") if direction is not None else None,
            color=_color(color, "color") if color is not None else None, hardness=hardness, erase=erase))
        return result["stroke"]

    async def _whole_stroke(self, stroke: int, dabs) -> dict:
        """The dabs of an open stroke in messages of at most max_dabs, then stroke.end."""
        dabs = [_dab(d) for d in dabs]
        per_message = int(self.limits.get("max_dabs", 256)) or 256
        applied = 0
        plane = None
        try:
            for start in range(0, len(dabs), per_message):
                result = await self.stroke_dabs(stroke, dabs[start:start + per_message])
                applied += result["applied"]
                plane = result.get("plane", plane)
        except (MarzipanError, ValueError):
            # Close the step the applied dabs made, but report the first failure.
            try:
                await self.end_stroke(stroke)
            except MarzipanError:
                pass
            raise
        end = await self.end_stroke(stroke)
        return {"stroke": stroke, "applied": applied, **end, **({"plane": plane} if plane else {})}

    async def stroke_dabs(self, stroke: int, dabs) -> dict:
        return await self._result("stroke.dabs", {"stroke": stroke, "dabs": [_dab(d) for d in dabs]})

    async def end_stroke(self, stroke: int) -> dict:
        return await self._result("stroke.end", {"stroke": stroke})

    async def stroke(self, tool: str, dabs, *, radius: float | None = None, strength: float | None = None,
                     symmetry=None, accumulate: bool | None = None, height: float | None = None,
                     volume: float | None = None, direction=None, color=None, hardness: float | None = None,
                     erase: bool | None = None) -> dict:
        """A whole stroke, one undo step: stroke.begin, the dabs (centres [x, y, z] or dicts
        {center | ray, pressure?}) in messages of at most max_dabs, stroke.end. Returns
        {stroke, applied, revision, can_undo, can_redo}, and the stroke's `plane` ({point,
        normal}, fitted at its first dab: flatten, contrast, clay with a height) when it has one.
        `volume` and `direction` are the warp tools' (warp()), `color`, `hardness` and `erase`
        the paint tools' (paint(), mask())."""
        stroke = await self.begin_stroke(tool, radius=radius, strength=strength, symmetry=symmetry,
                                         accumulate=accumulate, height=height, volume=volume, direction=direction,
                                         color=color, hardness=hardness, erase=erase)
        return await self._whole_stroke(stroke, dabs)

    async def warp(self, tool: str, anchor, points, *, radius: float | None = None, strength: float | None = None,
                   volume: float | None = None, direction=None) -> dict:
        """A whole warp stroke (grab, elastic_grab, snake_hook, twist, scale, pinch, pinch_path; PROTOCOL.md,
        warp strokes), one undo step: stroke.begin, the anchor (a point on the surface, [x, y, z],
        or a dict {center | ray}) and then the pointer's points, in messages of at most max_dabs,
        stroke.end. grab and elastic_grab move the anchor to the last point; snake_hook follows
        every point; twist, scale and pinch take their amount from the last point's way along
        `direction` (default: along the drag), in radii: a quarter turn, a factor 2, a pinch of
        0.5 per radius; pinch_path takes the points as the path on the surface (pinch_path()).
        Returns {stroke, revision, can_undo, can_redo}."""
        result = await self.stroke(tool, [anchor, *points], radius=radius, strength=strength, volume=volume,
                                   direction=direction)
        del result["applied"]
        return result

    async def grab(self, anchor, to, radius: float, *, strength: float | None = None) -> dict:
        """Grabs the surface at `anchor` (a point on it) and moves it to `to`, the material within
        `radius` vu of the way following less and less: a grab stroke of two dabs (warp())."""
        return await self.warp("grab", anchor, [to], radius=radius, strength=strength)

    async def pinch_path(self, path, radius: float, *, strength: float | None = None) -> dict:
        """Pinches along `path`, points on the surface ([x, y, z], or dicts {center, pressure}),
        the first starting it: the surface on both sides is drawn towards the path across it, by
        e^-(strength * pressure) where the whole brush passes (PROTOCOL.md, warp strokes). A warp
        stroke (warp()) of tool pinch_path, one undo step."""
        return await self.warp("pinch_path", path[0], path[1:], radius=radius, strength=strength)

    async def paint(self, color, dabs, *, radius: float | None = None, strength: float | None = None,
                    hardness: float | None = None, symmetry=None, accumulate: bool | None = None) -> dict:
        """A paint stroke (protocol 1.7; PROTOCOL.md, paint and mask strokes), one undo step:
        blends `color` ([r, g, b], 0..255 sRGB) into the surface under the brush swept over the
        dabs (centres [x, y, z] or dicts {center | ray, pressure?}), `strength` at the centre,
        fading from `hardness` (0 to below 1, default 0.5) of the radius to nothing at it. Moves no
        geometry; a masked voxel keeps its colour too. Returns what stroke() returns."""
        return await self.stroke("paint", dabs, radius=radius, strength=strength, symmetry=symmetry,
                                 accumulate=accumulate, color=color, hardness=hardness)

    async def mask(self, dabs, *, erase: bool = False, radius: float | None = None, strength: float | None = None,
                   hardness: float | None = None, symmetry=None, accumulate: bool | None = None) -> dict:
        """A mask stroke, one undo step: raises the mask weight under the brush (erase=True:
        lowers it). Every geometry tool moves a voxel of weight w by (1 - w / 255) of what it
        would: fully masked clay stays exactly as it is. Returns what stroke() returns."""
        return await self.stroke("mask", dabs, radius=radius, strength=strength, symmetry=symmetry,
                                 accumulate=accumulate, hardness=hardness, erase=erase or None)

    async def mask_clear(self) -> dict:
        """mask.clear: every band voxel's mask weight to 0, one undo step. Returns {revision, roi}
        (roi null when nothing was masked)."""
        return await self._result("mask.clear", {})

    async def mask_invert(self) -> dict:
        """mask.invert: every band voxel's mask weight w to 255 - w, one undo step."""
        return await self._result("mask.invert", {})

    async def mask_fill(self) -> dict:
        """mask.fill: every band voxel's mask weight to 255 (all clay frozen), one undo step."""
        return await self._result("mask.fill", {})

    # ------------------------------------------------------------------------------- presence

    async def presence(self, brush: dict | None = None, camera: dict | None = None, *, answer: bool = False):
        """presence (protocol 1.2): tells the session's other clients where this client's brush
        is and what it looks at. `brush` = {tool, radius, point: [x, y, z], normal: [x, y, z],
        active: bool}; `camera` = {eye, target, up?, fov?} as for view.set. Each call replaces
        the previous presence as a whole (leave out brush when the pointer is off the model); a
        view client's brush is dropped by the server. Sent as a notification (no answer, the
        way to send at pointer rate) unless `answer`, which waits for the server's {} and so
        raises InvalidParams for a presence it refuses. The others' presence arrives as
        `presence` notifications among the updates and is kept in `others`."""
        params = _without_none(brush=brush, camera=camera)
        if answer:
            return await self._result("presence", params)
        await self.notify("presence", params)
        return None

    async def undo(self, scope: str | None = None) -> dict:
        """history.undo: the session's newest step (scope None or "session"), or this client's
        own newest step (scope "mine"; UndoConflict when another step touched its bricks
        since). Returns {revision, can_undo, can_redo, step}."""
        return await self._result("history.undo", _without_none(scope=scope))

    async def redo(self, scope: str | None = None) -> dict:
        """history.redo, scoped as undo()."""
        return await self._result("history.redo", _without_none(scope=scope))

    async def history(self, before: int | None = None, limit: int | None = None) -> list:
        """history.list: one page of the session's steps, newest first (the undone ones first,
        from the furthest future): at most `limit` (1..1000, the server's default 100), after
        the step of revision `before` (absent: from the newest):
        [{revision, first_revision, client, tool, time_ms, region, undone}]. history_page()
        also says whether more steps follow."""
        return (await self.history_page(before, limit))["steps"]

    async def history_page(self, before: int | None = None, limit: int | None = None) -> dict:
        """history.list as the server answers it: {revision, steps, more}."""
        return await self._result("history.list", _without_none(before=before, limit=limit))

    async def fork(self, revision: int | None = None) -> dict:
        """session.fork: a new session from the current volume or an earlier `revision` still
        in history; this client leaves its session and is the new one's editor. Returns the
        result as create_session() (session, token, view_token, ...) with forked_from."""
        result = await self._result("session.fork", _without_none(revision=revision))
        self._remember_session(result)
        return result

    # --------------------------------------------------------------------------- bulk answers

    async def view(self, mode: str, camera: dict | None = None, width: int | None = None,
                   height: int | None = None, *, shading: str | None = None) -> dict:
        """view.set: what the server pushes after changes: "splats" (deltas), "frames" (JPEG
        frames of `camera` at width x height with `shading`) or "none" (notifications only)."""
        return await self._result("view.set", _without_none(mode=mode, camera=camera, width=width, height=height,
                                                            shading=shading))

    async def frame(self, camera: dict, width: int, height: int, format: str = "png", *,
                    quality: int | None = None, shading: str | None = None,
                    min_vu: float | None = None, revision: int | None = None) -> bytes:
        """render.frame: the image file (PNG or JPEG) of `camera` = {eye, target, up?, fov?}
        at width x height; shading "lit" (default), "normals", "gradient_error" or "thickness"
        (with min_vu: walls thinner than that are red); `revision`: the volume right after that
        step of history() instead of the current one."""
        _, frame = await self.call("render.frame", _without_none(
            camera=camera, width=width, height=height, format=format, quality=quality, shading=shading,
            min_vu=min_vu, revision=revision))
        return bytes(frame.payload)

    async def export_mesh(self, format: str = "stl", max_triangles: int | None = None,
                          max_error: float | None = None) -> bytes:
        """mesh.export: the marching-cubes mesh as an STL, OBJ, PLY or glTF binary (glb) file
        (vu), decimated to at most max_triangles and/or within max_error vu when given."""
        return (await self.export_mesh_with_result(format, max_triangles, max_error))[1]

    async def export_mesh_with_result(self, format: str = "stl", max_triangles: int | None = None,
                                      max_error: float | None = None) -> tuple[dict, bytes]:
        """export_mesh, with the result: {revision, format, vertices, triangles, bytes} and,
        when decimated, source_triangles and max_error (measured distance to the surface, vu)."""
        result, frame = await self.call("mesh.export", _without_none(
            format=format, max_triangles=max_triangles, max_error=max_error))
        return result, bytes(frame.payload)

    async def thickness(self, min_vu: float, max_places: int | None = None) -> dict:
        """analysis.thickness: {revision, min_vu, points, below, thinnest, places: [{point,
        normal, thickness}]}: the wall thickness under every surface point (vu), the thinnest
        places thinner than min_vu first."""
        result, _ = await self.call("analysis.thickness", _without_none(min_vu=min_vu, max_places=max_places))
        return result

    async def splats(self):
        """splats.get: the full splat buffer, decoded (splats.SplatBuffer)."""
        _, frame = await self.call("splats.get", {})
        return decode_splats(frame.payload)

    @property
    def volume_formats(self) -> list[str]:
        """The formats save() and load() take on this server (limits.volume_formats, since 1.3):
        ["mzv"], or ["mzv", "vdb"] for a server built with OpenVDB; ["mzv"] before 1.3."""
        return list(self.limits.get("volume_formats", ["mzv"]))

    async def save(self, format: str = "mzv") -> bytes:
        """volume.save: the session's volume as a .mzv file, or with format="vdb" as an OpenVDB
        level set (.vdb; a server built with OpenVDB, see volume_formats)."""
        return (await self.save_with_result(format))[1]

    async def save_with_result(self, format: str = "mzv") -> tuple[dict, bytes]:
        """save, with the result {revision, digest, bytes, format}."""
        params = {} if format == "mzv" else {"format": format}
        result, frame = await self.call("volume.save", params)
        want = FrameKind.VOLUME_VDB if format == "vdb" else FrameKind.VOLUME_FILE
        if frame.kind != want:
            raise ProtocolError(f"volume.save as {format} was answered by a frame of kind {int(frame.kind)}")
        return result, bytes(frame.payload)

    async def load(self, data: bytes | str | os.PathLike | None = None, format: str | None = None, *,
                   path: str | os.PathLike | None = None) -> dict:
        """volume.load: replaces the volume by a file of the session's grid size (one undo step):
        `data` the file's bytes, or `path` (also given as `data`) a file to read. `format` "mzv"
        or "vdb" (an OpenVDB level set, index (i, j, k) = voxel (i, j, k), clamped to the band;
        servers built with OpenVDB); by default from the path's extension, else "mzv". Returns
        {revision, digest, roi, can_undo, can_redo}."""
        if isinstance(data, (str, os.PathLike)):
            path, data = data, None
        if (data is None) == (path is None):
            raise TypeError("load() takes the file's bytes or a path, one of them")
        if path is not None:
            if format is None and str(path).lower().endswith(".vdb"):
                format = "vdb"
            with open(path, "rb") as f:
                data = f.read()
        params = {"bytes": len(data)}
        if format not in (None, "mzv"):
            params["format"] = format
        result, _ = await self.call("volume.load", params, upload=data)
        return result
