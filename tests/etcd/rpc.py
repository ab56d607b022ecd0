"""A JSON-RPC connection over one WebSocket, for the etcd process tests and measurements
(test_etcd_failover.py, session_cost.py): a view "none" client that only sends requests and
reads the answers, skipping notifications and binary frames.

Conventions: every wait is bounded (connect 5 s, close 2 s, a call its `timeout`); `server` is
the X-Marzipan-Server header of the answer to the upgrade (which server HAProxy chose).
"""

import asyncio
import json
import time

import websockets


class Rpc:
    """call() returns ("ok", result) or ("error", code, data); result() returns the result or
    raises RuntimeError(code, message, data). A closed connection raises ConnectionError."""

    def __init__(self, url):
        self.url = url
        self.next_id = 1

    async def __aenter__(self):
        self.ws = await asyncio.wait_for(websockets.connect(self.url, max_size=None), 5)
        self.server = self.ws.response_headers.get("X-Marzipan-Server")
        return self

    async def __aexit__(self, *exc):
        try:
            await asyncio.wait_for(self.ws.close(), 2)
        except Exception:
            pass

    async def reply(self, method, params, timeout):
        """The whole reply object (with "result" or "error") to this request."""
        rid = self.next_id
        self.next_id += 1
        try:
            await self.ws.send(json.dumps({"jsonrpc": "2.0", "id": rid, "method": method, "params": params}))
            deadline = time.monotonic() + timeout
            while True:
                message = await asyncio.wait_for(self.ws.recv(), max(0.01, deadline - time.monotonic()))
                if isinstance(message, bytes):
                    continue
                reply = json.loads(message)
                if reply.get("id") == rid:
                    return reply
        except (websockets.ConnectionClosed, OSError) as e:
            raise ConnectionError(str(e)) from None

    async def call(self, method, params, timeout=10):
        reply = await self.reply(method, params, timeout)
        if "error" in reply:
            return ("error", reply["error"]["code"], reply["error"].get("data"))
        return ("ok", reply["result"])

    async def result(self, method, params, timeout=30):
        reply = await self.reply(method, params, timeout)
        if "error" in reply:
            raise RuntimeError(reply["error"]["code"], reply["error"]["message"], reply["error"].get("data"))
        return reply["result"]
