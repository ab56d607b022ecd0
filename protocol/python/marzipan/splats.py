"""Splat buffers: the payload of binary frames of kind 1 (splats full) and 2 (splats delta).

protocol/cpp/splats.hpp specifies the format byte by byte; this decoder makes the checks of its
C++ decodeSplats in the same order and gives the same float32 values (each arithmetic step is
rounded to float32 as the C++ code rounds it).

Conventions: integers little-endian; positions in vu of the session grid (voxel (i, j, k) at
(i, j, k), y up); normals unit length, outward; colours sRGB bytes, mask 0 (free) .. 255
(frozen). Layout:
  header, 16 bytes: "MZSP", u16 version (1 or 2), u16 reserved = 0, u32 B bricks, u32 total points
  B blocks: u16 brick x, y, z (voxel / 8), u16 N, then the points. Version 1: N is the count
  (0..512; 0 = the brick has no points), each point a u64. Version 2: N's bits 0..9 are the
  count n, bit 15 is set for a painted brick (then n >= 1), bits 10..14 are 0; a painted
  brick's points are 12 bytes (the u64, then u8 r, g, b, mask), an unpainted brick's the u64
  alone, in the session's base_color with mask 0. Nothing after the last block.
  The u64: bits 0..13 X, 14..27 Y, 28..41 Z (position codes), 42..52 U, 53..63 V (octahedral
  normal).
  Position per axis: 8 * brick - 2 + C * 3 / 4096, i.e. [-2, 10) vu around the brick origin.
  Normal: u = (2U - 2047) / 2047, v = (2V - 2047) / 2047, z = 1 - |u| - |v|; where z < 0,
  (u, v) <- ((1 - |v|) sign(u), (1 - |u|) sign(v)) with sign(0) = +1; n = (u, v, z) / |(u, v, z)|.
decode_splats takes untrusted bytes; for bad content it raises SplatError (a ValueError) only.
Positions and normals come as array('f') of x, y, z per point, colours as array('B') of r, g,
b, mask per point, one of each for the whole buffer, with per-brick slices given as point
ranges.
"""

from __future__ import annotations

import enum
import math
import struct
from array import array
from dataclasses import dataclass

SPLAT_HEADER_BYTES = 16
SPLAT_BRICK_HEADER_BYTES = 8
SPLAT_POINT_BYTES = 8
SPLAT_PAINTED_POINT_BYTES = 12  # version 2, painted bricks
SPLAT_FORMAT_VERSION = 2  # the newest, which a client opts into with `splats: 2`
SPLAT_PAINTED_BIT = 0x8000  # version 2, in a block's N
SPLAT_COUNT_MASK = 0x03FF  # version 2, in a block's N
# The clay colour (server/engine/channels.hpp kClayColor): a session's base colour by default.
CLAY_COLOR = (221, 181, 155)
MAX_POINTS_PER_BRICK = 512
BRICK_SIDE = 8
# Position quantization: the step between codes and the largest error of a decoded coordinate.
POSITION_STEP = 3 / 4096
POSITION_ERROR = POSITION_STEP / 2

_MAGIC = b"MZSP"
_HEADER = struct.Struct("<HHII")  # version, reserved, bricks, points (after the magic)
_BRICK = struct.Struct("<HHHH")
_POS_MASK = 0x3FFF
_OCT_MAX = 2047


class SplatErrorCode(str, enum.Enum):
    TRUNCATED = "truncated"  # the bytes end inside the header, a brick header or a brick's points
    BAD_MAGIC = "bad_magic"  # bytes 0-3 are not "MZSP"
    BAD_VERSION = "bad_version"  # version other than 1 and 2
    BAD_RESERVED = "bad_reserved"  # the reserved header field is not 0
    COUNTS_TOO_LARGE = "counts_too_large"  # B or the point total exceeds what the bytes can hold
    BRICK_TOO_LARGE = "brick_too_large"  # a brick claims more than 512 points
    BAD_BRICK_WORD = "bad_brick_word"  # version 2: N's bits 10..14 set, or painted without points
    TRAILING_BYTES = "trailing_bytes"  # bytes after the last brick block
    POINT_COUNT_MISMATCH = "point_count_mismatch"  # the header's total differs from the blocks' sum
    REPEATED_BRICK = "repeated_brick"  # a brick listed twice


class SplatError(ValueError):
    def __init__(self, code: SplatErrorCode, message: str):
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class BrickSplats:
    brick: tuple  # (x, y, z) in bricks (voxel / 8)
    first: int  # index of its first point in the buffer-wide arrays
    count: int  # 0: the brick has no points (a delta removes it)
    painted: bool = False  # version 2: its points carried their own colours and masks


