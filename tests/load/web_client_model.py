"""How the browser client turns a pointer drag into dabs, for the load tool's web-client mode.

The web client (web-client/ui/sculpt.js) picks the surface under the pointer on its own copy
of the splats as they were when the stroke began (web-client/math/splat-pick.js), spaces dabs
DAB_SPACING of the radius apart along the path of those hits (web-client/math/dab-spacer.js),
puts each dab on the surface by picking again under its interpolated screen position, and
sends the dabs as centres. The server never picks for it. This module does the same in Python:
SplatSurface keeps a session's splats from the frames a client receives, StrokePicker finds the
first front-facing disc a ray of a drag meets, DabSpacer spaces the dabs.

Conventions: vu, y up, voxel (i, j, k) at (i, j, k); a brick (bx, by, bz) holds points within
[8 b - 2, 8 b + 10) per axis (protocol/python/marzipan/splats.py gives the byte layout, which
this module reads without its per-point checks: the frames come from the server under test);
pressure in (0, 1]; ray directions unit length.
"""

from __future__ import annotations

import bisect
import math
import struct

import numpy as np

# web-client/ui/sculpt.js and web-client/render/splat-renderer.js
DAB_SPACING = 0.25  # of the brush radius
MIN_DAB_SPACING = 0.25  # vu
DISC_RADIUS = 0.8  # vu: the splat discs the web client draws and picks

_BRICK = 8
_REACH_LO, _REACH_HI = -2, 10
_STEP = 3 / 4096
_HEADER = struct.Struct("<4sHHII")
_BRICK_HEADER = struct.Struct("<HHHH")


class SplatSurface:
    """A session's splats by brick, as a client holds them: a full buffer replaces everything,
    a delta replaces the bricks it lists (an empty one removes its brick). Entries are never
    changed in place, so a snapshot (a shallow copy of the dict) stays the surface it was."""

    def __init__(self):
        self.bricks = {}  # (bx, by, bz) -> _Brick

    def apply(self, payload, full: bool):
        view = memoryview(payload).cast("B")
        magic, version, _, count, _ = _HEADER.unpack_from(view, 0)
        if magic != b"MZSP":
            raise ValueError("not a splat buffer")
        if full:
            self.bricks = {}
        at = _HEADER.size
        for _ in range(count):
            bx, by, bz, word = _BRICK_HEADER.unpack_from(view, at)
            at += _BRICK_HEADER.size
            # Version 2 (what the browser asks for): N's low 10 bits count the points, bit 15
            # marks a painted brick, whose points carry 4 bytes of colour and mask after each u64.
            n, painted = (word & 0x3FF, word & 0x8000) if version == 2 else (word, 0)
            size = 12 if painted else 8
            if n and painted:
                self.bricks[(bx, by, bz)] = _Brick((bx, by, bz), b"".join(
                    view[at + size * i:at + size * i + 8] for i in range(n)))
            elif n:
                self.bricks[(bx, by, bz)] = _Brick((bx, by, bz), view[at:at + 8 * n])
            else:
                self.bricks.pop((bx, by, bz), None)
            at += size * n

    def snapshot(self) -> "SurfaceSnapshot":
        return SurfaceSnapshot(list(self.bricks.values()))


class _Brick:
    __slots__ = ("key", "words")

    def __init__(self, key, words):
        self.key = key
        self.words = bytes(words)


