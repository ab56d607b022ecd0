"""protocol/python/marzipan/client.py against a scripted WebSocket server in this process: the
order rules of PROTOCOL.md (a binary answer before its response, carrying the request's id;
pushes with id 0; volume.load's upload as the very next message), typed errors, the session id
in the URL, and what happens when the connection closes. tests/protocol/python/test_client_server.py
runs the same client against the real server."""

import asyncio
import http
import json
import re
import unittest
import urllib.parse

import support  # noqa: F401  (puts this checkout's marzipan on sys.path)

import websockets

from marzipan import rpc
from marzipan.client import Client, ConnectFailed, new_session_id, session_url
from marzipan.frames import FrameKind, decode_frame, encode_frame
from marzipan.rpc import ConnectionClosed, Notification, ProtocolError

SESSION_ID = re.compile(r"^[A-Za-z0-9_-]{22}$")


def reply(request, result):
    return json.dumps({"jsonrpc": "2.0", "id": request["id"], "result": result})


def created(request, revision=0):
    return reply(request, {"session": request["params"]["session"], "token": "t0k", "view_token": "v1ew",
                           "client": 1, "size": request["params"]["size"], "revision": revision,
                           "digest": "0123456789abcdef", "protocol": {"major": 1, "minor": 0},
                           "limits": {"max_dabs": 3}, "can_undo": False, "can_redo": False,
                           "read_only": False, "clients": [{"client": 1, "read_only": False}]})


class FakeServer:
    """Serves /ws with `script(ws, path, requests)`, an async function that plays the server's
    side; every text request it reads is appended to `requests` by `receive`. Other paths get
    HTTP 404 as the real server gave before its WebSocket layer."""

    def __init__(self, script):
        self.script = script
        self.paths = []
        self.requests = []
        self.server = None

    async def __aenter__(self):
        async def handler(ws, path):
            self.paths.append(path)
            await self.script(ws, self)

        async def only_ws(path, headers):
            if urllib.parse.urlsplit(path).path != "/ws":
                return http.HTTPStatus.NOT_FOUND, [], b"not found\n"
            return None

        self.server = await websockets.serve(handler, "127.0.0.1", 0, process_request=only_ws)
        return self

    async def __aexit__(self, *exc):
        self.server.close()
        await self.server.wait_closed()

    @property
    def url(self):
        return f"ws://127.0.0.1:{self.server.sockets[0].getsockname()[1]}"

    async def receive(self, ws):
        message = await ws.recv()
        if isinstance(message, str):
            message = json.loads(message)
            self.requests.append(message)
        return message


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, 20))


class Offline(unittest.TestCase):
    def test_session_ids_are_22_base64url_characters_and_differ(self):
        ids = {new_session_id() for _ in range(200)}
        self.assertEqual(len(ids), 200)
        for i in ids:
            self.assertRegex(i, SESSION_ID)

    def test_urls_get_the_ws_path_and_the_session_parameter(self):
        self.assertEqual(session_url("ws://h:1", "abc"), "ws://h:1/ws?session=abc")
        self.assertEqual(session_url("http://h:1/", "abc"), "ws://h:1/ws?session=abc")
        self.assertEqual(session_url("https://h/ws?session=old&x=1", "abc"), "wss://h/ws?x=1&session=abc")
        self.assertEqual(session_url("ws://h:1/lb/ws", "a-b_c"), "ws://h:1/lb/ws?session=a-b_c")
        with self.assertRaises(ValueError):
            session_url("ftp://h/ws", "abc")


