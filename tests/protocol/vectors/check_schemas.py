#!/usr/bin/env python3
"""Checks the golden vectors against protocol/schema (needs python3-jsonschema).

Every example request, response, error and notification must validate against its envelope
schema and its method's params/result schema; every invalid request of layer "op" or "params"
must fail its params schema; every valid op must pass op.json and every invalid op fail it,
except the checks a schema cannot express (listed in SCHEMA_BLIND). Exit status 1 on a mismatch.
Usage: python3 tests/protocol/vectors/check_schemas.py
"""
import json
import pathlib
import sys

import jsonschema

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCHEMA = ROOT / "protocol" / "schema"
VECTORS = json.loads((pathlib.Path(__file__).parent / "vectors.json").read_text())
# What JSON Schema cannot say: blend <= radius, and that 2.0 is not an integer.
SCHEMA_BLIND = {"blend above radius", "iterations 2.0"}


def validator(name):
    schema = json.loads((SCHEMA / name).read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def valid(name, instance):
    return validator(name).is_valid(instance)


failures = []


def expect(ok, what):
    if not ok:
        failures.append(what)


for r in VECTORS["requests"]:
    m = json.loads(r["text"])
    expect(valid("request.json", m), "request envelope: " + r["name"])
    expect(valid(m["method"] + ".params.json", m.get("params", {})), "request params: " + r["name"])
for r in VECTORS["responses"]:
    m = json.loads(r["text"])
    expect(valid("response.json", m), "response envelope: " + r["name"])
    expect(valid(r["method"] + ".result.json", m["result"]), "result: " + r["name"])
for e in VECTORS["errors"]:
    expect(valid("error.json", json.loads(e["text"])), "error: " + e["name"])
for n in VECTORS["notifications"]:
    m = json.loads(n["text"])
    expect(valid("notification.json", m), "notification envelope: " + n["name"])
    expect(valid(n["method"] + ".params.json", m["params"]), "notification params: " + n["name"])
for r in VECTORS["invalid_requests"]:
    if r["layer"] == "envelope":
        continue
    m = json.loads(r["text"])
    expect(not valid(m["method"] + ".params.json", m["params"]), "accepted invalid params: " + r["name"])
for o in VECTORS["ops"]["valid"]:
    expect(valid("op.json", o["op"]) and valid("op.json", o["canonical"]), "op refused: " + json.dumps(o["op"]))
for o in VECTORS["ops"]["invalid"]:
    if o["name"] not in SCHEMA_BLIND:
        expect(not valid("op.json", o["op"]), "invalid op accepted: " + o["name"])
for path in sorted(SCHEMA.glob("*.json")):
    validator(path.name)

for f in failures:
    print("FAIL", f)
print(f"{len(failures)} failures")
sys.exit(1 if failures else 0)