@dataclass(frozen=True)
class SplatBuffer:
    version: int
    point_count: int
    positions: array  # 'f', x, y, z per point, vu
    normals: array  # 'f', x, y, z per point, unit length
    bricks: list  # BrickSplats in buffer order
    colors: array  # 'B', r, g, b, mask per point (unpainted: the base colour, mask 0)

    def brick_positions(self, b: BrickSplats) -> array:
        return self.positions[3 * b.first : 3 * (b.first + b.count)]

    def brick_normals(self, b: BrickSplats) -> array:
        return self.normals[3 * b.first : 3 * (b.first + b.count)]

    def brick_colors(self, b: BrickSplats) -> array:
        return self.colors[4 * b.first : 4 * (b.first + b.count)]


def _f32(values) -> list:
    """Every value rounded to the nearest float32, as C++ rounds each float operation: the
    double result of one +, -, *, / or sqrt of float32 inputs rounds to the same float32."""
    return array("f", values).tolist()


# Per 11-bit normal code c: the coordinate (2c - 2047) / 2047 (never 0: 2047 is odd), 1 - |it|
# (the other coordinate after the fold), and the float32 squares of both.
_OCT = _f32((2 * c - _OCT_MAX) / _OCT_MAX for c in range(_OCT_MAX + 1))
_ONE_MINUS = _f32(1 - abs(x) for x in _OCT)
_SQUARE = _f32(x * x for x in _OCT)
_FOLDED_SQUARE = _f32(x * x for x in _ONE_MINUS)


def _read_count(word: int, version: int):
    """A block's N in `version`: (n, painted, error code or None)."""
    if version == 1:
        return word, False, SplatErrorCode.BRICK_TOO_LARGE if word > MAX_POINTS_PER_BRICK else None
    n = word & SPLAT_COUNT_MASK
    painted = bool(word & SPLAT_PAINTED_BIT)
    if word & ~(SPLAT_COUNT_MASK | SPLAT_PAINTED_BIT) or (painted and n == 0):
        return n, painted, SplatErrorCode.BAD_BRICK_WORD
    return n, painted, SplatErrorCode.BRICK_TOO_LARGE if n > MAX_POINTS_PER_BRICK else None


