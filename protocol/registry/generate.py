#!/usr/bin/env python3
"""The tool registry's generator (docs/tools.md): everything Marzipan lists about its tools,
derived from protocol/registry/tools.json.

  generate.py cpp OUTDIR   the C++ tables, at build time (protocol/CMakeLists.txt):
                           OUTDIR/protocol/cpp/tools.generated.hpp (names, parameter ranges,
                           the keys of each tool) and OUTDIR/service/engine_tools.generated.hpp
                           (the tie to the engine's enums and functions)
  generate.py write        rewrites the derived files kept in the source tree: the JSON schemas
                           of the messages that name tools, protocol/js/tools.js,
                           protocol/python/marzipan/tools.py, the tool tables of PROTOCOL.md,
                           README.md and web-client/README.md, and the names in the fuzz
                           dictionaries (tests/fuzz/dict)
  generate.py check        exits 1 naming every derived file that differs from what `write`
                           would make, with the difference (a test)

Those files are kept in the source tree because they are read without a build: the browser
loads the JavaScript as it is, the Python package installs alone, people read the schemas and
the docs. Standard library only (the build runs this with Debian's python3).

Conventions: the registry's parameters are in vu, as on the wire; a file is rewritten only when
its text changes (so that a build does not recompile what did not change); a registry the
generator refuses (RegistryError) says which entry and what to do.
"""

from __future__ import annotations

import copy
import difflib
import json
import pathlib
import re
import sys

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]
REGISTRY = HERE / "tools.json"
SCHEMA_ID = "https://marzipan.invalid/protocol/schema/"
GENERATED_NOTE = "generated from protocol/registry/tools.json by protocol/registry/generate.py (docs/tools.md)"

# What the code does with each kind (docs/tools.md): the C++ types an entry of that kind becomes,
# and the wire keys those types carry. A kind without an entry here has no mechanism yet: the
# first tool of a new kind adds its op type, parser and engine dispatch, then its line here.
TOOL_KINDS = {
    "surface_speed": {
        # protocol/cpp/ops.hpp BrushOp (BrushParams) and StrokeBeginParams; the engine's Brush
        # (server/engine/level_set.hpp), applied by applyStroke.
        "enum": "BrushTool", "defines_enum": True, "names": "kBrushToolNames", "engine_enum": "Brush",
        "keys": {"center", "radius", "strength", "height"}, "strokes": True, "cpp": "SurfaceSpeed",
        "title": "surface speed", "op": True, "dabs": {"swept"},
    },
    "csg": {
        # CsgToolOp (CsgParams); CsgOp is values.hpp's, shared with the engine (applyCsg).
        "enum": "CsgOp", "defines_enum": False, "names": "kCsgToolNames", "engine_enum": "CsgOp",
        "keys": {"shape", "center", "radius", "blend", "axis", "color"}, "strokes": False, "cpp": "Csg",
        "title": "CSG", "op": True, "dabs": {"swept"},
    },
    "warp": {
        # StrokeBeginParams::warp (rpc.hpp) and the service's WarpStroke (server/service/apply_op.hpp),
        # whose applyWarpStroke calls the engine function the registry's "engine" names
        # (server/engine/level_set.hpp, warps; enumerators: that name capitalised). Strokes only:
        # no operation object (tool.apply refuses them); the dabs are anchored, a path of the
        # pointer's points, or a path of surface points.
        "enum": "WarpTool", "defines_enum": True, "names": "kWarpToolNames", "engine_enum": None,
        "keys": {"radius", "strength", "volume", "direction"}, "strokes": True, "cpp": "Warp",
        "title": "warp", "op": False, "dabs": {"anchored", "path", "surface_path"},
    },
    "paint": {
        # StrokeBeginParams::paint (rpc.hpp) and the session's paint strokes (Session::paintDabs);
        # the engine's PaintMode (server/engine/paint.hpp), applied by paintStroke (mask with
        # erase: MaskErase). Strokes only: no operation object; swept dabs, as add_blob's.
        "enum": "PaintTool", "defines_enum": True, "names": "kPaintToolNames", "engine_enum": "PaintMode",
        "keys": {"radius", "strength", "hardness", "color", "erase"}, "strokes": True, "cpp": "Paint",
        "title": "paint", "op": False, "dabs": {"swept"},
    },
}
OPERATION_KINDS = {
    # {"op":"morph","kind":NAME,...} and volume.morph: MorphOp; the engine function by name.
    "morphology": {"keys": {"radius"}},
    # {"op":"smooth","global":true,...}: GlobalSmoothOp, named "smooth" (ops.hpp kOpSmooth).
    "surface_speed": {"keys": {"iterations", "strength"}},
}
# The actions of {"op":"mask","action":...} (protocol/cpp/values.hpp kMaskActionNames; not tools of
# the registry: whole-volume operations of the channels, with their own methods).
MASK_ACTIONS = ("clear", "invert", "fill")
# Keys the grammar of messages uses: no parameter may take them.
RESERVED_KEYS = {"tool", "op", "global", "kind", "action", "ray", "symmetry", "accumulate", "stroke", "dabs", "pressure"}
# stroke.begin's keys that belong to no tool (PROTOCOL.md, stroke.begin).
STROKE_FLAGS = ["symmetry", "accumulate"]


class RegistryError(Exception):
    """A registry the generator refuses; the message names the entry."""


# ---- reading and checking ----------------------------------------------------------------------

