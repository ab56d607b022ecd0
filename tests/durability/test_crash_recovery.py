#!/usr/bin/python3
"""Crash recovery of `marzipan serve --data-dir`, as a process: a scripted client edits one
session (brushes by centre and by ray, CSG, strokes with symmetry, morphology, global smoothing,
undo/redo, volume.save and volume.load) while the server is killed with SIGKILL at a seeded
moment of a request, over several rounds; after each kill the server is started again on the same
data directory, under the same --server-id, and the client joins with its token.

Checks after every restart (see harness.py for the reference twin that knows every digest):
- a server with another --server-id is refused the session while the killed one's lease runs
  (-32015), so a crash does not let two servers serve it; the same id gets it back at once;
- the recovered revision R is the last acknowledged one A, or A + 1: an edit that was applied and
  journaled but whose response the kill swallowed is allowed (the journal is written before the
  response, so the reverse, an acknowledged edit missing, is a loss);
- R == A: the digest is the one A was acknowledged with; R == A + 1: the request in flight at the
  kill was a change, and applying it to the twin gives exactly R and its digest;
- the undo history came back too (can_undo/can_redo, and a walk back through undo and redo);
- the session goes on being served: the next round edits it again.
At the end an orderly stop (SIGTERM, exit 0) and one more restart give the same state.

What SIGKILL tests is the order "journal, then respond" and the replay; it cannot lose data that
write() handed to the kernel, so fsync (a power cut) is not tested here.

Usage: test_crash_recovery.py --marzipan BIN --workdir DIR [--rounds N] [--seed S]
       [--edits MIN MAX]
Run by ctest ("durability: ..."); Debian's /usr/bin/python3 with python3-websockets. The seed
fixes every edit and the moment of every kill (as a fraction of the measured request time), so a
failure repeats with the same --seed; the data directory stays in WORKDIR for inspection.

Conventions: as harness.py.
"""

import sys

sys.dont_write_bytecode = True  # run from the source tree: no __pycache__ beside the test

import argparse  # noqa: E402
import asyncio  # noqa: E402
import os  # noqa: E402
import random  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

from harness import (CHANGES, HELD_ELSEWHERE, STORAGE_FAILED, Mirror, RpcError, Server,  # noqa: E402
                     Workload, connect, new_session_id, session_dir)

DIMS = [40, 32, 36]
SOLID = "torus"  # rays through its hole miss: the "hit": null path is exercised too
SERVER_ID = "durability-crash"


async def edit_until_kill(mirror, workload, server, requests, fraction):
    """Edits through `requests` requests; the last one is sent and the server killed `fraction`
    of a typical request's time later. Returns the step whose answer the kill swallowed, or None
    when it was answered (or refused) before the kill."""
    sent = 0
    while True:
        for step in workload.gesture():
            sent += 1
            if sent < requests:
                outcome = await mirror.step(step)
                if outcome.result is None and outcome.error is None:
                    raise AssertionError(f"the server closed the connection during {step.describe()} before the "
                                         f"planned kill")
                if outcome.error is not None and outcome.error.code == STORAGE_FAILED:
                    raise AssertionError(f"{step.describe()}: {outcome.error.code} {outcome.error.message} with "
                                         f"nothing limiting the data directory")
                continue
            delay = fraction * statistics.median(mirror.latencies[-50:] or [0.002])
            task = asyncio.ensure_future(mirror.send_durable(step))
            for _ in range(3):
                await asyncio.sleep(0)  # the request goes out on the first turns of the loop
            # A busy wait, not asyncio.sleep: the event loop's timers round up to milliseconds,
            # about a whole request, and the moments inside the request are the interesting ones.
            deadline = time.perf_counter() + delay
            while time.perf_counter() < deadline:
                pass
            server.kill()
            outcome = await task
            if outcome.result is not None:
                await mirror.acknowledge(step, outcome)
                return None
            if outcome.error is not None:
                await mirror.expect_same_refusal(step, outcome.error)
                return None
            return step


async def restart_and_verify(args, mirror, session, token, in_flight, tally, servers):
    server = Server(args.marzipan, f"durable (restart {tally['rounds'] + 1})", data_dir=args.data,
                    server_id=SERVER_ID)
    servers.append(server)
    client = await connect(server, session)
    try:
        joined = await client.join(session, token)
    except RpcError as e:
        raise AssertionError(f"joining after the restart: {e.code} {e.message}; log:\n{server.log_text()}") from None
    acknowledged, recovered = mirror.revision, joined["revision"]
    # One more than acknowledged is no loss: the kill can fall between the journal write and the
    # response. One request at a time is in flight, so never two more, and never fewer.
    if not acknowledged <= recovered <= acknowledged + 1:
        raise AssertionError(f"recovered revision {recovered}, last acknowledged {acknowledged}: it must be that "
                             f"or one more")
    if recovered == acknowledged:
        if joined["digest"] != mirror.history[acknowledged]:
            raise AssertionError(f"recovered revision {recovered} with digest {joined['digest']}, acknowledged with "
                                 f"{mirror.history[acknowledged]}")
        tally["equal"] += 1
    else:
        if in_flight is None or in_flight.method not in CHANGES:
            raise AssertionError(f"recovered revision {recovered}, one past the last acknowledged, but the request "
                                 f"in flight at the kill was {in_flight.describe() if in_flight else 'none'}")
        await mirror.adopt(in_flight, recovered, joined["digest"])
        tally["one more"] += 1
    tally["rounds"] += 1
    await mirror.end_reference_stroke()
    mirror.durable = client
    snapshots = [int(f[len("snapshot-"):-len(".mzv")]) for f in os.listdir(session_dir(args.data, session))
                 if f.startswith("snapshot-") and f.endswith(".mzv")]
    # A recovered session's undo history reaches back only to its last snapshot, undo or redo.
    mirror.history_cut = True
    if max(snapshots) > 0:
        tally["snapshots"] = max(snapshots)
    await mirror.compare_state(f"after restart {tally['rounds']}")
    return server


