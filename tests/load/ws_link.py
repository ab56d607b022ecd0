"""A WebSocket client connection for the load tool's sculpting clients: websockets' sans-I/O
ClientConnection (the protocol: handshake, framing, masking, pings, the closing handshake) on
asyncio's transport callbacks.

Why not websockets.connect: its legacy client runs a task per connection that parses frames
through asyncio stream reads and hands each message to the reader through a queue and a future,
several event-loop turns per message. A load client receives every splat delta of its session,
and its process shares the server's two cores: under the web-client load, that machinery was a
quarter of a client process's CPU. Here a message is parsed and handed to its callback in the
same data_received call that brought its bytes, and stamped there.

Conventions: callbacks run on the event loop, on_text(str, now) and on_binary(bytes, now) with
now = time.monotonic() when the bytes arrived; send_text writes at once (no drain: a load client
keeps at most a few small requests in flight); closed is a future set when the TCP connection is
gone, after which close_code / close_reason say how it ended.
"""

from __future__ import annotations

import asyncio
import time

from websockets.client import ClientConnection
from websockets.connection import State
from websockets.frames import OP_BINARY, OP_CONT, OP_TEXT
from websockets.http11 import Response
from websockets.uri import parse_uri


class WsLink(asyncio.Protocol):
    def __init__(self, uri: str, max_size: int, on_text, on_binary):
        self.conn = ClientConnection(parse_uri(uri), max_size=max_size)
        loop = asyncio.get_running_loop()
        self.opened = loop.create_future()
        self.closed = loop.create_future()
        self.on_text, self.on_binary = on_text, on_binary
        self.transport = None
        self.parts = []  # the frames so far of a fragmented message
        self.opcode = None  # its opcode

    @classmethod
    async def connect(cls, uri: str, max_size: int, on_text, on_binary, timeout: float) -> "WsLink":
        link = cls(uri, max_size, on_text, on_binary)
        wsuri = link.conn.wsuri
        loop = asyncio.get_running_loop()
        await asyncio.wait_for(loop.create_connection(lambda: link, wsuri.host, wsuri.port), timeout)
        try:
            await asyncio.wait_for(asyncio.shield(link.opened), timeout)
        except BaseException:
            link.transport.abort()
            raise
        return link

    # How the connection ended, once closed is done: the code and reason of the server's close
    # frame; else of this side's, when it failed the connection (a message over max_size: 1009);
    # else 1006 and "" (the TCP connection was lost without a closing handshake).
    @property
    def close_code(self):
        end = self._close_frame()
        return end.code if end is not None else 1006

    @property
    def close_reason(self):
        end = self._close_frame()
        return end.reason if end is not None else ""

    def _close_frame(self):
        return self.conn.close_rcvd or self.conn.close_sent

    def send_text(self, text: str):
        if self.closed.done():
            raise ConnectionError("WebSocket connection lost")
        if self.conn.state is not State.OPEN:
            raise ConnectionError(f"WebSocket {self.conn.state.name.lower()}")
        self.conn.send_text(text.encode())
        self._write()

    async def close(self, timeout: float = 10.0):
        """Starts the closing handshake and waits until the server has closed the connection."""
        if self.conn.state is State.OPEN:
            self.conn.send_close(1000)
            self._write()
        try:
            await asyncio.wait_for(asyncio.shield(self.closed), timeout)
        except asyncio.TimeoutError:
            self.transport.abort()
            await self.closed

    # asyncio.Protocol

    def connection_made(self, transport):
        self.transport = transport
        self.conn.send_request(self.conn.connect())
        self._write()

    def data_received(self, data: bytes):
        now = time.monotonic()
        try:
            self.conn.receive_data(data)
        except Exception as e:  # noqa: BLE001  only the handshake's parser raises (see _handshake_failed)
            if self.opened.done():
                raise
            self._handshake_failed(f"bad handshake response: {e!r}")
            self.transport.abort()
            return
        self._write()
        for event in self.conn.events_received():
            if isinstance(event, Response):
                if not self.opened.done():
                    if self.conn.handshake_exc is not None:
                        self.opened.set_exception(self.conn.handshake_exc)
                    else:
                        self.opened.set_result(None)
                continue
            opcode = event.opcode
            if opcode is OP_TEXT or opcode is OP_BINARY:
                if not event.fin:
                    self.opcode, self.parts = opcode, [event.data]
                    continue
                payload = event.data
            elif opcode is OP_CONT:
                self.parts.append(event.data)
                if not event.fin:
                    continue
                opcode, payload, self.parts = self.opcode, b"".join(self.parts), []
            else:
                continue  # control frames: the connection answered pings and closes itself
            if opcode is OP_TEXT:
                self.on_text(payload.decode(), now)
            else:
                self.on_binary(payload, now)

    def eof_received(self):
        try:
            self.conn.receive_eof()
        except EOFError as e:  # the server closed before its handshake response was whole
            self._handshake_failed(f"connection closed during the handshake: {e}")
        self._write()
        return False  # let the transport close

    def connection_lost(self, exc):
        self._handshake_failed(f"connection lost during the handshake: {exc!r}")
        if not self.closed.done():
            self.closed.set_result(None)

    def _handshake_failed(self, why: str):
        """Fails connect() with ConnectionError(why), unless the handshake already ended. Once
        open, websockets fails the connection itself on bad or missing bytes; during the
        handshake websockets 10's client parser lets the error out of receive_data or
        receive_eof instead, which asyncio would report as a protocol callback's fatal error."""
        if not self.opened.done():
            self.opened.set_exception(ConnectionError(why))

    def _write(self):
        for data in self.conn.data_to_send():
            if data:
                self.transport.write(data)
            elif self.transport.can_write_eof():
                self.transport.write_eof()
