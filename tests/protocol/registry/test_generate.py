"""The tool registry (protocol/registry/tools.json) and its generator (generate.py): the registry
is valid against its schema, every file derived from it is current (`generate.py check`), the
generator refuses a registry that contradicts itself or the code (naming the entry), the schema
can describe the tools to come (a surface tool like inflate with a height), every tool has a
golden vector (an operation object, or for a warp tool, which strokes only, a stroke.begin
request), and the Python client's marzipan.tools reads as the registry. Needs Debian's python3-jsonschema. Usage: python3 tests/protocol/registry/test_generate.py
"""

import contextlib
import copy
import io
import json
import pathlib
import sys
import unittest

import jsonschema

ROOT = pathlib.Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "protocol" / "registry"))
sys.path.insert(0, str(ROOT / "protocol" / "python"))

import generate  # noqa: E402  (the paths above)
from marzipan import tools as client_tools  # noqa: E402

REGISTRY = json.loads((ROOT / "protocol" / "registry" / "tools.json").read_text())
SCHEMA = json.loads((ROOT / "protocol" / "registry" / "tools.schema.json").read_text())


def refusal(mutate) -> str:
    """The generator's message for the registry as `mutate` changes it, or "" when it takes it."""
    data = copy.deepcopy(REGISTRY)
    mutate(data)
    try:
        generate.Registry(data)
    except generate.RegistryError as e:
        return str(e)
    return ""


def tool(data, name):
    return next(t for t in data["tools"] if t["name"] == name)


# A warp entry as the registry has them, to mutate.
GRAB = {
    "name": "grab2", "label": "Grab 2", "kind": "warp", "engine": "grab2", "group": "Warp", "strokes": True,
    "dabs": "anchored", "params": ["warp_radius", "strength"],
    "description": "moves the surface held at the anchor to the pointer's point, less towards the radius",
    "browser": {"key": "j", "short": "Grab", "icon": "\u2725", "color": [0.9, 0.9, 0.5]},
}


class RegistryFile(unittest.TestCase):
    def test_valid_against_its_schema(self):
        jsonschema.Draft202012Validator.check_schema(SCHEMA)
        errors = list(jsonschema.Draft202012Validator(SCHEMA).iter_errors(REGISTRY))
        self.assertEqual([e.message for e in errors], [])

    def test_derived_files_are_current(self):
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            status = generate.main(["generate.py", "check"])
        self.assertEqual(status, 0, out.getvalue())

    def test_every_tool_has_a_golden_vector(self):
        vectors = json.loads((ROOT / "tests" / "protocol" / "vectors" / "vectors.json").read_text())
        named = {o["op"].get("tool") for o in vectors["ops"]["valid"]}
        begun = {json.loads(r["text"])["params"].get("tool") for r in vectors["requests"] if r["method"] == "stroke.begin"}
        for t in REGISTRY["tools"]:
            if generate.TOOL_KINDS[t["kind"]]["op"]:
                self.assertIn(t["name"], named, f'tests/protocol/vectors/vectors.json has no valid op of {t["name"]}')
            else:
                self.assertIn(t["name"], begun, f'tests/protocol/vectors/vectors.json has no stroke.begin of {t["name"]}')

    def test_schema_says_what_the_tools_to_come_need(self):
        data = copy.deepcopy(REGISTRY)
        inflate = dict(tool(data, "add_blob"), name="inflate2", label="Inflate", engine="Inflate2",
                       browser={"key": "n", "short": "Inflate", "icon": "o", "color": [0.5, 0.8, 0.6]})
        del inflate["inverse"]
        data["tools"].append(inflate)
        errors = [e.message for e in jsonschema.Draft202012Validator(SCHEMA).iter_errors(data)]
        self.assertEqual(errors, [])
        bad = copy.deepcopy(data)
        bad["tools"][-1]["dabs"] = "dragged"
        self.assertTrue(list(jsonschema.Draft202012Validator(SCHEMA).iter_errors(bad)))


