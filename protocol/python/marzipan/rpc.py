"""JSON-RPC 2.0 text messages of the Marzipan protocol (protocol/PROTOCOL.md, sections
"Requests and responses", "Notifications" and "Errors"), without a transport.

Conventions: one message per WebSocket text frame, UTF-8 JSON. Request ids made here are
integers in [1, 2^32 - 1], so every request can use them, including those answered by a binary
frame, whose header carries the id as a u32. Errors from the server become RpcError, or the
subclass named after its code: branch on the class, `code` and `data`, never on `message`.
"""

from __future__ import annotations

import enum
import json
import re
from dataclasses import dataclass, field

PROTOCOL_VERSION = {"major": 1, "minor": 7}
MAX_REQUEST_ID = 0xFFFFFFFF

METHODS = (
    "session.create",
    "session.join",
    "session.leave",
    "session.stats",
    "tool.apply",
    "stroke.begin",
    "stroke.dabs",
    "stroke.end",
    "volume.morph",
    "history.undo",
    "history.redo",
    "view.set",
    "render.frame",
    "splats.get",
    "mesh.export",
    "volume.save",
    "volume.load",
    "analysis.thickness",
    "op.cancel",
    "history.list",
    "session.fork",
    "presence",
    "mask.clear",
    "mask.invert",
    "mask.fill",
)

# The methods whose id travels in a binary frame header (an answer, or volume.load's upload).
BINARY_METHODS = ("render.frame", "splats.get", "mesh.export", "volume.save", "volume.load")


class ErrorCode(enum.IntEnum):
    PARSE_ERROR = -32700
    INVALID_REQUEST = -32600
    UNKNOWN_METHOD = -32601
    INVALID_PARAMS = -32602
    INTERNAL_ERROR = -32000
    NO_SUCH_SESSION = -32001
    BAD_TOKEN = -32002
    SESSION_FULL = -32003
    LIMIT_EXCEEDED = -32004
    BUSY = -32005
    ENGINE_REFUSED = -32006
    READ_ONLY_TOKEN = -32007
    UNSUPPORTED_PROTOCOL_VERSION = -32008
    NOT_IN_SESSION = -32009
    ALREADY_IN_SESSION = -32010
    NO_SUCH_STROKE = -32011
    NOTHING_TO_UNDO_REDO = -32012
    UPLOAD_MISSING = -32013
    SESSION_EXISTS = -32014
    SESSION_HELD_ELSEWHERE = -32015
    CANCELLED = -32016
    UNDO_CONFLICT = -32017


class MarzipanError(Exception):
    """Base of every error this package raises about the server or the connection."""


class RpcError(MarzipanError):
    """An error response: the server's code, message and optional data."""

    code = None  # the subclasses' own code; an RpcError of an unknown code carries it per instance

    def __init__(self, code: int, message: str, data=None, method: str | None = None):
        super().__init__(f"{method + ': ' if method else ''}{message} ({code})")
        self.code = code
        self.message = message
        self.data = data if isinstance(data, dict) else {}
        self.method = method

    @property
    def field(self) -> str | None:
        """error.data.field: the parameter the server refused, when it names one."""
        value = self.data.get("field")
        return value if isinstance(value, str) else None


class ParseError(RpcError): pass
class InvalidRequest(RpcError): pass
class UnknownMethod(RpcError): pass
class InvalidParams(RpcError): pass
class InternalError(RpcError): pass
class NoSuchSession(RpcError): pass
class BadToken(RpcError): pass
class SessionFull(RpcError): pass
class LimitExceeded(RpcError): pass
class Busy(RpcError): pass
class EngineRefused(RpcError): pass
class ReadOnlyToken(RpcError): pass
class UnsupportedProtocolVersion(RpcError): pass
class NotInSession(RpcError): pass
class AlreadyInSession(RpcError): pass
class NoSuchStroke(RpcError): pass
class NothingToUndoRedo(RpcError): pass
class UploadMissing(RpcError): pass
class SessionExists(RpcError): pass
class SessionHeldElsewhere(RpcError):
    """-32015. With servers that share etcd, `owner` names the server that owns the session
    (its --server-id, by default HOST:PORT): Client.join(follow_owner=True) reconnects there."""

    @property
    def owner(self) -> str | None:
        value = self.data.get("owner")
        return value if isinstance(value, str) and re.fullmatch(r"[A-Za-z0-9._-]+:[0-9]{1,5}", value) else None

class Cancelled(RpcError): pass

class UndoConflict(RpcError):
    """-32017 (since 1.2): history.undo/redo with scope "mine" refused because another step
    touched the bricks of the caller's step; `client` and `revision` name that step."""

    @property
    def client(self) -> int | None:
        value = self.data.get("client")
        return value if isinstance(value, int) else None

    @property
    def revision(self) -> int | None:
        value = self.data.get("revision")
        return value if isinstance(value, int) else None