class Registry:
    def __init__(self, data: dict):
        self.data = data
        self.groups = data["groups"]
        self.params = {}
        for pid, p in data["parameters"].items():
            q = dict(p)
            q["id"] = pid
            q.setdefault("key", pid)
            self.params[pid] = q
        self.tools = [self._resolve(t, "tool") for t in data["tools"]]
        self.operations = [self._resolve(o, "operation") for o in data["operations"]]
        self._check()

    def _resolve(self, entry: dict, what: str) -> dict:
        e = copy.deepcopy(entry)
        for pid in e["params"]:
            if pid not in self.params:
                raise RegistryError(f'{what} "{e["name"]}": unknown parameter "{pid}" (define it under "parameters")')
        e["param_specs"] = [self.params[pid] for pid in e["params"]]
        if what == "tool":
            e.setdefault("dabs", "swept")
            e.setdefault("inverse", None)
            kind = TOOL_KINDS.get(e["kind"])
            e["enumerator"] = camel(e["engine"]) if kind and kind["engine_enum"] is None else e["engine"]
        return e

    def tool(self, name):
        return next((t for t in self.tools if t["name"] == name), None)

    def _check(self):
        def unique(names, what):
            seen = set()
            for n in names:
                if n in seen:
                    raise RegistryError(f'{what} "{n}" appears twice')
                seen.add(n)

        unique([g["name"] for g in self.groups], "group")
        unique([t["name"] for t in self.tools], "tool")
        unique([o["name"] for o in self.operations], "operation")
        unique([t["browser"]["key"] for t in self.tools], "browser key")
        for p in self.params.values():
            where = f'parameter "{p["id"]}"'
            if p["key"] in RESERVED_KEYS:
                raise RegistryError(f'{where}: key "{p["key"]}" is part of the message grammar; choose another')
            if p["type"] in ("number", "integer"):
                if not p["minimum"] <= p["maximum"]:
                    raise RegistryError(f"{where}: minimum above maximum")
                if "default" in p and not in_range(p, p["default"]):
                    raise RegistryError(f"{where}: default {p['default']} is outside its range")
            if p["type"] == "enum" and "default" in p and p["default"] not in p["values"]:
                raise RegistryError(f'{where}: default "{p["default"]}" is not one of its values')
            if p["type"] in ("point", "vector", "color") and "default" in p:
                raise RegistryError(f"{where}: a {p['type']} has no default")
            for other, values in p.get("only_with", {}).items():
                q = self.params.get(other)
                if not q or q["type"] != "enum" or not set(values) <= set(q["values"]):
                    raise RegistryError(f'{where}: only_with names "{other}", which must be an enum parameter with those values')
        groups = {g["name"] for g in self.groups}
        for t in self.tools:
            where = f'tool "{t["name"]}"'
            kind = TOOL_KINDS.get(t["kind"])
            if kind is None:
                raise RegistryError(f'{where}: kind "{t["kind"]}" has no mechanism in the code yet: the first tool of a '
                                    "kind adds its op type, parser and engine dispatch, then its line in "
                                    "generate.py's TOOL_KINDS (docs/tools.md, \"A new kind\")")
            if t["group"] not in groups:
                raise RegistryError(f'{where}: group "{t["group"]}" is not one of {", ".join(sorted(groups))}')
            keys = [p["key"] for p in t["param_specs"]]
            unique(keys, f"{where}: key")
            for p in t["param_specs"]:
                if p["key"] not in kind["keys"]:
                    raise RegistryError(f'{where}: parameter "{p["id"]}" (key "{p["key"]}") is not carried by the C++ '
                                        f'types of kind {t["kind"]} (keys {", ".join(sorted(kind["keys"]))}): add the '
                                        "field there first (docs/tools.md, \"A new parameter\")")
                if p["in"] == ["stroke"] and not t["strokes"]:
                    raise RegistryError(f'{where}: parameter "{p["id"]}" is for stroke.begin, but the tool does not stroke')
                if "max_per_radius" in p and "radius" not in keys:
                    raise RegistryError(f'{where}: parameter "{p["id"]}" is bounded by the radius, which the tool lacks')
                for other in p.get("only_with", {}):
                    if other not in t["params"]:
                        raise RegistryError(f'{where}: parameter "{p["id"]}" depends on "{other}", which the tool lacks')
            if kind["op"] and not any(p["type"] == "point" and p["role"] == "center" for p in t["param_specs"]):
                raise RegistryError(f"{where}: needs a point parameter of role center (where it acts)")
            if not kind["op"] and any("stroke" not in p["in"] for p in t["param_specs"]):
                raise RegistryError(f"{where}: the tools of kind {t['kind']} have no operation object: each of its "
                                    'parameters must be given to stroke.begin ("in": ["stroke"])')
            if t["strokes"] != kind["strokes"]:
                raise RegistryError(f'{where}: the tools of kind {t["kind"]} {"stroke" if kind["strokes"] else "do not stroke"} '
                                    "in the code (stroke.begin, and the browser's drag or click)")
            if t["dabs"] not in kind["dabs"]:
                raise RegistryError(f'{where}: dabs "{t["dabs"]}" has no mechanism for kind {t["kind"]} in the code '
                                    f'(it has {", ".join(sorted(kind["dabs"]))}; docs/tools.md)')
            if not kind["op"] and [p for p in t["param_specs"] if p["key"] == "radius"] == []:
                raise RegistryError(f"{where}: a {t['kind']} tool needs a radius parameter")
            if t["inverse"] is not None:
                inv = self.tool(t["inverse"])
                if inv is None or inv["inverse"] != t["name"]:
                    raise RegistryError(f'{where}: its inverse "{t["inverse"]}" must be a tool whose inverse is "{t["name"]}"')
        for kind_name in TOOL_KINDS:
            unique([t["enumerator"] for t in self.tools if t["kind"] == kind_name], f"engine name of kind {kind_name}")
        for o in self.operations:
            where = f'operation "{o["name"]}"'
            kind = OPERATION_KINDS.get(o["kind"])
            if kind is None:
                raise RegistryError(f'{where}: kind "{o["kind"]}" is not a whole-volume operation the code has')
            if o["kind"] == "surface_speed" and o["name"] != "smooth":
                raise RegistryError(f'{where}: the one whole-volume surface-speed operation is "smooth" (global smoothing)')
            for p in o["param_specs"]:
                if p["key"] not in kind["keys"] or "op" not in p["in"]:
                    raise RegistryError(f'{where}: parameter "{p["id"]}" is not carried by its C++ op')
        morph = self.morphology()
        if morph and any(o["params"] != morph[0]["params"] for o in morph):
            raise RegistryError("every morphology operation takes the same parameters (volume.morph has one shape)")

    def stroke_tools(self):
        return [t for t in self.tools if t["strokes"]]

    def op_tools(self):
        """The tools with an operation object (tool.apply, `marzipan batch`, the journal's ops)."""
        return [t for t in self.tools if TOOL_KINDS[t["kind"]]["op"]]

    def morphology(self):
        return [o for o in self.operations if o["kind"] == "morphology"]

    def global_smooth(self):
        return next((o for o in self.operations if o["kind"] == "surface_speed"), None)

    def stroke_params(self):
        """The parameters stroke.begin takes for some tool, in order of first use."""
        out = []
        for t in self.stroke_tools():
            for p in t["param_specs"]:
                if "stroke" in p["in"] and p not in out:
                    out.append(p)
        return out


def in_range(p, v) -> bool:
    low_ok = v > p["minimum"] if p.get("exclusive_minimum") else v >= p["minimum"]
    high_ok = v < p["maximum"] if p.get("exclusive_maximum") else v <= p["maximum"]
    return low_ok and high_ok


def load(path=REGISTRY) -> Registry:
    return Registry(json.loads(pathlib.Path(path).read_text()))


def op_keys(t) -> list:
    """The keys of the tool's operation object, in the order messages list them (none: it has none)."""
    if not TOOL_KINDS[t["kind"]]["op"]:
        return []
    grammar = ["tool", "global"] if t["kind"] == "surface_speed" else ["tool"]
    return grammar + [p["key"] for p in t["param_specs"] if "op" in p["in"]]


def stroke_keys(t) -> list:
    return [p["key"] for p in t["param_specs"] if "stroke" in p["in"]] if t["strokes"] else []


def camel(name: str) -> str:
    return "".join(w[:1].upper() + w[1:] for w in name.split("_"))


# ---- C++ (build time) -------------------------------------------------------------------------

