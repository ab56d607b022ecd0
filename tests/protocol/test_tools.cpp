// The tool registry's C++ side (protocol/cpp/tool_spec.hpp and the tables generated from
// protocol/registry/tools.json) against the registry file itself: the generated names and keys
// are the registry's, and the parsers obey every parameter it describes. Each tool parses with
// its parameters at their bounds and is refused just beyond them, naming the key; a parameter
// left out takes its default; stroke.begin takes exactly the tools that stroke, each with its
// own keys; presence takes every tool. The cases are built from the registry, so a tool the
// registry gains is checked here without a new line.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "protocol/cpp/ops.hpp"
#include "protocol/cpp/rpc.hpp"
#include "test_paths.hpp"

using namespace marzipan;
using namespace marzipan::protocol;
using nlohmann::json;

namespace {

const json& registry() {
  static const json r = [] {
    std::ifstream in(test_paths::kToolRegistry, std::ios::binary);
    REQUIRE(in.good());
    std::stringstream text;
    text << in.rdbuf();
    return json::parse(text.str());
  }();
  return r;
}

// A parameter by id, with its wire key filled in.
json param(const std::string& id) {
  json p = registry()["parameters"][id];
  p["id"] = id;
  if (!p.contains("key")) p["key"] = id;
  return p;
}

bool givenIn(const json& p, const std::string& where) {
  for (const json& w : p["in"])
    if (w == where) return true;
  return false;
}

std::vector<json> paramsOf(const json& entry, const std::string& where) {
  std::vector<json> out;
  for (const json& id : entry["params"])
    if (const json p = param(id); givenIn(p, where)) out.push_back(p);
  return out;
}

std::vector<std::string> strings(std::span<const std::string_view> keys) { return {keys.begin(), keys.end()}; }

bool isOptional(const json& p) { return p.contains("default") || p.value("optional", false); }

// The largest value the parameter takes when the tool's radius is `radius`.
double most(const json& p, double radius) {
  const double m = p["maximum"];
  return p.contains("max_per_radius") ? std::min(m, p["max_per_radius"].get<double>() * radius) : m;
}

// A valid number: its default, or its maximum.
json validNumber(const json& p) {
  if (p.contains("default")) return p["default"];
  return p["maximum"];
}

// The operation object of `tool` with every parameter at a valid value (an enum at the first
// value that every other parameter's only_with accepts, so that they may all be given).
json baseOp(const json& tool) {
  json op = {{"tool", tool["name"]}};
  const auto ops = paramsOf(tool, "op");
  for (const json& p : ops) {
    const std::string key = p["key"];
    if (p["type"] == "point") op[key] = {1.5, 2, -3};
    else if (p["type"] == "color") op[key] = {10, 200, 30};
    else if (p["type"] == "enum") {
      std::string value = p.value("default", p["values"][0].get<std::string>());
      for (const json& other : ops)
        if (other.contains("only_with") && other["only_with"].contains(p["id"].get<std::string>()))
          value = other["only_with"][p["id"].get<std::string>()][0];
      op[key] = value;
    } else op[key] = validNumber(p);
  }
  return op;
}

// The key of the parameter of `op` that refuses `value` of parameter `p` (its only_with), or "".
std::string dependentRefusing(const json& tool, const json& p, const json& value) {
  for (const json& other : paramsOf(tool, "op"))
    if (other.contains("only_with") && other["only_with"].contains(p["id"].get<std::string>())) {
      const json& allowed = other["only_with"][p["id"].get<std::string>()];
      if (std::find(allowed.begin(), allowed.end(), value) == allowed.end()) return other["key"];
    }
  return "";
}

std::string refusedField(const json& op) {
  try {
    parseOp(op);
  } catch (const OpError& e) {
    return e.field();
  }
  return "(accepted)";
}

std::string strokeRefusedField(const json& params) {
  try {
    parseStrokeBeginParams(params);
  } catch (const OpError& e) {
    return e.field();
  }
  return "(accepted)";
}

}  // namespace

