"""tests/load/web_client_model.py: the browser's dab spacing and picking as the load tool does them.

Run: /usr/bin/python3 -m unittest discover -s tests/load -p "test_*.py"
The splat buffers here are built by hand in protocol/cpp/splats.hpp's layout (the server's
encoder is not in Python); positions are checked against the project's reference decoder.
"""

import math
import random
import struct
import sys
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "protocol" / "python"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from marzipan.splats import decode_splats  # noqa: E402
from web_client_model import DabSpacer, SplatSurface, StrokePicker, decode_points  # noqa: E402


def encode_normal(n):
    """Octahedral codes (U, V) of a unit normal, as protocol/cpp/splats.hpp encodes them."""
    s = abs(n[0]) + abs(n[1]) + abs(n[2])
    u, v = n[0] / s, n[1] / s
    if n[2] < 0:
        u, v = (1 - abs(v)) * (1 if u >= 0 else -1), (1 - abs(u)) * (1 if v >= 0 else -1)
    return round((u * 2047 + 2047) / 2), round((v * 2047 + 2047) / 2)


def splat_buffer(bricks, painted=None):
    """A splat buffer of {(bx, by, bz): [(point, normal), ...]} (an empty list: an empty brick);
    with `painted` (a set of brick keys) of version 2, those bricks' points each followed by
    r, g, b, mask."""
    body = b""
    total = 0
    for key, points in bricks.items():
        paint = painted is not None and key in painted and points
        body += struct.pack("<HHHH", *key, len(points) | (0x8000 if paint else 0))
        for p, n in points:
            codes = [round((p[a] - (8 * key[a] - 2)) * 4096 / 3) for a in range(3)]
            assert all(0 <= c < 1 << 14 for c in codes), (p, key)
            cu, cv = encode_normal(n)
            body += struct.pack("<Q", codes[0] | codes[1] << 14 | codes[2] << 28 | cu << 42 | cv << 53)
            if paint:
                body += bytes((200, 40, 40, 255))
        total += len(points)
    version = 1 if painted is None else 2
    return b"MZSP" + struct.pack("<HHII", version, 0, len(bricks), total) + body


def sphere_bricks(centre, radius, spacing=0.7):
    """Points of a sphere about `spacing` vu apart with their outward normals, by brick."""
    bricks = {}
    rings = int(math.pi * radius / spacing)
    for i in range(rings + 1):
        polar = math.pi * i / rings
        around = max(1, int(2 * math.pi * radius * math.sin(polar) / spacing))
        for j in range(around):
            az = 2 * math.pi * j / around
            n = (math.sin(polar) * math.cos(az), math.cos(polar), math.sin(polar) * math.sin(az))
            p = tuple(centre[a] + radius * n[a] for a in range(3))
            key = tuple(int(math.floor(c / 8)) for c in p)
            bricks.setdefault(key, []).append((p, n))
    return bricks


def brute_pick(pos, nrm, origin, direction, disc_radius=0.8):
    """web-client/math/splat-pick.js over every disc at once: the nearest front-facing hit."""
    o, d = np.asarray(origin), np.asarray(direction)
    facing = nrm @ d
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((pos - o) * nrm).sum(axis=1) / facing
    e = o + t[:, None] * d - pos
    ok = (facing < -1e-3) & (t >= 0) & ((e * e).sum(axis=1) <= disc_radius**2)
    return None if not ok.any() else o + t[ok].min() * d


class DabSpacerTest(unittest.TestCase):
    # The cases of tests/browser/unit/dab-spacer.test.mjs, which the browser's spacer passes.
    def test_first_hit_then_every_spacing(self):
        s = DabSpacer(2)
        dabs = []
        for k in range(29):
            dabs += s.add([0.7 * k, 5, 5], 1)
        self.assertEqual(dabs[0][0], [0, 5, 5])
        self.assertEqual(len(dabs), 1 + math.floor(19.6 / 2))
        for a, b in zip(dabs, dabs[1:]):
            self.assertAlmostEqual(math.dist(a[0], b[0]), 2, delta=1e-9)

    def test_spacing_is_measured_along_the_path_around_corners(self):
        s = DabSpacer(1.5)
        path = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0], [-3, 2, 0]]
        dabs = [d for p in path for d in s.add(p, 1)]
        self.assertEqual(len(dabs), 5)
        self.assertEqual(dabs[1][0], [1, 0.5, 0])
        self.assertEqual(dabs[2][0], [1, 2, 0])
        self.assertEqual(dabs[3][0], [-0.5, 2, 0])

    def test_pressure_and_fraction_are_interpolated(self):
        s = DabSpacer(1)
        s.add([0, 0, 0], 0.2)
        dabs = s.add([4, 0, 0], 1)
        self.assertEqual(len(dabs), 4)
        self.assertAlmostEqual(dabs[1][1], 0.6, delta=1e-12)
        self.assertEqual([d[2] for d in dabs], [0.25, 0.5, 0.75, 1.0])

    def test_a_miss_or_a_jump_starts_a_new_path(self):
        s = DabSpacer(1, 5)
        self.assertEqual(len(s.add([0, 0, 0], 1)), 1)
        self.assertEqual(s.add(None, 1), [])
        self.assertEqual([d[0] for d in s.add([30, 0, 0], 1)], [[30, 0, 0]])
        self.assertEqual([d[0] for d in s.add([60, 0, 0], 1)], [[60, 0, 0]])
        with self.assertRaises(ValueError):
            DabSpacer(0)