_ERROR_CLASSES = {
    ErrorCode.PARSE_ERROR: ParseError,
    ErrorCode.INVALID_REQUEST: InvalidRequest,
    ErrorCode.UNKNOWN_METHOD: UnknownMethod,
    ErrorCode.INVALID_PARAMS: InvalidParams,
    ErrorCode.INTERNAL_ERROR: InternalError,
    ErrorCode.NO_SUCH_SESSION: NoSuchSession,
    ErrorCode.BAD_TOKEN: BadToken,
    ErrorCode.SESSION_FULL: SessionFull,
    ErrorCode.LIMIT_EXCEEDED: LimitExceeded,
    ErrorCode.BUSY: Busy,
    ErrorCode.ENGINE_REFUSED: EngineRefused,
    ErrorCode.READ_ONLY_TOKEN: ReadOnlyToken,
    ErrorCode.UNSUPPORTED_PROTOCOL_VERSION: UnsupportedProtocolVersion,
    ErrorCode.NOT_IN_SESSION: NotInSession,
    ErrorCode.ALREADY_IN_SESSION: AlreadyInSession,
    ErrorCode.NO_SUCH_STROKE: NoSuchStroke,
    ErrorCode.UNDO_CONFLICT: UndoConflict,
    ErrorCode.NOTHING_TO_UNDO_REDO: NothingToUndoRedo,
    ErrorCode.UPLOAD_MISSING: UploadMissing,
    ErrorCode.SESSION_EXISTS: SessionExists,
    ErrorCode.SESSION_HELD_ELSEWHERE: SessionHeldElsewhere,
    ErrorCode.CANCELLED: Cancelled,
}
for _code, _cls in _ERROR_CLASSES.items():
    _cls.code = int(_code)


def error_from_response(error: dict, method: str | None = None) -> RpcError:
    """The RpcError subclass of error["code"] (RpcError itself for a code not in ErrorCode)."""
    code = error.get("code")
    cls = _ERROR_CLASSES.get(code, RpcError)
    return cls(code, str(error.get("message", "")), error.get("data"), method)


class ProtocolError(MarzipanError):
    """The server sent something the contract does not allow (a bad frame, a reply without its
    binary frame, text that is not a JSON-RPC message)."""


class ConnectionClosed(MarzipanError):
    """The WebSocket closed; `code` and `reason` are the close frame's (1006 when there was none)."""

    def __init__(self, code: int, reason: str):
        super().__init__(f"connection closed ({code}{': ' + reason if reason else ''})")
        self.code = code
        self.reason = reason


class RequestIds:
    """Increasing integer ids in [1, 2^32 - 1], starting again at 1 after the last."""

    def __init__(self, first: int = 1):
        if not 1 <= first <= MAX_REQUEST_ID:
            raise ValueError(f"first request id {first} is outside [1, {MAX_REQUEST_ID}]")
        self._next = first

    def take(self, in_use=()) -> int:
        """The next id that is not in `in_use` (the ids still awaiting their response)."""
        while True:
            request_id = self._next
            self._next = 1 if request_id == MAX_REQUEST_ID else request_id + 1
            if request_id not in in_use:
                return request_id


def _refuse_non_finite(value):
    raise ValueError(f"{value} is not JSON (the protocol refuses NaN and infinities)")


def encode_request(method: str, params: dict | None, request_id: int | str | None) -> str:
    """The text of a request; without an id (None) a client notification, which the server
    carries out without any answer. Numbers must be finite: the server refuses NaN."""
    if not isinstance(method, str):
        raise TypeError("a method name must be a string")
    message = {"jsonrpc": "2.0"}
    if request_id is not None:
        message["id"] = request_id
    message["method"] = method
    if params is not None:
        if not isinstance(params, dict):
            raise TypeError("params must be a dict (by-name parameters only)")
        message["params"] = params
    return json.dumps(message, separators=(",", ":"), allow_nan=False, ensure_ascii=False)


@dataclass(frozen=True)
class Response:
    id: object  # int or str; None for an error about a request whose id could not be read
    result: object = None
    error: dict | None = None


@dataclass(frozen=True)
class Notification:
    method: str
    params: dict = field(default_factory=dict)


def _is_id(value) -> bool:
    return isinstance(value, str) or (isinstance(value, int) and not isinstance(value, bool))


def parse_message(text: str):
    """A Response or a Notification from one server text message. Raises ProtocolError for
    anything else: not JSON, not an object, not JSON-RPC 2.0, or a request (the server sends
    none). NaN and infinities are refused as the server never writes them."""
    try:
        m = json.loads(text, parse_constant=_refuse_non_finite)
    except ValueError as e:
        raise ProtocolError(f"server text is not JSON: {e}") from None
    if not isinstance(m, dict):
        raise ProtocolError("server text is not a JSON object")
    if m.get("jsonrpc") != "2.0":
        raise ProtocolError('server message without "jsonrpc": "2.0"')
    if "method" in m:
        if "id" in m:
            raise ProtocolError("the server sent a request")
        if not set(m) <= {"jsonrpc", "method", "params"}:
            raise ProtocolError("unknown key in a notification")
        params = m.get("params", {})
        if not isinstance(m["method"], str) or not isinstance(params, dict):
            raise ProtocolError("a notification needs a string method and object params")
        return Notification(m["method"], params)
    if "id" not in m:
        raise ProtocolError("neither a response nor a notification")
    if ("result" in m) == ("error" in m):
        raise ProtocolError('a response has exactly one of "result" and "error"')
    if "result" in m:
        if not set(m) <= {"jsonrpc", "id", "result"} or not _is_id(m["id"]):
            raise ProtocolError("malformed response")
        return Response(m["id"], result=m["result"])
    e = m["error"]
    if not set(m) <= {"jsonrpc", "id", "error"} or not (m["id"] is None or _is_id(m["id"])):
        raise ProtocolError("malformed error response")
    if (
        not isinstance(e, dict)
        or not set(e) <= {"code", "message", "data"}
        or not isinstance(e.get("code"), int)
        or isinstance(e.get("code"), bool)
        or not isinstance(e.get("message"), str)
    ):
        raise ProtocolError('"error" must be {code, message, data?}')
    return Response(m["id"], error=e)