class Refusals(unittest.TestCase):
    def test_the_registry_as_it_is_is_taken(self):
        self.assertEqual(refusal(lambda d: None), "")

    def test_a_name_twice(self):
        self.assertIn('tool "smooth" appears twice', refusal(lambda d: d["tools"].append(copy.deepcopy(tool(d, "smooth")))))

    def test_a_key_twice(self):
        self.assertIn('browser key "a" appears twice', refusal(lambda d: tool(d, "smooth")["browser"].update(key="a")))

    def test_inverses_pair_up(self):
        self.assertIn('its inverse "csg_add"', refusal(lambda d: tool(d, "csg_intersect").update(inverse="csg_add")))
        self.assertIn('its inverse "nothing"', refusal(lambda d: tool(d, "smooth").update(inverse="nothing")))

    def test_parameters_exist_and_fit(self):
        self.assertIn('unknown parameter "stiffness"', refusal(lambda d: tool(d, "smooth")["params"].append("stiffness")))
        self.assertIn("outside its range", refusal(lambda d: d["parameters"]["radius"].update(default=2000)))
        self.assertIn("part of the message grammar", refusal(lambda d: d["parameters"]["blend"].update(key="ray")))
        self.assertIn("the tools of kind surface_speed stroke", refusal(lambda d: tool(d, "smooth").update(strokes=False)))
        self.assertIn("the tool does not stroke", refusal(lambda d: tool(d, "add_blob").update(strokes=False)))
        self.assertIn("the tools of kind csg do not stroke", refusal(lambda d: tool(d, "csg_add").update(strokes=True)))

    def test_a_parameter_the_cpp_types_do_not_carry(self):
        self.assertIn("not carried by the C++ types", refusal(lambda d: tool(d, "smooth")["params"].append("volume")))

    def test_a_kind_without_code(self):
        self.assertIn('kind "sculpt" has no mechanism in the code yet', refusal(lambda d: d["tools"].append(dict(GRAB, kind="sculpt"))))

    def test_warps_stroke_anchored_or_along_a_path_without_an_operation_object(self):
        self.assertEqual(refusal(lambda d: d["tools"].append(GRAB)), "")
        self.assertIn('dabs "swept" has no mechanism for kind warp', refusal(lambda d: d["tools"].append(dict(GRAB, dabs="swept"))))
        self.assertIn('dabs "anchored" has no mechanism for kind surface_speed',
                      refusal(lambda d: tool(d, "smooth").update(dabs="anchored")))
        self.assertIn("no operation object", refusal(lambda d: d["tools"].append(dict(GRAB, params=["shape_radius", "strength"]))))
        self.assertIn("needs a radius", refusal(lambda d: d["tools"].append(dict(GRAB, params=["strength"]))))
        self.assertIn("the tool does not stroke", refusal(lambda d: d["tools"].append(dict(GRAB, strokes=False))))

    def test_a_group_that_is_none(self):
        self.assertIn('group "Blobs"', refusal(lambda d: tool(d, "add_blob").update(group="Blobs")))

    def test_an_engine_name_twice(self):
        self.assertIn("engine name of kind surface_speed", refusal(lambda d: tool(d, "sharpen").update(engine="Smooth")))


class Tables(unittest.TestCase):
    def test_markdown_tables_name_every_tool(self):
        reg = generate.load()
        for t in REGISTRY["tools"]:
            self.assertIn(f'`{{"tool":"{t["name"]}", ...}}`', generate.protocol_tools_table(reg))
        fields = generate.protocol_fields_table(reg)
        strokes = generate.stroke_fields_table(reg)
        for t in REGISTRY["tools"]:
            if generate.TOOL_KINDS[t["kind"]]["op"]:
                self.assertIn(f'`{{"tool":"{t["name"]}", ...}}`', generate.readme_ops_table(reg))
                self.assertIn(f'`{t["name"]}`', fields)
            else:
                # No operation object: not a value of "tool" (the mask tool's name is also the
                # "op" of the whole-volume mask, {"op":"mask","action":...}).
                tool_row = next(row for row in fields.splitlines() if row.startswith("| `tool` |"))
                self.assertNotIn(f'`{t["name"]}`', tool_row)
                self.assertIn(f'`{t["name"]}`', strokes)
                self.assertIn(f'`{{"stroke":{{"tool":"{t["name"]}", ...}},"dabs":[...]}}`', generate.readme_ops_table(reg))
        keys = generate.web_client_keys_table(reg)
        for t in REGISTRY["tools"]:
            self.assertIn(t["browser"]["key"].upper(), keys)
            self.assertIn(t["label"], keys)


class PythonClient(unittest.TestCase):
    def test_marzipan_tools_reads_as_the_registry(self):
        self.assertEqual(client_tools.TOOL_NAMES, tuple(t["name"] for t in REGISTRY["tools"]))
        self.assertEqual(client_tools.stroke_tools(), tuple(t["name"] for t in REGISTRY["tools"] if t["strokes"]))
        for t in REGISTRY["tools"]:
            self.assertEqual([p["id"] for p in client_tools.tool(t["name"])["params"]], t["params"])
        self.assertEqual(client_tools.tool("add_blob")["params"][1]["default"], REGISTRY["parameters"]["radius"]["default"])
        with self.assertRaises(KeyError):
            client_tools.tool("hammer")


if __name__ == "__main__":
    unittest.main()
