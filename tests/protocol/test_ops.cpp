// Operation objects (protocol/cpp/ops.cpp): every field's bad input is refused with an OpError
// that names the field, and toJson / parse round-trips every op exactly.
#include <catch2/catch.hpp>

#include <cmath>
#include <limits>
#include <string>

#include "protocol/cpp/ops.hpp"
#include "protocol/cpp/json_checks.hpp"
#include "protocol/cpp/rpc.hpp"

using namespace marzipan;
using namespace marzipan::protocol;
using nlohmann::json;

namespace {

// The OpError of parsing `text`; fails the test when the text parses.
OpError errorOf(const std::string& text) {
  try {
    parseOpText(text);
  } catch (const OpError& e) {
    return e;
  }
  FAIL("parsed, but should have been refused: " << text);
  return OpError("", "");
}

OpError errorOf(const json& object) {
  try {
    parseOp(object);
  } catch (const OpError& e) {
    return e;
  }
  FAIL("parsed, but should have been refused: " << object.dump());
  return OpError("", "");
}

void requireRefused(const json& object, const std::string& field, const std::string& fragment) {
  INFO(object.dump());
  const OpError e = errorOf(object);
  CHECK(e.field() == field);
  CHECK_THAT(e.message(), Catch::Contains(fragment));
  // The message names the key itself, so it reads on its own.
  if (!field.empty()) CHECK_THAT(e.message(), Catch::Contains("\"" + field + "\""));
}

json with(json object, const std::string& key, const json& value) {
  object[key] = value;
  return object;
}

json without(json object, const std::string& key) {
  object.erase(key);
  return object;
}

const json kBrush = {{"tool", "add_blob"}, {"center", {10, 20, 30}}, {"radius", 6}, {"strength", 0.5}};
const json kCsg = {{"tool", "csg_add"}, {"shape", "cylinder"}, {"center", {1, 2, 3}}, {"radius", 5}, {"blend", 1},
                   {"axis", "z"}};
const json kGlobal = {{"op", "smooth"}, {"global", true}, {"iterations", 3}, {"strength", 0.25}};
const json kMorph = {{"op", "morph"}, {"kind", "open"}, {"radius", 3}};

}  // namespace

TEST_CASE("each kind of operation object parses into its typed op", "[ops]") {
  const BrushOp brush = std::get<BrushOp>(parseOp(kBrush));
  CHECK(brush.tool == BrushTool::AddBlob);
  CHECK(brush.params.center == Vec3{10, 20, 30});
  CHECK(brush.params.radius == 6);
  CHECK(brush.params.strength == 0.5);

  for (const auto& [tool, name] : kBrushToolNames)
    CHECK(std::get<BrushOp>(parseOp(with(kBrush, "tool", name))).tool == tool);
  for (const auto& [op, name] : kCsgToolNames)
    CHECK(std::get<CsgToolOp>(parseOp(with(kCsg, "tool", name))).params.op == op);
  for (const auto& [shape, name] : kToolShapeNames)
    CHECK(std::get<CsgToolOp>(parseOp(with(without(kCsg, "axis"), "shape", name))).params.shape == shape);
  for (const auto& [kind, name] : kMorphKindNames)
    CHECK(std::get<MorphOp>(parseOp(with(kMorph, "kind", name))).kind == kind);

  const CsgToolOp csg = std::get<CsgToolOp>(parseOp(kCsg));
  CHECK(csg.params.axis == 2);
  CHECK(csg.params.blend == 1);
  CHECK(csg.params.radius == 5);

  const GlobalSmoothOp global = std::get<GlobalSmoothOp>(parseOp(kGlobal));
  CHECK(global.iterations == 3);
  CHECK(global.strength == 0.25);
  // The same with "tool":"smooth" and with "global" left implicit on "op":"smooth".
  CHECK(std::get<GlobalSmoothOp>(parseOp(with(without(kGlobal, "op"), "tool", "smooth"))) == global);
  CHECK(std::get<GlobalSmoothOp>(parseOp(without(kGlobal, "global"))) == global);

  const MorphOp morph = std::get<MorphOp>(parseOp(kMorph));
  CHECK(morph.kind == MorphKind::Open);
  CHECK(morph.radius == 3);
}

