// Strict parsing and canonical writing of operation objects (see ops.hpp). Every check
// throws OpError naming the key; messages quote keys and names the way they appear in JSON.
#include "ops.hpp"

#include "json_checks.hpp"

#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <set>
#include <sstream>
#include <type_traits>
#include <vector>

namespace marzipan::protocol {
namespace {

using nlohmann::json;
using namespace checks;

double strengthValue(const json& v) {
  const double d = finiteNumber(v, "strength");
  if (!(d > 0 && d <= 1)) fail("strength", "must be in (0, 1], got " + formatNumber(d));
  return d;
}

Vec3 centerValue(const json& v) { return vec3Value(v, "center", kMaxCoordinate); }

int iterationsValue(const json& v) { return int(integerInRange(v, "iterations", 1, kMaxIterations)); }

GlobalSmoothOp parseGlobalSmooth(const json& obj, std::string_view nameKey) {
  const std::string context = "global smoothing";
  checkKeys(obj, {nameKey, "global", "iterations", "strength"}, context);
  GlobalSmoothOp op;
  op.iterations = iterationsValue(require(obj, "iterations", context));
  if (const json* s = find(obj, "strength")) op.strength = strengthValue(*s);
  return op;
}

BrushOp parseBrush(const json& obj, BrushTool tool) {
  const std::string context = "tool " + inQuotes(nameOf(kBrushToolNames, tool));
  checkKeys(obj, {"tool", "global", "center", "radius", "strength"}, context);
  BrushOp op;
  op.tool = tool;
  op.params.center = centerValue(require(obj, "center", context));
  op.params.radius = kDefaultBrushRadius;
  if (const json* r = find(obj, "radius")) op.params.radius = numberInRange(*r, "radius", kMinToolRadius, kMaxToolRadius);
  op.params.strength = kDefaultStrength;
  if (const json* s = find(obj, "strength")) op.params.strength = strengthValue(*s);
  return op;
}

CsgToolOp parseCsg(const json& obj, CsgOp csg) {
  const std::string context = "tool " + inQuotes(nameOf(kCsgToolNames, csg));
  checkKeys(obj, {"tool", "shape", "center", "radius", "blend", "axis"}, context);
  CsgToolOp op;
  op.params.op = csg;
  const std::string shape = stringValue(require(obj, "shape", context), "shape");
  const auto s = fromWireName(kToolShapeNames, shape);
  if (!s) fail("shape", "must be one of " + listNames(kToolShapeNames) + ", got " + inQuotes(shape));
  op.params.shape = *s;
  op.params.center = centerValue(require(obj, "center", context));
  op.params.radius = numberInRange(require(obj, "radius", context), "radius", kMinToolRadius, kMaxToolRadius);
  op.params.blend = 0;
  if (const json* b = find(obj, "blend")) op.params.blend = numberInRange(*b, "blend", 0, op.params.radius);
  op.params.axis = 1;
  if (const json* a = find(obj, "axis")) {
    // Only a cylinder has an axis; accepting it elsewhere would let two spellings mean one op.
    if (op.params.shape != ToolShape::Cylinder) fail("axis", "applies to shape \"cylinder\" only");
    const std::string name = stringValue(*a, "axis");
    int axis = -1;
    for (std::size_t i = 0; i < kAxisNames.size(); ++i)
      if (kAxisNames[i] == name) axis = int(i);
    if (axis < 0) fail("axis", "must be one of x, y, z, got " + inQuotes(name));
    op.params.axis = axis;
  }
  return op;
}

MorphOp parseMorph(const json& obj) {
  const std::string context = "op \"morph\"";
  checkKeys(obj, {"op", "kind", "radius"}, context);
  MorphOp op;
  const std::string kind = stringValue(require(obj, "kind", context), "kind");
  const auto k = fromWireName(kMorphKindNames, kind);
  if (!k) fail("kind", "must be one of " + listNames(kMorphKindNames) + ", got " + inQuotes(kind));
  op.kind = *k;
  op.radius = numberInRange(require(obj, "radius", context), "radius", kMinMorphRadius, kMaxMorphRadius);
  return op;
}

Op parseTool(const json& obj, const std::string& name) {
  if (const auto brush = fromWireName(kBrushToolNames, name)) {
    const json* global = find(obj, "global");
    if (global && booleanValue(*global, "global")) {
      if (*brush != BrushTool::Smooth) fail("global", "is only available for tool \"smooth\"");
      return parseGlobalSmooth(obj, "tool");
    }
    return parseBrush(obj, *brush);
  }
  if (const auto csg = fromWireName(kCsgToolNames, name)) return parseCsg(obj, *csg);
  fail("tool", "must be one of " + listNames(kBrushToolNames) + ", " + listNames(kCsgToolNames) + ", got " +
                   inQuotes(name));
}

Op parseOpName(const json& obj, const std::string& name) {
  if (name == kOpSmooth) {
    if (const json* global = find(obj, "global"); global && !booleanValue(*global, "global"))
      fail("global", "must be true for op \"smooth\" (the brush is {\"tool\":\"smooth\", ...})");
    return parseGlobalSmooth(obj, "op");
  }
  if (name == kOpMorph) return parseMorph(obj);
  fail("op", "must be \"smooth\" or \"morph\", got " + inQuotes(name));
}

}  // namespace

Op parseOp(const json& object) {
  if (!object.is_object()) throw OpError("", "an operation must be a JSON object, got " + describe(object));
  const json* tool = find(object, "tool");
  const json* op = find(object, "op");
  if (tool && op) throw OpError("op", "an operation has either \"tool\" or \"op\", not both");
  if (tool) return parseTool(object, stringValue(*tool, "tool"));
  if (op) return parseOpName(object, stringValue(*op, "op"));
  throw OpError("tool", "\"tool\" is missing (an operation names a \"tool\" or an \"op\")");
}

Op parseOpText(std::string_view text) { return parseOp(parseJsonText(text)); }

json toJson(const Op& op) {
  const auto center = [](Vec3 c) { return json::array({c.x, c.y, c.z}); };
  return std::visit(
      [&](const auto& o) -> json {
        using T = std::decay_t<decltype(o)>;
        if constexpr (std::is_same_v<T, BrushOp>) {
          return {{"tool", nameOf(kBrushToolNames, o.tool)},
                  {"center", center(o.params.center)},
                  {"radius", o.params.radius},
                  {"strength", o.params.strength}};
        } else if constexpr (std::is_same_v<T, GlobalSmoothOp>) {
          return {{"op", kOpSmooth}, {"global", true}, {"iterations", o.iterations}, {"strength", o.strength}};
        } else if constexpr (std::is_same_v<T, CsgToolOp>) {
          json j = {{"tool", nameOf(kCsgToolNames, o.params.op)},
                    {"shape", nameOf(kToolShapeNames, o.params.shape)},
                    {"center", center(o.params.center)},
                    {"radius", o.params.radius},
                    {"blend", o.params.blend}};
          if (o.params.shape == ToolShape::Cylinder) j["axis"] = kAxisNames[std::size_t(o.params.axis)];
          return j;
        } else {
          return {{"op", kOpMorph}, {"kind", nameOf(kMorphKindNames, o.kind)}, {"radius", o.radius}};
        }
      },
      op);
}

std::string_view opName(const Op& op) {
  return std::visit(
      [](const auto& o) -> std::string_view {
        using T = std::decay_t<decltype(o)>;
        if constexpr (std::is_same_v<T, BrushOp>) return nameOf(kBrushToolNames, o.tool);
        else if constexpr (std::is_same_v<T, GlobalSmoothOp>) return kOpSmooth;
        else if constexpr (std::is_same_v<T, CsgToolOp>) return nameOf(kCsgToolNames, o.params.op);
        else return kOpMorph;
      },
      op);
}

}  // namespace marzipan::protocol
