"""protocol/python/marzipan/cli.py: `python3 -m marzipan batch` against `marzipan serve`, checked
against its offline twin `marzipan batch` on the same ops file (equal digests, equal meshes,
equal pictures), plus its exit statuses. Needs $MARZIPAN_BIN; the usage checks do not."""

import asyncio
import json
import math
import socket
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

from support import MARZIPAN_BIN, ServerProcess, needs_server, python_env

from marzipan.cli import InputError, default_camera, read_ops, stats_line
from marzipan.png import decode_png

# The README's example, on a 64^3 pig (coordinates halved), with a global smoothing as "op".
OPS = """# a knob, a dimple and a smoother pig
{"tool":"add_blob","center":[56,38,32],"radius":4,"strength":1}

{"tool":"csg_add","shape":"cylinder","center":[30,45,32],"radius":3,"axis":"y","blend":1}
  {"tool":"csg_subtract","shape":"sphere","center":[30,33,44],"radius":3,"blend":0.5}
{"tool":"smooth","center":[30,45,32],"radius":5,"strength":0.5}
{"op":"morph","kind":"close","radius":1}
{"op":"smooth","global":true,"iterations":2}
"""


def python_cli(*args, stdin=None):
    return subprocess.run([sys.executable, "-m", "marzipan", *args], capture_output=True, text=True,
                          env=python_env(), input=stdin, timeout=300)


