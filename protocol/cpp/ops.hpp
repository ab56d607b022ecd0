// Operation objects: the JSON form of one sculpting operation, shared by `marzipan batch`
// (one object per line) and the network protocol (`tool.apply`, `volume.morph`, the journal).
// protocol/PROTOCOL.md, section "Operation objects", is the contract; this is its C++ side.
//
// Conventions: coordinates and lengths in vu, as in server/engine/volume.hpp. Parsing is
// strict: every key must be known for its tool, every value of the right JSON type, finite
// and in range, or OpError names the key and what is wrong. Ranges are the engine's own (the
// tool registry writes them down; tests/service/test_engine_tools.cpp checks that the engine
// agrees), so an op that parses is only refused by the engine for what depends on the volume
// (a tool whose region misses the domain). toJson writes the canonical form (every field, defaults
// included, keys in a fixed order), and parseOp(toJson(op)) == op.
#pragma once

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>

#include <nlohmann/json.hpp>

#include "protocol/cpp/tools.generated.hpp"
#include "protocol/cpp/values.hpp"

namespace marzipan::protocol {

// The tools, their parameters' ranges and defaults and the keys each takes come from the tool
// registry (protocol/registry/tools.json), generated at build time into this header's neighbour
// protocol/cpp/tools.generated.hpp (tool_spec.hpp says how to read it): BrushTool and
// kBrushToolNames (the surface-speed tools), kCsgToolNames, MorphKind and kMorphKindNames, kTools
// and a kParam... constant per parameter. A surface-speed tool applied once in the ROI cube
// around `center`.
struct BrushOp {
  BrushTool tool = BrushTool::AddBlob;
  BrushParams params;  // defaults: kParamRadius, kParamStrength
  friend bool operator==(const BrushOp& a, const BrushOp& b) {
    return a.tool == b.tool && a.params.center == b.params.center && a.params.radius == b.params.radius &&
           a.params.strength == b.params.strength;
  }
};

// Whole-volume mean curvature flow: `iterations` steps of dt = strength / 6.
struct GlobalSmoothOp {
  int iterations = 1;
  double strength = 1;
  friend bool operator==(const GlobalSmoothOp&, const GlobalSmoothOp&) = default;
};

struct CsgToolOp {
  CsgParams params;  // axis and blend default to y and 0
  // The colour of what a union adds, or for subtract and intersect of the new walls cut (since
  // 1.7, kParamCsgColor); absent: colour follows by extension (engine applyCsg).
  std::optional<SrgbColor> color;
  friend bool operator==(const CsgToolOp& a, const CsgToolOp& b) {
    return a.params.op == b.params.op && a.params.shape == b.params.shape && a.params.center == b.params.center &&
           a.params.radius == b.params.radius && a.params.axis == b.params.axis && a.params.blend == b.params.blend &&
           a.color == b.color;
  }
};

struct MorphOp {
  MorphKind kind = MorphKind::Dilate;
  double radius = 1;
  friend bool operator==(const MorphOp&, const MorphOp&) = default;
};

// The mask of the whole volume ({"op":"mask","action":"clear"|"invert"|"fill"}; the methods
// mask.clear, mask.invert, mask.fill): every band voxel's weight to 0, 255 - w or 255.
struct MaskOp {
  MaskAction action = MaskAction::Clear;
  friend bool operator==(const MaskOp&, const MaskOp&) = default;
};

using Op = std::variant<BrushOp, GlobalSmoothOp, CsgToolOp, MorphOp, MaskOp>;

// A refused operation object. `field` is the offending key ("radius", "center", "tool"), or
// empty when the object as a whole is wrong (not an object, not JSON); `message` is a whole
// sentence that names the key too, ready for a person or a JSON-RPC error message.
class OpError : public std::runtime_error {
 public:
  OpError(std::string field, const std::string& message)
      : std::runtime_error(message), field_(std::move(field)) {}
  const std::string& field() const { return field_; }
  std::string message() const { return what(); }

 private:
  std::string field_;
};

// --- the names ---------------------------------------------------------------------------
// Tables of WireName (values.hpp), looked up with fromWireName and nameOf; the tools' own are
// generated (see above).
template <class E>
using NameOf = WireName<E>;

// The "op" values: whole-volume operations.
inline constexpr std::string_view kOpSmooth = "smooth";
inline constexpr std::string_view kOpMorph = "morph";
inline constexpr std::string_view kOpMask = "mask";

// The name of `value`, or "" for a value without one (wireName says "unknown").
template <class E, std::size_t N>
constexpr std::string_view nameOf(const std::array<NameOf<E>, N>& table, E value) {
  for (const auto& entry : table)
    if (entry.value == value) return entry.name;
  return {};
}

// No domain is wider than 1024 vu and no tool reaches further than 1024 vu, so a centre
// beyond this can only miss; the bound keeps coordinates far from int overflow in ROI maths.
inline constexpr double kMaxCoordinate = kParamCenter.bound;

// --- parsing and writing --------------------------------------------------------------------
// One operation object. Throws OpError.
Op parseOp(const nlohmann::json& object);
// One operation object as JSON text. Besides parseOp's checks: the text must be one JSON
// value (OpError with an empty field otherwise), and no object may repeat a key (a JSON
// reader would silently keep only one of them).
Op parseOpText(std::string_view text);

// The canonical object, e.g. {"tool":"add_blob","center":[1,2,3],"radius":8,"strength":1}.
nlohmann::json toJson(const Op& op);

// The name the op is known by: its "tool" value, or "smooth" / "morph" for "op" objects, and
// for a mask op the method's name ("mask.clear", "mask.invert", "mask.fill"), as history.list
// names its step.
std::string_view opName(const Op& op);
// "mask.clear", "mask.invert", "mask.fill": the method of each mask action.
std::string_view maskMethodName(MaskAction action);

}  // namespace marzipan::protocol
