#!/usr/bin/python3
"""A data directory that cannot take more: `marzipan serve --data-dir` when its writes fail.

Each scenario edits a session on a server without limits first (so that it has history, a saved
.mzv and, last, a volume.morph whose undo writes a large step file), kills it, and loads the
session on a server whose writes then fail, in one of two ways:
- "file size limit": RLIMIT_FSIZE set on the server process a little above the journal's size
  (the server ignores SIGXFSZ, so a write past it fails with EFBIG); always run;
- "full tmpfs": the data directory on a small tmpfs filled up by the test (ENOSPC); run when this
  process may mount (root with CAP_SYS_ADMIN: the test makes its own mount namespace, so nothing
  it mounts outlives it).
What fails to be written:
- "journal": appends, after some edits still fit (brushes, strokes, CSG, morphology only);
- "undo step": the undo of the morph, whose step file (step-R.bin) is larger than what is left;
- "upload": a volume.load, whose file (load-R.mzv) is stored beside the journal.
Checks: each change that cannot be stored is refused with -32000 "the change could not be stored
..." and the session stays exactly at the last acknowledged revision (digest, can_undo,
can_redo compared with a twin session on a reference server, harness.py); the server stays up
(/healthz); once space is back (the limit lifted, the filler deleted) the same server stores
edits again; after a SIGKILL and a restart without limits, the session is exactly the last
acknowledged revision with its digest, nothing more, and its undo history walks back like the
twin's.

And a read-only data directory (a read-only bind mount, which root cannot write either; same
condition as the tmpfs): a server on it refuses session.create and the join of a session at rest
there with -32000, stays up, and changes no byte; once writable again the session is intact. A
read-only directory without sessions/ stops the server at start (exit 1, the path named).

Usage: test_disk_full.py --marzipan BIN --workdir DIR [--seed S]
Run by ctest ("durability: ..."); Debian's /usr/bin/python3 with python3-websockets. Every
scenario runs even when one before it fails; the failures are listed at the end. Data
directories of failed scenarios are copied to WORKDIR/evidence/. Exit status: 0 when every
scenario ran and passed, 1 when one failed, 77 (SKIPPED_EXIT, ctest's SKIP_RETURN_CODE for
this test) when those that could run passed but the mounted ones could not run here: a pass
without them would claim what was not tested.

Conventions: as harness.py.
"""

import sys

sys.dont_write_bytecode = True  # run from the source tree: no __pycache__ beside the test

import argparse  # noqa: E402
import asyncio  # noqa: E402
import ctypes  # noqa: E402
import errno  # noqa: E402
import os  # noqa: E402
import random  # noqa: E402
import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

from harness import (STORAGE_FAILED, STORAGE_MESSAGE, Mirror, RpcError, Server, Step, Workload,  # noqa: E402
                     connect, listing, new_session_id, session_dir)
from marzipan.rpc import MarzipanError  # noqa: E402  (importable once harness set the path)

DIMS = [40, 32, 36]
SOLID = "torus"
SERVER_ID = "durability-disk"
ROOM = 2000  # bytes of journal the file size limit leaves: a handful of records
TMPFS_BYTES = 4 << 20
CLONE_NEWNS = 0x00020000
SKIPPED_EXIT = 77
# What a scenario records as a problem before going on with the next: a failed check, an
# answer or close the client did not expect, a file operation, a wait that timed out.
FAILURES = (AssertionError, MarzipanError, OSError, asyncio.TimeoutError)


def private_mounts():
    """Enters a mount namespace of this process's own, with propagation off, so that the mounts
    of this test vanish with it. Returns None, or why mounting is not possible here."""
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.unshare(CLONE_NEWNS) != 0:
        return f"unshare(CLONE_NEWNS): {os.strerror(ctypes.get_errno())}"
    done = subprocess.run(["mount", "--make-rprivate", "/"], capture_output=True, text=True)
    if done.returncode != 0:
        return f"mount --make-rprivate /: {done.stderr.strip()}"
    probe = tempfile.mkdtemp(prefix="marzipan-mount-probe-")
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", probe], capture_output=True,
                              text=True)
        if done.returncode != 0:
            return f"mount -t tmpfs: {done.stderr.strip()}"
        subprocess.run(["umount", probe], check=True)
    finally:
        os.rmdir(probe)
    return None


def mount(*args):
    subprocess.run(["mount", *args], check=True, capture_output=True, text=True)