async def held_elsewhere(args, session, token, servers):
    """Another server on the same data directory while the killed one's lease runs: refused."""
    other = Server(args.marzipan, "another server id", data_dir=args.data, server_id=SERVER_ID + "-other")
    servers.append(other)
    try:
        client = await connect(other, session)
        try:
            await client.join(session, token)
        except RpcError as e:
            if e.code != HELD_ELSEWHERE:
                raise AssertionError(f"another server id joining while the lease runs: {e.code} {e.message}, "
                                     f"expected {HELD_ELSEWHERE}") from None
        else:
            raise AssertionError("another server id loaded the session while the killed server's lease ran")
        await client.close()
    finally:
        other.stop()


async def run(args):
    rng = random.Random(args.seed)
    shutil.rmtree(args.workdir, ignore_errors=True)
    os.makedirs(args.workdir)
    args.data = os.path.join(args.workdir, "data")
    servers = []
    tally = {"rounds": 0, "equal": 0, "one more": 0, "snapshots": 0}
    started = time.monotonic()
    try:
        reference = Server(args.marzipan, "reference")
        servers.append(reference)
        durable = Server(args.marzipan, "durable", data_dir=args.data, server_id=SERVER_ID)
        servers.append(durable)
        session = new_session_id(rng)
        client = await connect(durable, session)
        created = await client.create_session(DIMS, SOLID, session=session)
        if created["session"] != session:
            raise AssertionError(f"proposed session id {session}, the server made {created['session']}")
        twin = await connect(reference)
        twin_created = await twin.create_session(DIMS, SOLID)
        if (created["revision"], created["digest"]) != (twin_created["revision"], twin_created["digest"]):
            raise AssertionError(f"the same solid differs: {created['digest']} vs {twin_created['digest']}")
        mirror = Mirror(client, twin, created["revision"], created["digest"])
        workload = Workload(rng, DIMS, mirror)
        for round_ in range(args.rounds):
            requests = rng.randint(*args.edits)
            fraction = rng.uniform(0.0, 1.2)
            in_flight = await edit_until_kill(mirror, workload, durable, requests, fraction)
            if round_ == 0:
                await held_elsewhere(args, session, created["token"], servers)
            try:
                durable = await restart_and_verify(args, mirror, session, created["token"], in_flight, tally,
                                                   servers)
            except AssertionError:
                print(f"round {round_} (seed {args.seed}): data directory {args.data}", file=sys.stderr)
                raise
            print(f"round {round_}: killed after {requests} requests, {fraction:.2f} of a request's time into "
                  f"{in_flight.describe()[:60] if in_flight else 'an answered request'}; recovered revision "
                  f"{mirror.revision}")
        for step in workload.gesture():
            await mirror.step(step)
        undone = await mirror.walk_back(8, "before the orderly stop")
        status = await asyncio.to_thread(durable.terminate)  # the loop answers the server's close meanwhile
        if status != 0:
            raise AssertionError(f"SIGTERM: exit status {status}, expected 0; log:\n{durable.log_text()}")
        durable = Server(args.marzipan, "durable (after SIGTERM)", data_dir=args.data, server_id=SERVER_ID)
        servers.append(durable)
        mirror.durable = await connect(durable, session)
        joined = await mirror.durable.join(session, created["token"])
        # Only the volume: the stop wrote a snapshot, and a session loaded from a snapshot starts
        # with an empty undo history (session_store.hpp), unlike one replayed from its journal.
        if (joined["revision"], joined["digest"]) != (mirror.revision, mirror.digest):
            raise AssertionError(f"after an orderly stop: revision {joined['revision']} digest {joined['digest']}, "
                                 f"expected {mirror.revision} {mirror.digest}")
        print(f"{tally['rounds']} kills: {tally['equal']} recovered the last acknowledged revision, "
              f"{tally['one more']} one more (the in-flight edit); {mirror.acknowledged} requests acknowledged, "
              f"median {1000 * statistics.median(mirror.latencies):.1f} ms; walked back {undone} undo steps; "
              f"final revision {mirror.revision}; newest snapshot at revision {tally['snapshots']}; "
              f"{time.monotonic() - started:.1f} s")
    except BaseException:
        for server in servers:
            if server.log:
                print(server.log_text(), file=sys.stderr)
        raise
    finally:
        for server in servers:
            server.stop()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--marzipan", required=True, help="the marzipan binary")
    parser.add_argument("--workdir", required=True, help="scratch directory (emptied first, kept after)")
    parser.add_argument("--rounds", type=int, default=5, help="kills and restarts (default 5)")
    parser.add_argument("--seed", type=int, default=7, help="seed of the edits and of the kill moments")
    parser.add_argument("--edits", type=int, nargs=2, default=(40, 90), metavar=("MIN", "MAX"),
                        help="requests per round, drawn between MIN and MAX (default 40 90)")
    args = parser.parse_args()
    asyncio.run(run(args))
    print("ok")


if __name__ == "__main__":
    main()
