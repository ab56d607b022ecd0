"""protocol/python/marzipan/rpc.py against the golden vectors and the error table of
protocol/PROTOCOL.md."""

import json
import re
import unittest

from support import PROTOCOL_MD, VECTORS

from marzipan import rpc
from marzipan.rpc import (
    BINARY_METHODS,
    METHODS,
    PROTOCOL_VERSION,
    ErrorCode,
    Notification,
    ProtocolError,
    RequestIds,
    Response,
    RpcError,
    encode_request,
    error_from_response,
    parse_message,
)


class Tables(unittest.TestCase):
    def test_session_held_elsewhere_names_its_owner_only_as_host_and_port(self):
        def held(data):
            return rpc.error_from_response({"code": -32015, "message": "held elsewhere", "data": data}, "session.join")
        self.assertEqual(held({"owner": "server-b:8080"}).owner, "server-b:8080")
        self.assertIsNone(held({}).owner)
        self.assertIsNone(held({"owner": "evil.example:80/x"}).owner)
        self.assertIsNone(held({"owner": 7}).owner)

    def test_methods_and_version_are_those_of_the_vectors(self):
        self.assertEqual(list(METHODS), VECTORS["methods"])
        self.assertEqual(list(BINARY_METHODS), VECTORS["binary_methods"])
        self.assertEqual(PROTOCOL_VERSION, VECTORS["protocol"])
        for method in METHODS:
            self.assertIn(f"`{method}`", PROTOCOL_MD)

    def test_every_code_of_the_error_table_has_its_own_class(self):
        section = PROTOCOL_MD[PROTOCOL_MD.index("## Errors"):PROTOCOL_MD.index("## Closing")]
        table = {int(c) for c in re.findall(r"^\| (-32\d{3}) \|", section, re.M)}
        self.assertEqual(len(table), 22)
        self.assertEqual(table, {int(c) for c in ErrorCode})
        classes = set()
        for code in ErrorCode:
            error = error_from_response({"code": int(code), "message": "m"})
            self.assertIsInstance(error, RpcError)
            self.assertIsNot(type(error), RpcError)
            self.assertEqual((error.code, type(error).code), (int(code), int(code)))
            classes.add(type(error))
        self.assertEqual(len(classes), len(ErrorCode))
        unknown = error_from_response({"code": -32050, "message": "new in a minor version"})
        self.assertIs(type(unknown), RpcError)
        self.assertEqual(unknown.code, -32050)


class Requests(unittest.TestCase):
    def test_requests_encode_to_the_exact_text_of_the_vectors(self):
        for v in VECTORS["requests"]:
            with self.subTest(v["name"]):
                m = json.loads(v["text"])
                self.assertEqual(encode_request(m["method"], m.get("params"), m.get("id")), v["text"])

    def test_a_request_without_id_is_a_notification(self):
        self.assertEqual(encode_request("stroke.dabs", {"stroke": 1, "dabs": []}, None),
                         '{"jsonrpc":"2.0","method":"stroke.dabs","params":{"stroke":1,"dabs":[]}}')

    def test_nan_infinities_and_non_object_params_are_refused_before_sending(self):
        for bad in (float("nan"), float("inf"), -float("inf")):
            with self.assertRaises(ValueError):
                encode_request("tool.apply", {"tool": "add_blob", "center": [1, 2, bad]}, 4)
        with self.assertRaises(TypeError):
            encode_request("tool.apply", [1, 2], 4)
        with self.assertRaises(TypeError):
            encode_request(None, {}, 4)

    def test_ids_run_from_1_to_2_to_the_32_minus_1_and_skip_those_in_use(self):
        ids = RequestIds(first=0xFFFFFFFE)
        self.assertEqual([ids.take(), ids.take(), ids.take()], [0xFFFFFFFE, 0xFFFFFFFF, 1])
        self.assertEqual(ids.take(in_use={2, 3}), 4)
        for bad in (0, 1 << 32):
            with self.assertRaises(ValueError):
                RequestIds(first=bad)


class Messages(unittest.TestCase):
    def test_responses_of_the_vectors_parse_to_their_results(self):
        for v in VECTORS["responses"]:
            with self.subTest(v["name"]):
                m = parse_message(v["text"])
                self.assertIsInstance(m, Response)
                self.assertIsNone(m.error)
                self.assertEqual(m.result, json.loads(v["text"])["result"])
        created = parse_message(VECTORS["responses"][0]["text"])
        self.assertEqual(created.result["limits"]["max_binary_bytes"], 268435456)

    def test_error_vectors_become_the_class_of_their_code_with_field_and_data(self):
        for v in VECTORS["errors"]:
            with self.subTest(v["name"]):
                m = parse_message(v["text"])
                self.assertIsInstance(m, Response)
                error = error_from_response(m.error, "some.method")
                self.assertEqual(error.code, v["code"])
                self.assertIs(type(error), rpc._ERROR_CLASSES[ErrorCode(v["code"])])
                want = json.loads(v["text"])["error"]
                self.assertEqual(error.message, want["message"])
                self.assertEqual(error.data, want.get("data", {}))
                self.assertEqual(error.field, want.get("data", {}).get("field"))
                self.assertIn(str(v["code"]), str(error))
        parse_error = parse_message(VECTORS["errors"][0]["text"])
        self.assertIsNone(parse_error.id)
        invalid = error_from_response(parse_message(VECTORS["errors"][1]["text"]).error)
        self.assertIsInstance(invalid, rpc.InvalidParams)
        self.assertEqual(invalid.field, "radius")

    def test_notifications_of_the_vectors_parse(self):
        for v in VECTORS["notifications"]:
            with self.subTest(v["name"]):
                m = parse_message(v["text"])
                self.assertIsInstance(m, Notification)
                self.assertEqual(m.method, v["method"])
                self.assertEqual(m.params, json.loads(v["text"])["params"])
        self.assertEqual(parse_message('{"jsonrpc":"2.0","method":"x.new"}'), Notification("x.new", {}))

    def test_what_a_server_must_not_send_is_a_protocol_error(self):
        for text in [
            "", "not json", "[]", "42", '{"id":1,"result":{}}', '{"jsonrpc":"1.0","id":1,"result":{}}',
            '{"jsonrpc":"2.0","id":1,"method":"session.stats"}', '{"jsonrpc":"2.0","id":1}',
            '{"jsonrpc":"2.0","id":1,"result":{},"error":{"code":1,"message":""}}',
            '{"jsonrpc":"2.0","id":[1],"result":{}}', '{"jsonrpc":"2.0","id":1,"result":{},"x":0}',
            '{"jsonrpc":"2.0","id":1,"error":{"code":"-32600","message":""}}',
            '{"jsonrpc":"2.0","id":1,"error":{"code":-32600}}',
            '{"jsonrpc":"2.0","id":1,"error":{"code":true,"message":""}}',
            '{"jsonrpc":"2.0","id":1,"result":{"x":NaN}}',
            '{"jsonrpc":"2.0","method":"session.changed","params":[1]}',
        ]:
            with self.assertRaises(ProtocolError, msg=text):
                parse_message(text)


if __name__ == "__main__":
    unittest.main()
