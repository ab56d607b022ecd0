"""tests/load/marzipan_load.py: a web-client sculptor's stroke against a scripted connection.

Run: /usr/bin/python3 tests/load/test_marzipan_load.py

The case: stroke.begin's answer completes its task after the timer of the stroke's last pointer
event has fired and before the stroke has run that event. The task's done-callback is then only
scheduled when the stroke awaits the task, and the stroke must still learn its id and send its
dabs and stroke.end; before 2026-11-29 it waited on an event that was already set and spun
without ever yielding (five of six pinned runs with several client processes hung so). Each
case runs in a process of its own, so that a client that spins fails the test by its timeout
instead of hanging it.
"""

import asyncio
import multiprocessing
import sys
import time
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import marzipan_load  # noqa: E402

STROKE_ID = 7


def sculpt_one_stroke(conn):
    """One stroke of two pointer events (ray dabs) against a scripted connection; sends back
    what the client sent."""
    # Two pointer events per stroke: the second, 1/60 s after the first, is the last.
    marzipan_load.WEB_CLIENT_STROKE_S = 2 / marzipan_load.WEB_CLIENT_FRAME_HZ

    async def main():
        loop = asyncio.get_running_loop()
        session = marzipan_load.SessionState(0, "s")
        stats = marzipan_load.WorkerStats([0], None)
        args = {"seed": 1, "size": 128, "dab_spacing": 0, "mode": "web-client"}
        client = marzipan_load.LoadClient(0, session, args, stats, creator=True)
        sent = []

        async def call(method, params):
            # Answered while the stroke sleeps until its second pointer event, and finished just
            # after that event's timer has woken the stroke: block past it, then yield twice (the
            # timer's turn, then the turn in which the stroke's wake-up is due).
            time.sleep(0.05)
            await asyncio.sleep(0)
            await asyncio.sleep(0)
            sent.append((method, params))
            return {"stroke": STROKE_ID}

        def send(method, params, want_result=False, dab_times=None):
            sent.append((method, params))
            if not want_result:
                return None
            future = loop.create_future()
            loop.call_soon(future.set_result, {"applied": len(params["dabs"]), "revision": 1})
            return future

        client.call, client.send = call, send
        await client.sculpt_like_web_client(time.monotonic() + 0.2)
        return sent

    conn.send(asyncio.run(main()))


class WebClientStroke(unittest.TestCase):
    def test_begin_answered_just_before_the_last_pointer_event(self):
        context = multiprocessing.get_context("spawn")
        parent, child = context.Pipe(duplex=False)
        proc = context.Process(target=sculpt_one_stroke, args=(child,), daemon=True)
        proc.start()
        finished = parent.poll(10)
        if not finished:
            proc.kill()
        proc.join()
        self.assertTrue(finished, "the stroke never ended: the client spun in its wait")
        sent = parent.recv()
        methods = [m for m, _ in sent]
        self.assertEqual(methods[0], "stroke.begin")
        dabs = [d for m, p in sent if m == "stroke.dabs" for d in p["dabs"]]
        self.assertEqual(len(dabs), 2)  # one ray dab per pointer event, both sent
        self.assertTrue(all(p["stroke"] == STROKE_ID for m, p in sent if m in ("stroke.dabs", "stroke.end")))
        self.assertEqual(methods[-1], "stroke.end")


if __name__ == "__main__":
    unittest.main()