def decode_splats(data, base_color=CLAY_COLOR) -> SplatBuffer:
    """Decodes a whole splat buffer (bytes, bytearray or memoryview) of version 1 or 2; the
    points of unpainted bricks (all of version 1) take `base_color` (the session's) with mask 0.

    Checks, in the order of the C++ decoder: header length, magic, version, reserved field,
    counts against the byte length, then per block its header, its N and its points, then
    trailing bytes, the point total and repeated bricks.
    """
    view = memoryview(data).cast("B")
    size = len(view)
    if size < SPLAT_HEADER_BYTES:
        raise SplatError(SplatErrorCode.TRUNCATED, f"truncated: {size} bytes, the header alone takes 16")
    if view[:4] != _MAGIC:
        raise SplatError(SplatErrorCode.BAD_MAGIC, "not a splat buffer (wrong magic bytes)")
    version, reserved, brick_count, point_count = _HEADER.unpack_from(view, 4)
    if version not in (1, 2):
        raise SplatError(SplatErrorCode.BAD_VERSION, f"unsupported version {version} (this decoder reads versions 1 and 2)")
    if reserved != 0:
        raise SplatError(SplatErrorCode.BAD_RESERVED, "reserved header bytes must be 0")
    room = (size - SPLAT_HEADER_BYTES) // SPLAT_BRICK_HEADER_BYTES
    if brick_count > room or point_count > room:
        raise SplatError(
            SplatErrorCode.COUNTS_TOO_LARGE,
            f"counts ({brick_count} bricks, {point_count} points) exceed what {size} bytes can hold",
        )

    # Pass 1: the structure, from the brick headers alone.
    bricks = []
    seen = set()
    repeated = False
    at = SPLAT_HEADER_BYTES
    points = 0
    for i in range(brick_count):
        if size - at < SPLAT_BRICK_HEADER_BYTES:
            raise SplatError(SplatErrorCode.TRUNCATED, f"truncated in the header of brick block {i}")
        bx, by, bz, word = _BRICK.unpack_from(view, at)
        n, painted, code = _read_count(word, version)
        at += SPLAT_BRICK_HEADER_BYTES
        if code is SplatErrorCode.BRICK_TOO_LARGE:
            raise SplatError(code, f"brick block {i} claims {n} points (at most 512)")
        if code is not None:
            raise SplatError(code, f"brick block {i} has N = {word} (bits 10..14 must be 0, a painted brick has points)")
        point_bytes = SPLAT_PAINTED_POINT_BYTES if painted else SPLAT_POINT_BYTES
        if (size - at) // point_bytes < n:
            raise SplatError(SplatErrorCode.TRUNCATED, f"truncated in the points of brick block {i}")
        bricks.append((BrickSplats((bx, by, bz), points, n, painted), at))
        at += n * point_bytes
        points += n
        key = (bx, by, bz)
        repeated = repeated or key in seen
        seen.add(key)
    if at != size:
        raise SplatError(SplatErrorCode.TRAILING_BYTES, f"{size - at} trailing bytes after the last brick block")
    if points != point_count:
        raise SplatError(
            SplatErrorCode.POINT_COUNT_MISMATCH,
            f"the header announces {point_count} points, the blocks hold {points}",
        )
    if repeated:
        raise SplatError(SplatErrorCode.REPEATED_BRICK, "a brick is listed twice")

    # Pass 2: the points, one list per quantity, rounded to float32 after every operation.
    words = []
    origins = []
    colors = array("B", bytes(4 * point_count))
    base = bytes((base_color[0], base_color[1], base_color[2], 0))
    for b, offset in bricks:
        if b.painted:
            stride = SPLAT_PAINTED_POINT_BYTES
            words.extend(struct.unpack_from("<Q", view, offset + k * stride)[0] for k in range(b.count))
            for k in range(b.count):
                at = offset + k * stride + SPLAT_POINT_BYTES
                colors[4 * (b.first + k) : 4 * (b.first + k + 1)] = array("B", view[at : at + 4])
        else:
            words.extend(struct.unpack_from(f"<{b.count}Q", view, offset))
            colors[4 * b.first : 4 * (b.first + b.count)] = array("B", base * b.count)
        origin = (BRICK_SIDE * b.brick[0] - 2, BRICK_SIDE * b.brick[1] - 2, BRICK_SIDE * b.brick[2] - 2)
        origins.extend([origin] * b.count)
    # (8 * brick - 2) + C * 3/4096 is exact in double and rounds once, as the float sum does.
    xs = [o[0] + (w & _POS_MASK) * POSITION_STEP for o, w in zip(origins, words)]
    ys = [o[1] + ((w >> 14) & _POS_MASK) * POSITION_STEP for o, w in zip(origins, words)]
    zs = [o[2] + ((w >> 28) & _POS_MASK) * POSITION_STEP for o, w in zip(origins, words)]
    # Normals: what depends on one code alone comes from the tables.
    codes_u = [(w >> 42) & 0x7FF for w in words]
    codes_v = [w >> 53 for w in words]
    ws = _f32([_ONE_MINUS[cu] - abs(_OCT[cv]) for cu, cv in zip(codes_u, codes_v)])
    folded_u = [_OCT[cu] if w >= 0 else math.copysign(_ONE_MINUS[cv], _OCT[cu])
                for cu, cv, w in zip(codes_u, codes_v, ws)]
    folded_v = [_OCT[cv] if w >= 0 else math.copysign(_ONE_MINUS[cu], _OCT[cv])
                for cu, cv, w in zip(codes_u, codes_v, ws)]
    sums = _f32([(_SQUARE[cu] + _SQUARE[cv]) if w >= 0 else (_FOLDED_SQUARE[cv] + _FOLDED_SQUARE[cu])
                 for cu, cv, w in zip(codes_u, codes_v, ws)])
    sums = _f32([s + q for s, q in zip(sums, _f32([w * w for w in ws]))])
    inv = _f32([1 / r for r in _f32([math.sqrt(s) for s in sums])])

    positions = array("f", [0.0]) * (3 * point_count)
    normals = array("f", [0.0]) * (3 * point_count)
    positions[0::3] = array("f", xs)
    positions[1::3] = array("f", ys)
    positions[2::3] = array("f", zs)
    normals[0::3] = array("f", [u * k for u, k in zip(folded_u, inv)])
    normals[1::3] = array("f", [v * k for v, k in zip(folded_v, inv)])
    normals[2::3] = array("f", [w * k for w, k in zip(ws, inv)])
    return SplatBuffer(version, point_count, positions, normals, [b for b, _ in bricks], colors)
