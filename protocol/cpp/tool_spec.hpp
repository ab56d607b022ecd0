// What the tool registry (protocol/registry/tools.json, docs/tools.md) says of each tool, as C++
// types. The values are generated at build time from the registry into the build tree
// (protocol/cpp/tools.generated.hpp, which ops.hpp includes): the name tables (kBrushToolNames,
// kCsgToolNames, kWarpToolNames, kPaintToolNames, kMorphKindNames), one constant per parameter
// (kParamRadius, kParamHeight, ...)
// and kTools, the keys each tool takes. Parsers read ranges, defaults and allowed keys from
// there, so that a tool's parameters are written down once.
//
// Conventions: lengths in vu (values.hpp); a parameter without a default is required; a range's
// bounds are included unless exclusiveMinimum / exclusiveMaximum say otherwise.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>

#include "protocol/cpp/values.hpp"

namespace marzipan::protocol {

struct NumberParam {
  std::string_view key;    // the wire key
  double minimum, maximum;
  bool exclusiveMinimum;   // the minimum itself is refused
  bool exclusiveMaximum;   // the maximum itself is refused
  double maxPerRadius;     // > 0: also at most this times the tool's radius
  std::optional<double> defaultValue;
};

struct IntegerParam {
  std::string_view key;
  std::int64_t minimum, maximum;
  std::optional<std::int64_t> defaultValue;
};

// [x, y, z], each coordinate finite and within +-bound.
struct PointParam {
  std::string_view key;
  double bound;
};

struct EnumParam {
  std::string_view key;
  std::span<const std::string_view> values;
  std::optional<std::string_view> defaultValue;
};

struct BooleanParam {
  std::string_view key;
  bool defaultValue;
};

// A colour: [r, g, b], three integers 0..255, sRGB (values.hpp, SrgbColor). Without
// `optional` the key is required.
struct ColorParam {
  std::string_view key;
  bool optional;
};

// A direction: [x, y, z], finite and not all zero; its length does not matter.
struct VectorParam {
  std::string_view key;
};

// How a tool changes the volume (the registry's "kind"): the shape of its operation object
// (a warp or a paint tool has none: it strokes only).
enum class ToolKind { SurfaceSpeed, Csg, Warp, Paint };

struct ToolSpec {
  std::string_view name;  // the wire "tool"
  ToolKind kind;
  bool strokes;           // stroke.begin takes it
  std::span<const std::string_view> opKeys;      // every key of its operation object, "tool" first; none for a warp or paint
  std::span<const std::string_view> strokeKeys;  // its own keys in stroke.begin (radius, height, ...)
};

// "[0.5, 1024]", "(0, 1]", "[0, 1)": the range as an interval, without the radius's bound.
inline std::string rangeText(const NumberParam& p) {
  std::ostringstream s;
  s << (p.exclusiveMinimum ? "(" : "[") << p.minimum << ", " << p.maximum << (p.exclusiveMaximum ? ")" : "]");
  return s.str();
}

constexpr bool hasKey(std::span<const std::string_view> keys, std::string_view key) {
  for (std::string_view k : keys)
    if (k == key) return true;
  return false;
}

// The spec of the tool named `name`, or nullptr.
constexpr const ToolSpec* findTool(std::span<const ToolSpec> tools, std::string_view name) {
  for (const ToolSpec& t : tools)
    if (t.name == name) return &t;
  return nullptr;
}

// Whether a table of wire names lists exactly `names`, in order: for the enumerations that
// values.hpp shares with the engine (shapes), whose registry values must be the same.
template <class E, std::size_t N>
constexpr bool sameNames(const std::array<WireName<E>, N>& table, std::span<const std::string_view> names) {
  if (names.size() != N) return false;
  for (std::size_t i = 0; i < N; ++i)
    if (table[i].name != names[i]) return false;
  return true;
}

}  // namespace marzipan::protocol