TEST_CASE("the generated tables name the registry's tools, in its order, with its keys", "[tools]") {
  const json& tools = registry()["tools"];
  REQUIRE(kTools.size() == tools.size());
  std::vector<std::string> surface, csg, warp, paint;
  const auto kindOf = [](const json& t) {
    return t["kind"] == "csg"     ? ToolKind::Csg
           : t["kind"] == "warp"  ? ToolKind::Warp
           : t["kind"] == "paint" ? ToolKind::Paint
                                  : ToolKind::SurfaceSpeed;
  };
  // Warps and paint tools stroke only: no operation object.
  const auto hasOp = [](const json& t) { return t["kind"] != "warp" && t["kind"] != "paint"; };
  std::set<std::string> strokeKeys{"tool", "symmetry", "accumulate"};
  for (std::size_t i = 0; i < tools.size(); ++i) {
    const json& t = tools[i];
    INFO(t["name"]);
    CHECK(kTools[i].name == t["name"].get<std::string>());
    CHECK(kTools[i].strokes == t["strokes"].get<bool>());
    CHECK(kTools[i].kind == kindOf(t));
    std::vector<std::string> opKeys;
    if (hasOp(t)) opKeys.push_back("tool");
    if (t["kind"] == "surface_speed") opKeys.push_back("global");
    if (hasOp(t))
      for (const json& p : paramsOf(t, "op")) opKeys.push_back(p["key"]);
    CHECK(strings(kTools[i].opKeys) == opKeys);
    std::vector<std::string> own;
    for (const json& p : paramsOf(t, "stroke")) own.push_back(p["key"]);
    CHECK(strings(kTools[i].strokeKeys) == own);
    strokeKeys.insert(own.begin(), own.end());
    (t["kind"] == "csg" ? csg : t["kind"] == "warp" ? warp : t["kind"] == "paint" ? paint : surface).push_back(t["name"]);
  }
  std::vector<std::string> names;
  for (const auto& n : kBrushToolNames) names.emplace_back(n.name);
  CHECK(names == surface);
  names.clear();
  for (const auto& n : kCsgToolNames) names.emplace_back(n.name);
  CHECK(names == csg);
  names.clear();
  for (const auto& n : kWarpToolNames) names.emplace_back(n.name);
  CHECK(names == warp);
  names.clear();
  for (const auto& n : kPaintToolNames) names.emplace_back(n.name);
  CHECK(names == paint);
  std::vector<std::string> morph;
  for (const json& o : registry()["operations"])
    if (o["kind"] == "morphology") morph.push_back(o["name"]);
  names.clear();
  for (const auto& n : kMorphKindNames) names.emplace_back(n.name);
  CHECK(names == morph);
  const auto begin = strings(kStrokeBeginKeys);
  CHECK(std::set<std::string>(begin.begin(), begin.end()) == strokeKeys);
}

TEST_CASE("the parameter constants the parsers name are the registry's", "[tools]") {
  const auto same = [](const NumberParam& c, const std::string& id) {
    const json p = param(id);
    INFO(id);
    CHECK(c.key == p["key"].get<std::string>());
    CHECK(c.minimum == p["minimum"].get<double>());
    CHECK(c.maximum == p["maximum"].get<double>());
    CHECK(c.exclusiveMinimum == p.value("exclusive_minimum", false));
    CHECK(c.exclusiveMaximum == p.value("exclusive_maximum", false));
    CHECK(c.maxPerRadius == p.value("max_per_radius", 0.0));
    CHECK(c.defaultValue.has_value() == p.contains("default"));
    if (c.defaultValue) CHECK(*c.defaultValue == p["default"].get<double>());
  };
  same(kParamRadius, "radius");
  same(kParamStrength, "strength");
  same(kParamHeight, "height");
  same(kParamShapeRadius, "shape_radius");
  same(kParamBlend, "blend");
  same(kParamMorphRadius, "morph_radius");
  same(kParamWarpRadius, "warp_radius");
  same(kParamElasticRadius, "elastic_radius");
  same(kParamSnakeRadius, "snake_radius");
  same(kParamVolume, "volume");
  same(kParamHardness, "hardness");
  CHECK(kParamPaintColor.key == param("paint_color")["key"].get<std::string>());
  CHECK(kParamPaintColor.optional == param("paint_color").value("optional", false));
  CHECK(kParamErase.key == param("erase")["key"].get<std::string>());
  CHECK(kParamErase.defaultValue == param("erase")["default"].get<bool>());
  CHECK(kParamCsgColor.key == param("csg_color")["key"].get<std::string>());
  CHECK(kParamCsgColor.optional == param("csg_color").value("optional", false));
  CHECK(kParamDirection.key == param("direction")["key"].get<std::string>());
  CHECK(kParamCenter.bound == param("center")["bound"].get<double>());
  CHECK(kMaxCoordinate == kParamCenter.bound);
  CHECK(kParamIterations.minimum == param("iterations")["minimum"].get<std::int64_t>());
  CHECK(kParamIterations.maximum == param("iterations")["maximum"].get<std::int64_t>());
  CHECK(strings(kParamShape.values) == param("shape")["values"].get<std::vector<std::string>>());
  CHECK(strings(kParamAxis.values) == param("axis")["values"].get<std::vector<std::string>>());
  CHECK(*kParamAxis.defaultValue == param("axis")["default"].get<std::string>());
}