def decode_points(bricks):
    """The positions and unit normals (each n x 3, float64) of the bricks' points, in order."""
    if not bricks:
        return np.zeros((0, 3)), np.zeros((0, 3))
    w = np.frombuffer(b"".join(b.words for b in bricks), dtype="<u8")
    counts = [len(b.words) // 8 for b in bricks]
    origin = np.repeat(np.array([b.key for b in bricks], dtype=np.float64) * _BRICK - 2, counts, axis=0)
    pos = np.stack([(w >> shift) & 0x3FFF for shift in (0, 14, 28)], axis=1).astype(np.float64) * _STEP + origin
    u = (2.0 * ((w >> 42) & 0x7FF).astype(np.float64) - 2047) / 2047
    v = (2.0 * (w >> 53).astype(np.float64) - 2047) / 2047
    z = 1 - np.abs(u) - np.abs(v)
    folded = z < 0
    fu = np.where(folded, (1 - np.abs(v)) * np.where(u >= 0, 1.0, -1.0), u)
    fv = np.where(folded, (1 - np.abs(u)) * np.where(v >= 0, 1.0, -1.0), v)
    nrm = np.stack([fu, fv, z], axis=1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pos, nrm


class SurfaceSnapshot:
    """The bricks of a SplatSurface at one moment, with the centres of their points' reach
    ([8 b - 2, 8 b + 10) per axis) as an array for picking."""

    def __init__(self, bricks):
        self.bricks = bricks
        keys = np.array([b.key for b in bricks], dtype=np.float64).reshape(-1, 3)
        self.centres = keys * _BRICK + (_REACH_LO + _REACH_HI) / 2


class StrokePicker:
    """Picks on a snapshot for the rays of one drag: an orthographic camera's rays, all along
    `direction`, from origins on the segment [origin_a, origin_b] (the load tool's Drag). pick
    answers what web-client/math/splat-pick.js pickSplats answers for such a ray: the point
    where it first meets a front-facing disc of radius disc_radius, or None. A disc can only be
    hit by a ray that passes within disc_radius of its centre, so the discs within that
    distance of the drag's strip are gathered once, ordered by where along the drag they lie,
    and each pick tests only those within disc_radius of its own place along it."""

    def __init__(self, surface: SurfaceSnapshot, origin_a, origin_b, direction, disc_radius: float = DISC_RADIUS):
        self.d = tuple(float(c) for c in direction)
        self.r = disc_radius
        d = np.asarray(self.d)
        a = np.asarray(origin_a, dtype=np.float64)
        span = np.asarray(origin_b, dtype=np.float64) - a
        span -= (span @ d) * d  # origins differ only across the view
        length = float(np.sqrt(span @ span))
        axis = span / length if length > 0 else np.zeros(3)
        self.origin_a, self.axis = tuple(a.tolist()), tuple(axis.tolist())

        def across(points):
            """Each point's place along the drag (vu from origin_a) and distance from it, across the view."""
            rel = points - a
            rel -= np.outer(rel @ d, d)
            along = rel @ axis
            gap = rel - np.outer(np.clip(along, 0.0, length), axis)
            return along, np.sqrt((gap * gap).sum(axis=1))

        self.along, self.discs = [], []
        if not surface.bricks:
            return
        # A brick's points and their discs lie within 6 + disc_radius of its centre per axis.
        _, off = across(surface.centres)
        near = np.nonzero(off <= (6 + disc_radius) * math.sqrt(3))[0]
        if not len(near):
            return
        p, n = decode_points([surface.bricks[k] for k in near])
        facing = n @ d
        along, off = across(p)
        keep = np.nonzero((facing < -1e-3) & (off <= disc_radius))[0]  # back faces are not drawn
        keep = keep[np.argsort(along[keep], kind="stable")]
        self.along = along[keep].tolist()
        pn = (p[keep] * n[keep]).sum(axis=1)
        self.discs = list(zip(map(tuple, p[keep].tolist()), map(tuple, n[keep].tolist()), facing[keep].tolist(),
                              pn.tolist()))

    def pick(self, origin):
        o = origin
        d = self.d
        a, axis = self.origin_a, self.axis
        at = (o[0] - a[0]) * axis[0] + (o[1] - a[1]) * axis[1] + (o[2] - a[2]) * axis[2]
        best, r2 = math.inf, self.r * self.r
        for k in range(bisect.bisect_left(self.along, at - self.r), bisect.bisect_right(self.along, at + self.r)):
            p, n, facing, pn = self.discs[k]
            t = (pn - (n[0] * o[0] + n[1] * o[1] + n[2] * o[2])) / facing
            if t < 0 or t >= best:
                continue
            ex, ey, ez = o[0] + t * d[0] - p[0], o[1] + t * d[1] - p[1], o[2] + t * d[2] - p[2]
            if ex * ex + ey * ey + ez * ez <= r2:
                best = t
        if best == math.inf:
            return None
        return [o[0] + best * d[0], o[1] + best * d[1], o[2] + best * d[2]]


class DabSpacer:
    """web-client/math/dab-spacer.js: the hits of a drag's pointer samples become dabs `spacing`
    vu apart along the polyline through them; the first hit of a path is a dab; a miss, or a
    step longer than max_gap, starts a new path. Each dab carries the fraction of the way from
    the previous sample to this one, for interpolating what the sample carries."""

    def __init__(self, spacing: float, max_gap: float | None = None):
        if not spacing > 0:
            raise ValueError(f"dab spacing must be positive, got {spacing}")
        self.spacing = spacing
        self.max_gap = 8 * spacing if max_gap is None else max_gap
        self.last = None  # (point, pressure) of the previous sample that hit
        self.travelled = 0.0

    def add(self, point, pressure: float):
        """One sample; returns [(point, pressure, fraction)] of the dabs it completes, in order."""
        if point is None:
            self.last = None
            return []
        prev = self.last
        self.last = (point, pressure)
        if prev is None:
            self.travelled = 0.0
            return [(point, pressure, 1.0)]
        step = math.dist(prev[0], point)
        if step > self.max_gap:
            self.travelled = 0.0
            return [(point, pressure, 1.0)]
        dabs = []
        along = self.spacing - self.travelled
        while along <= step:
            f = along / step
            dabs.append(([p + (q - p) * f for p, q in zip(prev[0], point)],
                         prev[1] + (pressure - prev[1]) * f, f))
            along += self.spacing
        self.travelled = step - (along - self.spacing)
        return dabs
