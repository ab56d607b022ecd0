#!/usr/bin/python3
"""Issue 31 item 2 against a real `marzipan serve`: view clients asking for an old revision must
not hold an editor's edits.

An editor makes a 192^3 sphere and eight whole-volume steps (volume.morph), so that the volume at
revision 1 is rebuilt by unpacking every later step. Eight view clients then loop `render.frame
{revision: 1, width: 1, height: 1}` while the editor makes small `tool.apply` edits one after the
other; the case prints the editor's round-trip latency (p50, p90, max, ms) and how many frames
the view clients got, and fails when a request fails or no frame came, and, given --max-p90-ms,
when p90 is over it. Issue 31 measured p90 1588 ms before the fix. The p90 is a speed figure,
which a loaded machine decides: ctest does not bound it. That the editor is answered while an
old revision is rebuilt is checked by order, not speed, in tests/service/test_hub_history.cpp
("an editor's edits are answered while an earlier revision is rebuilt for a view client"). A
second part checks that `session.fork {revision}` is counted against max_creates_per_minute
before its revision is looked up or rebuilt.

Usage: view_clients_stall.py --marzipan BIN [--max-p90-ms MS]. Exit status 0 when it holds, 1
otherwise. Debian's /usr/bin/python3 (python3-websockets).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from marzipan_hostile import Client, Server, error_code  # noqa: E402

VIEWERS = 8
STEPS = 8
EDITS = 40
CAMERA = {"eye": [96, 96, 400], "target": [96, 96, 96]}


async def make_history(editor: Client) -> dict:
    created = await editor.result("session.create", {"size": [192, 192, 192], "solid": "sphere", "view": "none"})
    for i in range(STEPS):
        await editor.result("volume.morph", {"kind": "dilate" if i % 2 == 0 else "erode", "radius": 1})
    return created


async def viewer(url: str, created: dict, stop: asyncio.Event, frames: list[int], errors: list[dict]) -> None:
    c = await Client.open(url)
    await c.result("session.join", {"session": created["session"], "token": created["view_token"], "view": "none"})
    n = 0
    while not stop.is_set():
        m = await c.call("render.frame", {"camera": CAMERA, "width": 1, "height": 1, "format": "png", "revision": 1})
        if "result" in m:
            n += 1
        else:
            errors.append(m)
            break
    frames.append(n)
    await c.ws.close()


async def stalled_edits(binary: str, max_p90_ms: float | None) -> bool:
    with Server(binary, []) as server:
        editor = await Client.open(server.url)
        created = await make_history(editor)
        stop = asyncio.Event()
        frames: list[int] = []
        errors: list[dict] = []
        viewers = [asyncio.create_task(viewer(server.url, created, stop, frames, errors)) for _ in range(VIEWERS)]
        await asyncio.sleep(0.5)
        latencies = []
        for i in range(EDITS):
            start = time.monotonic()
            await editor.result("tool.apply", {"tool": "add_blob", "center": [96 + (i % 5), 96, 192 - 20], "radius": 3,
                                               "strength": 0.5})
            latencies.append((time.monotonic() - start) * 1000)
        stop.set()
        await asyncio.gather(*viewers)
        latencies.sort()
        p50 = statistics.median(latencies)
        p90 = latencies[int(0.9 * (len(latencies) - 1))]
        print(f"editor latency with {VIEWERS} view clients looping render.frame at revision 1 of a 192^3 session "
              f"({STEPS} whole-volume steps later): p50 {p50:.0f} ms, p90 {p90:.0f} ms, max {latencies[-1]:.0f} ms; "
              f"frames {sum(frames)}")
        ok = not errors and (max_p90_ms is None or p90 <= max_p90_ms) and sum(frames) > 0
        if errors:
            print(f"a view client's render.frame failed: {errors[0]}")
        await editor.ws.close()
        return ok


async def fork_counted_first(binary: str) -> bool:
    """A fork is counted against max_creates_per_minute (10) before its revision is looked up or
    rebuilt: after the create, nine forks refused for their revision use the minute up, and a
    fork at revision 1 is refused at once without a rebuild (before: refusals were free, so a
    client could ask for rebuilds without end)."""
    with Server(binary, []) as server:
        c = await Client.open(server.url)
        await make_history(c)
        refusals = [error_code(await c.call("session.fork", {"revision": 999999})) for _ in range(9)]
        start = time.monotonic()
        m = await c.call("session.fork", {"revision": 1})
        answered_ms = (time.monotonic() - start) * 1000
        limit = m.get("error", {}).get("data", {}).get("limit")
        ok = refusals == [-32602] * 9 and error_code(m) == -32004 and limit == "max_creates_per_minute"
        print(f"nine forks refused for their revision ({set(refusals)}), then a fork at revision 1: "
              f"{error_code(m) or 'accepted'} {limit or ''} in {answered_ms:.0f} ms")
        await c.ws.close()
        return ok


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--marzipan", required=True)
    parser.add_argument("--max-p90-ms", type=float, default=None, help="fail when the editor's p90 is over this")
    parser.add_argument("--only", choices=["stall", "fork"])
    args = parser.parse_args()
    ok = True
    if args.only in (None, "stall"):
        passed = asyncio.run(stalled_edits(args.marzipan, args.max_p90_ms))
        print(("PASS" if passed else "FAIL") + " view clients at an old revision do not stall the editor")
        ok &= passed
    if args.only in (None, "fork"):
        passed = asyncio.run(fork_counted_first(args.marzipan))
        print(("PASS" if passed else "FAIL") + " session.fork is counted against the create rate before its rebuild")
        ok &= passed
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