TEST_CASE("optional fields take their documented defaults", "[ops]") {
  const BrushOp brush = std::get<BrushOp>(parseOp(json{{"tool", "smooth"}, {"center", {1, 2, 3}}}));
  CHECK(brush.params.radius == kParamRadius.defaultValue);
  CHECK(brush.params.radius == 8);
  CHECK(brush.params.strength == 1);
  CHECK(std::get<BrushOp>(parseOp(with(kBrush, "global", false))) == std::get<BrushOp>(parseOp(kBrush)));

  const CsgToolOp csg = std::get<CsgToolOp>(parseOp(without(without(kCsg, "axis"), "blend")));
  CHECK(csg.params.axis == 1);
  CHECK(csg.params.blend == 0);

  CHECK(std::get<GlobalSmoothOp>(parseOp(without(kGlobal, "strength"))).strength == 1);
}

TEST_CASE("missing fields are named", "[ops]") {
  requireRefused(without(kBrush, "center"), "center", "is missing");
  requireRefused(without(kCsg, "shape"), "shape", "is missing");
  requireRefused(without(kCsg, "center"), "center", "is missing");
  requireRefused(without(kCsg, "radius"), "radius", "is missing");
  requireRefused(without(kGlobal, "iterations"), "iterations", "is missing");
  requireRefused(without(kMorph, "kind"), "kind", "is missing");
  requireRefused(without(kMorph, "radius"), "radius", "is missing");
  requireRefused(json::object(), "tool", "is missing");
  requireRefused(json{{"center", {1, 2, 3}}}, "tool", "is missing");
}

TEST_CASE("values of the wrong type are named", "[ops]") {
  requireRefused(with(kBrush, "tool", 3), "tool", "must be a string");
  requireRefused(with(kMorph, "op", true), "op", "must be a string");
  requireRefused(with(kBrush, "center", "here"), "center", "must be an array of three numbers");
  requireRefused(with(kBrush, "center", json::object()), "center", "must be an array of three numbers");
  requireRefused(with(kBrush, "center", {1, "2", 3}), "center", "\"center\"[1] must be a number");
  requireRefused(with(kBrush, "center", {1, nullptr, 3}), "center", "\"center\"[1] must be a number");
  requireRefused(with(kBrush, "radius", "8"), "radius", "must be a number");
  requireRefused(with(kBrush, "radius", nullptr), "radius", "must be a number");
  requireRefused(with(kBrush, "strength", true), "strength", "must be a number");
  requireRefused(with(kBrush, "strength", {0.5}), "strength", "must be a number");
  requireRefused(with(kBrush, "global", 1), "global", "must be true or false");
  requireRefused(with(kGlobal, "global", "yes"), "global", "must be true or false");
  requireRefused(with(kCsg, "shape", 1), "shape", "must be a string");
  requireRefused(with(kCsg, "axis", 0), "axis", "must be a string");
  requireRefused(with(kCsg, "blend", "0"), "blend", "must be a number");
  requireRefused(with(kGlobal, "iterations", 2.5), "iterations", "must be an integer");
  requireRefused(with(kGlobal, "iterations", 2.0), "iterations", "must be an integer");
  requireRefused(with(kGlobal, "iterations", "2"), "iterations", "must be an integer");
  requireRefused(with(kGlobal, "strength", "1"), "strength", "must be a number");
  requireRefused(with(kMorph, "kind", 2), "kind", "must be a string");
  requireRefused(with(kMorph, "radius", {3}), "radius", "must be a number");
}