class WithFakeServer(unittest.TestCase):
    def test_create_proposes_the_id_of_the_url_and_binary_answers_come_first(self):
        async def script(ws, server):
            create = await server.receive(ws)
            await ws.send(created(create))
            frame = await server.receive(ws)
            png = b"\x89PNG\r\n\x1a\n" + bytes(20)
            await ws.send(encode_frame(FrameKind.FRAME_PNG, frame["id"], 3, png))
            await ws.send(reply(frame, {"revision": 3, "width": 4, "height": 2, "format": "png", "bytes": len(png)}))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    result = await client.create_session(64, "pig")
                    image = await client.frame({"eye": [1, 2, 3], "target": [0, 0, 0]}, 4, 2)
                return server, client, result, image

        server, client, result, image = run(go())
        path = urllib.parse.urlsplit(server.paths[0])
        proposed = urllib.parse.parse_qs(path.query)["session"][0]
        self.assertEqual(path.path, "/ws")
        self.assertRegex(proposed, SESSION_ID)
        create, frame = server.requests
        self.assertEqual(create["method"], "session.create")
        self.assertEqual(create["params"], {"size": [64, 64, 64], "solid": "pig", "session": proposed,
                                            "protocol": 1, "view": "none", "splats": 2})
        self.assertEqual((client.session, client.token, client.view_token), (proposed, "t0k", "v1ew"))
        self.assertEqual(result["revision"], 0)
        self.assertEqual(frame["method"], "render.frame")
        self.assertIsInstance(frame["id"], int)
        self.assertTrue(1 <= frame["id"] <= 0xFFFFFFFF)
        self.assertEqual(frame["params"], {"camera": {"eye": [1, 2, 3], "target": [0, 0, 0]}, "width": 4,
                                           "height": 2, "format": "png"})
        self.assertEqual(image, b"\x89PNG\r\n\x1a\n" + bytes(20))
        self.assertEqual(client.revision, 3)

    def test_errors_raise_the_class_of_their_code_with_message_and_field(self):
        async def script(ws, server):
            request = await server.receive(ws)
            await ws.send(json.dumps({"jsonrpc": "2.0", "id": request["id"], "error": {
                "code": -32602, "message": '"radius" must be between 0.5 and 1024, got 2000',
                "data": {"field": "radius"}}}))
            request = await server.receive(ws)
            await ws.send(json.dumps({"jsonrpc": "2.0", "id": request["id"], "error": {
                "code": -32014, "message": "session exists", "data": {"field": "session"}}}))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    with self.assertRaises(rpc.InvalidParams) as invalid:
                        await client.apply("add_blob", center=[1, 2, 3], radius=2000)
                    with self.assertRaises(rpc.SessionExists) as exists:
                        await client.create_session(8, "sphere")
                return server, invalid.exception, exists.exception

        server, invalid, exists = run(go())
        self.assertEqual(server.requests[0]["params"], {"tool": "add_blob", "center": [1, 2, 3], "radius": 2000})
        self.assertEqual((invalid.code, invalid.field, invalid.method), (-32602, "radius", "tool.apply"))
        self.assertEqual(invalid.message, '"radius" must be between 0.5 and 1024, got 2000')
        self.assertEqual((exists.code, exists.field), (-32014, "session"))

    def test_pushes_go_to_the_updates_in_order_and_end_with_the_connection(self):
        async def script(ws, server):
            request = await server.receive(ws)
            await ws.send(reply(request, {"revision": 7, "can_undo": True, "can_redo": False}))
            await ws.send(json.dumps({"jsonrpc": "2.0", "method": "session.changed", "params": {
                "revision": 7, "by": 1, "cause": "undo", "roi": None, "digest": "00", "can_undo": True,
                "can_redo": False}}))
            splats = b"MZSP" + bytes([1, 0, 0, 0]) + bytes(8)
            await ws.send(encode_frame(FrameKind.SPLATS_DELTA, 0, 7, splats))
            await ws.send(json.dumps({"jsonrpc": "2.0", "method": "session.clients", "params": {"clients": []}}))
            await ws.close(1001, "shutting down")

        async def go():
            async with FakeServer(script) as server:
                client = await Client.connect(server.url)
                await client.undo()
                updates = [u async for u in client.updates()]
                with self.assertRaises(ConnectionClosed) as closed:
                    await client.stats()
                await client.close()
                return updates, closed.exception

        updates, closed = run(go())
        self.assertEqual([type(u).__name__ for u in updates], ["Notification", "Frame", "Notification"])
        self.assertEqual(updates[0], Notification("session.changed", updates[0].params))
        self.assertEqual(updates[0].params["cause"], "undo")
        self.assertEqual((updates[1].kind, updates[1].request_id, updates[1].revision), (FrameKind.SPLATS_DELTA, 0, 7))
        self.assertEqual(updates[2].method, "session.clients")
        self.assertEqual((closed.code, closed.reason), (1001, "shutting down"))

    def test_a_full_update_queue_drops_the_oldest_and_counts_them(self):
        async def script(ws, server):
            for revision in range(1, 6):
                await ws.send(json.dumps({"jsonrpc": "2.0", "method": "session.changed",
                                          "params": {"revision": revision}}))
            await ws.close()

        async def go():
            async with FakeServer(script) as server:
                client = await Client.connect(server.url, max_updates=2)
                updates = [u.params["revision"] async for u in client.updates()]
                await client.close()
                return updates, client

        updates, client = run(go())
        self.assertEqual(updates, [4, 5])
        self.assertEqual((client.dropped_updates, client.revision), (3, 5))

    def test_load_sends_its_upload_as_the_next_message_with_the_request_id(self):
        async def script(ws, server):
            request = await server.receive(ws)
            upload = await ws.recv()
            frame = decode_frame(upload)
            server.upload = (frame.kind, frame.request_id, frame.revision, bytes(frame.payload))
            await ws.send(reply(request, {"revision": 1, "digest": "aa", "roi": None, "can_undo": True,
                                          "can_redo": False}))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    result = await client.load(b"MZVF" + bytes(60))
                return server, result

        server, result = run(go())
        request = server.requests[0]
        self.assertEqual((request["method"], request["params"]), ("volume.load", {"bytes": 64}))
        self.assertEqual(server.upload, (FrameKind.VOLUME_UPLOAD, request["id"], 0, b"MZVF" + bytes(60)))
        self.assertEqual(result["revision"], 1)

    def test_concurrent_requests_get_their_own_answers(self):
        async def script(ws, server):
            first = await server.receive(ws)
            second = await server.receive(ws)
            obj = b"# Marzipan\n"
            await ws.send(encode_frame(FrameKind.MESH_OBJ, second["id"], 2, obj))
            await ws.send(reply(second, {"revision": 2, "format": "obj", "vertices": 0, "triangles": 0,
                                         "bytes": len(obj)}))
            await ws.send(reply(first, {"revision": 2, "digest": "ff"}))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    return await asyncio.gather(client.stats(), client.export_mesh("obj"))

        stats, mesh = run(go())
        self.assertEqual(stats, {"revision": 2, "digest": "ff"})
        self.assertEqual(mesh, b"# Marzipan\n")

    def test_a_binary_answer_missing_late_or_of_another_size_is_a_protocol_error(self):
        async def script(ws, server):
            request = await server.receive(ws)  # the response alone
            await ws.send(reply(request, {"revision": 0, "digest": "00", "bytes": 4}))
            request = await server.receive(ws)  # a frame whose size differs from the result's
            await ws.send(encode_frame(FrameKind.VOLUME_FILE, request["id"], 0, b"MZVF"))
            await ws.send(reply(request, {"revision": 0, "digest": "00", "bytes": 5}))
            request = await server.receive(ws)  # a frame of a kind that does not answer splats.get
            await ws.send(encode_frame(FrameKind.VOLUME_FILE, request["id"], 0, b"MZVF"))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                client = await Client.connect(server.url)
                errors = []
                for call in (client.save, client.save, client.splats):
                    try:
                        await call()
                    except ProtocolError as e:
                        errors.append(str(e))
                closed = client.closed
                await client.close()
                return errors, closed

        errors, closed = run(go())
        self.assertEqual(len(errors), 3)
        self.assertIn("without its binary frame", errors[0])
        self.assertIn("says 5 bytes, the frame holds 4", errors[1])
        self.assertIn("kind 8", errors[2])
        self.assertTrue(closed, "a frame that breaks the contract closes the connection")

    def test_join_reconnects_under_the_session_it_joins_and_create_after_leave_under_a_new_id(self):
        async def script(ws, server):
            while True:
                try:
                    request = await server.receive(ws)
                except websockets.ConnectionClosed:
                    return
                if request["method"] == "session.join":
                    await ws.send(reply(request, {"session": request["params"]["session"], "client": 2,
                                                  "size": [8, 8, 8], "revision": 4, "read_only": True,
                                                  "limits": {}, "clients": []}))
                elif request["method"] == "session.leave":
                    await ws.send(reply(request, {"session": "joined-session-0001"}))
                else:
                    await ws.send(created(request))

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    first_route = client._route
                    joined = await client.join("joined-session-0001", "v1ew")
                    state = (client.session, client.read_only, client.token, client.view_token)
                    await client.leave()
                    await client.create_session([8, 16, 24], "box")
                return server, first_route, joined, state, client.session

        server, first_route, joined, state, new_session = run(go())
        sessions = [urllib.parse.parse_qs(urllib.parse.urlsplit(p).query)["session"][0] for p in server.paths]
        self.assertEqual(sessions[:2], [first_route, "joined-session-0001"])
        self.assertEqual(len(sessions), 3)
        self.assertNotIn(sessions[2], (first_route, "joined-session-0001"))
        self.assertEqual(new_session, sessions[2])
        self.assertEqual(joined["revision"], 4)
        self.assertEqual(state, ("joined-session-0001", True, None, "v1ew"))
        self.assertEqual(server.requests[-1]["params"]["size"], [8, 16, 24])

    def test_a_stroke_splits_its_dabs_by_max_dabs_and_ends(self):
        async def script(ws, server):
            await ws.send(created(await server.receive(ws)))
            while True:
                try:
                    request = await server.receive(ws)
                except websockets.ConnectionClosed:
                    return
                method = request["method"]
                if method == "stroke.begin":
                    await ws.send(reply(request, {"stroke": 9}))
                elif method == "stroke.dabs":
                    await ws.send(reply(request, {"revision": 1, "applied": len(request["params"]["dabs"]) - 1,
                                                  "roi": None}))
                else:
                    await ws.send(reply(request, {"revision": 2, "can_undo": True, "can_redo": False}))

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url) as client:
                    await client.create_session(32, "sphere")
                    dabs = [[1, 2, 3], {"center": [4, 5, 6], "pressure": 0.5}, {"ray": ([0, 0, 99], [0, 0, -1])},
                            (7, 8, 9)]
                    result = await client.stroke("smooth", dabs, radius=4, symmetry=["x"])
                return server, result

        server, result = run(go())
        methods = [r["method"] for r in server.requests[1:]]
        self.assertEqual(methods, ["stroke.begin", "stroke.dabs", "stroke.dabs", "stroke.end"])
        self.assertEqual(server.requests[1]["params"], {"tool": "smooth", "radius": 4, "symmetry": ["x"]})
        self.assertEqual(server.requests[2]["params"]["dabs"], [
            {"center": [1, 2, 3]}, {"center": [4, 5, 6], "pressure": 0.5},
            {"ray": {"origin": [0, 0, 99], "direction": [0, 0, -1]}}])
        self.assertEqual(server.requests[3]["params"], {"stroke": 9, "dabs": [{"center": [7, 8, 9]}]})
        self.assertEqual(server.requests[4]["params"], {"stroke": 9})
        self.assertEqual(result, {"stroke": 9, "applied": 2, "revision": 2, "can_undo": True, "can_redo": False})

    def test_a_request_timeout_leaves_the_connection_usable(self):
        async def script(ws, server):
            slow = await server.receive(ws)
            fast = await server.receive(ws)
            await ws.send(reply(slow, {"revision": 1}))  # too late: nobody waits for it any more
            await ws.send(reply(fast, {"revision": 2}))
            await ws.wait_closed()

        async def go():
            async with FakeServer(script) as server:
                async with Client.connect(server.url, request_timeout=0.2) as client:
                    with self.assertRaises(asyncio.TimeoutError):
                        await client.stats()
                    client.request_timeout = 5
                    return await client.stats()

        self.assertEqual(run(go()), {"revision": 2})

    def test_a_path_without_websocket_is_a_connect_failure(self):
        async def go():
            async with FakeServer(None) as server:
                with self.assertRaises(ConnectFailed) as failed:
                    await Client.connect(server.url + "/elsewhere")
                return str(failed.exception)

        self.assertIn("HTTP 404", run(go()))


if __name__ == "__main__":
    unittest.main()
