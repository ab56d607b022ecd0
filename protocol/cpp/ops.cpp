// Strict parsing and canonical writing of operation objects (see ops.hpp). Every check
// throws OpError naming the key; messages quote keys and names the way they appear in JSON.
#include "ops.hpp"

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

// Text from the request, cut to a readable length at a UTF-8 character boundary: messages
// must not grow with the input, and must stay valid UTF-8 for a JSON-RPC reply.
std::string excerpt(std::string_view s) {
  constexpr std::size_t kMaxChars = 40;
  if (s.size() <= kMaxChars) return std::string(s);
  std::size_t cut = kMaxChars;
  while (cut > 0 && (static_cast<unsigned char>(s[cut]) & 0xC0) == 0x80) --cut;
  std::string out(s.substr(0, cut));
  out.append("...");
  return out;
}

// Quoted and escaped as a JSON string, so that control characters cannot garble a log line.
std::string inQuotes(std::string_view s) {
  return json(excerpt(s)).dump(-1, ' ', false, json::error_handler_t::replace);
}

std::string formatNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

template <class E, std::size_t N>
std::string listNames(const std::array<NameOf<E>, N>& table) {
  std::string out;
  for (const auto& entry : table) out += (out.empty() ? "" : ", ") + std::string(entry.name);
  return out;
}

// What a value is, for "got ..." in messages; numbers say which.
std::string describe(const json& v) {
  if (v.is_number_float()) return "the number " + formatNumber(v.get<double>());
  if (v.is_number()) return "the integer " + v.dump();
  if (v.is_string()) return "the string " + inQuotes(v.get_ref<const std::string&>());
  return std::string(v.type_name());
}

[[noreturn]] void fail(std::string_view key, const std::string& what) {
  throw OpError(std::string(key), inQuotes(key) + " " + what);
}

// Refuses any key outside `allowed`; `context` says for which tool, so that a key that is
// valid elsewhere ("shape" on a brush) is explained rather than just called unknown.
void checkKeys(const json& obj, std::initializer_list<std::string_view> allowed, const std::string& context) {
  for (const auto& item : obj.items()) {
    bool known = false;
    for (std::string_view a : allowed) known = known || item.key() == a;
    if (known) continue;
    std::string list;
    for (std::string_view a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    throw OpError(excerpt(item.key()), "unknown key " + inQuotes(item.key()) + " for " + context + " (allowed: " + list + ")");
  }
}

const json* find(const json& obj, std::string_view key) {
  const auto it = obj.find(key);
  return it == obj.end() ? nullptr : &*it;
}

const json& require(const json& obj, std::string_view key, const std::string& context) {
  const json* v = find(obj, key);
  if (!v) fail(key, "is missing (required for " + context + ")");
  return *v;
}

std::string stringValue(const json& v, std::string_view key) {
  if (!v.is_string()) fail(key, "must be a string, got " + describe(v));
  return v.get<std::string>();
}

double finiteNumber(const json& v, std::string_view key) {
  if (!v.is_number()) fail(key, "must be a number, got " + describe(v));
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail(key, "must be a finite number");
  return d;
}

double numberInRange(const json& v, std::string_view key, double lo, double hi) {
  const double d = finiteNumber(v, key);
  if (d < lo || d > hi)
    fail(key, "must be between " + formatNumber(lo) + " and " + formatNumber(hi) + ", got " + formatNumber(d));
  return d;
}

double strengthValue(const json& v) {
  const double d = finiteNumber(v, "strength");
  if (!(d > 0 && d <= 1)) fail("strength", "must be in (0, 1], got " + formatNumber(d));
  return d;
}

Vec3 centerValue(const json& v) {
  if (!v.is_array() || v.size() != 3)
    fail("center", "must be an array of three numbers [x, y, z], got " +
                       (v.is_array() ? "an array of " + std::to_string(v.size()) : describe(v)));
  Vec3 c;
  for (int a = 0; a < 3; ++a) {
    const json& x = v[std::size_t(a)];
    const std::string element = "\"center\"[" + std::to_string(a) + "]";
    if (!x.is_number()) throw OpError("center", element + " must be a number, got " + describe(x));
    c[a] = x.get<double>();
    if (!std::isfinite(c[a])) throw OpError("center", element + " must be a finite number");
    if (std::abs(c[a]) > kMaxCoordinate)
      throw OpError("center", element + " must be within +-" + formatNumber(kMaxCoordinate) + " vu, got " +
                                  formatNumber(c[a]));
  }
  return c;
}

int iterationsValue(const json& v) {
  if (!v.is_number_integer()) fail("iterations", "must be an integer, got " + describe(v));
  // Unsigned and signed integers are stored apart; compare each without narrowing first.
  const bool inRange = v.is_number_unsigned()
                           ? v.get<std::uint64_t>() >= 1 && v.get<std::uint64_t>() <= std::uint64_t(kMaxIterations)
                           : v.get<std::int64_t>() >= 1 && v.get<std::int64_t>() <= kMaxIterations;
  if (!inRange) fail("iterations", "must be between 1 and " + std::to_string(kMaxIterations) + ", got " + v.dump());
  return int(v.get<std::int64_t>());
}

bool booleanValue(const json& v, std::string_view key) {
  if (!v.is_boolean()) fail(key, "must be true or false, got " + describe(v));
  return v.get<bool>();
}

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
  const auto s = fromName(kShapeNames, shape);
  if (!s) fail("shape", "must be one of " + listNames(kShapeNames) + ", got " + inQuotes(shape));
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
  const auto k = fromName(kMorphKindNames, kind);
  if (!k) fail("kind", "must be one of " + listNames(kMorphKindNames) + ", got " + inQuotes(kind));
  op.kind = *k;
  op.radius = numberInRange(require(obj, "radius", context), "radius", kMinMorphRadius, kMaxMorphRadius);
  return op;
}

Op parseTool(const json& obj, const std::string& name) {
  if (const auto brush = fromName(kBrushToolNames, name)) {
    const json* global = find(obj, "global");
    if (global && booleanValue(*global, "global")) {
      if (*brush != BrushTool::Smooth) fail("global", "is only available for tool \"smooth\"");
      return parseGlobalSmooth(obj, "tool");
    }
    return parseBrush(obj, *brush);
  }
  if (const auto csg = fromName(kCsgToolNames, name)) return parseCsg(obj, *csg);
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

// The parser's error text starts with a bracketed exception id that means nothing to a user.
std::string jsonErrorText(const std::string& what) {
  const auto close = what.find("] ");
  return close != std::string::npos && !what.empty() && what.front() == '[' ? what.substr(close + 2) : what;
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

Op parseOpText(std::string_view text) {
  std::vector<std::set<std::string>> openObjects;
  std::string duplicate;
  const json::parser_callback_t noteKeys = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
        openObjects.emplace_back();
        break;
      case json::parse_event_t::object_end:
        openObjects.pop_back();
        break;
      case json::parse_event_t::key:
        if (!openObjects.back().insert(parsed.get<std::string>()).second && duplicate.empty())
          duplicate = parsed.get<std::string>();
        break;
      default:
        break;
    }
    return true;
  };
  json object;
  try {
    object = json::parse(text.begin(), text.end(), noteKeys);
  } catch (const json::exception& e) {
    throw OpError("", "not valid JSON: " + jsonErrorText(e.what()));
  }
  if (!duplicate.empty()) throw OpError(excerpt(duplicate), "key " + inQuotes(duplicate) + " appears more than once");
  return parseOp(object);
}

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
                    {"shape", nameOf(kShapeNames, o.params.shape)},
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