def fill(directory):
    """Fills the file system of `directory` with a filler file until it takes no more byte."""
    path = os.path.join(directory, "filler")
    with open(path, "wb", buffering=0) as f:
        for chunk in (1 << 16, 1 << 12, 1):
            try:
                while True:
                    f.write(b"\0" * chunk)
            except OSError as e:
                if e.errno != errno.ENOSPC:
                    raise
    return path


async def prepare(args, rng, data_dir, servers, reference):
    """A session edited without limits, ending with a volume.save and a volume.morph; the
    server is then killed. Returns (mirror, workload, session, token)."""
    server = Server(args.marzipan, "unlimited", data_dir=data_dir, server_id=SERVER_ID)
    servers.append(server)
    session = new_session_id(rng)
    client = await connect(server, session)
    created = await client.create_session(DIMS, SOLID, session=session)
    twin = await connect(reference)
    twin_created = await twin.create_session(DIMS, SOLID)
    mirror = Mirror(client, twin, created["revision"], created["digest"])
    # A refused write rolls the session back through its journal, and restarts recover it: in
    # both its undo history then starts at the last snapshot, undo or redo (session_store.hpp).
    mirror.history_cut = True
    if twin_created["digest"] != created["digest"]:
        raise AssertionError("the same solid has two digests")
    workload = Workload(rng, DIMS, mirror)
    for _ in range(12):
        for step in workload.gesture(allow_load=False):
            await mirror.step(step)
    await mirror.step(Step("volume.save"))
    await mirror.step(Step("volume.morph", {"kind": "dilate", "radius": 1.0}))
    server.kill()
    return mirror, workload, session, created["token"]


async def expect_refused(mirror, step, what, problems):
    """`step` cannot be stored: it must be refused as such, and change nothing."""
    outcome = await mirror.step(step)
    if outcome.result is not None:
        raise AssertionError(f"{what}: acknowledged ({outcome.result}) although it could not be stored")
    error = outcome.error
    if error is None:
        raise AssertionError(f"{what}: the connection closed instead of an answer")
    expected = f"expected {STORAGE_FAILED} '... {STORAGE_MESSAGE} ...'"
    if error.code != STORAGE_FAILED:
        raise AssertionError(f"{what}: refused with {error.code} {error.message!r}; {expected}")
    if STORAGE_MESSAGE not in error.message:
        problems.append(f"{what}: refused with {error.code} {error.message!r}; {expected}")
    try:
        await mirror.compare_state(f"after the refused {what}")
    except AssertionError as e:
        problems.append(str(e))
        mirror.lose_twin()


async def refuse_journal(mirror, workload, problems):
    """Edits until the journal refuses a few appends; every refusal is checked."""
    refusals = acknowledged = 0
    for _ in range(300):
        for step in workload.gesture(allow_history=False):
            before = mirror.acknowledged
            outcome = await mirror.send_durable(step)
            if outcome.result is None and outcome.error is None:
                raise AssertionError(f"{step.describe()}: the connection closed instead of an answer")
            if outcome.result is not None:
                await mirror.acknowledge(step, outcome)
                acknowledged += mirror.acknowledged - before
                continue
            if outcome.error.code != STORAGE_FAILED:
                await mirror.expect_same_refusal(step, outcome.error)
                continue
            mirror.refused += 1
            await mirror.end_reference_stroke()
            if STORAGE_MESSAGE not in outcome.error.message:
                problems.append(f"journal full: {step.describe()} refused with {outcome.error.message!r}")
            await mirror.compare_state(f"after the refused {step.describe()}")
            refusals += 1
            break
        if refusals >= 4:
            break
    if refusals == 0:
        raise AssertionError(f"{acknowledged} edits stored and none refused: the limit did not bite")
    return acknowledged, refusals


def describe(error, prefix=""):
    return prefix + (str(error) if isinstance(error, AssertionError) else f"{type(error).__name__}: {error}")


async def scenario(args, rng, name, mode, kind, workdir, reference):
    """One scenario; returns a list of problems (empty: passed)."""
    problems = []
    servers = []
    data_dir = os.path.join(workdir, "data")
    state = {}
    try:
        try:
            detail = await refuse(args, rng, mode, kind, workdir, data_dir, reference, servers, problems, state)
        except FAILURES as e:
            problems.append(describe(e))
        if state.get("filler"):
            os.remove(state["filler"])
        for server in servers:
            server.stop()
        if "token" in state:
            try:
                await restart_and_check(args, state["mirror"], state["session"], state["token"], data_dir, servers)
            except FAILURES as e:
                problems.append(describe(e, "after a restart without limits: "))
    finally:
        for server in servers:
            server.stop()
    if not problems:
        print(f"{name}: refused{detail}, the session unchanged; stored again once space was back; intact after "
              f"a restart")
        return problems
    evidence = os.path.join(args.workdir, "evidence", name.replace(" ", "-").replace(",", ""))
    shutil.copytree(data_dir, evidence, dirs_exist_ok=True)
    for server in servers:
        problems.append(f"log:\n{server.log_text()}")
    problems.append(f"data directory copied to {evidence}")
    return problems


