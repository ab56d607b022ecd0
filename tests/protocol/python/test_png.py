"""protocol/python/marzipan/png.py: PNGs written here with every row filter and colour type
(from the PNG specification's definitions, not the decoder's code) decode to their pixels;
damage is refused."""

import struct
import unittest
import zlib

from support import XorShift

from marzipan.png import PngError, decode_png, png_size


def paeth(a, b, c):
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb and pa <= pc:
        return a
    return b if pb <= pc else c


def filtered_row(kind, row, previous, bpp):
    """Filter type `kind` applied to one row (PNG specification, section 9.2)."""
    out = bytearray()
    for i, x in enumerate(row):
        a = row[i - bpp] if i >= bpp else 0
        b = previous[i]
        c = previous[i - bpp] if i >= bpp else 0
        predictor = [0, a, b, (a + b) // 2, paeth(a, b, c)][kind] if kind <= 4 else 0
        out.append((x - predictor) & 0xFF)
    return bytes([kind]) + bytes(out)


def make_png(width, height, colour, pixels, filters, chunk_size=None):
    bpp = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    stride = width * bpp
    raw = bytearray()
    previous = bytes(stride)
    for y in range(height):
        row = pixels[y * stride:(y + 1) * stride]
        raw += filtered_row(filters[y % len(filters)], row, previous, bpp)
        previous = row
    data = zlib.compress(bytes(raw))
    chunk_size = chunk_size or len(data)

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    idats = b"".join(chunk(b"IDAT", data[i:i + chunk_size]) for i in range(0, len(data), chunk_size))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, colour, 0, 0, 0))
            + chunk(b"tEXt", b"Comment\x00marzipan") + idats + chunk(b"IEND", b""))


class DecodePng(unittest.TestCase):
    def test_every_filter_and_colour_type_decodes_to_the_pixels(self):
        rng = XorShift(5)
        for colour, channels in ((0, 1), (2, 3), (4, 2), (6, 4)):
            width, height = 13, 10
            pixels = bytes(rng.below(256) for _ in range(width * height * channels))
            for filters in ([0], [1], [2], [3], [4], [0, 1, 2, 3, 4]):
                data = make_png(width, height, colour, pixels, filters, chunk_size=37)
                with self.subTest(colour=colour, filters=filters):
                    self.assertEqual(decode_png(data), (width, height, channels, pixels))
                    self.assertEqual(png_size(data), (width, height))

    def test_damage_is_refused(self):
        good = make_png(4, 3, 2, bytes(range(36)), [4])
        decode_png(good)
        crc_broken = bytearray(good)
        crc_broken[40] ^= 1
        cases = [
            good[:20], b"GIF89a" + good[6:], bytes(crc_broken), good[:-12],
            make_png(4, 3, 2, bytes(range(36)), [5]),
        ]
        for data in cases:
            with self.assertRaises(PngError):
                decode_png(data)
        sixteen_bit = bytearray(good)
        sixteen_bit[24] = 16
        with self.assertRaises(PngError):
            decode_png(bytes(sixteen_bit))


if __name__ == "__main__":
    unittest.main()