def cpp_number(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    text = repr(float(v))
    return text if ("e" in text or "." in text) else text + ".0"


def cpp_string(s: str) -> str:
    return json.dumps(s)


def cpp_strings(values) -> str:
    return "{" + ", ".join(cpp_string(v) for v in values) + "}"


def cpp_param(p) -> str:
    name = "kParam" + camel(p["id"])
    key = cpp_string(p["key"])
    if p["type"] == "number":
        default = cpp_number(p["default"]) if "default" in p else "std::nullopt"
        return (f"inline constexpr NumberParam {name}{{{key}, {cpp_number(p['minimum'])}, {cpp_number(p['maximum'])}, "
                f"{cpp_number(bool(p.get('exclusive_minimum')))}, {cpp_number(bool(p.get('exclusive_maximum')))}, "
                f"{cpp_number(p.get('max_per_radius', 0))}, {default}}};")
    if p["type"] == "integer":
        default = str(p["default"]) if "default" in p else "std::nullopt"
        return f"inline constexpr IntegerParam {name}{{{key}, {p['minimum']}, {p['maximum']}, {default}}};"
    if p["type"] == "point":
        return f"inline constexpr PointParam {name}{{{key}, {cpp_number(p['bound'])}}};"
    if p["type"] == "vector":
        return f"inline constexpr VectorParam {name}{{{key}}};"
    if p["type"] == "color":
        return f"inline constexpr ColorParam {name}{{{key}, {cpp_number(bool(p.get('optional')))}}};"
    if p["type"] == "enum":
        values = f"k{camel(p['id'])}Values"
        default = cpp_string(p["default"]) if "default" in p else "std::nullopt"
        return (f"inline constexpr std::array<std::string_view, {len(p['values'])}> {values}{cpp_strings(p['values'])};\n"
                f"inline constexpr EnumParam {name}{{{key}, {values}, {default}}};")
    return f"inline constexpr BooleanParam {name}{{{key}, {cpp_number(bool(p.get('default', False)))}}};"


def cpp_tools_header(reg: Registry) -> str:
    out = [f"// The tool registry's C++ tables, {GENERATED_NOTE}:",
           "// do not edit; change the registry. protocol/cpp/tool_spec.hpp defines the types and says how to",
           "// read them; protocol/cpp/ops.hpp includes this file.",
           "#pragma once", "",
           "#include <array>",
           "#include <optional>",
           "#include <string_view>", "",
           '#include "protocol/cpp/tool_spec.hpp"',
           '#include "protocol/cpp/values.hpp"', "",
           "namespace marzipan::protocol {", "",
           "// --- parameters: registry \"parameters\", by id ---"]
    for p in reg.params.values():
        out.append(f"// {p['description']}")
        out.append(cpp_param(p))
    out.append("")
    for kind_name, kind in TOOL_KINDS.items():
        tools = [t for t in reg.tools if t["kind"] == kind_name]
        out.append(f"// --- kind {kind_name}: the \"tool\" names, enumerators named after the registry's \"engine\" ---")
        if kind["defines_enum"]:
            out.append(f"enum class {kind['enum']} {{ {', '.join(t['enumerator'] for t in tools)} }};")
        entries = ", ".join(f"{{{kind['enum']}::{t['enumerator']}, {cpp_string(t['name'])}}}" for t in tools)
        out.append(f"inline constexpr std::array<WireName<{kind['enum']}>, {len(tools)}> {kind['names']}{{{{{entries}}}}};")
        out.append("")
    out.append("// --- every tool: its kind, whether it strokes, the keys of its operation object and of stroke.begin ---")
    specs = []
    for t in reg.tools:
        ident = camel(t["name"])
        ok, sk = op_keys(t), stroke_keys(t)
        out.append(f"inline constexpr std::array<std::string_view, {len(ok)}> k{ident}OpKeys{cpp_strings(ok)};")
        out.append(f"inline constexpr std::array<std::string_view, {len(sk)}> k{ident}StrokeKeys{cpp_strings(sk)};")
        specs.append(f"    {{{cpp_string(t['name'])}, ToolKind::{TOOL_KINDS[t['kind']]['cpp']}, {cpp_number(t['strokes'])}, "
                     f"k{ident}OpKeys, k{ident}StrokeKeys}},")
    out.append(f"inline constexpr std::array<ToolSpec, {len(reg.tools)}> kTools{{{{")
    out.extend(specs)
    out.append("}};")
    warps = [t for t in reg.tools if t["kind"] == "warp"]
    if warps:
        out.append("// Each warp tool's radius parameter (the engine's range differs between them), and whether its")
        out.append("// dabs are a path (snake hook: the anchor follows them; pinch path: surface points, a move from each to")
        out.append("// the next) rather than anchored (only the last counts).")
        out.append("constexpr const NumberParam& radiusParamOf(WarpTool tool) {")
        out.append("  switch (tool) {")
        for t in warps:
            radius = next(p for p in t["param_specs"] if p["key"] == "radius")
            out.append(f"    case WarpTool::{t['enumerator']}: return kParam{camel(radius['id'])};")
        out.append("  }")
        out.append(f"  return kParam{camel(next(p for p in warps[0]['param_specs'] if p['key'] == 'radius')['id'])};")
        out.append("}")
        out.append("constexpr bool dabsArePath(WarpTool tool) {")
        out.append("  switch (tool) {")
        for t in warps:
            out.append(f"    case WarpTool::{t['enumerator']}: return {cpp_number(t['dabs'] in ('path', 'surface_path'))};")
        out.append("  }")
        out.append("  return false;")
        out.append("}")
    begin = ["tool"] + list(dict.fromkeys(p["key"] for p in reg.stroke_params())) + STROKE_FLAGS
    out.append("// Every key stroke.begin may have, for some tool.")
    out.append(f"inline constexpr std::array<std::string_view, {len(begin)}> kStrokeBeginKeys{cpp_strings(begin)};")
    out.append("")
    morph = reg.morphology()
    out.append("// --- whole-volume operations: the morphology kinds ({\"op\":\"morph\",\"kind\":...}, volume.morph) ---")
    out.append(f"enum class MorphKind {{ {', '.join(camel(o['name']) for o in morph)} }};")
    entries = ", ".join(f"{{MorphKind::{camel(o['name'])}, {cpp_string(o['name'])}}}" for o in morph)
    out.append(f"inline constexpr std::array<WireName<MorphKind>, {len(morph)}> kMorphKindNames{{{{{entries}}}}};")
    keys = [p["key"] for p in morph[0]["param_specs"]] if morph else []
    out.append(f"inline constexpr std::array<std::string_view, {len(keys)}> kMorphKeys{cpp_strings(keys)};")
    smooth = reg.global_smooth()
    keys = [p["key"] for p in smooth["param_specs"]] if smooth else []
    out.append("// Global smoothing's parameters ({\"op\":\"smooth\",\"global\":true,...}).")
    out.append(f"inline constexpr std::array<std::string_view, {len(keys)}> kGlobalSmoothKeys{cpp_strings(keys)};")
    out += ["", "}  // namespace marzipan::protocol"]
    return "\n".join(out) + "\n"


def cpp_engine_header(reg: Registry) -> str:
    out = [f"// The tie between the tool registry and the engine, {GENERATED_NOTE}:",
           "// do not edit; change the registry. The registry's \"engine\" field names each tool's enumerator of the",
           "// engine's enum, or each whole-volume operation's engine function: a name the engine lacks fails to",
           "// compile here (-Wswitch is an error in this file: every registry tool is mapped). An engine",
           "// enumerator that no registry entry names yet (a tool the engine has before the wire does) has no",
           "// registry name. The engine itself knows nothing of the registry.",
           "#pragma once", "",
           "#include <string_view>", "",
           '#include "engine/edit.hpp"',
           '#include "engine/errors.hpp"',
           '#include "engine/level_set.hpp"',
           '#include "engine/paint.hpp"',
           '#include "engine/thread_pool.hpp"',
           '#include "engine/volume.hpp"',
           '#include "protocol/cpp/tools.generated.hpp"', "",
           "namespace marzipan::service {", "",
           "#pragma GCC diagnostic push",
           '#pragma GCC diagnostic error "-Wswitch"', ""]
    for kind_name, kind in TOOL_KINDS.items():
        tools = [t for t in reg.tools if t["kind"] == kind_name]
        enum, engine = kind["enum"], kind["engine_enum"]
        if engine is None:
            continue  # a function per tool, called by the service (TOOL_KINDS)
        if enum != engine:
            out.append(f"// The engine's {engine} of each tool of kind {kind_name}.")
            out.append(f"inline {engine} engine{engine}(protocol::{enum} tool) {{")
            out.append("  switch (tool) {")
            for t in tools:
                out.append(f"    case protocol::{enum}::{t['engine']}: return {engine}::{t['engine']};")
            out.append("  }")
            out.append(f'  throw EngineError(ErrorKind::InvalidArgument, "tool", "unknown {kind["title"]} tool");')
            out.append("}")
        out.append(f"// The registry's name of a {engine} of the engine, or \"\" for one no registry tool names.")
        out.append(f"inline std::string_view registryName({engine} value) {{")
        out.append("  switch (value) {")
        for t in tools:
            out.append(f"    case {engine}::{t['engine']}: return {cpp_string(t['name'])};")
        out.append("    default: return {};")
        out.append("  }")
        out.append("}")
        out.append("")
    out.append("// The engine function of each morphology kind: the volume by `radius` vu.")
    out.append("inline Edit applyMorph(Volume& vol, protocol::MorphKind kind, double radius, ThreadPool& pool) {")
    out.append("  switch (kind) {")
    for o in reg.morphology():
        out.append(f"    case protocol::MorphKind::{camel(o['name'])}: return {o['engine']}(vol, radius, pool);")
    out.append("  }")
    out.append('  throw EngineError(ErrorKind::InvalidArgument, "kind", "unknown morphology kind");')
    out.append("}")
    smooth = reg.global_smooth()
    if smooth:
        out.append("")
        out.append("// Global smoothing: `iterations` whole-volume steps of dt = strength / 6.")
        out.append("inline Edit applyGlobalSmooth(Volume& vol, int iterations, double strength, ThreadPool& pool) {")
        out.append(f"  return {smooth['engine']}(vol, iterations, strength, pool);")
        out.append("}")
    out += ["", "#pragma GCC diagnostic pop", "", "}  // namespace marzipan::service"]
    return "\n".join(out) + "\n"


# ---- JSON schemas ------------------------------------------------------------------------------

def schema_of(p, in_tool_apply=False) -> dict:
    t = p["type"]
    if t == "point":
        b = float(p["bound"])
        return {"type": "array", "items": {"type": "number", "minimum": -b, "maximum": b}, "minItems": 3, "maxItems": 3,
                "description": f"a point in vu, each coordinate finite and within +-{bound_text(p['bound'])}"}
    if t == "vector":
        s = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3, "not": {"items": {"const": 0}},
             "description": "a direction: three finite numbers, not all zero; its length does not matter"}
        return s
    if t == "color":
        return {"type": "array", "items": {"type": "integer", "minimum": 0, "maximum": 255}, "minItems": 3, "maxItems": 3,
                "description": "a colour: [r, g, b], three integers 0..255, sRGB (the bytes a client draws)"}
    if t == "enum":
        s = {"enum": list(p["values"])}
    elif t == "boolean":
        s = {"type": "boolean"}
    else:
        s = {"type": t}
        s["exclusiveMinimum" if p.get("exclusive_minimum") else "minimum"] = p["minimum"]
        s["exclusiveMaximum" if p.get("exclusive_maximum") else "maximum"] = p["maximum"]
    if "default" in p:
        s["default"] = p["default"]
    notes = []
    if t == "integer":
        notes.append("JSON Schema accepts 2.0 here; parseOp does not: send integers")
    if "max_per_radius" in p:
        notes.append(f"at most {ratio_text(p['max_per_radius'])}the radius (not expressible here; the server checks it)")
    if notes:
        s["description"] = "; ".join(notes)
    return s