TEST_CASE("numbers out of range, non-finite numbers and unknown names are named", "[ops]") {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();

  requireRefused(with(kBrush, "center", {1, 2}), "center", "array of 2");
  requireRefused(with(kBrush, "center", {1, 2, 3, 4}), "center", "array of 4");
  requireRefused(with(kBrush, "center", {1, 2, nan}), "center", "\"center\"[2] must be a finite number");
  requireRefused(with(kBrush, "center", {inf, 2, 3}), "center", "\"center\"[0] must be a finite number");
  requireRefused(with(kBrush, "center", {1, -2e6, 3}), "center", "must be within");
  requireRefused(with(kBrush, "radius", 0.25), "radius", "between 0.5 and 1024");
  requireRefused(with(kBrush, "radius", 2000), "radius", "between 0.5 and 1024");
  requireRefused(with(kBrush, "radius", -8), "radius", "between 0.5 and 1024");
  requireRefused(with(kBrush, "radius", nan), "radius", "finite");
  requireRefused(with(kBrush, "strength", 0), "strength", "in (0, 1]");
  requireRefused(with(kBrush, "strength", 1.5), "strength", "in (0, 1]");
  requireRefused(with(kBrush, "strength", -0.5), "strength", "in (0, 1]");
  requireRefused(with(kBrush, "strength", inf), "strength", "finite");

  requireRefused(with(kCsg, "radius", 0.1), "radius", "between 0.5 and 1024");
  requireRefused(with(kCsg, "blend", -1), "blend", "between 0 and 5");
  requireRefused(with(kCsg, "blend", 6), "blend", "between 0 and 5");
  requireRefused(with(kCsg, "shape", "cone"), "shape", "sphere, box, cylinder");
  requireRefused(with(kCsg, "axis", "w"), "axis", "x, y, z");
  requireRefused(with(with(kCsg, "shape", "box"), "axis", "x"), "axis", "cylinder");

  requireRefused(with(kGlobal, "iterations", 0), "iterations", "between 1 and 100000");
  requireRefused(with(kGlobal, "iterations", -3), "iterations", "between 1 and 100000");
  requireRefused(with(kGlobal, "iterations", 100001), "iterations", "between 1 and 100000");
  requireRefused(with(kGlobal, "iterations", std::uint64_t(1) << 63), "iterations", "between 1 and 100000");
  requireRefused(with(kGlobal, "strength", 0), "strength", "in (0, 1]");

  requireRefused(with(kMorph, "radius", 0), "radius", "between 0.001 and 64");
  requireRefused(with(kMorph, "radius", 65), "radius", "between 0.001 and 64");
  requireRefused(with(kMorph, "kind", "grow"), "kind", "dilate, erode, open, close");

  requireRefused(with(kBrush, "tool", "add_blobs"), "tool", "must be one of");
  requireRefused(with(kBrush, "tool", ""), "tool", "must be one of");
  requireRefused(json{{"op", "explode"}}, "op", "must be \"smooth\", \"morph\" or \"mask\"");
}

TEST_CASE("unknown keys are refused, also keys that belong to another tool", "[ops]") {
  requireRefused(with(kBrush, "radius_", 1), "radius_", "unknown key");
  requireRefused(with(kBrush, "shape", "sphere"), "shape", "for tool \"add_blob\"");
  requireRefused(with(kBrush, "iterations", 3), "iterations", "unknown key");
  requireRefused(with(kCsg, "strength", 1), "strength", "for tool \"csg_add\"");
  requireRefused(with(kCsg, "global", true), "global", "unknown key");
  requireRefused(with(kGlobal, "center", {1, 2, 3}), "center", "global smoothing");
  requireRefused(with(kGlobal, "radius", 3), "radius", "unknown key");
  requireRefused(with(kMorph, "center", {1, 2, 3}), "center", "for op \"morph\"");
  requireRefused(with(kMorph, "Kind", "open"), "Kind", "unknown key");
}

TEST_CASE("contradictory objects are refused", "[ops]") {
  requireRefused(with(kBrush, "op", "morph"), "op", "not both");
  requireRefused(with(kBrush, "global", true), "global", "only available for tool \"smooth\"");
  requireRefused(with(kGlobal, "global", false), "global", "must be true");
}

TEST_CASE("JSON text that is not one object is refused without a field", "[ops]") {
  for (const char* text : {"", "{", "nonsense", "{\"tool\":\"add_blob\",}", "{} {}", "1e400"}) {
    INFO(text);
    const OpError e = errorOf(std::string(text));
    CHECK(e.field().empty());
    CHECK_THAT(e.message(), Catch::Contains("not valid JSON"));
    // The parser's internal exception id is not for users.
    CHECK_THAT(e.message(), !Catch::Contains("[json.exception"));
  }
  for (const char* text : {"[1, 2, 3]", "\"add_blob\"", "null", "7"}) {
    INFO(text);
    const OpError e = errorOf(std::string(text));
    CHECK(e.field().empty());
    CHECK_THAT(e.message(), Catch::Contains("must be a JSON object"));
  }
  const OpError big = errorOf(std::string(R"({"tool":"add_blob","center":[1,2,3],"radius":1e999})"));
  CHECK_THAT(big.message(), Catch::Contains("not valid JSON"));
}

