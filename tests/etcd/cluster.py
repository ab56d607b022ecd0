"""Local etcd clusters for the tests: N members of Debian's `etcd` (3.4) on loopback ports, each
with a data directory of its own under a scratch directory, started together as one new cluster.

Conventions: every wait is bounded; stop() kills every member still running (call it in a
finally); a member's stderr goes to MEMBER.log beside its data directory, printed by log_tail()
when a check fails. Ports are picked free just before the start (bound, then released).
"""

import json
import os
import shutil
import signal
import socket
import subprocess
import time
import urllib.request


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Member:
    def __init__(self, name, workdir):
        self.name = name
        self.client_port = free_port()
        self.peer_port = free_port()
        self.data_dir = os.path.join(workdir, name)
        self.log_path = os.path.join(workdir, name + ".log")
        self.proc = None

    @property
    def url(self):
        return f"http://127.0.0.1:{self.client_port}"

    @property
    def peer_url(self):
        return f"http://127.0.0.1:{self.peer_port}"

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def post(self, path, body, timeout=2.0):
        request = urllib.request.Request(self.url + path, data=json.dumps(body).encode(), method="POST",
                                         headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(request, timeout=timeout) as r:
            return json.loads(r.read())


class EtcdCluster:
    """`size` members named m0, m1, ...; start() returns once every member answers and one
    is leader. Timings suited to loopback: 50 ms heartbeats, 500 ms election timeout."""

    def __init__(self, workdir, size=3, etcd="etcd"):
        self.workdir = workdir
        self.etcd = etcd
        shutil.rmtree(workdir, ignore_errors=True)
        os.makedirs(workdir)
        self.members = [Member(f"m{k}", workdir) for k in range(size)]

    @property
    def endpoints(self):
        return ",".join(m.url for m in self.members)

    def start(self, timeout=20.0):
        initial = ",".join(f"{m.name}={m.peer_url}" for m in self.members)
        for m in self.members:
            self._spawn(m, initial, "new")
        self.wait_leader(timeout)
        return self

    def _spawn(self, m, initial, state):
        args = [self.etcd, "--name", m.name, "--data-dir", m.data_dir,
                "--listen-client-urls", m.url, "--advertise-client-urls", m.url,
                "--listen-peer-urls", m.peer_url, "--initial-advertise-peer-urls", m.peer_url,
                "--initial-cluster", initial, "--initial-cluster-state", state,
                "--initial-cluster-token", "marzipan-test",
                "--heartbeat-interval", "50", "--election-timeout", "500",
                # Old revisions go within the hour, as docker/compose.yaml configures them.
                "--auto-compaction-mode", "periodic", "--auto-compaction-retention", "1h"]
        log = open(m.log_path, "ab")
        m.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=log, stderr=log)
        log.close()

    def status(self, m):
        """(member id, leader id) as member m sees them, or None when it does not answer."""
        try:
            s = m.post("/v3/maintenance/status", {}, timeout=1.0)
            return int(s["header"]["member_id"]), int(s.get("leader", "0"))
        except (OSError, ValueError, KeyError):
            return None

    def leader(self):
        """The member that is leader by its own account, or None."""
        for m in self.members:
            if not m.alive():
                continue
            s = self.status(m)
            if s and s[0] == s[1]:
                return m
        return None

    def wait_leader(self, timeout=20.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for m in self.members:
                if m.proc is not None and m.proc.poll() is not None:
                    raise AssertionError(f"etcd {m.name} exited ({m.proc.returncode}):\n{self.log_tail(m)}")
            leader = self.leader()
            if leader is not None and all(self.status(m) for m in self.members if m.alive()):
                return leader
            time.sleep(0.05)
        raise AssertionError("no etcd leader within %.0f s:\n%s" % (timeout, "\n".join(self.log_tail(m) for m in self.members)))

    def kill(self, m):
        """SIGKILL one member."""
        if m.alive():
            m.proc.send_signal(signal.SIGKILL)
            m.proc.wait(timeout=10)

    def log_tail(self, m, lines=30):
        try:
            with open(m.log_path, errors="replace") as f:
                return "".join(f"  [{m.name}] {line}" for line in f.readlines()[-lines:])
        except OSError:
            return f"  [{m.name}] (no log)"

    def stop(self):
        for m in self.members:
            if m.alive():
                m.proc.kill()
            if m.proc is not None:
                m.proc.wait(timeout=10)
