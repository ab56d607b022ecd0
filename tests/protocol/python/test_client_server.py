"""protocol/python/marzipan/client.py against `marzipan serve` ($MARZIPAN_BIN, started on a free
port for this file): every method, the typed errors the contract lists, two clients of one
session, and the exact numbers the server reports (digests, byte counts, splat geometry)."""

import asyncio
import json
import math
import os
import re
import struct
import tempfile
import unittest
import zlib

from support import ServerProcess, ServerTestCase, needs_server

from marzipan import rpc
from marzipan.client import Client, new_session_id
from marzipan.frames import FrameKind
from marzipan.png import decode_png
from marzipan.rpc import Notification
from marzipan.splats import decode_splats

HEX16 = re.compile(r"^[0-9a-f]{16}$")
LIMIT_KEYS = {"max_text_bytes", "max_binary_bytes", "max_grid_side", "max_sessions", "max_clients_per_session",
              "max_dabs", "max_frame_side", "history_bytes", "idle_session_seconds", "ping_seconds",
              "max_queue_bytes", "max_connections", "max_connections_per_address", "lobby_seconds",
              "max_volume_bytes", "max_output_bytes", "max_vdb_bytes", "max_creates_per_minute", "max_creates_per_address_per_minute",
              "max_session_age_days", "max_op_voxels", "volume_formats"}


def run(coroutine, timeout=120):
    return asyncio.run(asyncio.wait_for(coroutine, timeout))


async def take_until(client, predicate, timeout=10):
    """The updates up to and including the first one that satisfies `predicate`."""
    taken = []
    while True:
        update = await client.next_update(timeout=timeout)
        if update is None:
            raise AssertionError(f"the connection closed; updates so far: {taken}")
        taken.append(update)
        if predicate(update):
            return taken


