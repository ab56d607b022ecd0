"""protocol/python/marzipan/splats.py: the splat payloads of the golden vectors, round trips
through an encoder written here from the description in protocol/cpp/splats.hpp, every
refusal, and bit-equality with the JavaScript decoder (protocol/js/splats.js), which mirrors the
C++ one, when node is installed."""

import json
import math
import shutil
import struct
import subprocess
import unittest

from support import REPO, VECTORS, XorShift

from marzipan.frames import FrameKind, decode_frame
from marzipan.splats import (
    BRICK_SIDE,
    POSITION_ERROR,
    SPLAT_BRICK_HEADER_BYTES,
    SPLAT_HEADER_BYTES,
    SPLAT_POINT_BYTES,
    SplatError,
    SplatErrorCode,
    decode_splats,
)

# splats.hpp: "error about 0.12 degrees at most" for normals.
NORMAL_ERROR_DEGREES = 0.125


def encode_splats(bricks, version=1, reserved=0, brick_count=None, point_count=None):
    """The encoder of splats.hpp. `bricks`: [(brick (x, y, z), [(x, y, z, nx, ny, nz), ...],
    count or None)]. C = round((q - 8 brick + 2) * 16384 / 12) clamped to [0, 16383]; n projected
    onto the octahedron, the lower half folded, (c + 1) * 2047 / 2 rounded and clamped."""
    total = sum(len(points) for _, points, _ in bricks)
    out = bytearray(b"MZSP")
    out += struct.pack("<HHII", version, reserved, len(bricks) if brick_count is None else brick_count,
                       total if point_count is None else point_count)

    def sign(x):
        return -1.0 if x < 0 else 1.0

    def pos_code(q, b):
        return min(16383, max(0, round((q - BRICK_SIDE * b + 2) * (16384 / 12))))

    def oct_code(c):
        return min(2047, max(0, round((c + 1) * 2047 / 2)))

    for brick, points, count in bricks:
        out += struct.pack("<HHHH", *brick, len(points) if count is None else count)
        for x, y, z, nx, ny, nz in points:
            l1 = abs(nx) + abs(ny) + abs(nz)
            u, v = nx / l1, ny / l1
            if nz < 0:
                u, v = (1 - abs(v)) * sign(u), (1 - abs(u)) * sign(v)
            word = (pos_code(x, brick[0]) | pos_code(y, brick[1]) << 14 | pos_code(z, brick[2]) << 28
                    | oct_code(u) << 42 | oct_code(v) << 53)
            out += struct.pack("<Q", word)
    return bytes(out)


def angle_degrees(a, b):
    dot = sum(p * q for p, q in zip(a, b))
    return math.degrees(math.acos(min(1.0, dot)))


def random_bricks(rng, n):
    bricks = []
    for b in range(n):
        brick = (b, 3 * b + 1, 63 - b)
        count = 0 if b == 5 else 512 if b == 6 else 1 + rng.below(40)
        points = []
        for k in range(count):
            q = [BRICK_SIDE * c - 2 + rng.uniform() * 11.99 for c in brick]
            normal = [rng.uniform() * 2 - 1 for _ in range(3)]
            normal = [[0, 0, -1], [1, 0, 0], [0, -1, 0]][k] if k < 3 else normal
            length = math.sqrt(sum(c * c for c in normal)) or 1.0
            points.append((*q, *(c / length for c in normal)))
        bricks.append((brick, points, None))
    return bricks


