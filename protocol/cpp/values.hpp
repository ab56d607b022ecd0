// Plain value types that the engine computes with and the protocol carries: tool parameters,
// starting solids, cameras and shading, splats. Standard library only (plus the other dependency-free
// headers of protocol/cpp: geometry.hpp, errors.hpp, little_endian.hpp), so that a client can use protocol/cpp without the server's engine.
//
// Conventions: coordinates and lengths in voxel units (vu), voxel (i,j,k) at the point (i,j,k),
// y up; the signed distance is negative inside (see server/engine/volume.hpp). Names are the
// wire names of protocol/PROTOCOL.md.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/cpp/errors.hpp"
#include "protocol/cpp/geometry.hpp"

namespace marzipan {

// A wire name of an enumerator.
template <class E>
struct WireName {
  E value;
  std::string_view name;
};

template <class E, std::size_t N>
constexpr std::optional<E> fromWireName(const std::array<WireName<E>, N>& names, std::string_view name) {
  for (const auto& n : names)
    if (n.name == name) return n.value;
  return std::nullopt;
}

template <class E, std::size_t N>
constexpr std::string_view wireName(const std::array<WireName<E>, N>& names, E value) {
  for (const auto& n : names)
    if (n.value == value) return n.name;
  return "unknown";
}

// The largest side of a session's grid, in voxels (the smallest is 8).
inline constexpr int kMaxDomainSide = 1024;

// ---- Tools ----------------------------------------------------------------------------------

// Deformative brushes (server/engine/level_set.hpp): the region of interest is the cube of half
// side `radius` around `center`.
struct BrushParams {
  Vec3 center;            // tool centre, vu; the ROI must meet the domain
  double radius = 8;      // half side of the ROI cube, vu, in (0, 1024]
  double strength = 1;    // in (0, 1]: see each tool
};

// A stroke's height (stroke.begin `height`, engine StrokeSettings::height), in vu: at most half
// the radius (the risen surface stays well inside the dab's ROI cube) and at most 64 vu (the
// work grows with it).
inline constexpr double kMaxStrokeHeightPerRadius = 0.5, kMaxStrokeHeight = 64;

// Constructive tools (server/engine/csg.hpp).
enum class CsgOp { Add, Subtract, Intersect };
enum class ToolShape { Sphere, Box, Cylinder };

inline constexpr std::array<WireName<ToolShape>, 3> kToolShapeNames{{
    {ToolShape::Sphere, "sphere"},
    {ToolShape::Box, "box"},
    {ToolShape::Cylinder, "cylinder"},
}};
inline std::optional<ToolShape> toolShapeFromName(std::string_view name) { return fromWireName(kToolShapeNames, name); }

struct CsgParams {
  CsgOp op = CsgOp::Add;
  ToolShape shape = ToolShape::Sphere;
  Vec3 center;
  // Sphere: its radius. Box: half side (all three half extents). Cylinder: radius and half
  // height, along `axis`. In [0.5, 1024] vu.
  double radius = 8;
  int axis = 1;       // cylinder axis: 0 x, 1 y, 2 z
  double blend = 0;   // smooth-blend radius in [0, radius] vu; 0 = sharp crease
};

// ---- Colours and masks -----------------------------------------------------------------------

// A colour as the wire carries it ([r, g, b], PROTOCOL.md): sRGB, 8 bits a channel, the bytes a
// client draws (the engine's Rgb8, server/engine/channels.hpp).
struct SrgbColor {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const SrgbColor&, const SrgbColor&) = default;
};

// What mask.clear / mask.invert / mask.fill do to the mask weight w of every band voxel
// (server/engine/paint.hpp, maskClear, maskInvert, maskFill): w = 0, w = 255 - w, w = 255.
enum class MaskAction { Clear, Invert, Fill };
inline constexpr std::array<WireName<MaskAction>, 3> kMaskActionNames{{
    {MaskAction::Clear, "clear"},
    {MaskAction::Invert, "invert"},
    {MaskAction::Fill, "fill"},
}};

// ---- Starting solids (server/engine/solids.hpp) ---------------------------------------------

enum class SolidKind { Empty, Sphere, Box, Torus, Cylinder, Dumbbell, Pig };

inline constexpr std::array<WireName<SolidKind>, 7> kSolidKindNames{{
    {SolidKind::Empty, "empty"},
    {SolidKind::Sphere, "sphere"},
    {SolidKind::Box, "box"},
    {SolidKind::Torus, "torus"},
    {SolidKind::Cylinder, "cylinder"},
    {SolidKind::Dumbbell, "dumbbell"},
    {SolidKind::Pig, "pig"},
}};
inline std::optional<SolidKind> solidKindFromName(std::string_view name) { return fromWireName(kSolidKindNames, name); }
inline const char* solidKindName(SolidKind kind) { return wireName(kSolidKindNames, kind).data(); }

// ---- Cameras and shading (server/engine/raycast.hpp) ----------------------------------------

inline constexpr int kMaxFrameSide = 4096;

// A pinhole at `eye` looking at `target`; `up` fixes the roll (it need not be orthogonal to the
// view direction); fovY_degrees is the full vertical field of view; pixels are square.
struct Camera {
  Vec3 eye, target, up{0, 1, 0};
  double fovY_degrees = 40;
  int width = 512, height = 512;

