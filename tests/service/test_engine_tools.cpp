// The tool registry's tie to the engine (service/engine_tools.generated.hpp, generated from
// protocol/registry/tools.json): each registry tool is an engine enumerator and back (a name
// missing on either side does not compile; this checks that the pairs are the right ones), and
// every range the registry gives the wire (the kParam... constants, which tests/protocol/
// test_tools.cpp ties to the registry file) is the range the engine itself accepts: its bounds
// are taken, the next double beyond is refused naming the same field, before anything changes.
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <string>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/solids.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/apply_op.hpp"

using namespace marzipan;
using namespace marzipan::protocol;

namespace {

const double kHuge = 1e300;

// The field of the EngineError `f` throws, or "(accepted)".
std::string refused(const std::function<void()>& f) {
  try {
    f();
  } catch (const EngineError& e) {
    return e.field();
  }
  return "(accepted)";
}

Volume smallSphere() { return makeSolid(SolidKind::Sphere, {16, 16, 16}); }

double lowestTaken(const NumberParam& p) { return p.exclusiveMinimum ? std::nextafter(p.minimum, kHuge) : p.minimum; }
double highestRefusedBelow(const NumberParam& p) { return p.exclusiveMinimum ? p.minimum : std::nextafter(p.minimum, -kHuge); }

}  // namespace

TEST_CASE("each registry tool is its engine enumerator, and back", "[engine_tools]") {
  for (const auto& [tool, name] : kBrushToolNames) CHECK(service::registryName(service::engineBrush(tool)) == name);
  for (const auto& [op, name] : kCsgToolNames) CHECK(service::registryName(op) == name);
}

TEST_CASE("the registry's ranges of surface-speed tools are the engine's", "[engine_tools]") {
  for (const auto& [tool, name] : kBrushToolNames) {
    INFO(name);
    const Brush brush = service::engineBrush(tool);
    // Flatten and contrast also need the stroke's plane (the session fits it at the first dab).
    const auto check = [&](double radius, double strength, std::optional<double> height = std::nullopt) {
      StrokeSettings st{brush, radius, strength, height};
      if (brushUsesPlane(brush)) st.plane = Plane{{8, 8, 8}, {0, 1, 0}};
      return refused([&] { checkStrokeSettings(st); });
    };
    CHECK(check(kParamRadius.minimum, 1) == "(accepted)");
    CHECK(check(kParamRadius.maximum, 1) == "(accepted)");
    CHECK(check(std::nextafter(kParamRadius.minimum, -kHuge), 1) == "radius");
    CHECK(check(std::nextafter(kParamRadius.maximum, kHuge), 1) == "radius");
    CHECK(check(8, lowestTaken(kParamStrength)) == "(accepted)");
    CHECK(check(8, kParamStrength.maximum) == "(accepted)");
    CHECK(check(8, highestRefusedBelow(kParamStrength)) == "strength");
    CHECK(check(8, std::nextafter(kParamStrength.maximum, kHuge)) == "strength");
    if (!hasKey(findTool(kTools, name)->strokeKeys, kParamHeight.key)) {
      CHECK(check(8, 1, 1.0) == "height");
      continue;
    }
    for (const double radius : {8.0, kParamRadius.maximum}) {
      INFO("radius " << radius);
      const double most = std::min(kParamHeight.maximum, kParamHeight.maxPerRadius * radius);
      CHECK(check(radius, 1, most) == "(accepted)");
      CHECK(check(radius, 1, lowestTaken(kParamHeight)) == "(accepted)");
      CHECK(check(radius, 1, std::nextafter(most, kHuge)) == "height");
      CHECK(check(radius, 1, highestRefusedBelow(kParamHeight)) == "height");
    }
  }
}

TEST_CASE("the registry's ranges of CSG tools are the engine's", "[engine_tools]") {
  for (const auto& [op, name] : kCsgToolNames) {
    INFO(name);
    const auto apply = [&](double radius, double blend) {
      return refused([&] {
        Volume v = smallSphere();
        applyCsg(v, CsgParams{op, ToolShape::Box, {8, 8, 8}, radius, 1, blend});
      });
    };
    CHECK(apply(kParamShapeRadius.minimum, 0) == "(accepted)");
    CHECK(apply(kParamShapeRadius.maximum, 0) == "(accepted)");
    CHECK(apply(std::nextafter(kParamShapeRadius.minimum, -kHuge), 0) == "radius");
    CHECK(apply(std::nextafter(kParamShapeRadius.maximum, kHuge), 0) == "radius");
    CHECK(apply(4, kParamBlend.maxPerRadius * 4) == "(accepted)");
    CHECK(apply(4, std::nextafter(kParamBlend.maxPerRadius * 4, kHuge)) == "blend");
    CHECK(apply(4, highestRefusedBelow(kParamBlend)) == "blend");
  }
}

TEST_CASE("the registry's ranges of whole-volume operations are the engine's", "[engine_tools]") {
  ThreadPool pool(2);
  for (const auto& [kind, name] : kMorphKindNames) {
    INFO(name);
    const auto morph = [&](double radius) {
      return refused([&] {
        Volume v = smallSphere();
        service::applyMorph(v, kind, radius, pool);
      });
    };
    CHECK(morph(kParamMorphRadius.minimum) == "(accepted)");
    CHECK(morph(kParamMorphRadius.maximum) == "(accepted)");
    CHECK(morph(highestRefusedBelow(kParamMorphRadius)) == "radius");
    CHECK(morph(std::nextafter(kParamMorphRadius.maximum, kHuge)) == "radius");
  }
  const auto smooth = [&](std::int64_t iterations, double strength) {
    return refused([&] {
      Volume v = smallSphere();
      service::applyGlobalSmooth(v, int(iterations), strength, pool);
    });
  };
  CHECK(smooth(kParamIterations.minimum, kParamStrength.maximum) == "(accepted)");
  CHECK(smooth(kParamIterations.minimum - 1, 1) == "iterations");
  // The largest count is accepted by the same check (not run here: it would take minutes).
  CHECK(smooth(kParamIterations.maximum + 1, 1) == "iterations");
  CHECK(smooth(1, highestRefusedBelow(kParamStrength)) == "strength");
  CHECK(smooth(1, std::nextafter(kParamStrength.maximum, kHuge)) == "strength");
}