TEST_CASE("a repeated key is refused, not silently resolved", "[ops]") {
  const OpError e = errorOf(std::string(R"({"tool":"add_blob","radius":4,"center":[1,2,3],"radius":40})"));
  CHECK(e.field() == "radius");
  CHECK_THAT(e.message(), Catch::Contains("more than once"));
  const OpError tool = errorOf(std::string(R"({"tool":"add_blob","tool":"remove_blob","center":[1,2,3]})"));
  CHECK(tool.field() == "tool");
  // The empty key is a key: its repeat was taken as "no repeat" (2026-11-30 review).
  const OpError empty = errorOf(std::string(R"({"tool":"add_blob","center":[1,2,3],"":1,"":2})"));
  CHECK(empty.field().empty());
  CHECK_THAT(empty.message(), Catch::Contains("key \"\" appears more than once"));
}

TEST_CASE("toJson writes the canonical form and parsing it gives the same op", "[ops]") {
  const Op ops[] = {
      parseOp(kBrush),
      parseOp(json{{"tool", "sharpen"}, {"center", {0.1, -2.5, 1e-7}}}),
      parseOp(kCsg),
      parseOp(json{{"tool", "csg_intersect"}, {"shape", "box"}, {"center", {64, 64, 64}}, {"radius", 30.25}}),
      parseOp(kGlobal),
      parseOp(json{{"tool", "smooth"}, {"global", true}, {"iterations", 100000}}),
      parseOp(kMorph),
      parseOp(json{{"op", "morph"}, {"kind", "erode"}, {"radius", 0.1 + 0.2}}),
  };
  for (const Op& op : ops) {
    const json canonical = toJson(op);
    INFO(canonical.dump());
    CHECK(parseOp(canonical) == op);
    CHECK(parseOpText(canonical.dump()) == op);
    CHECK(toJson(parseOpText(canonical.dump())) == canonical);
  }
  CHECK(toJson(parseOp(json{{"tool", "remove_blob"}, {"center", {1, 2, 3}}})) ==
        json{{"tool", "remove_blob"}, {"center", {1.0, 2.0, 3.0}}, {"radius", 8.0}, {"strength", 1.0}});
  CHECK(toJson(parseOp(json{{"tool", "smooth"}, {"global", true}, {"iterations", 5}})) ==
        json{{"op", "smooth"}, {"global", true}, {"iterations", 5}, {"strength", 1.0}});
  CHECK(toJson(parseOp(without(with(kCsg, "shape", "sphere"), "axis"))).contains("axis") == false);
  CHECK(toJson(parseOp(without(kCsg, "axis")))["axis"] == "y");
}

TEST_CASE("opName gives the name an op is known by", "[ops]") {
  CHECK(opName(parseOp(kBrush)) == "add_blob");
  CHECK(opName(parseOp(kCsg)) == "csg_add");
  CHECK(opName(parseOp(kGlobal)) == "smooth");
  CHECK(opName(parseOp(kMorph)) == "morph");
  // A mask op is named as its method, as history.list names its step.
  CHECK(opName(parseOp(json{{"op", "mask"}, {"action", "clear"}})) == "mask.clear");
  CHECK(opName(parseOp(json{{"op", "mask"}, {"action", "invert"}})) == "mask.invert");
  CHECK(opName(parseOp(json{{"op", "mask"}, {"action", "fill"}})) == "mask.fill");
  CHECK(std::get<MaskOp>(parseOp(json{{"op", "mask"}, {"action", "fill"}})).action == MaskAction::Fill);
}

TEST_CASE("messages stay short and valid UTF-8 whatever the input", "[ops]") {
  const std::string huge(100000, 'x');
  // A two-byte character straddling the point where quoted input is cut.
  const std::string straddling = std::string(39, 'a') + "\xC3\xA9" + std::string(1000, 'b');
  for (const json& object : {with(kBrush, "tool", huge), with(kBrush, "tool", straddling), with(kBrush, "radius", huge),
                             with(kCsg, "shape", straddling), with(kMorph, "kind", "open\nclose"),
                             with(kBrush, huge, 1), with(kBrush, straddling, 1)}) {
    const OpError e = errorOf(object);
    CHECK(e.message().size() < 300);
    CHECK(e.field().size() < 50);
    CHECK(e.message().find('\n') == std::string::npos);
    // nlohmann refuses to write invalid UTF-8, as any JSON-RPC reply would have to.
    CHECK_NOTHROW(json(e.message()).dump());
    CHECK_NOTHROW(json(e.field()).dump());
  }
}