class Offline(unittest.TestCase):
    def test_ops_files_skip_comments_and_blank_lines_and_name_bad_lines(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "ops.jsonl"
            path.write_text(OPS)
            ops = read_ops(str(path))
            self.assertEqual([n for n, _ in ops], [2, 4, 5, 6, 7, 8])
            self.assertEqual(ops[-1][1], {"op": "smooth", "global": True, "iterations": 2})
            for text, line, reason in [
                ('{"tool":"smooth"}\n{"tool":"add_blob",}\n', 2, "Expecting property name"),
                ('# ok\n[1, 2]\n', 2, "must be a JSON object"),
                ('{"tool":"add_blob","radius":2,"radius":3}\n', 1, 'key "radius" appears twice'),
                ('{"tool":"add_blob","center":[1,2,NaN]}\n', 1, "NaN"),
                ('{"tool":"add_blob","center":[1,2,1e999]}\n', 1, "beyond double range"),
            ]:
                path.write_text(text)
                with self.assertRaises(InputError) as caught:
                    read_ops(str(path))
                self.assertTrue(str(caught.exception).startswith(f"{path}:{line}: "), str(caught.exception))
                self.assertIn(reason, str(caught.exception))

    def test_stats_lines_have_the_keys_of_marzipan_batch(self):
        line = json.loads(stats_line({"revision": 3, "inside_volume": 1.5, "surface_area": 2.5, "components": 1,
                                      "bounds": {"empty": False, "lo": [1, 2, 3], "hi": [4, 5, 6]},
                                      "gradient_error": {"max": 0.1, "mean": 0.01, "voxels": 9},
                                      "digest": "00ff00ff00ff00ff"}, 12.34567))
        self.assertEqual(list(line), ["revision", "inside_volume", "surface_area", "components", "bounds",
                                      "gradient_error", "digest", "ms"])
        self.assertEqual(line["bounds"], {"empty": False, "lo": [1, 2, 3], "hi": [4, 5, 6]})
        self.assertEqual(line["gradient_error"], {"max": 0.1, "mean": 0.01, "voxels": 9})
        self.assertEqual(line["ms"], 12.346)

    def test_the_default_camera_is_that_of_marzipan_batch(self):
        camera = default_camera([128, 128, 128], 40)
        self.assertEqual(camera["target"], [63.5, 63.5, 63.5])
        distance = 64 / math.sin(math.radians(20))
        offset = [e - t for e, t in zip(camera["eye"], camera["target"])]
        self.assertAlmostEqual(sum(c * c for c in offset) ** 0.5, distance, places=9)
        self.assertAlmostEqual(offset[0] / offset[2], 0.55 / 0.72, places=12)

    def test_usage_errors_exit_2(self):
        for args in [
            [], ["batch"], ["batch", "x.jsonl", "--size", "7"], ["batch", "x.jsonl", "--out", "x.vtk"],
            ["batch", "x.jsonl", "--render", "x.bmp"], ["batch", "x.jsonl", "--camera-eye", "1,2,3"],
            ["batch", "x.jsonl", "--join", "abcdefabcdefabcdef"], ["batch", "x.jsonl", "--load", "pig.stl"],
            ["batch", "x.jsonl", "--load", "v.mzv", "--solid", "pig"], ["batch", "x.jsonl", "--camera-eye", "1,2"],
            ["batch", "x.jsonl", "--render", "x.png", "--fov", "170"],
        ]:
            with self.subTest(args=args):
                result = python_cli(*args)
                self.assertEqual(result.returncode, 2, result.stderr)
                self.assertIn("usage:", result.stderr)

    def test_an_unreachable_server_exits_3(self):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        result = python_cli("batch", "-", "--url", f"ws://127.0.0.1:{port}/ws", stdin="")
        self.assertEqual(result.returncode, 3, result.stderr)
        self.assertIn(f"127.0.0.1:{port}", result.stderr)


@needs_server
class AgainstServer(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = ServerProcess().start()
        cls.tmp = tempfile.TemporaryDirectory(prefix="marzipan-cli-")
        cls.dir = Path(cls.tmp.name)
        (cls.dir / "ops.jsonl").write_text(OPS)

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        cls.tmp.cleanup()

    def cli(self, *args, stdin=None):
        return python_cli("batch", *args, "--url", self.server.ws_url, stdin=stdin)

    def test_the_network_run_equals_marzipan_batch(self):
        d = self.dir
        common = ["--size", "64", "--solid", "pig", "--stats-every", "3", "--width", "96", "--height", "80"]
        offline = subprocess.run([MARZIPAN_BIN, "batch", str(d / "ops.jsonl"), *common, "--out", str(d / "a.stl"),
                                  "--render", str(d / "a.png")], capture_output=True, text=True, timeout=300)
        self.assertEqual(offline.returncode, 0, offline.stderr)
        online = self.cli(str(d / "ops.jsonl"), *common, "--out", str(d / "b.stl"), "--render", str(d / "b.png"))
        self.assertEqual(online.returncode, 0, online.stderr)
        a_lines = [json.loads(line) for line in offline.stdout.splitlines()]
        b_lines = [json.loads(line) for line in online.stdout.splitlines()]
        self.assertEqual(len(b_lines), 2)  # after operation 3 and after the last (6)
        for a, b in zip(a_lines, b_lines):
            self.assertEqual(list(a), list(b))
            for key in ("revision", "digest", "inside_volume", "surface_area", "components", "bounds",
                        "gradient_error"):
                self.assertEqual(a[key], b[key], key)
        self.assertEqual((d / "a.stl").read_bytes(), (d / "b.stl").read_bytes())
        self.assertEqual(decode_png((d / "a.png").read_bytes()), decode_png((d / "b.png").read_bytes()))

    def test_a_volume_file_round_trips_through_load(self):
        d = self.dir
        saved = self.cli(str(d / "ops.jsonl"), "--size", "64", "--solid", "pig", "--stats", "--out", str(d / "v.mzv"))
        self.assertEqual(saved.returncode, 0, saved.stderr)
        loaded = self.cli("-", "--load", str(d / "v.mzv"), "--stats", "--out", str(d / "v.obj"), stdin="# nothing\n")
        self.assertEqual(loaded.returncode, 0, loaded.stderr)
        self.assertEqual(json.loads(saved.stdout)["digest"], json.loads(loaded.stdout)["digest"])
        self.assertTrue((d / "v.obj").read_text().startswith(("#", "v ")))

    def test_out_vdb_writes_an_openvdb_file_or_says_the_server_has_no_openvdb(self):
        d = self.dir
        result = self.cli(str(d / "ops.jsonl"), "--size", "64", "--solid", "pig", "--out", str(d / "v.vdb"))
        if result.returncode == 0:
            self.assertEqual((d / "v.vdb").read_bytes()[:8], bytes.fromhex("2042445600000000"))  # OpenVDB's magic
        else:
            self.assertEqual(result.returncode, 1, result.stderr)
            self.assertIn("built without OpenVDB", result.stderr)
            self.assertFalse((d / "v.vdb").exists())

    def test_joining_a_session_applies_the_ops_there(self):
        from marzipan.client import Client

        async def create():
            client = await Client.connect(self.server.ws_url)
            created = await client.create_session(64, "pig")
            return client, created

        async def stats(client):
            result = await client.stats()
            await client.close()
            return result

        loop = asyncio.new_event_loop()
        try:
            client, created = loop.run_until_complete(create())
            joined = self.cli(str(self.dir / "ops.jsonl"), "--join", created["session"], "--token", created["token"],
                              "--stats", "--print-session")
            owner_view = loop.run_until_complete(stats(client))
        finally:
            loop.close()
        self.assertEqual(joined.returncode, 0, joined.stderr)
        line = json.loads(joined.stdout)
        self.assertEqual(line["revision"], 6)
        self.assertEqual(owner_view["digest"], line["digest"])
        self.assertEqual(json.loads(joined.stderr)["session"], created["session"])

    def test_a_refused_operation_exits_1_naming_its_line_and_writes_nothing(self):
        d = self.dir
        bad = OPS + '{"tool":"add_blob","center":[500,30,30]}\n'
        result = self.cli("-", "--size", "64", "--solid", "pig", "--out", str(d / "never.stl"), stdin=bad)
        self.assertEqual(result.returncode, 1, result.stderr)
        self.assertRegex(result.stderr.strip(), r"^-:9: center: ")
        self.assertFalse((d / "never.stl").exists())
        typo = self.cli("-", "--out", str(d / "never.stl"),
                        stdin='{"tool":"add_blob","center":[1,2,3],"radius":2000}\n')
        self.assertEqual(typo.returncode, 1)
        self.assertIn('-:1: "radius" must be between 0.5 and 1024, got 2000', typo.stderr)
        self.assertFalse((d / "never.stl").exists())


if __name__ == "__main__":
    unittest.main()
