"""Binary frames: the fixed 24-byte header in front of every binary WebSocket message.

protocol/PROTOCOL.md, section "Binary frames", is the contract; protocol/cpp/frames.cpp and
protocol/js/frames.js are the other sides, and this module makes the same checks in the same
order with the same error codes (the spelling of tests/protocol/vectors/vectors.json).

Conventions: every integer little-endian; byte offsets from the frame start:
   0  4  magic "MZPN"      4  2  u16 format version (1)   6  2  u16 kind (FrameKind)
   8  4  u32 request id   12  8  u64 session revision    20  4  u32 payload length
  24  ... payload, exactly `payload length` bytes, nothing after it.
decode_frame takes untrusted bytes: for bad content it raises FrameError (a ValueError) and
nothing else; the payload it returns is a memoryview of the input, not a copy.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

FRAME_HEADER_BYTES = 24
FRAME_FORMAT_VERSION = 1
# The largest payload the 32-bit length field can describe; callers pass a smaller limit.
MAX_FRAME_PAYLOAD = 0xFFFFFFFF

_MAGIC = b"MZPN"
# version, kind, request id, revision, payload length, after the magic.
_FIELDS = struct.Struct("<HHIQI")
_MAX_U64 = (1 << 64) - 1


class FrameKind(enum.IntEnum):
    SPLATS_FULL = 1  # server -> client: every brick with points (splats.py buffer)
    SPLATS_DELTA = 2  # server -> client: the listed bricks replace their old points
    FRAME_JPEG = 3  # server -> client: a ray-cast image, JPEG file
    FRAME_PNG = 4  # server -> client: a ray-cast image, PNG file
    MESH_STL = 5  # server -> client: binary STL
    MESH_OBJ = 6  # server -> client: Wavefront OBJ text
    MESH_PLY = 7  # server -> client: binary little-endian PLY
    VOLUME_FILE = 8  # server -> client: a .mzv file
    VOLUME_UPLOAD = 9  # client -> server: the file (.mzv or .vdb) for the volume.load request it names
    MESH_GLB = 10  # server -> client: binary glTF 2.0 (.glb)
    VOLUME_VDB = 11  # server -> client: an OpenVDB level set (.vdb), volume.save {format: "vdb"} (1.3)


def frame_kind_name(kind: int) -> str:
    """"splats_full", "splats_delta", ..., "volume_upload"; "" for values outside FrameKind."""
    try:
        return FrameKind(kind).name.lower()
    except ValueError:
        return ""


class FrameErrorCode(str, enum.Enum):
    SHORT_HEADER = "short_header"  # fewer than 24 bytes
    BAD_MAGIC = "bad_magic"  # bytes 0-3 are not "MZPN"
    BAD_VERSION = "bad_version"  # format version other than 1
    BAD_KIND = "bad_kind"  # kind outside 1..11
    TOO_LARGE = "too_large"  # declared payload length above the caller's limit
    LENGTH_MISMATCH = "length_mismatch"  # declared payload length differs from the bytes after the header


class FrameError(ValueError):
    """A binary message refused by decode_frame; `code` says which check failed."""

    def __init__(self, code: FrameErrorCode, message: str):
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class FrameHeader:
    version: int
    kind: int
    request_id: int  # the JSON-RPC id it answers; 0 for a push
    revision: int  # the session revision the payload shows (0 in uploads)
    payload_length: int


@dataclass(frozen=True)
class Frame:
    header: FrameHeader
    payload: memoryview  # a view into the decoded bytes

    @property
    def kind(self) -> int:
        return self.header.kind

    @property
    def request_id(self) -> int:
        return self.header.request_id

    @property
    def revision(self) -> int:
        return self.header.revision


def decode_frame(data, max_payload: int = MAX_FRAME_PAYLOAD) -> Frame:
    """Checks and splits one whole binary message (bytes, bytearray or memoryview).

    Checks, in this order: at least 24 bytes, magic, version, kind, payload length within
    `max_payload`, payload length equal to the bytes after the header.
    """
    view = memoryview(data).cast("B")
    if len(view) < FRAME_HEADER_BYTES:
        raise FrameError(
            FrameErrorCode.SHORT_HEADER,
            f"binary frame of {len(view)} bytes is shorter than its 24-byte header",
        )
    if view[:4] != _MAGIC:
        raise FrameError(
            FrameErrorCode.BAD_MAGIC,
            f'binary frame magic must be "MZPN" (4d5a504e), got {view[:4].hex()}',
        )
    version, kind, request_id, revision, payload_length = _FIELDS.unpack_from(view, 4)
    if version != FRAME_FORMAT_VERSION:
        raise FrameError(
            FrameErrorCode.BAD_VERSION,
            f"binary frame format version {version} is not supported (supported: 1)",
        )
    if not 1 <= kind <= 11:
        raise FrameError(FrameErrorCode.BAD_KIND, f"binary frame kind {kind} is unknown (known: 1 to 11)")
    if payload_length > max_payload:
        raise FrameError(
            FrameErrorCode.TOO_LARGE,
            f"binary frame payload of {payload_length} bytes is over the limit of {max_payload}",
        )
    following = len(view) - FRAME_HEADER_BYTES
    if payload_length != following:
        raise FrameError(
            FrameErrorCode.LENGTH_MISMATCH,
            f"binary frame header declares {payload_length} payload bytes but {following} follow",
        )
    header = FrameHeader(version, kind, request_id, revision, payload_length)
    return Frame(header, view[FRAME_HEADER_BYTES:])


def encode_frame(kind: int, request_id: int, revision: int, payload=b"") -> bytes:
    """The header followed by the payload. Raises ValueError for a kind outside FrameKind, a
    request id outside u32, a revision outside u64 or a payload over MAX_FRAME_PAYLOAD."""
    if isinstance(kind, bool) or not isinstance(kind, int) or not 1 <= kind <= 11:
        raise ValueError(f"binary frame kind {kind!r} is unknown")
    if isinstance(request_id, bool) or not isinstance(request_id, int) or not 0 <= request_id <= 0xFFFFFFFF:
        raise ValueError(f"binary frame request id {request_id!r} is not a u32")
    if isinstance(revision, bool) or not isinstance(revision, int) or not 0 <= revision <= _MAX_U64:
        raise ValueError(f"binary frame revision {revision!r} is not a u64")
    body = memoryview(payload).cast("B")
    if len(body) > MAX_FRAME_PAYLOAD:
        raise ValueError(f"binary frame payload of {len(body)} bytes does not fit the 32-bit length field")
    return b"".join((_MAGIC, _FIELDS.pack(FRAME_FORMAT_VERSION, kind, request_id, revision, len(body)), body))