def bound_text(b) -> str:
    exponent = len(str(int(b))) - 1
    return f"10^{exponent}" if b == 10 ** exponent and exponent > 3 else number_text(b)


def ratio_text(f) -> str:
    """"half ", "", "twice ", "3 times ": what goes before "the radius"."""
    return {0.5: "half ", 1: "", 2: "twice "}.get(f, f"{number_text(f)} times ")


def number_text(v) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


RAY_SCHEMA = {
    "type": "object",
    "additionalProperties": False,
    "required": ["origin", "direction"],
    "properties": {
        "origin": None,  # the centre's point schema
        "direction": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3,
                      "description": "need not be unit length; not all zero"},
    },
    "description": "a pick ray in vu: the tool is centred where it first meets the surface",
}


def tool_branches(reg: Registry) -> list:
    """op.json's branches for the tools: tools of one kind with the same parameters share one, and
    a parameter allowed only with some values of another splits its tools' branch in two."""
    groups = []
    for t in reg.op_tools():
        sig = (t["kind"], tuple(p["id"] for p in t["param_specs"] if "op" in p["in"]))
        for g in groups:
            if g["sig"] == sig:
                g["tools"].append(t)
                break
        else:
            groups.append({"sig": sig, "tools": [t]})
    branches = []
    for g in groups:
        first = g["tools"][0]
        names = [t["name"] for t in g["tools"]]
        params = [p for p in first["param_specs"] if "op" in p["in"]]
        dependent = [p for p in params if p.get("only_with")]
        if len(dependent) > 1:
            raise RegistryError(f'tool "{first["name"]}": the schemas split a branch on one only_with parameter at most')
        title = TOOL_KINDS[first["kind"]]["title"]
        defaults = ", ".join(f"{p['key']} {json.dumps(p['default'])}" for p in params
                             if "default" in p and not p.get("only_with"))
        if not dependent:
            branches.append(branch(first, names, params, None, f"{title}: default {defaults}" if defaults else title))
            continue
        d = dependent[0]
        (other, values), = d["only_with"].items()
        other_p = reg.params[other]
        rest = [v for v in other_p["values"] if v not in values]
        without = [p for p in params if p is not d]
        branches.append(branch(first, names, without, (other_p, rest),
                               f"{title} with {other_p['key']} {' or '.join(rest)}; default {defaults}"))
        note = f"{d['key']} default {json.dumps(d['default'])}" if "default" in d else d["key"]
        branches.append(branch(first, names, params, (other_p, values),
                               f"{title} with {other_p['key']} {' or '.join(values)}; {note}"))
    return branches