async def refuse(args, rng, mode, kind, workdir, data_dir, reference, servers, problems, state):
    """The scenario up to the kill of the limited server; `state` keeps what the restart needs
    (mirror, session, token) and the filler to delete, whatever fails. Returns a detail line."""
    mirror, workload, session, token = await prepare(args, rng, data_dir, servers, reference)
    state.update(mirror=mirror, session=session, token=token)
    journal = max((f for f in os.listdir(session_dir(data_dir, session)) if f.startswith("journal-")),
                  key=lambda f: int(f[len("journal-"):-len(".log")]))
    fsize = None
    if mode == "fsize":
        fsize = os.path.getsize(os.path.join(session_dir(data_dir, session), journal)) + ROOM
    limited = Server(args.marzipan, f"limited ({mode})", data_dir=data_dir, server_id=SERVER_ID, fsize=fsize)
    servers.append(limited)
    mirror.durable = await connect(limited, session)
    await mirror.durable.join(session, token)
    await mirror.compare_state("loaded by the limited server")
    if mode == "tmpfs":
        state["filler"] = fill(workdir)
    detail = ""
    if kind == "undo step":
        await expect_refused(mirror, Step("history.undo"), "undo of the morph (its step file)", problems)
    elif kind == "upload":
        data = mirror.saved[-1]
        await expect_refused(mirror, Step("volume.load", {"bytes": len(data)}, upload=data),
                             "volume.load (its load-R.mzv)", problems)
    else:
        acknowledged, refusals = await refuse_journal(mirror, workload, problems)
        detail = f" after {acknowledged} requests were stored ({refusals} refusals)"
    if not limited.alive() or not limited.healthy():
        raise AssertionError(f"the server is not up after the refusals (exit status {limited.proc.poll()})")
    if mode == "fsize":
        limited.lift_fsize()
    else:
        os.remove(state.pop("filler"))
    refused = mirror.refused
    for _ in range(3):
        for step in workload.gesture():
            await mirror.step(step)
    if mirror.refused != refused:
        raise AssertionError(f"space is back, yet {mirror.refused - refused} more edits were refused")
    limited.kill()
    return detail


async def restart_and_check(args, mirror, session, token, data_dir, servers):
    """Every acknowledged revision, nothing more: the last acknowledged revision and digest, the
    same history as the twin, and the session takes edits again."""
    server = Server(args.marzipan, "restarted", data_dir=data_dir, server_id=SERVER_ID)
    servers.append(server)
    mirror.durable = await connect(server, session)
    try:
        joined = await mirror.durable.join(session, token)
    except RpcError as e:
        raise AssertionError(f"join refused: {e.code} {e.message}") from None
    if (joined["revision"], joined["digest"]) != (mirror.revision, mirror.digest):
        raise AssertionError(f"recovered revision {joined['revision']} digest {joined['digest']}; last acknowledged "
                             f"{mirror.revision} {mirror.digest}")
    await mirror.end_reference_stroke()
    await mirror.compare_state("after the restart")
    await mirror.walk_back(6, "after the restart")
    outcome = await mirror.step(Step("tool.apply", {"tool": "add_blob", "center": [d / 2 for d in DIMS],
                                                    "radius": 6}))
    if outcome.result is None:
        raise AssertionError(f"an edit after the restart was not acknowledged: {outcome.error}")
    status = await asyncio.to_thread(server.terminate)
    if status != 0:
        raise AssertionError(f"SIGTERM: exit status {status}")


