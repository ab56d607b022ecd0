"""Presence through protocol/python/marzipan/client.py against `marzipan serve` ($MARZIPAN_BIN):
names and colours, two clients (and a viewer) seeing each other's brush and camera, the
server's refusals, the rate bound under a 60 Hz sender, and gone on leaving (PROTOCOL.md,
"Presence")."""

import asyncio
import time
import unittest

from support import ServerTestCase, needs_server

from marzipan import rpc
from marzipan.client import Client
from marzipan.rpc import Notification


def run(coroutine, timeout=60):
    return asyncio.run(asyncio.wait_for(coroutine, timeout))


def brush(x, active=False):
    return {"tool": "smooth", "radius": 5, "point": [x, 30, 24], "normal": [0, 0, 3], "active": active}


CAMERA = {"eye": [24, 24, 120], "target": [24, 24, 24], "fov": 35}


async def presences(client, until, timeout=10):
    """The presence notifications taken up to the first for which until(params) holds."""
    got = []
    while True:
        update = await client.next_update(timeout=timeout)
        if update is None:
            raise AssertionError(f"the connection closed; presence so far: {got}")
        if isinstance(update, Notification) and update.method == "presence":
            got.append(update.params)
            if until(update.params):
                return got


@needs_server
class PresenceAgainstServer(ServerTestCase):
    def test_two_sculptors_and_a_viewer_see_each_other(self):
        async def go():
            async with Client.connect(self.url) as a, Client.connect(self.url) as b, Client.connect(self.url) as v:
                created = await a.create_session(48, "sphere", name="  Ada  ")
                self.assertEqual(created["clients"], [{"client": 1, "read_only": False, "name": "Ada", "color": "#e6194b"}])
                joined = await b.join(created["session"], created["token"], name="Bob")
                self.assertEqual(joined["clients"][1], {"client": 2, "read_only": False, "name": "Bob",
                                                        "color": "#3cb44b"})
                viewer = await v.join(created["session"], created["view_token"])
                self.assertEqual(viewer["clients"][2]["name"], "Sculptor 3")

                await a.presence(brush=brush(10.5, active=True), camera=CAMERA)
                for other in (b, v):
                    got = await presences(other, lambda p: p.get("client") == 1)
                    self.assertEqual(got[-1], {
                        "client": 1, "name": "Ada", "color": "#e6194b",
                        "brush": {"tool": "smooth", "radius": 5.0, "point": [10.5, 30.0, 24.0],
                                  "normal": [0.0, 0.0, 1.0], "active": True},
                        "camera": {"eye": [24.0, 24.0, 120.0], "target": [24.0, 24.0, 24.0],
                                   "up": [0.0, 1.0, 0.0], "fov": 35.0}})
                    self.assertEqual(other.others[1], got[-1])
                # The viewer's brush is dropped, its camera kept.
                self.assertEqual(await v.presence(brush=brush(3), camera=CAMERA, answer=True), {})
                got = await presences(a, lambda p: p.get("client") == 3)
                self.assertNotIn("brush", got[-1])
                self.assertEqual(got[-1]["camera"]["eye"], [24.0, 24.0, 120.0])
                self.assertNotIn(1, a.others)  # never its own

                with self.assertRaises(rpc.InvalidParams) as refused:
                    await a.presence(brush={**brush(1), "radius": 5000}, answer=True)
                self.assertEqual(refused.exception.data.get("field"), "brush")
                with self.assertRaises(rpc.InvalidParams):
                    await a.presence(camera={"eye": [1, 2, 3], "target": [1, 2, 3]}, answer=True)
                with self.assertRaises(rpc.InvalidParams) as bad_name:
                    async with Client.connect(self.url) as c:
                        await c.join(created["session"], created["token"], name="a\x07b")
                self.assertEqual(bad_name.exception.data.get("field"), "name")

                # Presence is not an edit.
                self.assertEqual((await a.stats())["revision"], 0)

                await b.leave()
                got = await presences(a, lambda p: p.get("gone"))
                self.assertEqual(got[-1], {"client": 2, "gone": True})
                self.assertNotIn(2, a.others)

        run(go())

    def test_a_60_hz_sender_reaches_the_other_at_most_20_times_a_second_newest_last(self):
        async def go():
            async with Client.connect(self.url) as a, Client.connect(self.url) as b:
                created = await a.create_session(32, "sphere")
                await b.join(created["session"], created["token"])
                start = time.monotonic()
                n = 60
                for i in range(1, n + 1):
                    await a.presence(brush=brush(float(i)))
                    await asyncio.sleep(max(0.0, start + i / 60 - time.monotonic()))
                got = await presences(b, lambda p: p["brush"]["point"][0] == float(n))
                elapsed = time.monotonic() - start
                # One delivery per 50 ms at most (the first at once), each newer than the last.
                self.assertLessEqual(len(got), int(elapsed / 0.05) + 1, f"{len(got)} in {elapsed:.3f} s")
                self.assertGreaterEqual(len(got), 5)
                xs = [p["brush"]["point"][0] for p in got]
                self.assertEqual(xs, sorted(set(xs)))

        run(go())


if __name__ == "__main__":
    unittest.main()