class GoldenVectors(unittest.TestCase):
    def test_the_splat_payloads_of_the_vectors_decode(self):
        seen = 0
        for v in VECTORS["binary"]:
            if v["header"]["kind"] not in (FrameKind.SPLATS_FULL, FrameKind.SPLATS_DELTA):
                continue
            with self.subTest(v["name"]):
                buffer = decode_splats(decode_frame(bytes.fromhex(v["hex"])).payload)
                self.assertEqual(buffer.version, 1)
                # 16 + 8 B + 8 P bytes: the counts account for every byte of the payload.
                self.assertEqual(SPLAT_HEADER_BYTES + SPLAT_BRICK_HEADER_BYTES * len(buffer.bricks)
                                 + SPLAT_POINT_BYTES * buffer.point_count, v["header"]["payload_length"])
                again = decode_splats(bytes.fromhex(v["payload_hex"]))
                self.assertEqual((again.bricks, again.positions, again.normals),
                                 (buffer.bricks, buffer.positions, buffer.normals))
                seen += 1
        self.assertGreaterEqual(seen, 2)

    def test_the_delta_vector_holds_an_emptied_brick_and_one_point(self):
        v = next(v for v in VECTORS["binary"] if v["name"].startswith("splat delta push"))
        buffer = decode_splats(decode_frame(bytes.fromhex(v["hex"])).payload)
        self.assertEqual([(b.brick, b.count) for b in buffer.bricks], [((1, 2, 3), 0), ((4, 5, 6), 1)])
        # The point's word, 0x7fdff00400c00100: X = 256, Y = 768, Z = 64, U = 2044, V = 1022.
        word = struct.unpack("<Q", bytes.fromhex("0001c00004f0df7f"))[0]
        self.assertEqual([word & 0x3FFF, word >> 14 & 0x3FFF, word >> 28 & 0x3FFF, word >> 42 & 0x7FF, word >> 53],
                         [256, 768, 64, 2044, 1022])
        self.assertEqual(list(buffer.positions), [30.1875, 38.5625, 46.046875])
        u, v_ = (2 * 2044 - 2047) / 2047, (2 * 1022 - 2047) / 2047
        z = 1 - abs(u) - abs(v_)
        length = math.sqrt(u * u + v_ * v_ + z * z)
        for got, want in zip(buffer.normals, (u / length, v_ / length, z / length)):
            self.assertAlmostEqual(got, want, delta=1e-6)


class RoundTrips(unittest.TestCase):
    def check_geometry(self, buffer):
        counted = 0
        for b in buffer.bricks:
            positions, normals = buffer.brick_positions(b), buffer.brick_normals(b)
            self.assertEqual((len(positions), len(normals)), (3 * b.count, 3 * b.count))
            self.assertEqual(b.first, counted)
            for k in range(0, 3 * b.count, 3):
                for axis in range(3):
                    lo = BRICK_SIDE * b.brick[axis] - 2
                    self.assertTrue(lo <= positions[k + axis] < lo + 12)
                self.assertAlmostEqual(math.sqrt(sum(c * c for c in normals[k:k + 3])), 1, delta=1e-6)
            counted += b.count
        self.assertEqual(counted, buffer.point_count)

    def test_points_round_trip_within_the_documented_quantization(self):
        bricks = random_bricks(XorShift(7), 20)
        buffer = decode_splats(encode_splats(bricks))
        self.check_geometry(buffer)
        self.assertEqual([b.brick for b in buffer.bricks], [b for b, _, _ in bricks])
        worst = 0.0
        for b, (_, points, _) in zip(buffer.bricks, bricks):
            self.assertEqual(b.count, len(points))
            positions, normals = buffer.brick_positions(b), buffer.brick_normals(b)
            for k, p in enumerate(points):
                for axis in range(3):
                    self.assertLessEqual(abs(positions[3 * k + axis] - p[axis]), POSITION_ERROR + 1e-6)
                worst = max(worst, angle_degrees(normals[3 * k:3 * k + 3], p[3:]))
        self.assertLessEqual(worst, NORMAL_ERROR_DEGREES)
        self.assertGreater(worst, 0.01, "the normals really went through the 11-bit codes")

    def test_codes_at_the_ends_of_their_ranges(self):
        buffer = decode_splats(encode_splats([((0, 0, 0), [(-2, -2, -2, 0, 0, 1), (10, 10, 10, 1, 0, 0),
                                                           (0, 4, 8, 0, 0, -1)], None)]))
        top = 10 - 3 / 4096
        self.assertEqual(list(buffer.positions[:6]), [-2.0, -2.0, -2.0, top, top, top])
        for k, want in enumerate([(0, 0, 1), (1, 0, 0), (0, 0, -1)]):
            self.assertLess(angle_degrees(buffer.normals[3 * k:3 * k + 3], want), NORMAL_ERROR_DEGREES)

    @unittest.skipUnless(shutil.which("node"), "node (Debian nodejs) compares with protocol/js/splats.js")
    def test_floats_equal_those_of_the_javascript_decoder_bit_for_bit(self):
        data = encode_splats(random_bricks(XorShift(21), 12))
        script = (
            "import { decodeSplats } from " + json.dumps((REPO / "protocol/js/splats.js").as_uri()) + ";"
            "const hex = process.argv[1];"
            "const bytes = Uint8Array.from(hex.match(/../g), (h) => parseInt(h, 16));"
            "const r = decodeSplats(bytes);"
            "const out = (a) => Buffer.from(a.buffer, a.byteOffset, a.byteLength).toString('hex');"
            "console.log(JSON.stringify({positions: out(r.positions), normals: out(r.normals)}));"
        )
        result = subprocess.run(["node", "--input-type=module", "-e", script, data.hex()],
                                capture_output=True, text=True, check=True)
        js = json.loads(result.stdout)
        buffer = decode_splats(data)
        self.assertEqual(buffer.positions.tobytes().hex(), js["positions"])
        self.assertEqual(buffer.normals.tobytes().hex(), js["normals"])


