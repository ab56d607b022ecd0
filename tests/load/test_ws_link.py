"""tests/load/ws_link.py: the load clients' WebSocket connection, against websockets' own server.

Run: /usr/bin/python3 -m unittest tests/load/test_ws_link.py
Marzipan's server never fragments a message nor closes a sculpting client without cause, so the
load ctests do not reach these paths: a fragmented message, a ping, the server's close code, a
connection reset, a handshake refused or cut short.
"""

import asyncio
import http
import socket
import struct
import sys
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import websockets  # noqa: E402
from websockets.exceptions import InvalidStatus  # noqa: E402

from ws_link import WsLink  # noqa: E402


async def serve(handler, **options):
    """A websockets server of handler on a free port, and its URL."""
    return url_of(await websockets.serve(handler, "127.0.0.1", 0, **options))


async def serve_raw(handler):
    """A plain TCP server of handler(reader, writer) on a free port, and its ws:// URL."""
    return url_of(await asyncio.start_server(handler, "127.0.0.1", 0))


def url_of(server):
    return server, f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}/ws"


async def stop(server):
    server.close()
    await server.wait_closed()


async def until_closed(link, server):
    """Waits for the link's connection to end, then stops the server."""
    await asyncio.wait_for(link.closed, 5)
    await stop(server)


class WsLinkTest(unittest.TestCase):
    def assertEnded(self, link, code, reason):
        """The connection ended with this close code and reason, and refuses to send."""
        self.assertEqual((link.close_code, link.close_reason), (code, reason))
        with self.assertRaises(ConnectionError):
            link.send_text("after the end")

    def test_messages_in_order_fragments_joined_pings_answered_close_code_kept(self):
        async def run():
            pong = asyncio.get_running_loop().create_future()

            async def handler(ws):
                request = await ws.recv()
                await ws.send(f"echo {request}")
                await ws.send([b"\x00\x01", b"\x02", b"\x03\x04"])  # one binary message in three frames
                await ws.send(["frag", "mented"])
                pong.set_result(await asyncio.wait_for(await ws.ping(b"p"), 5))
                await ws.close(1008, "too far behind")

            server, url = await serve(handler)
            got = []
            link = await WsLink.connect(url, 1 << 20, lambda t, now: got.append(t), lambda b, now: got.append(bytes(b)), 5)
            link.send_text("hello")
            await until_closed(link, server)
            self.assertEqual(got, ["echo hello", b"\x00\x01\x02\x03\x04", "fragmented"])
            self.assertIsNotNone(pong.result(), "the server's ping was not answered")
            self.assertEnded(link, 1008, "too far behind")

        asyncio.run(run())

    def test_close_waits_for_the_server_and_a_refused_cut_or_garbled_handshake_raises(self):
        async def run():
            async def handler(ws):
                async for _ in ws:
                    pass

            server, url = await serve(handler)
            link = await WsLink.connect(url, 1 << 20, lambda t, now: None, lambda b, now: None, 5)
            await link.close()
            self.assertTrue(link.closed.done())
            self.assertEqual(link.close_code, 1000)
            await stop(server)

            async def refuse(path, headers):
                return http.HTTPStatus.FORBIDDEN, [], b"no"

            server, url = await serve(handler, process_request=refuse)
            with self.assertRaises(InvalidStatus) as refused:
                await WsLink.connect(url, 1 << 20, None, None, 5)
            self.assertEqual(refused.exception.response.status_code, 403)
            await stop(server)

            async def hang_up(reader, writer):  # a server that reads the request and closes
                await reader.readuntil(b"\r\n\r\n")
                writer.close()

            server, url = await serve_raw(hang_up)
            # ... and not as a protocol callback failing (asyncio's "Fatal error" path).
            loop_errors = []
            asyncio.get_running_loop().set_exception_handler(lambda loop, ctx: loop_errors.append(ctx["message"]))
            with self.assertRaisesRegex(ConnectionError, "closed during the handshake"):
                await WsLink.connect(url, 1 << 20, None, None, 5)
            await stop(server)

            async def babble(reader, writer):  # a server that answers with no HTTP at all
                await reader.readuntil(b"\r\n\r\n")
                writer.write(b"HELLO THERE\r\n\r\n")
                await writer.drain()
                await reader.read()

            server, url = await serve_raw(babble)
            with self.assertRaisesRegex(ConnectionError, "bad handshake response"):
                await WsLink.connect(url, 1 << 20, None, None, 5)
            await asyncio.sleep(0.05)
            self.assertEqual(loop_errors, [])
            await stop(server)

        asyncio.run(run())

    def test_a_connection_lost_without_a_closing_handshake_reads_1006_and_refuses_sends(self):
        async def run():
            async def handler(ws):
                await ws.recv()
                # A reset, not a FIN: the client sees no end of stream, only the loss.
                ws.transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_LINGER,
                                                                 struct.pack("ii", 1, 0))
                ws.transport.abort()

            server, url = await serve(handler)
            link = await WsLink.connect(url, 1 << 20, lambda t, now: None, lambda b, now: None, 5)
            link.send_text("hello")
            await until_closed(link, server)
            self.assertEnded(link, 1006, "")

        asyncio.run(run())

    def test_a_message_over_max_size_closes_with_1009(self):
        async def run():
            async def handler(ws):
                await ws.send(b"x" * 2048)
                await ws.wait_closed()

            server, url = await serve(handler)
            got = []
            link = await WsLink.connect(url, 1024, lambda t, now: got.append(t), lambda b, now: got.append(b), 5)
            await until_closed(link, server)
            self.assertEqual(got, [])
            self.assertEqual(link.close_code, 1009)

        asyncio.run(run())


if __name__ == "__main__":
    unittest.main()
