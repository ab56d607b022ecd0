"""tests/load/load_client.cpp against the Python model: the compiled load client makes the same
strokes as marzipan_load.py's web-client mode from the same seed. Its --plan mode prints the
first strokes of one client on a splat buffer (no server); WebClientStroke makes them here
from the same buffer and seed, and they must agree: tool, radius, strength, height, the
number of pointer events, the dabs of each event (how many, where, how hard), grab strokes
among them.

Run: MARZIPAN_LOAD_CLIENT=build/tests/marzipan-load-client /usr/bin/python3 tests/load/test_load_client.py
(ctest sets the variable). Centres are sent rounded to 4 decimals by both; the two pick with
the same arithmetic in another order of additions, so they may differ by one in that last
place, hence the 2e-4 vu tolerance.
"""

import json
import math
import os
import random
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from marzipan_load import TOOLS, WebClientStroke  # noqa: E402
from test_web_client_model import sphere_bricks, splat_buffer  # noqa: E402
from web_client_model import SplatSurface  # noqa: E402

CLIENT = os.environ.get("MARZIPAN_LOAD_CLIENT", "")
SIZE = 128
STROKES = 3


def python_plan(buffer: bytes, client: int, seed: int, spacing: float):
    surface = SplatSurface()
    surface.apply(buffer, full=True)
    rng = random.Random(seed * 100003 + client)
    out = []
    for s in range(STROKES):
        stroke = WebClientStroke(rng, TOOLS[(client + s) % len(TOOLS)], SIZE, surface, spacing)
        out.append({"params": stroke.params, "frames": stroke.frames,
                    "pointer": [stroke.pointer(k) for k in range(stroke.frames)]})
    return out


def compiled_plan(path: str, client: int, seed: int, spacing: float):
    text = subprocess.run([CLIENT, "--plan", path, "--client", str(client), "--seed", str(seed), "--size", str(SIZE),
                           "--strokes", str(STROKES), "--dab-spacing", str(spacing)],
                          check=True, capture_output=True, text=True, timeout=60).stdout
    return [json.loads(line) for line in text.splitlines()]


@unittest.skipUnless(CLIENT, "MARZIPAN_LOAD_CLIENT names the built marzipan-load-client")
class CompiledClientAgainstPython(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # A sphere in the middle of the grid, as wide as the pig: the drags cross it from every side.
        cls.buffer = splat_buffer(sphere_bricks((63.5, 63.5, 63.5), 36.0))
        cls.dir = tempfile.TemporaryDirectory()
        cls.path = os.path.join(cls.dir.name, "sphere.mzsp")
        Path(cls.path).write_bytes(cls.buffer)

    @classmethod
    def tearDownClass(cls):
        cls.dir.cleanup()

    def compare(self, client, seed, spacing):
        mine, theirs = compiled_plan(self.path, client, seed, spacing), python_plan(self.buffer, client, seed, spacing)
        self.assertEqual(len(mine), len(theirs))
        dabs = 0
        for s, (c, p) in enumerate(zip(mine, theirs)):
            where = f"client {client}, seed {seed}, stroke {s}"
            self.assertEqual(c["params"], p["params"], where)
            self.assertEqual(c["frames"], p["frames"], where)
            self.assertEqual([len(d) for d in c["pointer"]], [len(d) for d in p["pointer"]], where)
            for k, (cd, pd) in enumerate(zip(c["pointer"], p["pointer"])):
                for a, b in zip(cd, pd):
                    dabs += 1
                    self.assertEqual(a["pressure"], b["pressure"], f"{where}, event {k}")
                    if "ray" in b:
                        self.assertEqual(a["ray"], b["ray"], f"{where}, event {k}")
                    else:
                        for x, y in zip(a["center"], b["center"]):
                            self.assertAlmostEqual(x, y, delta=2e-4, msg=f"{where}, event {k}")
        return dabs, sum(p["frames"] for p in theirs)

    def test_spaced_dabs_picked_on_the_splats(self):
        dabs = events = 0
        for seed in (1, 7):
            for client in range(6):
                d, e = self.compare(client, seed, 0.25)
                dabs, events = dabs + d, events + e
        # Drags that mostly hit, spaced a quarter of the radius apart, and a fifth of the strokes
        # grabs of a dab per event: neither none nor one per event.
        self.assertGreater(dabs, 0.2 * events)
        self.assertLess(dabs, 0.95 * events)

    def test_grab_strokes(self):
        strokes = [s for seed in (1, 7) for client in range(6)
                   for s in compiled_plan(self.path, client, seed, 0.25)]
        grabs = [s for s in strokes if s["params"]["tool"] == "grab"]
        self.assertTrue(2 <= len(grabs) <= len(strokes) // 2, (len(grabs), len(strokes)))
        for g in grabs:
            self.assertEqual(g["params"]["strength"], 1.0)
            dabs = [d["center"] for event in g["pointer"] for d in event]
            # The anchor, then one dab per pointer event from the first that picked it, the
            # last GRAB_REACH (20) vu from the anchor.
            first = next(k for k, event in enumerate(g["pointer"]) if event)
            self.assertEqual(len(dabs), g["frames"] - first)
            self.assertAlmostEqual(math.dist(dabs[0], dabs[-1]), 20.0, delta=1e-3)

    def test_ray_dabs_without_spacing(self):
        for client in range(3):
            dabs, events = self.compare(client, 1, 0)
            self.assertEqual(dabs, events)


if __name__ == "__main__":
    unittest.main()
