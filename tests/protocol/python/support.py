"""Shared helpers of the Python protocol tests: paths, the golden vectors, a server process.

The tests import `marzipan` from protocol/python of this checkout: ctest sets PYTHONPATH to it,
and this module adds it too so that `python3 -m unittest` works from any directory. Integration
tests read the `marzipan` binary from $MARZIPAN_BIN (ctest passes the built one) and are
skipped without it.
"""

import json
import os
import re
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
PYTHON_PACKAGE = REPO / "protocol" / "python"
EXAMPLES = PYTHON_PACKAGE / "examples"
if str(PYTHON_PACKAGE) not in sys.path:
    sys.path.insert(0, str(PYTHON_PACKAGE))

VECTORS = json.loads((REPO / "tests" / "protocol" / "vectors" / "vectors.json").read_text(encoding="utf-8"))
PROTOCOL_MD = (REPO / "protocol" / "PROTOCOL.md").read_text(encoding="utf-8")
MARZIPAN_BIN = os.environ.get("MARZIPAN_BIN")


def python_env() -> dict:
    """The environment for a child python3 that must import this checkout's marzipan."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(PYTHON_PACKAGE), env.get("PYTHONPATH")) if p)
    return env


class XorShift:
    """A small deterministic generator (xorshift64*), so that random tests repeat exactly."""

    def __init__(self, seed: int):
        self.state = (seed * 0x9E3779B97F4A7C15 + 1) & 0xFFFFFFFFFFFFFFFF

    def next64(self) -> int:
        x = self.state
        x ^= x >> 12
        x ^= (x << 25) & 0xFFFFFFFFFFFFFFFF
        x ^= x >> 27
        self.state = x
        return (x * 0x2545F4914F6CDD1D) & 0xFFFFFFFFFFFFFFFF

    def uniform(self) -> float:
        return (self.next64() >> 11) / float(1 << 53)

    def below(self, n: int) -> int:
        return self.next64() % n


def needs_server(cls):
    """Skips a TestCase class when no marzipan binary is given."""
    return unittest.skipUnless(MARZIPAN_BIN, "set MARZIPAN_BIN to the built marzipan binary")(cls)


class ServerProcess:
    """`marzipan serve --port 0` in a scratch data directory, for one test class.

    start() waits for its `listening on http://HOST:PORT` line; stop() sends SIGTERM and waits
    (the server finishes what runs and exits 0), killing it after 20 s.
    """

    def __init__(self, *extra_args: str):
        self.extra_args = extra_args
        self.process = None
        self.data_dir = None
        self.http_url = None

    def start(self) -> "ServerProcess":
        self.data_dir = tempfile.TemporaryDirectory(prefix="marzipan-py-")
        self.process = subprocess.Popen(
            [MARZIPAN_BIN, "serve", "--port", "0", "--threads", "2", "--data-dir", self.data_dir.name,
             *self.extra_args],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        line = self.process.stdout.readline()
        match = re.search(r"listening on (http://\S+)", line)
        if not match:
            self.stop()
            raise RuntimeError(f"marzipan serve did not start (first line: {line!r})")
        self.http_url = match.group(1).rstrip("/")
        return self

    @property
    def ws_url(self) -> str:
        return "ws" + self.http_url[len("http"):] + "/ws"

    def stop(self) -> int | None:
        code = None
        if self.process is not None:
            self.process.terminate()
            try:
                code = self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                code = self.process.wait()
            self.process.stdout.close()
            self.process = None
        if self.data_dir is not None:
            self.data_dir.cleanup()
            self.data_dir = None
        return code


class ServerTestCase(unittest.TestCase):
    """A test class sharing one `marzipan serve` (cls.server, its WebSocket URL cls.url); the
    server must exit 0 on SIGTERM after the class's tests. Decorate subclasses with needs_server."""

    @classmethod
    def setUpClass(cls):
        cls.server = ServerProcess().start()
        cls.url = cls.server.ws_url

    @classmethod
    def tearDownClass(cls):
        code = cls.server.stop()
        if code not in (0, None):
            raise AssertionError(f"marzipan serve exited with {code} after SIGTERM")