  // Throws EngineError unless every number is finite, eye and target are within 1e5 vu of the
  // origin on each axis (the ray kernel works in float), width and height are in
  // [1, kMaxFrameSide], the field of view is in (1, 170) degrees, eye != target and up is not
  // parallel to the view direction.
  void validate() const {
    constexpr double kMaxCoordinate = 1e5;
    for (const auto& [v, name] : {std::pair{eye, "eye"}, std::pair{target, "target"}, std::pair{up, "up"}})
      if (!isFinite(v)) throw EngineError(ErrorKind::InvalidArgument, name, "must be three finite numbers");
    for (const auto& [v, name] : {std::pair{eye, "eye"}, std::pair{target, "target"}})
      for (int a = 0; a < 3; ++a)
        if (std::fabs(v[a]) > kMaxCoordinate) {
          std::ostringstream s;
          s << "must be within " << kMaxCoordinate << " vu of the origin on each axis";
          throw EngineError(ErrorKind::InvalidArgument, name, s.str());
        }
    if (!std::isfinite(fovY_degrees))
      throw EngineError(ErrorKind::InvalidArgument, "fovY_degrees", "must be a finite number");
    if (!(fovY_degrees > 1 && fovY_degrees < 170)) {
      std::ostringstream s;
      s << "must be strictly between 1 and 170 degrees (got " << fovY_degrees << ")";
      throw EngineError(ErrorKind::InvalidArgument, "fovY_degrees", s.str());
    }
    for (const auto& [v, name] : {std::pair{width, "width"}, std::pair{height, "height"}}) {
      if (v < 1 || v > kMaxFrameSide) {
        std::ostringstream s;
        s << "must be between 1 and " << kMaxFrameSide << " pixels (got " << v << ")";
        throw EngineError(v > kMaxFrameSide ? ErrorKind::TooLarge : ErrorKind::InvalidArgument, name, s.str());
      }
    }
    const Vec3 view = target - eye;
    const double dist = length(view);
    if (!(dist > 1e-9) || !std::isfinite(dist))
      throw EngineError(ErrorKind::InvalidArgument, "target", "must differ from eye");
    const double upLength = length(up);
    if (!(upLength > 0) || !std::isfinite(upLength))
      throw EngineError(ErrorKind::InvalidArgument, "up", "must not be the zero vector");
    // sin of the angle between up and the view direction; below ~0.06 degree the roll is undefined.
    if (length(cross(view / dist, up / upLength)) < 1e-3)
      throw EngineError(ErrorKind::InvalidArgument, "up", "must not be parallel to the view direction");
  }
};

enum class Shading {
  Lit,            // clay: warm albedo, soft key and hemisphere fill, faint specular, SDF ambient occlusion
  Normals,        // RGB = (n + 1) / 2 for the outward unit normal n (world axes)
  GradientError,  // grey level = max | |grad d| - 1 | over the hit cell's 8 corners, 0.1 -> white
  Thickness,      // Lit, tinted by the wall thickness under the hit (engine/thickness.hpp): red below
                  // the minimum thickness, shading to yellow at twice that, clay from three times on
};

inline constexpr std::array<WireName<Shading>, 4> kShadingNames{{
    {Shading::Lit, "lit"},
    {Shading::Normals, "normals"},
    {Shading::GradientError, "gradient_error"},
    {Shading::Thickness, "thickness"},
}};
inline std::optional<Shading> shadingFromName(std::string_view name) { return fromWireName(kShadingNames, name); }

// ---- Splats (server/engine/splats.hpp extracts them, protocol/cpp/splats.hpp encodes them) ---

struct Splat {
  float x, y, z;     // foot point, vu
  float nx, ny, nz;  // unit outward normal
  friend bool operator==(const Splat&, const Splat&) = default;
};

// A splat's channels: the texel (server/engine/channels.hpp) of the voxel its foot point came
// from; colour sRGB bytes, mask 0 (free) to 255 (frozen).
struct SplatTexel {
  std::uint8_t r = 0, g = 0, b = 0, mask = 0;
  friend bool operator==(const SplatTexel&, const SplatTexel&) = default;
};

struct BrickSplats {
  Int3 brick;                 // brick coordinates: voxel / kSplatBrickSide
  std::vector<Splat> points;  // at most one per voxel of the brick
  // Empty for a brick nothing painted (its points take the session's base colour, mask 0);
  // else one per point, in the same order (a painted brick).
  std::vector<SplatTexel> texels = {};
  friend bool operator==(const BrickSplats&, const BrickSplats&) = default;
};

// What a brick's splats can carry on the wire: bricks of 8^3 voxels, and per axis foot points in
// [o + kSplatPositionLow, o + kSplatPositionLow + kSplatPositionStep * kSplatPositionMax] around
// the brick origin o = 8 * brick, in steps of 3/4096 vu. Extraction clamps to this range.
inline constexpr int kSplatBrickSide = 8;
inline constexpr int kSplatPositionBits = 14;
inline constexpr int kSplatPositionMax = (1 << kSplatPositionBits) - 1;
inline constexpr float kSplatPositionLow = -2.0f;
inline constexpr float kSplatPositionStep = 12.0f / float(1 << kSplatPositionBits);

}  // namespace marzipan