def branch(tool, names, params, restrict, description) -> dict:
    props = {"tool": {"enum": names} if len(names) > 1 else {"const": names[0]}}
    if tool["kind"] == "surface_speed":
        props["global"] = {"const": False}
    for p in params:
        s = schema_of(p)
        if restrict and p["id"] == restrict[0]["id"]:
            s = {"enum": restrict[1]} if len(restrict[1]) > 1 else {"const": restrict[1][0]}
        props[p["key"]] = s
    required = ["tool"] + [p["key"] for p in params if not optional(p)]
    return {"type": "object", "additionalProperties": False, "properties": props, "required": required,
            "description": description}


def global_smooth_branches(reg: Registry) -> list:
    o = reg.global_smooth()
    if not o:
        return []
    props = {p["key"]: schema_of(p) for p in o["param_specs"]}
    required = [p["key"] for p in o["param_specs"] if not optional(p)]
    by_tool = {"type": "object", "additionalProperties": False,
               "properties": {"tool": {"const": "smooth"}, "global": {"const": True}, **props},
               "required": ["tool", "global"] + required, "description": "global smoothing"}
    by_op = {"type": "object", "additionalProperties": False,
             "properties": {"op": {"const": "smooth"}, "global": {"const": True}, **props},
             "required": ["op"] + required, "description": "global smoothing"}
    return [by_tool, by_op]


def morph_properties(reg: Registry) -> tuple:
    morph = reg.morphology()
    props = {"kind": {"enum": [o["name"] for o in morph]}}
    props.update({p["key"]: schema_of(p) for p in morph[0]["param_specs"]})
    required = ["kind"] + [p["key"] for p in morph[0]["param_specs"] if not optional(p)]
    return props, required


def schema_file(name: str, title: str, body: dict) -> dict:
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "$id": SCHEMA_ID + name,
            "$comment": "Generated from protocol/registry/tools.json by protocol/registry/generate.py: do not edit.",
            "title": title, **body}


def op_schema(reg: Registry) -> dict:
    by_tool, by_op = global_smooth_branches(reg)
    tools = tool_branches(reg)
    surface = [b for b in tools if "global" in b["properties"]]
    others = [b for b in tools if "global" not in b["properties"]]
    props, required = morph_properties(reg)
    morph = {"type": "object", "additionalProperties": False, "properties": {"op": {"const": "morph"}, **props},
             "required": ["op"] + required, "description": "morphology"}
    mask = {"type": "object", "additionalProperties": False,
            "properties": {"op": {"const": "mask"}, "action": {"enum": list(MASK_ACTIONS)}},
            "required": ["op", "action"], "description": "the mask of the whole volume (mask.clear, mask.invert, mask.fill)"}
    return schema_file("op.json", "An operation object (PROTOCOL.md, Operation objects; protocol/cpp/ops.hpp)",
                       {"oneOf": surface + [by_tool, by_op] + others + [morph, mask]})


def tool_apply_schema(reg: Registry) -> dict:
    by_tool, _ = global_smooth_branches(reg)
    branches = []
    for b in tool_branches(reg):
        b = copy.deepcopy(b)
        ray = copy.deepcopy(RAY_SCHEMA)
        ray["properties"]["origin"] = copy.deepcopy(b["properties"]["center"])
        b["properties"]["ray"] = ray
        b["required"].remove("center")
        b["oneOf"] = [{"required": ["center"], "not": {"required": ["ray"]}},
                      {"required": ["ray"], "not": {"required": ["center"]}}]
        branches.append(b)
    surface = [b for b in branches if "global" in b["properties"]]
    others = [b for b in branches if "global" not in b["properties"]]
    return schema_file("tool.apply.params.json", "params of tool.apply", {"oneOf": surface + [by_tool] + others})


def stroke_begin_schema(reg: Registry) -> dict:
    tools = reg.stroke_tools()
    props = {"tool": {"enum": [t["name"] for t in tools]}}
    conditions = []
    by_key = {}
    for p in reg.stroke_params():
        by_key.setdefault(p["key"], []).append(p)

    def described(p):
        s = schema_of(p)
        users = [t["name"] for t in tools if p in t["param_specs"]]
        notes = [p["description"] + (f" ({p['unit']})" if "unit" in p else "")]
        if "since" in p:
            notes.append(f"since {p['since']}")
        if len(users) < len(tools):
            notes.append("for " + ", ".join(users) + " only")
        if "max_per_radius" in p:
            notes.append(f"at most {ratio_text(p['max_per_radius'])}the radius (checked by the server)")
        notes += [f"not with {flag}" for flag in p.get("not_with", [])]
        if s.get("description"):
            notes.append(s["description"])
        s["description"] = "; ".join(notes)
        return s, users

    for key, params in by_key.items():
        if len(params) == 1:
            s, users = described(params[0])
            props[key] = s
        else:
            # Several parameters share the key (a warp's radius has the engine's own range): each
            # applies to its tools.
            users = []
            kinds = {p["type"] for p in params}
            props[key] = {"type": kinds.pop() if len(kinds) == 1 else None,
                          "description": "; ".join(f"{', '.join(u)}: see the condition below" for u in [[t["name"] for t in tools if p in t["param_specs"]] for p in params])}
            if props[key]["type"] is None:
                del props[key]["type"]
            for p in params:
                s, own = described(p)
                users += own
                conditions.append({"if": {"properties": {"tool": {"enum": own}}, "required": ["tool"]},
                                   "then": {"properties": {key: s}}})
        others = [t["name"] for t in tools if t["name"] not in users]
        if others:
            conditions.append({"if": {"properties": {"tool": {"enum": others}}, "required": ["tool"]},
                               "then": {"not": {"required": [key]}}})
        for p in params:
            if not optional(p):
                # A stroke parameter without a default: the tools that take it need it (paint's colour).
                conditions.append({"if": {"properties": {"tool": {"enum": [t["name"] for t in tools if p in t["param_specs"]]}},
                                          "required": ["tool"]},
                                   "then": {"required": [key]}})
            for flag in p.get("not_with", []):
                conditions.append({"if": {"properties": {flag: {"const": True}}, "required": [flag]},
                                   "then": {"not": {"required": [p["key"]]}}})
    props["symmetry"] = {"type": "array", "items": {"enum": ["x", "y", "z"]}, "uniqueItems": True, "maxItems": 3}
    props["accumulate"] = {"type": "boolean"}
    warps = [t["name"] for t in tools if t["kind"] == "warp"]
    if warps:
        # PROTOCOL.md, warp strokes: a warp has no mirror images and remembers no dabs.
        for flag in ("symmetry", "accumulate"):
            conditions.append({"if": {"properties": {"tool": {"enum": warps}}, "required": ["tool"]},
                               "then": {"not": {"required": [flag]}}})
    body = {"type": "object", "additionalProperties": False, "properties": props, "required": ["tool"]}
    if conditions:
        body["allOf"] = conditions
    return schema_file("stroke.begin.params.json", "params of stroke.begin", body)