TEST_CASE("every tool parses with its parameters at their bounds and is refused beyond them", "[tools]") {
  for (const json& tool : registry()["tools"]) {
    if (tool["kind"] == "warp" || tool["kind"] == "paint") {
      // Strokes only: its name is no operation object.
      CHECK(refusedField(json{{"tool", tool["name"]}, {"center", {1, 2, 3}}}) == "tool");
      continue;
    }
    const json base = baseOp(tool);
    INFO(base.dump());
    REQUIRE(refusedField(base) == "(accepted)");
    const json canonical = toJson(parseOp(base));
    CHECK(canonical["tool"] == tool["name"]);
    json unknown = base;
    unknown["no_such_key"] = 1;
    CHECK(refusedField(unknown) == "no_such_key");
    const double radius = base.contains("radius") ? base["radius"].get<double>() : 0;
    for (const json& p : paramsOf(tool, "op")) {
      const std::string key = p["key"];
      INFO("parameter " << p.dump());
      json without = base;
      without.erase(key);
      if (!isOptional(p)) CHECK(refusedField(without) == key);
      else if (p.contains("default") && !p.contains("only_with")) CHECK(toJson(parseOp(without))[key] == p["default"]);
      json bad = base;
      bad[key] = "not a value";
      if (p["type"] != "enum") CHECK(refusedField(bad) == key);
      if (p["type"] == "color") {
        CHECK(toJson(parseOp(base))[key] == base[key]);
        for (const json& wrong : {json{256, 0, 0}, json{-1, 0, 0}, json{0.5, 0, 0}, json{1, 2}}) {
          bad[key] = wrong;
          CHECK(refusedField(bad) == key);
        }
      }
      if (p["type"] == "number" || p["type"] == "integer") {
        const bool integer = p["type"] == "integer";
        const double lo = p["minimum"], hi = most(p, key == "radius" ? 0 : radius);
        const auto at = [&](double v) {
          json op = base;
          if (integer) op[key] = std::int64_t(v);
          else op[key] = v;
          return refusedField(op);
        };
        CHECK(at(hi) == "(accepted)");
        CHECK(at(integer ? hi + 1 : std::nextafter(hi, 1e300)) == key);
        CHECK(at(p.value("exclusive_minimum", false) ? lo : integer ? lo - 1 : std::nextafter(lo, -1e300)) == key);
        if (!p.value("exclusive_minimum", false)) CHECK(at(lo) == "(accepted)");
        else CHECK(at(std::nextafter(lo, 1e300)) == "(accepted)");
      } else if (p["type"] == "enum") {
        for (const json& v : p["values"]) {
          json op = base;
          op[key] = v;
          const std::string refusing = p.contains("only_with") ? "" : dependentRefusing(tool, p, v);
          CHECK(refusedField(op) == (refusing.empty() ? "(accepted)" : refusing));
        }
        CHECK(refusedField(bad) == key);
      }
      if (p.contains("only_with")) {
        for (const auto& [other, allowed] : p["only_with"].items()) {
          const json q = param(other);
          for (const json& v : q["values"]) {
            json op = base;
            op[q["key"].get<std::string>()] = v;
            const bool ok = std::find(allowed.begin(), allowed.end(), v) != allowed.end();
            CHECK(refusedField(op) == (ok ? "(accepted)" : key));
          }
        }
      }
    }
  }
}