class SplatSurfaceTest(unittest.TestCase):
    def test_points_decode_as_the_reference_decoder_does(self):
        buf = splat_buffer(sphere_bricks((40.3, 41.7, 39.2), 12.5))
        surface = SplatSurface()
        surface.apply(buf, full=True)
        ref = decode_splats(buf)
        positions = np.frombuffer(ref.positions, dtype=np.float32).reshape(-1, 3)
        normals = np.frombuffer(ref.normals, dtype=np.float32).reshape(-1, 3)
        for b in ref.bricks:
            pos, nrm = decode_points([surface.bricks[tuple(b.brick)]])
            self.assertEqual(len(pos), b.count)
            # float32 against float64: within one float32 step of coordinates near 60 vu
            self.assertLess(np.abs(pos - positions[b.first:b.first + b.count]).max(), 1e-5)
            self.assertLess(np.abs(nrm - normals[b.first:b.first + b.count]).max(), 1e-6)

    def test_version_2_painted_or_not_gives_the_points_of_version_1(self):
        bricks = sphere_bricks((40.3, 41.7, 39.2), 12.5)
        plain = SplatSurface()
        plain.apply(splat_buffer(bricks), full=True)
        painted = SplatSurface()
        keys = sorted(bricks)
        painted.apply(splat_buffer(bricks, painted=set(keys[::2])), full=True)
        self.assertEqual(sorted(painted.bricks), keys)
        for key in keys:
            self.assertEqual(painted.bricks[key].words, plain.bricks[key].words)

    def test_a_delta_replaces_or_removes_only_the_bricks_it_lists(self):
        surface = SplatSurface()
        surface.apply(splat_buffer({(1, 1, 1): [((9, 9, 9), (0, 1, 0))], (2, 1, 1): [((17, 9, 9), (0, 1, 0))]}), True)
        before = surface.snapshot()
        surface.apply(splat_buffer({(1, 1, 1): [((10, 9, 9), (0, 1, 0)), ((11, 9, 9), (0, 1, 0))],
                                    (2, 1, 1): []}), full=False)
        self.assertEqual(sorted(surface.bricks), [(1, 1, 1)])
        self.assertEqual(len(decode_points([surface.bricks[(1, 1, 1)]])[0]), 2)
        # the snapshot taken before keeps the surface as it was
        self.assertEqual(sorted(b.key for b in before.bricks), [(1, 1, 1), (2, 1, 1)])
        self.assertEqual(len(decode_points(before.bricks)[0]), 2)
        surface.apply(splat_buffer({(5, 5, 5): [((41, 41, 41), (1, 0, 0))]}), full=True)
        self.assertEqual(sorted(surface.bricks), [(5, 5, 5)])


class StrokePickerTest(unittest.TestCase):
    def test_picks_what_picking_every_disc_picks(self):
        # Two spheres, one partly behind the other, picked by drags from random sides: every
        # pick along each drag equals the nearest front-facing disc over all discs.
        bricks = sphere_bricks((40, 40, 40), 14)
        for key, points in sphere_bricks((52, 44, 36), 9).items():
            bricks.setdefault(key, []).extend(points)
        surface = SplatSurface()
        surface.apply(splat_buffer(bricks), full=True)
        snapshot = surface.snapshot()
        pos, nrm = decode_points(snapshot.bricks)
        rng = random.Random(4)
        hits = misses = 0
        for _ in range(12):
            d = np.array([rng.uniform(-1, 1) for _ in range(3)])
            d /= np.linalg.norm(d)
            right = np.cross([0.0, 1.0, 0.0], -d)
            right /= np.linalg.norm(right)
            up = np.cross(-d, right)
            eye = np.array([44.0, 42, 38]) - 150 * d
            a = eye + right * rng.uniform(-25, 25) + up * rng.uniform(-20, 20)
            b = eye + right * rng.uniform(-25, 25) + up * rng.uniform(-20, 20)
            picker = StrokePicker(snapshot, a.tolist(), b.tolist(), d.tolist())
            for k in range(61):
                o = (a + (b - a) * k / 60).tolist()
                got, want = picker.pick(o), brute_pick(pos, nrm, o, d)
                self.assertEqual(got is None, want is None, (o, got, want))
                if want is not None:
                    hits += 1
                    self.assertLess(np.abs(np.array(got) - want).max(), 1e-9)
                else:
                    misses += 1
        self.assertGreater(hits, 200)
        self.assertGreater(misses, 20)

    def test_an_empty_surface_misses(self):
        picker = StrokePicker(SplatSurface().snapshot(), [0, 0, 100], [50, 0, 100], [0, 0, -1])
        self.assertIsNone(picker.pick([10, 0, 100]))


if __name__ == "__main__":
    unittest.main()