async def read_only(args, rng, workdir, reference):
    """A read-only data directory: refusals, no change, then intact once writable."""
    problems = []
    servers = []
    source = os.path.join(workdir, "data")
    target = os.path.join(workdir, "read-only")
    os.makedirs(target)
    try:
        mirror, _, session, token = await prepare(args, rng, source, servers, reference)
        before = listing(session_dir(source, session))
        mount("--bind", source, target)
        mount("-o", "remount,bind,ro", target)
        try:
            with open(os.path.join(target, "probe"), "w"):
                pass
            raise AssertionError("root can write the read-only bind mount: the scenario proves nothing")
        except OSError as e:
            if e.errno != errno.EROFS:
                raise
        server = Server(args.marzipan, "read-only", data_dir=target, server_id=SERVER_ID)
        servers.append(server)
        client = await connect(server, session)
        refusals = []
        attempts = (("join", lambda: client.join(session, token)),
                    ("create", lambda: client.create_session(DIMS, SOLID, session=new_session_id(rng))))
        for what, attempt in attempts:
            try:
                await attempt()
            except RpcError as e:
                if e.code != STORAGE_FAILED:
                    raise AssertionError(f"{what} on a read-only data directory: {e.code} {e.message}, expected "
                                         f"{STORAGE_FAILED}") from None
                refusals.append(f"{what}: {e.message!r}")
            else:
                raise AssertionError(f"{what} succeeded on a read-only data directory")
        if not server.healthy():
            raise AssertionError("the server on the read-only data directory is not up after the refusals")
        if listing(session_dir(source, session)) != before:
            raise AssertionError("files of the session changed under the read-only mount")
        server.stop()
        subprocess.run(["umount", target], check=True)
        await restart_and_check(args, mirror, session, token, source, servers)
        print(f"read-only data directory: refused ({'; '.join(refusals)}), nothing changed, intact afterwards")
        empty = os.path.join(workdir, "empty")
        os.makedirs(empty)
        mount("--bind", "-o", "ro", empty, target)
        mount("-o", "remount,bind,ro", target)
        started = time.monotonic()
        done = subprocess.run([args.marzipan, "serve", "--port", "0", "--data-dir", target], capture_output=True,
                              text=True, timeout=30)
        if done.returncode != 1 or target not in done.stderr:
            raise AssertionError(f"serve on an empty read-only data directory: exit {done.returncode}, stderr "
                                 f"{done.stderr.strip()!r}; expected exit 1 naming {target}")
        print(f"read-only empty data directory: exit 1 in {time.monotonic() - started:.1f} s: "
              f"{done.stderr.strip().splitlines()[0]}")
    except FAILURES as e:
        problems.append(describe(e))
        for server in servers:
            problems.append(f"log:\n{server.log_text()}")
    finally:
        for server in servers:
            server.stop()
    return problems


async def run(args, cannot_mount):
    """Runs every scenario this process can; returns the names of those that failed."""
    rng = random.Random(args.seed)
    shutil.rmtree(args.workdir, ignore_errors=True)
    os.makedirs(args.workdir)
    failures = {}
    started = time.monotonic()
    reference = Server(args.marzipan, "reference")
    try:
        for mode in ("fsize", "tmpfs"):
            for kind in ("journal", "undo step", "upload"):
                name = f"{'file size limit' if mode == 'fsize' else 'full tmpfs'}, {kind}"
                if mode == "tmpfs" and cannot_mount:
                    print(f"{name}: SKIPPED, cannot mount here ({cannot_mount})")
                    continue
                workdir = os.path.join(args.workdir, name.replace(" ", "-").replace(",", ""))
                os.makedirs(workdir)
                if mode == "tmpfs":
                    mount("-t", "tmpfs", "-o", f"size={TMPFS_BYTES},mode=0700", "tmpfs", workdir)
                problems = await scenario(args, rng, name, mode, kind, workdir, reference)
                if problems:
                    failures[name] = problems
        if cannot_mount:
            print(f"read-only data directory: SKIPPED, cannot mount here ({cannot_mount})")
        else:
            workdir = os.path.join(args.workdir, "read-only")
            os.makedirs(workdir)
            problems = await read_only(args, rng, workdir, reference)
            if problems:
                failures["read-only data directory"] = problems
    finally:
        reference.stop()
    print(f"{time.monotonic() - started:.1f} s")
    for name, problems in failures.items():
        print(f"FAILED {name}:", file=sys.stderr)
        for problem in problems:
            print(f"  {problem}", file=sys.stderr)
    return list(failures)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--marzipan", required=True, help="the marzipan binary")
    parser.add_argument("--workdir", required=True, help="scratch directory (emptied first, kept after)")
    parser.add_argument("--seed", type=int, default=11, help="seed of the edits")
    args = parser.parse_args()
    cannot_mount = private_mounts()  # before any thread exists: unshare refuses a threaded process
    failed = asyncio.run(run(args, cannot_mount))
    if failed:
        print("FAILED")
        sys.exit(1)
    if cannot_mount:
        print(f"SKIPPED: the full tmpfs and read-only scenarios need mounts ({cannot_mount}); the others passed")
        sys.exit(SKIPPED_EXIT)
    print("ok")
    sys.exit(0)


if __name__ == "__main__":
    main()