TEST_CASE("stroke.begin takes the tools that stroke, each with its own keys", "[tools]") {
  // Every key of stroke.begin, with the parameters that give it (a warp's radius has its own).
  std::vector<std::string> keys;
  for (const json& tool : registry()["tools"])
    for (const json& p : paramsOf(tool, "stroke"))
      if (std::find(keys.begin(), keys.end(), p["key"]) == keys.end()) keys.push_back(p["key"]);
  CHECK(!keys.empty());
  for (const json& tool : registry()["tools"]) {
    INFO(tool["name"]);
    json begin = {{"tool", tool["name"]}, {"radius", 8}};
    if (!tool["strokes"].get<bool>()) {
      CHECK(strokeRefusedField(begin) == "tool");
      continue;
    }
    const auto own = paramsOf(tool, "stroke");
    // A required colour is named when it is missing, and given in every case below.
    for (const json& p : own)
      if (p["type"] == "color" && !isOptional(p)) {
        CHECK(strokeRefusedField(begin) == p["key"]);
        begin[p["key"].get<std::string>()] = {0, 128, 255};
      }
    CHECK(strokeRefusedField(begin) == "(accepted)");
    for (const std::string& key : keys) {
      INFO(key);
      const auto mine = std::find_if(own.begin(), own.end(), [&](const json& p) { return p["key"] == key; });
      json params = begin;
      if (mine == own.end()) {
        params[key] = key == "direction" ? json{1, 0, 0} : key == "color" ? json{1, 2, 3} : key == "erase" ? json(true) : json(1.0);
        CHECK(strokeRefusedField(params) == key);
        continue;
      }
      const json& p = *mine;
      if (p["type"] == "color") {
        params[key] = {255, 0, 255};
        CHECK(strokeRefusedField(params) == "(accepted)");
        for (const json& bad : {json{256, 0, 0}, json{-1, 0, 0}, json{1.5, 0, 0}, json{1, 2}, json{1, 2, 3, 4}, json("red"),
                                json{"1", 2, 3}, json{1.0, 2, 3}}) {
          params[key] = bad;
          CHECK(strokeRefusedField(params) == key);
        }
        continue;
      }
      if (p["type"] == "boolean") {
        for (const bool v : {true, false}) {
          params[key] = v;
          CHECK(strokeRefusedField(params) == "(accepted)");
        }
        params[key] = 1;
        CHECK(strokeRefusedField(params) == key);
        continue;
      }
      if (p["type"] == "vector") {
        params[key] = {0.5, -2, 1e300};
        CHECK(strokeRefusedField(params) == "(accepted)");
        params[key] = {0, 0, 0};
        CHECK(strokeRefusedField(params) == key);
        params[key] = {1, 0};
        CHECK(strokeRefusedField(params) == key);
        continue;
      }
      const double bound = key == "radius" ? 0 : 8;
      params[key] = key == "radius" ? most(p, 0) : most(p, bound);
      if (p.value("exclusive_maximum", false)) {
        CHECK(strokeRefusedField(params) == key);
        params[key] = std::nextafter(most(p, bound), -1e300);
        CHECK(strokeRefusedField(params) == "(accepted)");
      } else {
        CHECK(strokeRefusedField(params) == "(accepted)");
      }
      params[key] = std::nextafter(key == "radius" ? most(p, 0) : most(p, bound), 1e300);
      CHECK(strokeRefusedField(params) == key);
      params[key] = p.value("exclusive_minimum", false) ? p["minimum"].get<double>()
                                                       : std::nextafter(p["minimum"].get<double>(), -1e300);
      CHECK(strokeRefusedField(params) == key);
      for (const json& flag : p.value("not_with", json::array())) {
        params = begin;
        params[key] = most(p, 8);
        params[flag.get<std::string>()] = true;
        CHECK(strokeRefusedField(params) == key);
      }
    }
    if (tool["kind"] == "warp")
      for (const std::string flag : {"symmetry", "accumulate"}) {
        json params = begin;
        params[flag] = flag == "symmetry" ? json{"x"} : json(true);
        CHECK(strokeRefusedField(params) == flag);
      }
  }
}