def volume_morph_schema(reg: Registry) -> dict:
    props, required = morph_properties(reg)
    return schema_file("volume.morph.params.json", "params of volume.morph",
                       {"type": "object", "additionalProperties": False, "properties": props, "required": required})


def patch_presence(reg: Registry, schema: dict) -> dict:
    """presence.params.json is written by hand but for the brush's tool names and radius."""
    radius = next(p for p in reg.params.values() if p["key"] == "radius" and "stroke" in p["in"])

    def walk(node):
        if isinstance(node, dict):
            props = node.get("properties")
            if isinstance(props, dict) and {"tool", "radius", "point", "normal"} <= props.keys():
                props["tool"] = {"enum": [t["name"] for t in reg.tools]}
                props["radius"] = {"type": "number", "minimum": radius["minimum"], "maximum": radius["maximum"]}
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    schema = copy.deepcopy(schema)
    walk(schema)
    return schema


def json_text(value) -> str:
    return json.dumps(value, indent=2, ensure_ascii=False) + "\n"


# ---- JavaScript and Python ---------------------------------------------------------------------

class Code(str):
    """Source text that literal() writes as it is (a reference to a parameter)."""


def public_param(p) -> dict:
    return {"id": p["id"], "key": p["key"], **{k: v for k, v in p.items() if k not in ("id", "key")}}


def public_data(reg: Registry, lang: str) -> dict:
    """What the JavaScript and Python modules hold: parameters once by id, and each tool's
    parameters as references to them."""
    def refs(entry):
        return [Code(f'PARAMETERS[{json.dumps(p["id"])}]') for p in entry["param_specs"]]

    tools = [{"name": t["name"], "label": t["label"], "kind": t["kind"], "group": t["group"], "strokes": t["strokes"],
              "dabs": t["dabs"], "inverse": t["inverse"], "description": t["description"],
              "params": refs(t), "browser": t["browser"]} for t in reg.tools]
    operations = [{"name": o["name"], "label": o["label"], "kind": o["kind"], "description": o["description"],
                   "params": refs(o), "browser": o["browser"]} for o in reg.operations]
    return {"groups": reg.groups, "parameters": {pid: public_param(p) for pid, p in reg.params.items()},
            "tools": tools, "operations": operations}


def literal(value, lang: str, indent: int = 0) -> str:
    """A value as JavaScript or Python source: objects and lists of objects one entry a line,
    lists of plain values on one line."""
    pad, inner = "  " * indent, "  " * (indent + 1)
    if isinstance(value, Code):
        return str(value)
    if value is None:
        return "null" if lang == "js" else "None"
    if isinstance(value, bool):
        return ("true" if value else "false") if lang == "js" else repr(value)
    if isinstance(value, (int, float, str)):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, dict):
        if not value:
            return "{}"
        items = [f"{inner}{json.dumps(k)}: {literal(v, lang, indent + 1)}," for k, v in value.items()]
        return "{\n" + "\n".join(items) + f"\n{pad}}}"
    if all(not isinstance(v, (dict, list)) for v in value) and sum(isinstance(v, Code) for v in value) < 4:
        return "[" + ", ".join(literal(v, lang) for v in value) + "]"
    return "[\n" + "\n".join(f"{inner}{literal(v, lang, indent + 1)}," for v in value) + f"\n{pad}]"


def js_module(reg: Registry) -> str:
    data = public_data(reg, "js")
    return f"""// Marzipan's sculpting tools and whole-volume operations, as data: {GENERATED_NOTE}.
// Do not edit: change the registry and run `python3 protocol/registry/generate.py write`.
//
// GROUPS: the palette's groups, in order. TOOLS: the local tools in palette order, each {{name (the
// wire "tool"), label, kind, group, strokes (stroke.begin takes it), dabs, inverse (or null),
// description, params, browser: {{key, short, icon, color}}}}. OPERATIONS: the whole-volume
// operations ({{"op":"morph","kind":name}} or global smoothing), each {{name, label, kind,
// description, params, browser: {{doing, value}}}}. PARAMETERS: by id, each {{id, key (its wire
// name), type, in ("op": the operation object, "stroke": stroke.begin), description}} with, as the
// registry gives them, unit, minimum, exclusive_minimum, maximum, exclusive_maximum, max_per_radius, default (absent:
// required unless optional), optional, values, bound, role, only_with, not_with, since; the
// params of tools and operations are these same objects. Lengths in vu. Everything is frozen.

function frozen(value) {{
  if (value && typeof value === "object") {{
    for (const v of Object.values(value)) frozen(v);
    Object.freeze(value);
  }}
  return value;
}}

export const GROUPS = frozen({literal(data["groups"], "js")});

export const PARAMETERS = frozen({literal(data["parameters"], "js")});

export const TOOLS = frozen({literal(data["tools"], "js")});

export const OPERATIONS = frozen({literal(data["operations"], "js")});

export const TOOL_NAMES = frozen(TOOLS.map((t) => t.name));
"""


def py_module(reg: Registry) -> str:
    data = public_data(reg, "py")
    return f'''"""Marzipan's sculpting tools and whole-volume operations, as data: {GENERATED_NOTE}.
Do not edit: change the registry and run `python3 protocol/registry/generate.py write`.

GROUPS: the palette's groups, in order. TOOLS: the local tools in palette order, each a dict
{{name (the wire "tool"), label, kind, group, strokes (stroke.begin takes it), dabs, inverse (or
None), description, params, browser}}. OPERATIONS: the whole-volume operations ({{"op": "morph",
"kind": name}} or global smoothing). PARAMETERS: by id, each a dict {{id, key (its wire name), type,
in ("op": the operation object, "stroke": stroke.begin), description}} with, as the registry gives
them, unit, minimum, exclusive_minimum, maximum, exclusive_maximum, max_per_radius, default (absent: required unless
optional), optional, values, bound, role, only_with, not_with, since; the params of tools and
operations are these same dicts. Lengths in vu.
"""

GROUPS = {literal(data["groups"], "py")}

PARAMETERS = {literal(data["parameters"], "py")}

TOOLS = {literal(data["tools"], "py")}

OPERATIONS = {literal(data["operations"], "py")}

TOOL_NAMES = tuple(t["name"] for t in TOOLS)


def tool(name: str) -> dict:
    """The tool of that wire name; KeyError for a name that is none."""
    for t in TOOLS:
        if t["name"] == name:
            return t
    raise KeyError(f"no tool {{name!r}}; the tools are {{', '.join(TOOL_NAMES)}}")


def stroke_tools() -> tuple:
    """The names stroke.begin takes."""
    return tuple(t["name"] for t in TOOLS if t["strokes"])
'''


