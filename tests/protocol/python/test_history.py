"""Undo mine, history and fork of protocol/python/marzipan/client.py against `marzipan serve`
($MARZIPAN_BIN on a free port): two clients each stroke, A's undo(scope="mine") removes A's
stroke and leaves B's (the digest of a session where only B stroked), a conflict names the
other client, history() lists the authors, fork() opens the chosen revision, and frame() of an
earlier revision draws what that fork holds."""

import asyncio
import unittest

from support import ServerTestCase, needs_server

from marzipan import rpc
from marzipan.client import Client


def run(coroutine, timeout=120):
    return asyncio.run(asyncio.wait_for(coroutine, timeout))


LEFT = [[6, 24, 24], [6, 27, 24]]
RIGHT = [[41, 24, 24], [41, 27, 24]]


@needs_server
class HistoryAgainstServer(ServerTestCase):

    def test_undo_mine_removes_only_my_stroke(self):
        async def go():
            async with Client.connect(self.url) as alone:
                await alone.create_session(48, "sphere")
                await alone.stroke("add_blob", RIGHT, radius=4)
                only_b = (await alone.stats())["digest"]
            async with Client.connect(self.url) as a:
                created = await a.create_session(48, "sphere")
                async with Client.connect(self.url, session=created["session"]) as b:
                    await b.join(created["session"], created["token"])
                    await a.stroke("add_blob", LEFT, radius=4)
                    await b.stroke("add_blob", RIGHT, radius=4)
                    undone = await a.undo(scope="mine")
                    after = (await a.stats())["digest"]
                    steps = await b.history()
                    with self.assertRaises(rpc.NothingToUndoRedo):
                        await a.undo(scope="mine")
                    redone = await a.redo(scope="mine")
                    return only_b, undone, after, steps, redone

        only_b, undone, after, steps, redone = run(go())
        self.assertEqual(after, only_b)
        self.assertEqual((undone["revision"], undone["step"]["client"], undone["step"]["revision"]), (3, 1, 1))
        self.assertEqual([(s["client"], s["tool"], s["revision"], s["undone"]) for s in steps],
                         [(1, "add_blob", 1, True), (2, "add_blob", 2, False)])
        self.assertEqual(redone["revision"], 4)

    def test_a_conflicting_undo_names_the_other_client(self):
        async def go():
            async with Client.connect(self.url) as a:
                created = await a.create_session(48, "sphere")
                async with Client.connect(self.url, session=created["session"]) as b:
                    await b.join(created["session"], created["token"])
                    await a.apply("add_blob", center=[6, 24, 24], radius=4)
                    await b.apply("add_blob", center=[7, 25, 24], radius=4)
                    try:
                        await a.undo(scope="mine")
                    except rpc.UndoConflict as e:
                        conflict = e
                    else:
                        raise AssertionError("undo mine under B's step was not refused")
                    with self.assertRaises(rpc.InvalidParams) as bad:
                        await a.undo(scope="all")
                    return conflict, bad.exception, await a.stats()

        conflict, bad, stats = run(go())
        self.assertEqual((conflict.code, conflict.client, conflict.revision), (-32017, 2, 2))
        self.assertIn("client 2", conflict.message)
        self.assertEqual(bad.field, "scope")
        self.assertEqual(stats["revision"], 2)

    def test_fork_opens_the_chosen_revision(self):
        async def go():
            async with Client.connect(self.url) as a:
                created = await a.create_session(48, "sphere")
                await a.apply("add_blob", center=[6, 24, 24], radius=4)
                at_one = (await a.stats())["digest"]
                await a.apply("add_blob", center=[41, 24, 24], radius=4)
                with self.assertRaises(rpc.InvalidParams) as unknown:
                    await a.fork(revision=9)
                camera = {"eye": [24, 30, 120], "target": [24, 24, 24]}
                past = await a.frame(camera, 64, 48, revision=1)
                current = await a.frame(camera, 64, 48)
                forked = await a.fork(revision=1)
                forked_frame = await a.frame(camera, 64, 48)
                stats = await a.stats()
                async with Client.connect(self.url, session=created["session"]) as b:
                    rejoined = await b.join(created["session"], created["view_token"])
                return (created, at_one, unknown.exception, forked, stats, rejoined, a.session, a.token,
                        (past, current, forked_frame))

        created, at_one, unknown, forked, stats, rejoined, session, token, frames = run(go())
        past, current, forked_frame = frames
        self.assertEqual(past, forked_frame, "render.frame of revision 1 draws what the fork at 1 holds")
        self.assertNotEqual(past, current)
        self.assertEqual(unknown.field, "revision")
        self.assertNotEqual(forked["session"], created["session"])
        self.assertEqual((session, token), (forked["session"], forked["token"]))
        self.assertEqual((forked["revision"], forked["digest"], forked["read_only"]), (1, at_one, False))
        self.assertEqual(forked["forked_from"], {"session": created["session"], "revision": 1})
        self.assertEqual((stats["session"], stats["digest"]), (forked["session"], at_one))
        self.assertEqual(rejoined["revision"], 2)


if __name__ == "__main__":
    unittest.main()