@needs_server
class AgainstServer(ServerTestCase):

    def test_create_answers_every_documented_field(self):
        async def go():
            async with Client.connect(self.url) as client:
                proposed = client._route
                return proposed, await client.create_session([40, 32, 24], "sphere")

        proposed, r = run(go())
        self.assertEqual(r["session"], proposed)
        self.assertRegex(r["token"], r"^[A-Za-z0-9_-]{1,128}$")
        self.assertRegex(r["view_token"], r"^[A-Za-z0-9_-]{1,128}$")
        self.assertNotEqual(r["token"], r["view_token"])
        self.assertEqual((r["client"], r["size"], r["revision"]), (1, [40, 32, 24], 0))
        self.assertRegex(r["digest"], HEX16)
        self.assertEqual(r["protocol"], {"major": 1, "minor": 7})
        self.assertEqual(set(r["limits"]), LIMIT_KEYS)
        self.assertEqual((r["can_undo"], r["can_redo"], r["read_only"]), (False, False, False))
        self.assertEqual(r["clients"], [{"client": 1, "read_only": False, "name": "Sculptor 1", "color": "#e6194b"}])

    def test_edits_undo_and_redo_move_revision_and_digest_exactly(self):
        async def go():
            async with Client.connect(self.url) as client:
                start = await client.create_session(48, "sphere")
                applied = await client.apply("add_blob", center=[23.5, 40, 23.5], radius=6)
                after = await client.stats()
                undone = await client.undo()
                back = await client.stats()
                redone = await client.redo()
                again = await client.stats()
                with self.assertRaises(rpc.NothingToUndoRedo):
                    await client.redo()
                morphed = await client.morph("dilate", 1)
                grown = await client.stats()
                return start, applied, after, undone, back, redone, again, morphed, grown

        start, applied, after, undone, back, redone, again, morphed, grown = run(go())
        self.assertEqual(applied["revision"], 1)
        self.assertEqual(set(applied["roi"]), {"lo", "hi"})
        self.assertNotEqual(after["digest"], start["digest"])
        self.assertEqual(undone["step"]["revision"], 1)  # since 1.2: the step moved
        undone.pop("step")
        self.assertEqual(undone, {"revision": 2, "can_undo": False, "can_redo": True})
        self.assertEqual(back["digest"], start["digest"])
        redone.pop("step")
        self.assertEqual(redone, {"revision": 3, "can_undo": True, "can_redo": False})
        self.assertEqual(again["digest"], after["digest"])
        self.assertEqual(morphed["revision"], 4)
        # Dilation by 1 vu grows a sphere of radius R = 0.35 * 48 by 4/3 pi ((R + 1)^3 - R^3) vu^3;
        # the blob on it adds a little area, hence 1%.
        radius = 0.35 * 48
        shell = 4 / 3 * math.pi * ((radius + 1) ** 3 - radius ** 3)
        self.assertAlmostEqual((grown["inside_volume"] - again["inside_volume"]) / shell, 1, delta=0.01)
        self.assertEqual(grown["components"], 1)

    def test_errors_come_as_the_class_of_their_code(self):
        async def go():
            errors = {}
            async with Client.connect(self.url) as client:
                with self.assertRaises(rpc.NotInSession) as e:
                    await client.stats()
                errors["not in session"] = e.exception
                with self.assertRaises(rpc.UnsupportedProtocolVersion) as e:
                    await client.create_session(16, "sphere", protocol=2)
                errors["protocol"] = e.exception
                with self.assertRaises(rpc.InvalidParams) as e:
                    await client.create_session(16, "teapot")
                errors["solid"] = e.exception
                created = await client.create_session(32, "sphere")
                with self.assertRaises(rpc.InvalidParams) as e:
                    await client.apply("add_blob", center=[16, 16, 16], radius=2000)
                errors["radius"] = e.exception
                with self.assertRaises(rpc.EngineRefused) as e:
                    await client.apply("add_blob", center=[500, 16, 16], radius=4)
                errors["outside"] = e.exception
                with self.assertRaises(rpc.InvalidParams) as e:
                    await client.apply({"op": "morph", "kind": "open", "radius": 3})
                errors["op in tool.apply"] = e.exception
                with self.assertRaises(rpc.UnknownMethod) as e:
                    await client.call("volume.explode", {})
                errors["method"] = e.exception
                with self.assertRaises(rpc.AlreadyInSession) as e:
                    await client.create_session(16, "sphere")
                errors["already"] = e.exception
                with self.assertRaises(rpc.NoSuchStroke) as e:
                    await client.end_stroke(12345)
                errors["stroke"] = e.exception
                with self.assertRaises(rpc.LimitExceeded) as e:
                    await client.frame({"eye": [50, 50, 50], "target": [16, 16, 16]}, 5000, 10)
                errors["frame side"] = e.exception
                stats = await client.stats()
            async with Client.connect(self.url) as other:
                with self.assertRaises(rpc.SessionExists) as e:
                    await other.create_session(16, "sphere", session=created["session"])
                errors["exists"] = e.exception
                with self.assertRaises(rpc.NoSuchSession) as e:
                    await other.join(new_session_id(), "whatever")
                errors["no session"] = e.exception
                with self.assertRaises(rpc.BadToken) as e:
                    await other.join(created["session"], "not-the-token")
                errors["token"] = e.exception
            async with Client.connect(self.url) as big:
                limits = created["limits"]
                with self.assertRaises(rpc.LimitExceeded) as e:
                    await big.create_session(limits["max_grid_side"] + 8, "sphere")
                errors["grid"] = e.exception
            return errors, stats

        errors, stats = run(go())
        self.assertEqual(stats["revision"], 0, "no refused request changed anything")
        self.assertEqual(errors["radius"].field, "radius")
        self.assertIn('"radius"', errors["radius"].message)
        self.assertEqual(errors["outside"].field, "center")
        self.assertEqual(errors["op in tool.apply"].field, "op")
        self.assertEqual(errors["solid"].field, "solid")
        self.assertEqual(errors["protocol"].data.get("supported"), {"major": 1, "minor": 7})
        self.assertEqual(errors["exists"].code, -32014)
        self.assertEqual(errors["grid"].data.get("limit"), "max_grid_side")
        self.assertEqual(errors["frame side"].data.get("limit"), "max_frame_side")
        for name, error in errors.items():
            self.assertTrue(error.message, name)

    def test_frames_meshes_and_files_carry_what_their_results_announce(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "pig")
                camera = {"eye": [120, 90, 140], "target": [31.5, 31.5, 31.5]}
                png = await client.frame(camera, 160, 120, "png")
                error_png = await client.frame(camera, 160, 120, "png", shading="gradient_error")
                jpeg = await client.frame(camera, 160, 120, "jpeg", quality=80)
                stl_result, stl = await client.call("mesh.export", {"format": "stl"})
                obj = await client.export_mesh("obj")
                ply = await client.export_mesh("ply")
                glb = await client.export_mesh_with_result("glb", max_triangles=1000)
                thick = await client.thickness(100, max_places=3)
                thick_png = await client.frame(camera, 64, 48, "png", shading="thickness", min_vu=100)
                return png, error_png, jpeg, stl_result, bytes(stl.payload), obj, ply, glb, thick, thick_png

        png, error_png, jpeg, stl_result, stl, obj, ply, (glb_result, glb), thick, thick_png = run(go())
        width, height, channels, pixels = decode_png(png)
        self.assertEqual((width, height, channels), (160, 120, 3))
        self.assertGreater(len(set(pixels)), 20, "a lit picture, not a blank one")
        _, _, _, grey = decode_png(error_png)
        self.assertTrue(any(grey[i] == grey[i + 1] == grey[i + 2] for i in range(0, len(grey), 3)))
        self.assertEqual((jpeg[:2], jpeg[-2:]), (b"\xff\xd8", b"\xff\xd9"))
        triangles = stl_result["triangles"]
        self.assertGreater(triangles, 1000)
        self.assertEqual(len(stl), 84 + 50 * triangles)
        self.assertEqual(struct.unpack_from("<I", stl, 80)[0], triangles)
        text = obj.decode("ascii")
        self.assertEqual(sum(1 for line in text.splitlines() if line.startswith("f ")), triangles)
        self.assertEqual(sum(1 for line in text.splitlines() if line.startswith("v ")), stl_result["vertices"])
        self.assertTrue(ply.startswith(b"ply\nformat binary_little_endian 1.0\n"))
        self.assertIn(f"element face {triangles}\n".encode(), ply[:400])
        # glTF binary decimated to 1000 triangles: header, JSON chunk, and the index count.
        self.assertEqual(glb[:4], b"glTF")
        self.assertEqual(struct.unpack_from("<II", glb, 4), (2, len(glb)))
        self.assertEqual(glb_result["source_triangles"], triangles)
        self.assertLessEqual(glb_result["triangles"], 1000)
        self.assertGreater(glb_result["triangles"], 900)
        self.assertTrue(0 < glb_result["max_error"] < 3)
        doc = json.loads(glb[20:20 + struct.unpack_from("<I", glb, 12)[0]])
        indices = doc["accessors"][doc["meshes"][0]["primitives"][0]["indices"]]
        self.assertEqual(indices["count"], 3 * glb_result["triangles"])
        # The whole 64^3 pig is thinner than 100 vu: every point is below, three places listed.
        self.assertEqual(thick["below"], thick["points"])
        self.assertEqual(len(thick["places"]), 3)
        self.assertEqual(thick["places"][0]["thickness"], thick["thinnest"])
        _, _, _, red = decode_png(thick_png)
        self.assertTrue(any(red[i] > 2 * red[i + 1] + 20 for i in range(0, len(red), 3)), "thin walls in red")

    def test_messages_over_websockets_default_limit_of_1_mib_arrive(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(128, "sphere")
                result, frame = await client.call("volume.save", {})
                return result, len(frame.payload)

        result, size = run(go())
        self.assertGreater(size, 1 << 20)
        self.assertEqual(result["bytes"], size)

    def test_save_and_load_give_back_the_volume(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(32, "torus")
                await client.apply("add_blob", center=[16, 24, 16], radius=5)
                saved_stats = await client.stats()
                saved_result, saved = await client.call("volume.save", {})
                await client.apply("csg_subtract", shape="sphere", center=[16, 16, 16], radius=9)
                changed = await client.stats()
                loaded = await client.load(bytes(saved.payload))
                after = await client.stats()
                undone = await client.undo()
                before_load = await client.stats()
                with self.assertRaises(rpc.EngineRefused) as refused:
                    await client.load(b"MZVF" + bytes(60))
                return (saved_stats, saved_result, bytes(saved.payload), changed, loaded, after, undone,
                        before_load, refused.exception)

        saved_stats, saved_result, data, changed, loaded, after, undone, before_load, refused = run(go())
        self.assertEqual(saved_result["bytes"], len(data))
        self.assertEqual(saved_result["digest"], saved_stats["digest"])
        self.assertEqual(data[:4], b"MZVF")
        self.assertEqual(struct.unpack_from("<4I", data, 4), (1, 32, 32, 32))
        stored, inside = struct.unpack_from("<2I", data, 36)
        self.assertEqual(len(data), 48 + 2056 * stored + 8 * inside + 4)
        self.assertEqual(struct.unpack_from("<I", data, len(data) - 4)[0], zlib.crc32(data[:-4]))
        self.assertNotEqual(changed["digest"], saved_stats["digest"])
        self.assertEqual(loaded["digest"], saved_stats["digest"])
        self.assertEqual(loaded["revision"], changed["revision"] + 1)
        self.assertEqual(after["digest"], saved_stats["digest"])
        self.assertTrue(undone["can_redo"])
        self.assertEqual(before_load["digest"], changed["digest"])
        self.assertEqual(refused.field, "file")

    def test_vdb_files_round_trip_where_the_server_has_openvdb_and_are_refused_elsewhere(self):
        """The server's limits.volume_formats decides: a build with OpenVDB saves a .vdb that
        loads back with the same digest (from bytes and from a path); one without refuses "vdb"
        with InvalidParams on "format" and changes nothing."""
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(32, "torus")
                await client.apply("add_blob", center=[16, 24, 16], radius=5)
                before = await client.stats()
                formats = client.volume_formats
                if "vdb" not in formats:
                    with self.assertRaises(rpc.InvalidParams) as save_refused:
                        await client.save(format="vdb")
                    with self.assertRaises(rpc.InvalidParams) as load_refused:
                        await client.load(b"\x20BDV" + bytes(60), format="vdb")
                    return formats, before, await client.stats(), (save_refused.exception, load_refused.exception)
                result, vdb = await client.save_with_result(format="vdb")
                await client.apply("csg_subtract", shape="sphere", center=[16, 16, 16], radius=9)
                loaded = await client.load(vdb, format="vdb")
                with tempfile.TemporaryDirectory() as d:
                    path = os.path.join(d, "torus.vdb")
                    with open(path, "wb") as f:
                        f.write(vdb)
                    await client.undo()
                    from_path = await client.load(path)
                with self.assertRaises(rpc.EngineRefused) as refused:
                    await client.load(vdb[: len(vdb) // 2], format="vdb")
                return formats, before, (result, vdb, loaded, from_path), refused.exception

        formats, before, outcome, refusal = run(go())
        if "vdb" not in formats:
            self.assertEqual(formats, ["mzv"])
            self.assertEqual(outcome["digest"], before["digest"])
            for e in refusal:
                self.assertEqual(e.field, "format")
                self.assertIn("built without OpenVDB", str(e))
            return
        result, vdb, loaded, from_path = outcome
        self.assertEqual(formats, ["mzv", "vdb"])
        self.assertEqual((result["format"], result["bytes"], result["digest"]), ("vdb", len(vdb), before["digest"]))
        self.assertEqual(vdb[:4], b"\x20BDV")  # OpenVDB's magic, 0x56444220 little-endian
        self.assertEqual(loaded["digest"], before["digest"])
        self.assertEqual(from_path["digest"], before["digest"])
        self.assertEqual(refusal.field, "file")

    def test_a_load_not_followed_by_its_upload_fails_and_the_next_request_is_served(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(16, "sphere")
                load = asyncio.ensure_future(client.call("volume.load", {"bytes": 100}))
                await asyncio.sleep(0)
                stats = await client.stats()
                with self.assertRaises(rpc.UploadMissing):
                    await load
                return stats

        self.assertEqual(run(go())["revision"], 0)

    def test_splats_lie_on_the_sphere(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "sphere")
                result, frame = await client.call("splats.get", {})
                return result, decode_splats(frame.payload), frame

        result, buffer, frame = run(go())
        self.assertEqual(frame.kind, FrameKind.SPLATS_FULL)
        self.assertEqual((buffer.point_count, len(buffer.bricks)), (result["points"], result["bricks"]))
        self.assertGreater(buffer.point_count, 4 * math.pi * 22 ** 2 * 0.5)
        centre, radius = 31.5, 0.35 * 64
        worst_distance = worst_normal = 0.0
        p, n = buffer.positions, buffer.normals
        for k in range(0, len(p), 3):
            d = [p[k] - centre, p[k + 1] - centre, p[k + 2] - centre]
            r = math.sqrt(sum(c * c for c in d))
            worst_distance = max(worst_distance, abs(r - radius))
            worst_normal = max(worst_normal, 1 - sum(n[k + i] * d[i] / r for i in range(3)))
        self.assertLess(worst_distance, 0.05)
        self.assertLess(worst_normal, 1 - math.cos(math.radians(3)))

    def test_rays_pick_the_surface_and_a_miss_changes_nothing(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "sphere")
                hit = await client.apply("remove_blob", ray=([31.5, 31.5, 200], [0, 0, -1]), radius=4)
                miss = await client.apply("remove_blob", ray=([31.5, 31.5, 200], [0, 0, 1]), radius=4)
                stats = await client.stats()
                return hit, miss, stats

        hit, miss, stats = run(go())
        self.assertEqual(hit["revision"], 1)
        self.assertAlmostEqual(hit["hit"][2], 31.5 + 0.35 * 64, delta=0.05)
        self.assertAlmostEqual(hit["hit"][0], 31.5, delta=1e-6)
        self.assertEqual(miss, {"revision": 1, "roi": None, "hit": None})
        self.assertEqual(stats["revision"], 1)

    def test_a_stroke_is_one_undo_step(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(48, "box")
                before = await client.stats()
                face = before["bounds"]["hi"][0]
                stroke = await client.stroke("add_blob", [[face, 20, 20], [face, 24, 24], {"center": [face, 28, 28],
                                                                                         "pressure": 0.5}],
                                             radius=4, symmetry=["z"])
                after = await client.stats()
                await client.undo()
                undone = await client.stats()
                return before, stroke, after, undone

        before, stroke, after, undone = run(go())
        self.assertEqual(stroke["applied"], 3)
        self.assertEqual((stroke["revision"], stroke["can_undo"]), (1, True))
        self.assertGreater(after["inside_volume"], before["inside_volume"])
        self.assertEqual(undone["digest"], before["digest"])
        self.assertFalse(undone["can_undo"])

    def test_a_stroke_with_a_height_rises_by_it_however_often_it_passes(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(48, "box")
                before = await client.stats()
                face = before["bounds"]["hi"][0]
                path = [[face, 24, z] for z in (20, 22, 24, 26, 28)]
                once = await client.stroke("add_blob", path, radius=6, height=3)
                after_once = await client.stats()
                await client.undo()
                thrice = await client.stroke("add_blob", path + path[::-1] + path, radius=6, height=3)
                after_thrice = await client.stats()
                with self.assertRaises(rpc.InvalidParams) as refused:
                    await client.begin_stroke("smooth", height=1)
                return before, once, after_once, thrice, after_thrice, refused.exception

        before, once, after_once, thrice, after_thrice, refused = run(go())
        self.assertEqual((once["applied"], thrice["applied"]), (5, 15))
        face = before["bounds"]["hi"][0]
        self.assertAlmostEqual(after_once["bounds"]["hi"][0] - face, 3, delta=0.3)
        added = after_once["inside_volume"] - before["inside_volume"]
        self.assertAlmostEqual(after_thrice["inside_volume"] - before["inside_volume"], added, delta=0.005 * added)
        self.assertEqual(refused.data.get("field"), "height")

    def test_the_surface_tools_stroke_and_flatten_answers_its_plane(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "sphere")
                start = await client.stats()
                top = [{"ray": [[x, 100, 33], [0, -1, 0]]} for x in (36, 38, 40)]
                done = {}
                for tool, height in (("inflate", 2), ("clay", 2), ("flatten", None), ("contrast", None), ("crease", None)):
                    before = await client.stats()
                    stroke = await client.stroke(tool, top, radius=6, height=height, symmetry=["x"])
                    after = await client.stats()
                    steps = await client.history(limit=1)
                    done[tool] = (before, stroke, after, steps[0]["tool"])
                with self.assertRaises(rpc.InvalidParams) as refused:
                    await client.stroke("flatten", [[4, 4, 4]], radius=3)
                end = await client.stats()
                return start, done, refused.exception, end

        start, done, refused, end = run(go())
        for tool, (before, stroke, after, listed) in done.items():
            self.assertEqual(stroke["applied"], 3, tool)
            self.assertNotEqual(after["digest"], before["digest"], tool)
            self.assertEqual(listed, tool)
            self.assertEqual("plane" in stroke, tool in ("clay", "flatten", "contrast"), tool)
        plane = done["flatten"][1]["plane"]
        self.assertGreater(plane["normal"][1], 0.9)
        self.assertAlmostEqual(math.hypot(*plane["normal"]), 1, delta=1e-9)
        self.assertEqual(refused.data.get("field"), "dabs[0].center")
        self.assertEqual(end["digest"], done["crease"][2]["digest"])

    def test_warp_strokes_grab_and_twist_as_the_contract_says(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "sphere")
                start = await client.stats()
                hi = start["bounds"]["hi"][0]
                anchor = [31.5 + 22.4, 31.5, 31.5]  # the 64^3 sphere's surface point on +x
                grabbed = await client.grab(anchor, [anchor[0] + 6, 31.5, 31.5], 12)
                after = await client.stats()
                listed = (await client.history(limit=1))[0]["tool"]
                await client.undo()
                undone = await client.stats()
                # One stroke, its pointer in three messages: the same volume as in one message.
                path = [[anchor[0], 31.5 + y, 31.5] for y in (2, 4, 6)]
                one = await client.warp("twist", anchor, path, radius=10, direction=[0, 1, 0])
                in_one = await client.stats()
                await client.undo()
                stroke = await client.begin_stroke("twist", radius=10, direction=[0, 1, 0])
                for dabs in ([anchor], path[:1], path[1:2], path[2:]):
                    await client.stroke_dabs(stroke, dabs)
                await client.end_stroke(stroke)
                in_four = await client.stats()
                with self.assertRaises(rpc.InvalidParams) as off:
                    await client.grab([anchor[0] + 5, 31.5, 31.5], [60, 31.5, 31.5], 8)
                with self.assertRaises(rpc.InvalidParams) as mirrored:
                    await client.begin_stroke("grab", symmetry=["x"])
                return hi, grabbed, after, listed, undone, start, one, in_one, in_four, off.exception, mirrored.exception

        hi, grabbed, after, listed, undone, start, one, in_one, in_four, off, mirrored = run(go())
        self.assertEqual((grabbed["revision"], grabbed["can_undo"]), (1, True))
        # The anchor went 6 vu out along +x: the solid's bounds grow by that (within 0.25 vu).
        self.assertAlmostEqual(after["bounds"]["hi"][0] - hi, 6, delta=0.25 + 1)
        self.assertEqual(listed, "grab")
        self.assertEqual(undone["digest"], start["digest"])
        self.assertNotEqual(in_one["digest"], start["digest"])
        self.assertEqual(in_one["digest"], in_four["digest"])
        self.assertEqual(off.data.get("field"), "center")
        self.assertEqual(mirrored.data.get("field"), "symmetry")

    def test_a_pinch_path_draws_the_surface_towards_it_in_one_undo_step(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(64, "sphere")
                start = await client.stats()
                # Along the 64^3 sphere's equator over +x, with pressures.
                path = [[31.5 + 22.4 * math.cos(0.1 * i), 31.5 + 22.4 * math.sin(0.1 * i), 31.5] for i in range(-3, 4)]
                dabs = [path[0]] + [{"center": p, "pressure": 0.5 + 0.1 * k} for k, p in enumerate(path[1:])]
                done = await client.pinch_path(dabs, 6, strength=0.8)
                after = await client.stats()
                listed = (await client.history(limit=1))[0]["tool"]
                await client.undo()
                undone = await client.stats()
                with self.assertRaises(rpc.InvalidParams) as mirrored:
                    await client.begin_stroke("pinch_path", symmetry=["x"])
                return start, done, after, listed, undone, mirrored.exception

        start, done, after, listed, undone, mirrored = run(go())
        self.assertEqual((done["revision"], done["can_undo"]), (1, True))
        self.assertNotEqual(after["digest"], start["digest"])
        self.assertEqual(listed, "pinch_path")
        self.assertEqual(undone["digest"], start["digest"])
        self.assertEqual(mirrored.data.get("field"), "symmetry")

    def test_paint_and_mask_colour_and_protect_the_clay(self):
        async def go():
            async with Client.connect(self.url) as client:
                created = await client.create_session(64, "sphere", base_color=[120, 130, 150])
                start = await client.stats()
                side = [31.5 + 22.4, 31.5, 31.5]  # the 64^3 sphere's surface point on +x
                painted = await client.paint([200, 20, 10], [side, [side[0], 34, 31.5]], radius=6, symmetry=["x"])
                after_paint = await client.stats()
                filled = await client.mask_fill()
                frozen = await client.stats()
                blob = await client.stroke("add_blob", [side], radius=8)
                after_blob = await client.stats()
                inverted = await client.mask_invert()
                erased = await client.mask([[9.1, 31.5, 31.5]], erase=True, radius=6)
                cleared = await client.mask_clear()
                steps = [s["tool"] for s in await client.history(limit=10)]
                # The same through apply_op, as `marzipan batch`'s lines.
                await client.apply_op({"op": "mask", "action": "fill"})
                await client.apply_op({"stroke": {"tool": "paint", "color": [0, 0, 255], "radius": 4}, "dabs": [side]})
                unchanged = await client.stats()
                for _ in range(3):
                    await client.undo()
                with self.assertRaises(rpc.InvalidParams) as no_colour:
                    await client.begin_stroke("paint")
                with self.assertRaises(rpc.InvalidParams) as bad_colour:
                    await client.paint([0, 300, 0], [side])
                with self.assertRaises(rpc.InvalidParams) as height:
                    await client.stroke("paint", [side], color=[1, 2, 3], height=2)
                undone = await client.stats()
                return (created, start, painted, after_paint, filled, frozen, blob, after_blob, inverted, erased,
                        cleared, steps, unchanged, no_colour.exception, bad_colour.exception, height.exception, undone)

        (created, start, painted, after_paint, filled, frozen, blob, after_blob, inverted, erased, cleared, steps,
         unchanged, no_colour, bad_colour, height, undone) = run(go())
        self.assertEqual(created["base_color"], [120, 130, 150])
        # Paint moves no geometry: the same volume and area, another digest.
        self.assertEqual(painted["revision"], 1)  # both dabs in one message: one application
        self.assertNotEqual(after_paint["digest"], start["digest"])
        self.assertEqual(after_paint["inside_volume"], start["inside_volume"])
        self.assertEqual(after_paint["surface_area"], start["surface_area"])
        self.assertEqual(filled["roi"]["lo"], [0, 0, 0])
        # Under the full mask an add_blob stroke changes nothing.
        self.assertEqual(blob["applied"], 0)
        self.assertEqual(after_blob["digest"], frozen["digest"])
        self.assertEqual(after_blob["revision"], frozen["revision"])
        self.assertEqual(inverted["revision"], frozen["revision"] + 1)
        self.assertIsNone(erased.get("plane"))
        self.assertIsNone(cleared["roi"])  # inverted from full: nothing was masked any more
        # Newest first; the erase (over nothing masked) and the clear (of nothing) made no step.
        self.assertEqual(steps, ["mask.invert", "mask.fill", "paint"])
        # The paint under the full mask changed nothing: the digest of the fill alone.
        self.assertEqual(unchanged["digest"], frozen["digest"])
        self.assertEqual(no_colour.data.get("field"), "color")
        self.assertEqual(bad_colour.data.get("field"), "color")
        self.assertEqual(height.data.get("field"), "height")
        self.assertEqual(undone["digest"], after_paint["digest"])

    def test_two_clients_see_each_others_changes(self):
        async def go():
            async with Client.connect(self.url) as owner:
                created = await owner.create_session(48, "sphere")
                async with Client.connect(self.url, session=created["session"]) as viewer:
                    joined = await viewer.join(created["session"], created["view_token"], view="splats")
                    full = await take_until(viewer, lambda u: getattr(u, "kind", None) == FrameKind.SPLATS_FULL)
                    clients = await take_until(owner, lambda u: getattr(u, "method", None) == "session.clients")
                    with self.assertRaises(rpc.ReadOnlyToken):
                        await viewer.apply("add_blob", center=[23.5, 40, 23.5])
                    applied = await owner.apply("add_blob", center=[23.5, 40, 23.5], radius=5)
                    seen = await take_until(viewer, lambda u: getattr(u, "kind", None) == FrameKind.SPLATS_DELTA)
                    own = await take_until(owner, lambda u: getattr(u, "method", None) == "session.changed")
                    return created, joined, full, clients, applied, seen, own

        created, joined, full, clients, applied, seen, own = run(go())
        self.assertEqual((joined["read_only"], joined["client"], joined["session"]), (True, 2, created["session"]))
        self.assertNotIn("token", joined)
        self.assertEqual(full[-1].request_id, 0)
        self.assertGreater(decode_splats(full[-1].payload).point_count, 1000)
        self.assertEqual(clients[-1].params["clients"],
                         [{"client": 1, "read_only": False, "name": "Sculptor 1", "color": "#e6194b"},
                          {"client": 2, "read_only": True, "name": "Sculptor 2", "color": "#3cb44b"}])
        changed = [u for u in seen if isinstance(u, Notification) and u.method == "session.changed"]
        self.assertEqual(len(changed), 1)
        params = changed[0].params
        self.assertEqual((params["revision"], params["by"], params["cause"]), (applied["revision"], 1, "tool"))
        self.assertEqual(params["roi"], applied["roi"])
        self.assertLess(seen.index(changed[0]), len(seen) - 1, "the notification comes before the delta")
        delta = seen[-1]
        self.assertEqual((delta.request_id, delta.revision), (0, applied["revision"]))
        bricks = decode_splats(delta.payload).bricks
        lo, hi = applied["roi"]["lo"], applied["roi"]["hi"]
        for b in bricks:
            # A changed brick or one of its face neighbours (splats read six neighbours).
            for axis in range(3):
                self.assertLessEqual(8 * b.brick[axis], hi[axis] + 8)
                self.assertGreaterEqual(8 * b.brick[axis] + 8, lo[axis] - 8)
        self.assertEqual(own[-1].params["by"], 1)

    def test_frames_mode_pushes_a_frame_of_every_change(self):
        async def go():
            async with Client.connect(self.url) as client:
                await client.create_session(48, "sphere")
                camera = {"eye": [100, 80, 120], "target": [23.5, 23.5, 23.5]}
                mode = await client.view("frames", camera, 64, 48, shading="normals")
                first = await take_until(client, lambda u: getattr(u, "request_id", None) == 0)
                applied = await client.apply("add_blob", center=[23.5, 40, 23.5], radius=5)
                pushed = await take_until(client, lambda u: getattr(u, "revision", -1) == applied["revision"]
                                          and getattr(u, "request_id", None) == 0)
                left = await client.leave()
                with self.assertRaises(rpc.NotInSession):
                    await client.stats()
                return mode, first[-1], pushed[-1], left

        mode, first, pushed, left = run(go())
        self.assertEqual(mode, {"mode": "frames", "revision": 0})
        for frame in (first, pushed):
            self.assertEqual(frame.kind, FrameKind.FRAME_JPEG)  # pushed frames are JPEG
            self.assertEqual((bytes(frame.payload[:2]), bytes(frame.payload[-2:])), (b"\xff\xd8", b"\xff\xd9"))
        self.assertEqual(first.revision, 0)
        self.assertEqual(set(left), {"session"})


@needs_server
class ServerPings(unittest.TestCase):
    """The server pings every --ping-seconds and closes after two unanswered: the client, which
    sends no pings of its own, must answer them (websockets does) and stay connected."""

    def test_an_idle_connection_stays_open_across_pings(self):
        server = ServerProcess("--ping-seconds", "1").start()
        try:
            async def go():
                async with Client.connect(server.ws_url) as client:
                    created = await client.create_session(16, "sphere")
                    await asyncio.sleep(3.5)
                    stats = await client.stats()
                    return created, stats, client.closed

            created, stats, closed = run(go())
        finally:
            server.stop()
        self.assertEqual(created["limits"]["ping_seconds"], 1)
        self.assertFalse(closed)
        self.assertEqual(stats["revision"], 0)


if __name__ == "__main__":
    unittest.main()