class Refusals(unittest.TestCase):
    TWO = [((1, 2, 3), [(9, 17, 25, 0, 0, 1)], None),
           ((4, 5, 6), [(33, 41, 49, 1, 0, 0), (34, 42, 50, 0, 1, 0)], None)]

    def code_of(self, data):
        with self.assertRaises(SplatError) as caught:
            decode_splats(data)
        self.assertTrue(str(caught.exception))
        return caught.exception.code

    def test_invalid_buffers_are_refused_with_their_code(self):
        good = encode_splats(self.TWO)
        decode_splats(good)

        def with_byte(offset, value):
            data = bytearray(good)
            data[offset] = value
            return bytes(data)

        truncated, trailing = SplatErrorCode.TRUNCATED, SplatErrorCode.TRAILING_BYTES
        cases = [
            ("empty", b"", SplatErrorCode.TRUNCATED),
            ("15 bytes", good[:15], SplatErrorCode.TRUNCATED),
            ("magic MZSX", with_byte(3, 0x58), SplatErrorCode.BAD_MAGIC),
            ("a frame header's magic", with_byte(2, 0x50), SplatErrorCode.BAD_MAGIC),
            ("version 3", with_byte(4, 3), SplatErrorCode.BAD_VERSION),
            ("version 0", with_byte(4, 0), SplatErrorCode.BAD_VERSION),
            ("reserved 1", with_byte(6, 1), SplatErrorCode.BAD_RESERVED),
            ("brick count 2^32-1", encode_splats(self.TWO, brick_count=0xFFFFFFFF), SplatErrorCode.COUNTS_TOO_LARGE),
            ("point count 2^32-1", encode_splats(self.TWO, point_count=0xFFFFFFFF), SplatErrorCode.COUNTS_TOO_LARGE),
            ("a brick of 513 points", encode_splats([((0, 0, 0), [], 513)], point_count=0),
             SplatErrorCode.BRICK_TOO_LARGE),
            ("one brick block more than the bytes", encode_splats(self.TWO, brick_count=3), truncated),
            ("more points than the bytes", encode_splats([((0, 0, 0), [(1, 1, 1, 0, 0, 1)], 2)]), truncated),
            ("one byte too many", good + b"\x00", SplatErrorCode.TRAILING_BYTES),
            ("one brick block fewer than the bytes", encode_splats(self.TWO, brick_count=1), trailing),
            ("point total too small", encode_splats(self.TWO, point_count=2), SplatErrorCode.POINT_COUNT_MISMATCH),
            ("point total too large", encode_splats(self.TWO, point_count=4), SplatErrorCode.POINT_COUNT_MISMATCH),
            ("a brick listed twice", encode_splats(self.TWO + [((1, 2, 3), [], None)]), SplatErrorCode.REPEATED_BRICK),
        ]
        for name, data, code in cases:
            self.assertEqual(self.code_of(data), code, name)
        distinct = encode_splats([((1, 2, 3), [], None), ((3, 2, 1), [], None), ((1, 3, 2), [], None)])
        self.assertEqual(len(decode_splats(distinct).bricks), 3)

    # The buffer of tests/engine/test_splats.cpp's kGoldenV2 (the C++ encoder's bytes): brick
    # (1, 2, 3) painted, its point at (9, 17, 25) facing +z in (200, 20, 10) under mask 255;
    # brick (0, 0, 0) unpainted, its point at (-2, -2, 4) facing -z.
    GOLDEN_V2 = bytes([
        0x4D, 0x5A, 0x53, 0x50, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00,
        0x01, 0x00, 0x02, 0x00, 0x03, 0x00, 0x01, 0x80,
        0x00, 0x10, 0x00, 0x04, 0x00, 0x01, 0x10, 0x80, 0xC8, 0x14, 0x0A, 0xFF,
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00,
        0x00, 0x00, 0x00, 0x00, 0x00, 0xFE, 0xFF, 0xFF])

    def test_version_2_painted_bricks_carry_texels_unpainted_the_base_colour(self):
        buffer = decode_splats(self.GOLDEN_V2, base_color=(10, 20, 30))
        self.assertEqual(buffer.version, 2)
        self.assertEqual([b.painted for b in buffer.bricks], [True, False])
        self.assertEqual(list(buffer.positions), [9, 17, 25, -2, -2, 4])
        self.assertEqual(list(buffer.colors), [200, 20, 10, 255, 10, 20, 30, 0])
        self.assertEqual(list(buffer.brick_colors(buffer.bricks[0])), [200, 20, 10, 255])
        self.assertEqual(list(decode_splats(self.GOLDEN_V2).brick_colors(buffer.bricks[1])), [221, 181, 155, 0])
        v1 = decode_splats(encode_splats(self.TWO), base_color=(1, 2, 3))
        self.assertEqual(list(v1.colors), [1, 2, 3, 0] * v1.point_count)

    def test_version_2_inconsistent_brick_words_are_refused(self):
        def with_byte(offset, value):
            data = bytearray(self.GOLDEN_V2)
            data[offset] = value
            return bytes(data)
        for bit in range(10, 15):
            for block in (16, 36):
                data = bytearray(self.GOLDEN_V2)
                data[block + 7] |= 1 << (bit - 8)
                self.assertEqual(self.code_of(bytes(data)), SplatErrorCode.BAD_BRICK_WORD, (block, bit))
        painted_empty = bytes(self.GOLDEN_V2[:8]) + struct.pack("<II", 1, 0) + struct.pack("<HHHH", 0, 0, 0, 0x8000)
        self.assertEqual(self.code_of(painted_empty), SplatErrorCode.BAD_BRICK_WORD)
        self.assertEqual(self.code_of(with_byte(16 + 7, 0x82)), SplatErrorCode.BRICK_TOO_LARGE)
        self.assertEqual(self.code_of(with_byte(16 + 7, 0x00)), SplatErrorCode.TRAILING_BYTES)
        self.assertEqual(self.code_of(with_byte(36 + 7, 0x80)), SplatErrorCode.TRUNCATED)
        self.assertEqual(self.code_of(with_byte(4, 1)), SplatErrorCode.BRICK_TOO_LARGE)  # v1: 0x8001 points
        for n in range(len(self.GOLDEN_V2)):
            self.assertIn(self.code_of(self.GOLDEN_V2[:n]), (SplatErrorCode.TRUNCATED, SplatErrorCode.COUNTS_TOO_LARGE), n)

    def test_every_proper_prefix_is_refused(self):
        data = encode_splats([((0, 0, 0), [(1, 2, 3, 0, 0, 1), (2, 3, 4, 0, 1, 0)], None),
                              ((0, 0, 1), [], None), ((0, 1, 0), [(3, 9, 4, -1, 0, 0)], None)])
        for n in range(len(data)):
            self.assertIn(self.code_of(data[:n]), (SplatErrorCode.TRUNCATED, SplatErrorCode.COUNTS_TOO_LARGE), n)

    def test_random_damage_raises_splat_error_only(self):
        rng = XorShift(3)
        base = encode_splats([((2, 2, 2), [(17, 17, 17, 0, 0, 1), (18, 18, 18, 0, 1, 0)], None),
                              ((2, 2, 3), [(17, 17, 25, 1, 0, 0)], None)])
        for _ in range(3000):
            data = bytearray(base[: rng.below(len(base) + 9)])
            for _ in range(3):
                if data:
                    data[rng.below(len(data))] = rng.below(256)
            try:
                buffer = decode_splats(data)
            except SplatError as e:
                self.assertIn(e.code, set(SplatErrorCode))
                continue
            self.assertEqual(len(buffer.positions), 3 * buffer.point_count)
        with self.assertRaises(TypeError):
            decode_splats([1, 2, 3])


if __name__ == "__main__":
    unittest.main()
