#!/usr/bin/python3
"""Long requests against `marzipan serve --data-dir` as a process: progress, cancel, SIGTERM.

1. A global smoothing of 1500 iterations on a 128^3 pig reports op.progress; op.cancel (the
   Python client's cancel(), from a second task) stops it: the request fails with Cancelled and
   the session keeps its revision and digest.
2. The same smoothing again, then SIGTERM while it runs: the server exits 0 within 10 s.
3. Restarted on the same data directory, the session is exactly the last acknowledged revision
   (digest from session.stats before the long request), nothing of the cancelled smoothing.
4. A smoothing of 100000 iterations is refused at once with -32004 naming max_op_voxels.

Usage: test_long_requests.py --marzipan BIN --workdir DIR
Run by ctest ("durability: ..."); Debian's /usr/bin/python3 with python3-websockets.
Conventions: as harness.py.
"""

import sys

sys.dont_write_bytecode = True  # run from the source tree: no __pycache__ beside the test

import argparse  # noqa: E402
import asyncio  # noqa: E402
import shutil  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from harness import Server, connect  # noqa: E402
from marzipan.rpc import Cancelled, LimitExceeded, Notification  # noqa: E402

LONG_SMOOTH = {"tool": "smooth", "global": True, "iterations": 1500}
BLOB = {"ray": ([64, 64, 300], [0, 0, -1]), "radius": 8}


async def first_progress(client, timeout=30):
    """The first op.progress with a fraction above 0 (other updates are skipped)."""
    deadline = time.monotonic() + timeout
    while True:
        update = await client.next_update(timeout=max(0.1, deadline - time.monotonic()))
        if isinstance(update, Notification) and update.method == "op.progress" and update.params["fraction"] > 0:
            return update.params


async def scenario(binary, workdir):
    data = workdir / "data"
    server = Server(binary, "long", data_dir=data)
    try:
        client = await connect(server)
        created = await client.create_session(128, "pig")
        await client.apply("add_blob", **BLOB)
        before = await client.stats()

        # 1. progress, then op.cancel from a second task.
        smoothing = asyncio.create_task(client.apply(dict(LONG_SMOOTH)))
        progress = await first_progress(client)
        assert 0 < progress["fraction"] < 1, progress
        assert await client.cancel() is True
        try:
            await smoothing
            raise AssertionError("the cancelled smoothing answered with a result")
        except Cancelled:
            pass
        after = await client.stats()
        assert (after["revision"], after["digest"]) == (before["revision"], before["digest"]), (before, after)

        # 4. over the budget: refused before anything runs.
        try:
            await client.apply({"tool": "smooth", "global": True, "iterations": 100000})
            raise AssertionError("100000 iterations were accepted")
        except LimitExceeded as e:
            assert e.data["limit"] == "max_op_voxels", e.data

        # 2. SIGTERM while a long request runs.
        smoothing = asyncio.create_task(client.apply(dict(LONG_SMOOTH)))
        await first_progress(client)
        start = time.monotonic()
        status = await asyncio.get_running_loop().run_in_executor(None, server.terminate)
        seconds = time.monotonic() - start
        assert status == 0, f"exit status {status}; log:\n{server.log_text()}"
        assert seconds < 10, f"SIGTERM took {seconds:.1f} s; log:\n{server.log_text()}"
        print(f"SIGTERM with a long smoothing running: exited 0 in {seconds:.2f} s")
        try:
            await smoothing
            raise AssertionError("the smoothing interrupted by SIGTERM answered with a result")
        except Exception as e:  # Cancelled when the answer went out before the close, else closed
            assert type(e).__name__ in ("Cancelled", "ConnectionClosed"), repr(e)
        await client.close()
    finally:
        server.stop()

    # 3. the session as last acknowledged.
    server = Server(binary, "long-restarted", data_dir=data)
    try:
        client = await connect(server, session=created["session"])
        await client.join(created["session"], created["token"])
        back = await client.stats()
        assert (back["revision"], back["digest"]) == (before["revision"], before["digest"]), (before, back)
        await client.close()
    finally:
        server.stop()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--marzipan", required=True, help="the marzipan binary")
    parser.add_argument("--workdir", required=True, help="scratch directory (emptied first, kept after)")
    args = parser.parse_args()
    workdir = Path(args.workdir)
    shutil.rmtree(workdir, ignore_errors=True)
    workdir.mkdir(parents=True)
    asyncio.run(scenario(args.marzipan, workdir))
    print("ok")


if __name__ == "__main__":
    main()
