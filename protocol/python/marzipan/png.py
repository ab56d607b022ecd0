"""Reading the PNG frames the server renders (render.frame with format "png"), with the
standard library only: enough to measure a frame (the gradient-error image of Bærentzen's
Fig. 7.13 stores | |grad d| - 1 | as a grey level) without an imaging package.

Supports what a PNG writer of 8-bit images produces: bit depth 8, colour types grey (0), RGB
(2), grey + alpha (4) and RGBA (6), no interlace, any of the five row filters. Integers in PNG
are big-endian. Pixels come as bytes, rows top to bottom, `channels` bytes per pixel.
"""

from __future__ import annotations

import struct
import zlib

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_CHANNELS = {0: 1, 2: 3, 4: 2, 6: 4}


class PngError(ValueError):
    pass


def png_size(data) -> tuple:
    """(width, height) from the IHDR chunk, which a PNG file must start with."""
    data = bytes(data[:24])
    if len(data) < 24 or data[:8] != PNG_SIGNATURE or data[12:16] != b"IHDR":
        raise PngError("not a PNG file (signature or IHDR missing)")
    return struct.unpack(">II", data[16:24])


def _chunks(data: bytes):
    at = len(PNG_SIGNATURE)
    while at + 12 <= len(data):
        (length,) = struct.unpack_from(">I", data, at)
        kind = data[at + 4 : at + 8]
        body = data[at + 8 : at + 8 + length]
        if len(body) != length or at + 12 + length > len(data):
            raise PngError(f"chunk {kind!r} is truncated")
        (crc,) = struct.unpack_from(">I", data, at + 8 + length)
        if zlib.crc32(kind + body) != crc:
            raise PngError(f"chunk {kind!r} fails its CRC")
        yield kind, body
        if kind == b"IEND":
            return
        at += 12 + length
    raise PngError("no IEND chunk")


def decode_png(data) -> tuple:
    """(width, height, channels, pixels) of an 8-bit, non-interlaced PNG."""
    data = bytes(data)
    width, height = png_size(data)
    depth, colour, compression, filtering, interlace = struct.unpack_from(">BBBBB", data, 24)
    if depth != 8 or colour not in _CHANNELS or compression or filtering or interlace:
        raise PngError(f"unsupported PNG (bit depth {depth}, colour type {colour}, interlace {interlace})")
    channels = _CHANNELS[colour]
    compressed = b"".join(body for kind, body in _chunks(data) if kind == b"IDAT")
    try:
        raw = zlib.decompress(compressed)
    except zlib.error as e:
        raise PngError(f"image data does not inflate: {e}") from None
    stride = width * channels
    if len(raw) != height * (stride + 1):
        raise PngError(f"image data holds {len(raw)} bytes, {height * (stride + 1)} expected")
    out = bytearray(height * stride)
    previous = bytearray(stride)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        row = bytearray(raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)])
        if kind == 1:  # Sub
            for i in range(channels, stride):
                row[i] = (row[i] + row[i - channels]) & 0xFF
        elif kind == 2:  # Up
            row = bytearray((a + b) & 0xFF for a, b in zip(row, previous))
        elif kind == 3:  # Average
            for i in range(stride):
                left = row[i - channels] if i >= channels else 0
                row[i] = (row[i] + ((left + previous[i]) >> 1)) & 0xFF
        elif kind == 4:  # Paeth
            for i in range(stride):
                a = row[i - channels] if i >= channels else 0
                b = previous[i]
                c = previous[i - channels] if i >= channels else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                predictor = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                row[i] = (row[i] + predictor) & 0xFF
        elif kind != 0:
            raise PngError(f"row {y} has unknown filter type {kind}")
        out[y * stride : (y + 1) * stride] = row
        previous = row
    return width, height, channels, bytes(out)