TEST_CASE("paint and mask strokes carry their colour, hardness and erase, with symmetry and accumulate", "[tools]") {
  const StrokeBeginParams paint = parseStrokeBeginParams(
      {{"tool", "paint"}, {"color", {250, 0, 17}}, {"radius", 6}, {"strength", 0.5}, {"symmetry", {"x"}}, {"accumulate", true}});
  REQUIRE(paint.paint);
  CHECK_FALSE(paint.warp);
  CHECK(paint.paint->tool == PaintTool::Color);
  CHECK(paint.paint->color == SrgbColor{250, 0, 17});
  CHECK(paint.paint->hardness == 0.5);
  CHECK_FALSE(paint.paint->erase);
  CHECK(paint.radius == 6);
  CHECK(paint.strength == 0.5);
  CHECK(paint.mirrorX);
  CHECK(paint.accumulate);
  const StrokeBeginParams mask = parseStrokeBeginParams({{"tool", "mask"}, {"erase", true}, {"hardness", 0}});
  REQUIRE(mask.paint);
  CHECK(mask.paint->tool == PaintTool::MaskAdd);
  CHECK(mask.paint->erase);
  CHECK(mask.paint->hardness == 0);
  CHECK(mask.radius == *kParamRadius.defaultValue);
  // What belongs to other tools or is malformed is refused, naming the key.
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, 3}}, {"height", 2}}) == "height");
  CHECK(strokeRefusedField({{"tool", "mask"}, {"color", {1, 2, 3}}}) == "color");
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, 3}}, {"erase", true}}) == "erase");
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, 3}}, {"hardness", 1}}) == "hardness");
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, 3}}, {"radius", 1e9}}) == "radius");
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, 3}}, {"strength", std::nan("")}}) == "strength");
  CHECK(strokeRefusedField({{"tool", "paint"}, {"color", {1, 2, std::nan("")}}}) == "color");
  CHECK(strokeRefusedField({{"tool", "add_blob"}, {"hardness", 0.5}}) == "hardness");
}

TEST_CASE("presence carries a paint colour, [r, g, b] bytes, and refuses any other", "[tools]") {
  json params = {{"brush", {{"tool", "paint"}, {"radius", 4}, {"point", {1, 2, 3}}, {"normal", {0, 1, 0}}, {"active", true},
                            {"color", {12, 34, 255}}}}};
  const PresenceParams p = parsePresenceParams(params);
  REQUIRE(p.brush->color);
  CHECK(*p.brush->color == SrgbColor{12, 34, 255});
  CHECK(brushJson(*p.brush)["color"] == json{12, 34, 255});
  params["brush"].erase("color");
  CHECK_FALSE(parsePresenceParams(params).brush->color);
  CHECK_FALSE(brushJson(*parsePresenceParams(params).brush).contains("color"));
  for (const json& bad : {json{256, 0, 0}, json{0.5, 0, 0}, json{1, 2}, json("#ff0000")}) {
    params["brush"]["color"] = bad;
    CHECK_THROWS_AS(parsePresenceParams(params), OpError);
  }
}

TEST_CASE("presence takes every tool's name and no other", "[tools]") {
  for (const json& tool : registry()["tools"]) {
    const json params = {{"brush", {{"tool", tool["name"]}, {"radius", 4}, {"point", {1, 2, 3}}, {"normal", {0, 1, 0}}, {"active", true}}}};
    CHECK(parsePresenceParams(params).brush->tool == tool["name"].get<std::string>());
  }
  const json bad = {{"brush", {{"tool", "morph"}, {"radius", 4}, {"point", {1, 2, 3}}, {"normal", {0, 1, 0}}, {"active", true}}}};
  CHECK_THROWS_AS(parsePresenceParams(bad), OpError);
}

TEST_CASE("whole-volume operations take the registry's parameters at their bounds", "[tools]") {
  for (const json& o : registry()["operations"]) {
    json op = o["kind"] == "morphology" ? json{{"op", "morph"}, {"kind", o["name"]}} : json{{"op", "smooth"}};
    for (const json& p : paramsOf(o, "op")) op[p["key"].get<std::string>()] = validNumber(p);
    INFO(op.dump());
    CHECK(refusedField(op) == "(accepted)");
    for (const json& p : paramsOf(o, "op")) {
      const std::string key = p["key"];
      json beyond = op;
      if (p["type"] == "integer") beyond[key] = p["maximum"].get<std::int64_t>() + 1;
      else beyond[key] = std::nextafter(p["maximum"].get<double>(), 1e300);
      CHECK(refusedField(beyond) == key);
      json at = op;
      at[key] = p["maximum"];
      CHECK(refusedField(at) == "(accepted)");
    }
  }
}
