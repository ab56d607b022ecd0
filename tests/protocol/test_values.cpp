// protocol/cpp/values.hpp: the wire names of the value types the engine and the protocol share.
#include <catch2/catch.hpp>

#include <set>
#include <string>

#include "protocol/cpp/values.hpp"

using namespace marzipan;

TEST_CASE("every shading, solid and tool shape has one wire name that parses back to it", "[values]") {
  std::set<std::string> seen;
  for (const auto& n : kShadingNames) {
    CHECK(shadingFromName(n.name) == n.value);
    seen.insert(std::string(n.name));
  }
  CHECK(seen == std::set<std::string>{"lit", "normals", "gradient_error", "thickness"});
  for (const auto& n : kSolidKindNames) {
    CHECK(solidKindFromName(n.name) == n.value);
    CHECK(std::string(solidKindName(n.value)) == std::string(n.name));
  }
  CHECK(std::string(solidKindName(SolidKind::Pig)) == "pig");
  CHECK(toolShapeFromName("cylinder") == ToolShape::Cylinder);
}

TEST_CASE("names are matched exactly: no case folding, no prefixes", "[values][errors]") {
  CHECK_FALSE(shadingFromName("Lit").has_value());
  CHECK_FALSE(shadingFromName("gradient").has_value());
  CHECK_FALSE(solidKindFromName("").has_value());
  CHECK_FALSE(solidKindFromName("pig ").has_value());
  CHECK_FALSE(toolShapeFromName("torus").has_value());  // a solid, not a tool shape
}

TEST_CASE("a camera is validated where it is declared, without the engine", "[values][errors]") {
  Camera c;
  c.eye = {0, 0, 10};
  c.target = {0, 0, 0};
  CHECK_NOTHROW(c.validate());
  c.width = kMaxFrameSide + 1;
  try {
    c.validate();
    FAIL("a frame wider than kMaxFrameSide was accepted");
  } catch (const EngineError& e) {
    CHECK(e.kind() == ErrorKind::TooLarge);
    CHECK(e.field() == "width");
  }
  c.width = 512;
  c.up = {0, 0, 1};  // along the view direction
  CHECK_THROWS_WITH(c.validate(), "up: must not be parallel to the view direction");
}
