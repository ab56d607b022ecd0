"""Python client of the Marzipan remote volume-sculpting protocol (protocol/PROTOCOL.md).

Modules: frames (binary frame header), splats (splat buffers), rpc (JSON-RPC messages and the
error classes), png (reading the server's PNG frames), client (the asyncio Client, which needs
python3-websockets), cli (`python3 -m marzipan`). Units are vu of the session's grid, y up.

The client module is imported on first use of its names, so that the decoders work where
websockets is not installed.
"""

from .frames import (
    FRAME_HEADER_BYTES,
    Frame,
    FrameError,
    FrameErrorCode,
    FrameHeader,
    FrameKind,
    decode_frame,
    encode_frame,
)
from .rpc import (
    PROTOCOL_VERSION,
    AlreadyInSession,
    BadToken,
    Busy,
    ConnectionClosed,
    EngineRefused,
    ErrorCode,
    InternalError,
    InvalidParams,
    InvalidRequest,
    LimitExceeded,
    MarzipanError,
    NoSuchSession,
    NoSuchStroke,
    NothingToUndoRedo,
    Notification,
    NotInSession,
    ParseError,
    ProtocolError,
    ReadOnlyToken,
    RpcError,
    SessionExists,
    SessionFull,
    SessionHeldElsewhere,
    Cancelled,
    UnknownMethod,
    UnsupportedProtocolVersion,
    UploadMissing,
)
from .splats import BrickSplats, SplatBuffer, SplatError, SplatErrorCode, decode_splats

__version__ = "1.0.0"

__all__ = [
    "AlreadyInSession",
    "BadToken",
    "BrickSplats",
    "Busy",
    "ConnectionClosed",
    "EngineRefused",
    "ErrorCode",
    "FRAME_HEADER_BYTES",
    "Frame",
    "FrameError",
    "FrameErrorCode",
    "FrameHeader",
    "FrameKind",
    "InternalError",
    "InvalidParams",
    "InvalidRequest",
    "LimitExceeded",
    "MarzipanError",
    "NoSuchSession",
    "NoSuchStroke",
    "NotInSession",
    "NothingToUndoRedo",
    "Notification",
    "PROTOCOL_VERSION",
    "ParseError",
    "ProtocolError",
    "ReadOnlyToken",
    "RpcError",
    "SessionExists",
    "SessionFull",
    "SessionHeldElsewhere",
    "Cancelled",
    "SplatBuffer",
    "SplatError",
    "SplatErrorCode",
    "UnknownMethod",
    "UnsupportedProtocolVersion",
    "UploadMissing",
    "decode_frame",
    "decode_splats",
    "encode_frame",
    "Client",
    "ConnectFailed",
    "new_session_id",
    "session_url",
]

_CLIENT_NAMES = {"Client", "ConnectFailed", "new_session_id", "session_url"}


def __getattr__(name):
    if name in _CLIENT_NAMES:
        from . import client

        return getattr(client, name)
    raise AttributeError(f"module 'marzipan' has no attribute {name!r}")