TEST_CASE("a JSON syntax error quotes only an excerpt of the token it stopped in", "[ops]") {
  // The JSON parser's own message quotes the whole token it was reading, which the input can
  // make as long as a frame and fill with bytes that are not UTF-8.
  const std::string unterminated = R"({"tool":"add_blob","center":[1,2,3],"x":")" + std::string(100000, 'x');
  const std::string badUtf8 = R"({"tool":"add_blob","x":")" + std::string(10, '\xFF') + R"("})";
  const std::string longNumber = R"({"tool":"add_blob","center":[1,2,3],"radius":)" + std::string(5000, '9') + "}";
  const std::string badLiteral = std::string("[").append(1000, 't').append("]");
  const std::string quoteInToken = R"({"a":"x'; expected ':')" + std::string(500, '\xC3');
  for (const std::string& text : {unterminated, badUtf8, longNumber, badLiteral, quoteInToken}) {
    INFO(text.substr(0, 60));
    const OpError e = errorOf(text);
    CHECK(e.field().empty());
    CHECK_THAT(e.message(), Catch::StartsWith("not valid JSON: "));
    CHECK(e.message().size() < 300);
    CHECK_NOTHROW(json(e.message()).dump());
  }
  // What the parser says stays readable: where it stopped, why, and the start of the token.
  const OpError e = errorOf(unterminated);
  CHECK_THAT(e.message(), Catch::Contains("missing closing quote") && Catch::Contains("xxxxxxxx..."));
  CHECK_THAT(errorOf(std::string(R"({"tool" "add_blob"})")).message(), Catch::Contains("expected ':'"));
}

TEST_CASE("JSON nested deeper than 64 arrays and objects is refused while it is read", "[ops]") {
  const auto nested = [](int depth) { return std::string(std::size_t(depth), '[') + std::string(std::size_t(depth), ']'); };
  // 64 levels, more than any message needs, are read; the 65th is refused.
  CHECK_THAT(errorOf(R"({"tool":"add_blob","center":)" + nested(63) + "}").message(), Catch::Contains("\"center\""));
  const OpError deep = errorOf(R"({"tool":"add_blob","center":)" + nested(64) + "}");
  CHECK(deep.field().empty());
  CHECK_THAT(deep.message(), Catch::Contains("not valid JSON") && Catch::Contains("64"));
  // A request of one text frame (max_text_bytes, 1 MiB) nested 500000 deep: copying its params
  // recursed once per level and overflowed the stack.
  const std::string frame =
      R"({"jsonrpc":"2.0","id":1,"method":"session.stats","params":{"a":)" + nested(500000) + "}}";
  const ParsedRequest r = parseRequest(frame);
  REQUIRE(r.error);
  CHECK(r.error->code == RpcCode::ParseError);
}

TEST_CASE("an unknown key of control characters is quoted short in its error (found by fuzz_rpc)", "[rpc]") {
  // Forty tabs quote as eighty bytes and forty \u0001 as 240: the excerpt is bounded as quoted.
  for (const char c : {'\t', '\x01'}) {
    const std::string key(60, c);
    const ParsedRequest r = parseRequest(json{{"jsonrpc", "2.0"}, {"id", 1}, {"method", "session.stats"}, {key, 1}}.dump());
    REQUIRE(r.error);
    CHECK(r.error->message.size() < 160);
  }
}

TEST_CASE("a response and a notification are the dumps of their envelope objects", "[rpc]") {
  // resultText and notificationText write the envelope around their parts' texts; these are the
  // bytes the envelope objects themselves dump to, invalid UTF-8 replaced as there.
  const auto dumped = [](const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); };
  const json box{{"lo", {1, 2, 3}}, {"hi", {4, 5, 6}}};
  const std::vector<json> ids{7, 4294967295u, -3, "a \"quoted\" id", "bad \xff utf-8", nullptr};
  const std::vector<json> values{json::object(),
                                 {{"revision", 12}, {"applied", 2}, {"roi", box}, {"plane", {0.5, -1e-300, 2}}},
                                 {{"z", "last"}, {"a", "first \xfe"}, {"m", json::array()}},
                                 "text",
                                 nullptr};
  for (const json& id : ids)
    for (const json& v : values) {
      INFO(dumped(id) << " " << dumped(v));
      CHECK(resultText(id, v) == dumped({{"jsonrpc", "2.0"}, {"id", id}, {"result", v}}));
    }
  for (const char* method : {"session.changed", "a \"method\" \x80"})
    for (const json& v : values) {
      INFO(method << " " << dumped(v));
      CHECK(notificationText(method, v) == dumped({{"jsonrpc", "2.0"}, {"method", method}, {"params", v}}));
    }
}