# ---- Markdown tables ---------------------------------------------------------------------------

def range_text(p) -> str:
    t = p["type"]
    if t == "point":
        return f"[x, y, z], each finite, within ±{bound_text(p['bound'])} vu"
    if t == "vector":
        return "[x, y, z], finite, not all zero, any length"
    if t == "enum":
        return " ".join(f"`{v}`" for v in p["values"])
    if t == "boolean":
        return "`true` or `false`"
    if t == "color":
        return "[r, g, b], three integers 0 … 255 (sRGB)"
    lo, hi = number_text(p["minimum"]), number_text(p["maximum"])
    if p.get("exclusive_minimum") or p.get("exclusive_maximum"):
        text = ("(" if p.get("exclusive_minimum") else "[") + f"{lo}, {hi}" + (")" if p.get("exclusive_maximum") else "]")
    else:
        text = f"{lo} … {hi}"
    if "unit" in p:
        text += f" {p['unit']}"
    if "max_per_radius" in p:
        text += f", at most {ratio_text(p['max_per_radius'])}the radius"
    return text


def condition_text(p) -> str:
    """When a parameter may be given at all: "only with `shape` `cylinder`"."""
    parts = [f"only with `{other}` " + " ".join(f"`{v}`" for v in values) for other, values in p.get("only_with", {}).items()]
    parts += [f"not with `{flag}`" for flag in p.get("not_with", [])]
    return "; ".join(parts)


def default_text(p) -> str:
    return f"`{p['default']}`" if isinstance(p["default"], str) else json.dumps(p["default"])


def optional(p) -> bool:
    return "default" in p or p.get("optional", False)


def field_list(params) -> str:
    return ", ".join(f"`{p['key']}`" + ("?" if optional(p) else "") for p in params)


def protocol_tools_table(reg: Registry) -> str:
    rows = ["| object | kind | fields | `stroke.begin` fields | what one application does |", "| --- | --- | --- | --- | --- |"]
    previous = None
    for t in reg.tools:
        ops = [p for p in t["param_specs"] if "op" in p["in"]] if TOOL_KINDS[t["kind"]]["op"] else []
        strokes = [p for p in t["param_specs"] if "stroke" in p["in"]]
        fields = field_list(ops) if ops else "— (strokes only)"
        shown = "same" if fields == previous else fields
        previous = fields
        stroke = "`tool`, " + field_list(strokes) if t["strokes"] else "— (no strokes)"
        rows.append(f'| `{{"tool":"{t["name"]}", ...}}` | {TOOL_KINDS[t["kind"]]["title"]} | {shown} | {stroke} | {t["description"]} |')
    smooth = reg.global_smooth()
    if smooth:
        fields = field_list(smooth["param_specs"])
        rows.append(f'| `{{"op":"smooth","global":true, ...}}` | surface speed, whole volume | {fields} | — | {smooth["description"]} |')
        rows.append('| `{"tool":"smooth","global":true, ...}` | the same | same | — | the same as the line above |')
    for o in reg.morphology():
        fields = field_list(o["param_specs"])
        rows.append(f'| `{{"op":"morph","kind":"{o["name"]}", ...}}` | morphology | {fields} | — | {o["description"]} |')
    return "\n".join(rows)


def users_text(reg: Registry, pid: str) -> str:
    users = []
    for kind_name, kind in TOOL_KINDS.items():
        if not kind["op"]:
            continue  # the operation object's fields: a warp has none
        tools = [t for t in reg.tools if t["kind"] == kind_name]
        taking = [t for t in tools if pid in t["params"]]
        if taking and len(taking) == len(tools):
            users.append(f"{kind['title']} tools")
        elif taking:
            users.append(", ".join(f"`{t['name']}`" for t in taking))
    smooth = reg.global_smooth()
    if smooth and pid in smooth["params"]:
        users.append("global smoothing")
    if any(pid in o["params"] for o in reg.morphology()):
        users.append("morphology")
    return ", ".join(users)


def protocol_fields_table(reg: Registry) -> str:
    rows = ["| field | JSON type | valid values | default | used by |", "| --- | --- | --- | --- | --- |"]
    names = " ".join(f"`{t['name']}`" for t in reg.op_tools())
    rows.append(f"| `tool` | string | {names} | — | tools, global smoothing |")
    rows.append("| `op` | string | `smooth` `morph` `mask` | — | global smoothing, morphology, the mask |")
    rows.append("| `global` | boolean | `true` selects global smoothing: only with `\"tool\":\"smooth\"` or `\"op\":\"smooth\"`; "
                "`false` (surface speed tools only) is the same as leaving it out | `false` for tools, `true` for "
                "`\"op\":\"smooth\"` | surface speed tools, global smoothing |")
    kinds = " ".join(f"`{o['name']}`" for o in reg.morphology())
    rows.append(f"| `kind` | string | {kinds} | — | morphology |")
    rows.append("| `action` | string | " + " ".join(f"`{a}`" for a in MASK_ACTIONS) + ": every band voxel's mask weight "
                "to 0, to 255 minus itself, or to 255 (the methods `mask.clear`, `mask.invert`, `mask.fill`) | — | the mask |")
    keys = {}
    for p in reg.params.values():
        keys.setdefault(p["key"], []).append(p)
    json_types = {"number": "number", "integer": "integer", "point": "array of 3 numbers", "enum": "string",
                  "boolean": "boolean", "color": "array of 3 integers"}
    for p in reg.params.values():
        if "op" not in p["in"]:
            continue
        users = users_text(reg, p["id"])
        label = f"`{p['key']}`" + (f" ({users})" if len(keys[p["key"]]) > 1 else "")
        default = default_text(p) if "default" in p else "—"
        condition = condition_text(p)
        rows.append(f"| {label} | {json_types[p['type']]} | {range_text(p)}: {p['description']}"
                    f"{'; ' + condition if condition else ''} | {default} | {users} |")
    return "\n".join(rows)


def stroke_fields_table(reg: Registry) -> str:
    rows = ["| field | valid values | default | tools |", "| --- | --- | --- | --- |"]
    tools = reg.stroke_tools()
    for p in reg.stroke_params():
        users = [t["name"] for t in tools if p in t["param_specs"]]
        who = "all" if len(users) == len(tools) else " ".join(f"`{u}`" for u in users)
        condition = condition_text(p)
        since = f" (since {p['since']})" if "since" in p else ""
        default = default_text(p) if "default" in p else "none"
        rows.append(f"| `{p['key']}`{since} | {range_text(p)}: {p['description']}{'; ' + condition if condition else ''} "
                    f"| {default} | {who} |")
    return "\n".join(rows)


