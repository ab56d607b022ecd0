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

// The tool's spec; the generated tables name every tool of every kind.
const ToolSpec& specOf(std::string_view name) { return *findTool(kTools, name); }

// The registry's values of the enumerations values.hpp shares with the engine, and the axis
// order CsgParams::axis counts in.
static_assert(sameNames(kToolShapeNames, kShapeValues), "the registry's shapes are values.hpp's ToolShape");
static_assert(kAxisValues.size() == 3 && kAxisValues[0] == "x" && kAxisValues[1] == "y" && kAxisValues[2] == "z",
              "CsgParams::axis counts x, y, z");

GlobalSmoothOp parseGlobalSmooth(const json& obj, std::string_view nameKey) {
  const std::string context = "global smoothing";
  std::vector<std::string_view> keys{nameKey, "global"};
  keys.insert(keys.end(), kGlobalSmoothKeys.begin(), kGlobalSmoothKeys.end());
  checkKeys(obj, keys, context);
  GlobalSmoothOp op;
  op.iterations = int(integerParam(obj, kParamIterations, context));
  op.strength = numberParam(obj, kParamStrength, context);
  return op;
}

BrushOp parseBrush(const json& obj, BrushTool tool) {
  const ToolSpec& spec = specOf(nameOf(kBrushToolNames, tool));
  const std::string context = "tool " + inQuotes(spec.name);
  checkKeys(obj, spec.opKeys, context);
  BrushOp op;
  op.tool = tool;
  op.params.center = pointParam(obj, kParamCenter, context);
  op.params.radius = numberParam(obj, kParamRadius, context);
  op.params.strength = numberParam(obj, kParamStrength, context);
  return op;
}

CsgToolOp parseCsg(const json& obj, CsgOp csg) {
  const ToolSpec& spec = specOf(nameOf(kCsgToolNames, csg));
  const std::string context = "tool " + inQuotes(spec.name);
  checkKeys(obj, spec.opKeys, context);
  CsgToolOp op;
  op.params.op = csg;
  op.params.shape = kToolShapeNames[enumParam(obj, kParamShape, context)].value;
  op.params.center = pointParam(obj, kParamCenter, context);
  op.params.radius = numberParam(obj, kParamShapeRadius, context);
  op.params.blend = numberParam(obj, kParamBlend, context, op.params.radius);
  // Only a cylinder has an axis; accepting it elsewhere would let two spellings mean one op.
  if (find(obj, kParamAxis.key) && op.params.shape != ToolShape::Cylinder)
    fail(kParamAxis.key, "applies to shape \"cylinder\" only");
  op.params.axis = int(enumParam(obj, kParamAxis, context));
  op.color = colorParam(obj, kParamCsgColor, context);
  return op;
}

MorphOp parseMorph(const json& obj) {
  const std::string context = "op \"morph\"";
  std::vector<std::string_view> keys{"op", "kind"};
  keys.insert(keys.end(), kMorphKeys.begin(), kMorphKeys.end());
  checkKeys(obj, keys, context);
  MorphOp op;
  const std::string kind = stringValue(require(obj, "kind", context), "kind");
  const auto k = fromWireName(kMorphKindNames, kind);
  if (!k) fail("kind", "must be one of " + listNames(kMorphKindNames) + ", got " + inQuotes(kind));
  op.kind = *k;
  op.radius = numberParam(obj, kParamMorphRadius, context);
  return op;
}

MaskOp parseMask(const json& obj) {
  const std::string context = "op \"mask\"";
  checkKeys(obj, {"op", "action"}, context);
  const std::string action = stringValue(require(obj, "action", context), "action");
  const auto a = fromWireName(kMaskActionNames, action);
  if (!a) fail("action", "must be one of " + listNames(kMaskActionNames) + ", got " + inQuotes(action));
  return MaskOp{*a};
}

Op parseTool(const json& obj, const std::string& name) {
  if (const auto brush = fromWireName(kBrushToolNames, name)) {
    const json* global = find(obj, "global");
    if (global && booleanValue(*global, "global")) {
      if (name != kOpSmooth) fail("global", "is only available for tool \"smooth\"");
      return parseGlobalSmooth(obj, "tool");
    }
    return parseBrush(obj, *brush);
  }
  if (const auto csg = fromWireName(kCsgToolNames, name)) return parseCsg(obj, *csg);
  if (fromWireName(kWarpToolNames, name))
    fail("tool", inQuotes(name) + " is a warp tool: it has no operation object, it strokes (stroke.begin, then "
                 "stroke.dabs from the anchor)");
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
  if (name == kOpMask) return parseMask(obj);
  fail("op", "must be \"smooth\", \"morph\" or \"mask\", got " + inQuotes(name));
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
          if (o.params.shape == ToolShape::Cylinder) j["axis"] = kAxisValues[std::size_t(o.params.axis)];
          if (o.color) j["color"] = json::array({o.color->r, o.color->g, o.color->b});
          return j;
        } else if constexpr (std::is_same_v<T, MorphOp>) {
          return {{"op", kOpMorph}, {"kind", nameOf(kMorphKindNames, o.kind)}, {"radius", o.radius}};
        } else {
          return {{"op", kOpMask}, {"action", nameOf(kMaskActionNames, o.action)}};
        }
      },
      op);
}

std::string_view maskMethodName(MaskAction action) {
  switch (action) {
    case MaskAction::Clear: return "mask.clear";
    case MaskAction::Invert: return "mask.invert";
    case MaskAction::Fill: return "mask.fill";
  }
  return "mask";
}

std::string_view opName(const Op& op) {
  return std::visit(
      [](const auto& o) -> std::string_view {
        using T = std::decay_t<decltype(o)>;
        if constexpr (std::is_same_v<T, BrushOp>) return nameOf(kBrushToolNames, o.tool);
        else if constexpr (std::is_same_v<T, GlobalSmoothOp>) return kOpSmooth;
        else if constexpr (std::is_same_v<T, CsgToolOp>) return nameOf(kCsgToolNames, o.params.op);
        else if constexpr (std::is_same_v<T, MorphOp>) return kOpMorph;
        else return maskMethodName(o.action);
      },
      op);
}

}  // namespace marzipan::protocol