TEST_CASE("a bad dab and a bad colour are named down to the element", "[rpc]") {
  // The element's name is written only for an error (not for every number read): these are the
  // texts it gives.
  const auto messageOf = [](const auto& parse) -> std::string {
    try {
      parse();
    } catch (const OpError& e) {
      return e.message();
    }
    return "";
  };
  const json dabs{{"stroke", 1}, {"dabs", {{{"center", {1, 2, 3}}}, {{"center", {1, 2, 1e300}}, {"pressure", 1}}}}};
  CHECK(messageOf([&] { parseStrokeDabsParams(dabs, 16); }) ==
        "\"dabs\"[1]: \"center\"[2] must be within +-1e+06 vu, got 1e+300");
  const json notNumber{{"stroke", 1}, {"dabs", {{{"center", {1, "2", 3}}}}}};
  CHECK(messageOf([&] { parseStrokeDabsParams(notNumber, 16); }) ==
        "\"dabs\"[0]: \"center\"[1] must be a number, got the string \"2\"");
  CHECK(messageOf([] { checks::colorValue(json{0, 255, 256}, "color"); }) ==
        "\"color\"[2] must be an integer from 0 to 255, got the integer 256");
}

TEST_CASE("session.changed is notificationText of its params object", "[rpc]") {
  const auto expected = [](std::uint64_t revision, int by, const std::string& cause, const Box& roi,
                           const std::string& digest, bool canUndo, bool canRedo) {
    return notificationText("session.changed", {{"revision", revision},
                                                {"by", by},
                                                {"cause", cause},
                                                {"roi", boxJson(roi)},
                                                {"digest", digest},
                                                {"can_undo", canUndo},
                                                {"can_redo", canRedo}});
  };
  const std::vector<Box> rois{Box{}, Box{{1, 2, 3}, {40, 50, 60}}, Box{{-5, 0, 7}, {-4, 1, 2147483647}}};
  for (const Box& roi : rois)
    for (const std::uint64_t revision : {std::uint64_t(1), std::uint64_t(9007199254740991)})
      for (const bool undo : {false, true}) {
        INFO(revision << " " << undo);
        CHECK(sessionChangedText(revision, 3, "stroke", roi, "0123456789abcdef", undo, !undo) ==
              expected(revision, 3, "stroke", roi, "0123456789abcdef", undo, !undo));
        CHECK(sessionChangedText(revision, -1, "a \"cause\" \x01\xff", roi, "", !undo, !undo) ==
              expected(revision, -1, "a \"cause\" \x01\xff", roi, "", !undo, !undo));
      }
}

TEST_CASE("a stroke.dabs result written directly is the dump of its object", "[rpc]") {
  // No plane, and a flatten stroke's plane (service planeJson's shape) with values json writes
  // in its shortest form, an exponent and a signed zero.
  const json planes[] = {nullptr, {{"point", {12.5, -0.1, 1e-300}}, {"normal", {0.0, -0.0, 1.0}}},
                         {{"point", {1.0 / 3.0, 2e21, -7.0}}, {"normal", {0.6, 0.8, 0.0}}}};
  for (const json& plane : planes)
    for (const Box& roi : {Box{}, Box{{1, 2, 3}, {40, 50, 60}}, Box{{-5, 0, 7}, {-4, 1, 2147483647}}})
      for (const std::uint64_t revision : {std::uint64_t(1), std::uint64_t(9007199254740991)})
        for (const std::uint64_t applied : {std::uint64_t(0), std::uint64_t(16)}) {
          json result{{"revision", revision}, {"applied", applied}, {"roi", boxJson(roi)}};
          if (!plane.is_null()) result["plane"] = plane;
          const std::string text = strokeDabsResultJson(revision, applied, roi, plane);
          CHECK(text == result.dump());
          CHECK(resultTextOfJson(json(12), text) == resultText(json(12), result));
        }
  CHECK(strokeDabsResultJson(5, 2, Box{{1, 2, 3}, {4, 5, 6}}, planes[1]) ==
        R"({"applied":2,"plane":{"normal":[0.0,-0.0,1.0],"point":[12.5,-0.1,1e-300]},"revision":5,)"
        R"("roi":{"hi":[4,5,6],"lo":[1,2,3]}})");
}