def readme_ops_table(reg: Registry) -> str:
    rows = ["| line | fields (`?` optional, default) | one application |", "| --- | --- | --- |"]

    def fields(params):
        out = []
        for p in params:
            text = f"`{p['key']}`"
            if "default" in p:
                text += f"? {default_text(p)},"
            text += f" {range_text(p)}"
            if condition_text(p):
                text += f", {condition_text(p)}"
            out.append(text)
        return "; ".join(out)

    previous = None
    for t in reg.op_tools():
        ops = [p for p in t["param_specs"] if "op" in p["in"]]
        text = fields(ops)
        shown = "the same" if text == previous else text
        previous = text
        rows.append(f'| `{{"tool":"{t["name"]}", ...}}` | {shown} | {t["description"]} |')
    smooth = reg.global_smooth()
    if smooth:
        rows.append(f'| `{{"op":"smooth","global":true, ...}}` | {fields(smooth["param_specs"])} | '
                    f'{smooth["description"]}; `"tool":"smooth","global":true` is the same |')
    previous = None
    for o in reg.morphology():
        text = fields(o["param_specs"])
        shown = "the same" if text == previous else text
        previous = text
        rows.append(f'| `{{"op":"morph","kind":"{o["name"]}", ...}}` | {shown} | {o["description"]} |')
    rows.append('| `{"op":"mask","action":"clear"}` | `action` ' + " ".join(f"`{a}`" for a in MASK_ACTIONS) +
                ' | every band voxel\'s mask weight to 0 (`invert`: w to 255 - w, `fill`: to 255); colours stay |')
    # A warp or a paint tool has no operation object: a line holds a whole stroke (server/service/batch.cpp).
    previous = None
    for t in reg.tools:
        if TOOL_KINDS[t["kind"]]["op"]:
            continue
        text = fields([p for p in t["param_specs"] if "stroke" in p["in"]])
        shown = "the same" if text == previous else text
        previous = text
        dabs = ("the dabs' centres, swept as one stroke (`symmetry`, `accumulate` as in stroke.begin)" if t["dabs"] == "swept"
                else "points on the surface along the path (the first starts it; `pressure` scales each move)" if t["dabs"] == "surface_path"
                else "the anchor on the surface, then the pointer's points")
        rows.append(f'| `{{"stroke":{{"tool":"{t["name"]}", ...}},"dabs":[...]}}` | {shown}; `dabs`: {dabs} | {t["description"]} |')
    return "\n".join(rows)


def web_client_keys_table(reg: Registry) -> str:
    rows = ["| keys | tools |", "| --- | --- |"]
    for g in reg.groups:
        tools = [t for t in reg.tools if t["group"] == g["name"]]
        if tools:
            keys = " ".join(t["browser"]["key"].upper() for t in tools)
            rows.append(f"| {keys} | {g['name']}: {', '.join(t['label'] for t in tools)} |")
    return "\n".join(rows)


# ---- the derived files ---------------------------------------------------------------------------

def marked(name: str) -> re.Pattern:
    return re.compile(r"(<!-- generated: " + re.escape(name) + r" .*?-->\n)(.*?)(<!-- end of generated: "
                      + re.escape(name) + r" -->)", re.S)


def replace_marked(text: str, path: str, name: str, body: str) -> str:
    pattern = marked(name)
    if not pattern.search(text):
        raise RegistryError(f"{path}: the markers of the generated section {name!r} are missing")
    return pattern.sub(lambda m: m.group(1) + body + "\n" + m.group(3), text, count=1)


def derived(reg: Registry) -> dict:
    """{path relative to the root: function(current text) -> text the registry gives}."""
    def whole(make):
        return lambda _old: make()

    def sections(path, parts):
        def update(old):
            for name, make in parts:
                old = replace_marked(old, path, name, make(reg))
            return old
        return update

    return {
        "protocol/schema/op.json": whole(lambda: json_text(op_schema(reg))),
        "protocol/schema/tool.apply.params.json": whole(lambda: json_text(tool_apply_schema(reg))),
        "protocol/schema/stroke.begin.params.json": whole(lambda: json_text(stroke_begin_schema(reg))),
        "protocol/schema/volume.morph.params.json": whole(lambda: json_text(volume_morph_schema(reg))),
        "protocol/schema/presence.params.json": lambda old: json_text(patch_presence(reg, json.loads(old))),
        "protocol/js/tools.js": whole(lambda: js_module(reg)),
        "protocol/python/marzipan/tools.py": whole(lambda: py_module(reg)),
        "protocol/PROTOCOL.md": sections("protocol/PROTOCOL.md", [("tools", protocol_tools_table),
                                                                  ("fields", protocol_fields_table),
                                                                  ("stroke fields", stroke_fields_table)]),
        "README.md": sections("README.md", [("ops file", readme_ops_table)]),
        "web-client/README.md": sections("web-client/README.md", [("tool keys", web_client_keys_table)]),
        **{path: (lambda old, where=where: with_fuzz_words(old, fuzz_words(reg, where))) for path, where in FUZZ_DICTS.items()},
    }


# Fuzz dictionaries: libFuzzer word lists that must hold every name and key of the registry.
# `write` appends those missing and leaves the rest, chosen by hand.
FUZZ_DICTS = {"tests/fuzz/dict/op.dict": {"op"}, "tests/fuzz/dict/rpc.dict": {"op", "stroke"}}


def fuzz_words(reg: Registry, where: set) -> list:
    words = [t["name"] for t in reg.tools] + [o["name"] for o in reg.operations]
    for p in reg.params.values():
        if set(p["in"]) & where:
            words.append(p["key"])
            words += p.get("values", [])
    return list(dict.fromkeys(words))


def with_fuzz_words(text: str, words: list) -> str:
    """The dictionary with the two entries ("\\"w\\":" and "\\"w\\"") of every word it lacks appended."""
    entries = {line for line in text.splitlines() if line.startswith('"')}
    new = [line for w in words for line in (f'"\\"{w}\\":"', f'"\\"{w}\\""') if line not in entries]
    return text + "".join(line + "\n" for line in new)


def write_if_changed(path: pathlib.Path, text: str) -> bool:
    if path.exists() and path.read_text() == text:
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return True


def main(argv) -> int:
    if len(argv) < 2 or argv[1] not in ("cpp", "write", "check") or (argv[1] == "cpp") != (len(argv) == 3):
        print(__doc__, file=sys.stderr)
        return 2
    try:
        reg = load()
        if argv[1] == "cpp":
            out = pathlib.Path(argv[2])
            write_if_changed(out / "protocol" / "cpp" / "tools.generated.hpp", cpp_tools_header(reg))
            write_if_changed(out / "service" / "engine_tools.generated.hpp", cpp_engine_header(reg))
            return 0
        stale = []
        for rel, make in derived(reg).items():
            path = ROOT / rel
            old = path.read_text() if path.exists() else ""
            new = make(old)
            if argv[1] == "write":
                if write_if_changed(path, new):
                    print("wrote", rel)
            elif new != old:
                stale.append(rel)
                sys.stdout.writelines(difflib.unified_diff(old.splitlines(True), new.splitlines(True), rel, rel + " (from the registry)", n=1))
        for rel in stale:
            print(f"{rel} differs from what protocol/registry/tools.json gives: run python3 protocol/registry/generate.py write")
        return 1 if stale else 0
    except RegistryError as e:
        print(f"protocol/registry/tools.json: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
