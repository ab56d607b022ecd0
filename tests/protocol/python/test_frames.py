"""protocol/python/marzipan/frames.py against the golden vectors and the checks of
protocol/cpp/frames.cpp (tests/protocol/test_frames.cpp and tests/protocol/js do the same)."""

import re
import unittest

from support import PROTOCOL_MD, VECTORS, XorShift

from marzipan.frames import (
    FRAME_HEADER_BYTES,
    FrameError,
    FrameErrorCode,
    FrameKind,
    decode_frame,
    encode_frame,
    frame_kind_name,
)


class GoldenVectors(unittest.TestCase):
    def test_every_binary_vector_decodes_to_its_fields_and_re_encodes_to_its_bytes(self):
        kinds = set()
        self.assertGreaterEqual(len(VECTORS["binary"]), 9)
        for v in VECTORS["binary"]:
            with self.subTest(v["name"]):
                data = bytes.fromhex(v["hex"])
                frame = decode_frame(data)
                want = v["header"]
                self.assertEqual(frame.header.version, want["version"])
                self.assertEqual(frame.kind, want["kind"])
                self.assertEqual(frame_kind_name(frame.kind), want["kind_name"])
                self.assertEqual(frame.request_id, want["request_id"])
                self.assertEqual(frame.revision, int(want["revision"]))
                self.assertEqual(str(frame.revision), want["revision"])
                self.assertEqual(frame.header.payload_length, want["payload_length"])
                self.assertEqual(bytes(frame.payload), bytes.fromhex(v["payload_hex"]))
                self.assertIs(frame.payload.obj, data, "the payload is a view of the input, not a copy")
                self.assertEqual(encode_frame(frame.kind, frame.request_id, frame.revision, frame.payload), data)
                kinds.add(frame.kind)
        self.assertEqual(kinds, set(range(1, 12)))

    def test_bytearray_and_memoryview_at_an_offset_decode_alike(self):
        for v in VECTORS["binary"]:
            data = bytes.fromhex(v["hex"])
            padded = bytearray(3) + data + bytearray(5)
            for source in (bytearray(data), memoryview(padded)[3:3 + len(data)]):
                frame = decode_frame(source)
                self.assertEqual(frame.revision, int(v["header"]["revision"]), v["name"])
                self.assertEqual(bytes(frame.payload), bytes.fromhex(v["payload_hex"]), v["name"])
        with self.assertRaises(TypeError):
            decode_frame("MZPN")

    def test_frame_kind_names_are_those_of_the_vectors(self):
        for v in VECTORS["binary"]:
            self.assertEqual(FrameKind[v["header"]["kind_name"].upper()], v["header"]["kind"], v["name"])
        self.assertEqual([int(k) for k in FrameKind], list(range(1, 12)))
        for k in (0, 12, 65535, -1):
            self.assertEqual(frame_kind_name(k), "")

    def test_invalid_vectors_are_refused_with_their_code(self):
        codes = set()
        for v in VECTORS["binary_invalid"]:
            with self.subTest(v["name"]):
                limit = v.get("max_payload")
                with self.assertRaises(FrameError) as caught:
                    if limit is None:
                        decode_frame(bytes.fromhex(v["hex"]))
                    else:
                        decode_frame(bytes.fromhex(v["hex"]), max_payload=limit)
                self.assertEqual(caught.exception.code.value, v["error"])
                self.assertTrue(str(caught.exception))
                codes.add(caught.exception.code)
        self.assertEqual(codes, set(FrameErrorCode))

    def test_the_example_of_protocol_md_is_a_vector(self):
        line = re.search(r"`(4d5a504e [0-9a-f ]+)` then 16 payload bytes", PROTOCOL_MD).group(1)
        header = bytes.fromhex(line.replace(" ", ""))
        self.assertEqual(len(header), FRAME_HEADER_BYTES)
        matches = [v for v in VECTORS["binary"] if v["hex"].startswith(header.hex())]
        self.assertEqual(len(matches), 1)
        frame = decode_frame(bytes.fromhex(matches[0]["hex"]))
        self.assertEqual((frame.kind, frame.request_id, frame.revision), (FrameKind.SPLATS_FULL, 18, 64))


class Checks(unittest.TestCase):
    def test_limit_is_inclusive_and_checked_before_the_length(self):
        data = encode_frame(FrameKind.MESH_OBJ, 5, 9, b"x" * 16)
        self.assertEqual(len(decode_frame(data, max_payload=16).payload), 16)
        with self.assertRaises(FrameError) as caught:
            decode_frame(data[:-3], max_payload=15)
        self.assertEqual(caught.exception.code, FrameErrorCode.TOO_LARGE)

    def test_every_proper_prefix_is_refused(self):
        data = encode_frame(FrameKind.FRAME_PNG, 77, 3, bytes(range(40)))
        for n in range(len(data)):
            with self.assertRaises(FrameError) as caught:
                decode_frame(data[:n])
            want = FrameErrorCode.SHORT_HEADER if n < FRAME_HEADER_BYTES else FrameErrorCode.LENGTH_MISMATCH
            self.assertEqual(caught.exception.code, want, n)

    def test_random_damage_raises_frame_error_only(self):
        rng = XorShift(11)
        base = encode_frame(FrameKind.SPLATS_DELTA, 0, 65, bytes(range(40)))
        decoded = 0
        for _ in range(3000):
            data = bytearray(base[: rng.below(len(base) + 6)])
            for _ in range(3):
                if data:
                    data[rng.below(len(data))] = rng.below(256)
            try:
                frame = decode_frame(data)
            except FrameError as e:
                self.assertIn(e.code, set(FrameErrorCode))
                continue
            decoded += 1
            self.assertEqual(len(frame.payload), frame.header.payload_length)
            self.assertTrue(1 <= frame.kind <= 9)
        self.assertGreater(decoded, 0)

    def test_encode_refuses_what_the_header_cannot_hold(self):
        for kind, request_id, revision in [
            (0, 1, 0), (12, 1, 0), (True, 1, 0), (1, -1, 0), (1, 1 << 32, 0), (1, 1.0, 0),
            (1, 1, -1), (1, 1, 1 << 64), (1, 1, 2.0),
        ]:
            with self.assertRaises(ValueError, msg=(kind, request_id, revision)):
                encode_frame(kind, request_id, revision, b"")
        data = encode_frame(FrameKind.VOLUME_UPLOAD, 0xFFFFFFFF, (1 << 64) - 1, b"abc")
        self.assertEqual(data[:24].hex(), "4d5a504e01000900ffffffffffffffffffffffff03000000")


if __name__ == "__main__":
    unittest.main()
