// Dispatch of operation objects to the engine's tools (see apply_op.hpp).
#include "service/apply_op.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <sstream>
#include <numbers>
#include <string>
#include <unordered_map>
#include <vector>
#include <variant>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"
#include "engine/paint.hpp"

namespace marzipan::service {
namespace {

using namespace protocol;

// Every surface-speed tool is a one-dab stroke, bit for bit the engine's addBlob, smooth, ...
// Flatten and contrast move towards (from) the plane fitted around the centre on the volume as
// it is, as a stroke's first dab fits it (Session::beginStroke): a replay of the op fits the
// same plane. Inflate and clay are add blob without a height.
Edit apply(Volume& vol, const BrushOp& op, ThreadPool& pool) {
  const StrokeDab dab{op.params.center, 1.0};
  StrokeSettings st{engineBrush(op.tool), op.params.radius, op.params.strength};
  if (brushUsesPlane(st.tool)) st.plane = fitBrushPlane(vol, op.params.center, op.params.radius);
  return applyStroke(vol, st, {&dab, 1}, {}, pool);
}

Edit apply(Volume& vol, const GlobalSmoothOp& op, ThreadPool& pool) {
  return applyGlobalSmooth(vol, op.iterations, op.strength, pool);
}

Edit apply(Volume& vol, const CsgToolOp& op, ThreadPool& pool) {
  std::optional<Rgb8> color;
  if (op.color) color = Rgb8{op.color->r, op.color->g, op.color->b};
  return applyCsg(vol, op.params, pool, color);
}

Edit apply(Volume& vol, const MorphOp& op, ThreadPool& pool) { return applyMorph(vol, op.kind, op.radius, pool); }

Edit apply(Volume& vol, const MaskOp& op, ThreadPool&) {
  switch (op.action) {
    case MaskAction::Clear: return maskClear(vol);
    case MaskAction::Invert: return maskInvert(vol);
    case MaskAction::Fill: return maskFill(vol);
  }
  throw EngineError(ErrorKind::InvalidArgument, "action", "must be clear, invert or fill");
}

// The voxels of a cube of half side `reach` around a point, clipped to the domain (the
// centre is unknown before a pick, so the worst place is assumed).
double cubeVoxels(const Volume& vol, double reach) {
  double v = 1;
  for (int a = 0; a < 3; ++a) v *= std::min(double(vol.dims()[a]), 2 * reach + 1);
  return v;
}

// A whole-volume pass gathers every chunk near a stored brick densely (chunked_pass.hpp): on
// a solid that spans the grid that is about the domain, and the time per pass goes with it
// (2026-11-24, this 2-core VM: 0.26 s quiet to 0.65 s busy per smoothing pass of the 192^3
// pig, 7.1M voxels).
double passVoxels(const Volume& vol) { return vol.presentBricks() == 0 ? 0 : cubeVoxels(vol, 1e9); }

// Passes of morphology by k vu, as engine/level_set/global.cpp makes them (applications of at most 1 vu).
double morphPasses(double k) { return std::ceil(k - 1e-9); }

OpCost cost(const Volume& vol, const BrushOp& op) { return {brushVoxels(vol, op.params.radius), 1}; }

OpCost cost(const Volume& vol, const GlobalSmoothOp& op) {
  return {passVoxels(vol) * op.iterations, double(op.iterations)};
}

OpCost cost(const Volume& vol, const CsgToolOp& op) {
  // Intersect clears every brick outside the tool: its region is the whole domain.
  if (op.params.op == CsgOp::Intersect) return {cubeVoxels(vol, 1e9), 1};
  return {cubeVoxels(vol, op.params.radius + op.params.blend + vol.band() + 1), 1};
}

// Every stored brick's channels once, no distances.
OpCost cost(const Volume& vol, const MaskOp&) { return {double(vol.presentBricks()) * kBrickVoxels, 1}; }

OpCost cost(const Volume& vol, const MorphOp& op) {
  const bool twice = op.kind == MorphKind::Open || op.kind == MorphKind::Close;
  const double passes = morphPasses(op.radius) * (twice ? 2 : 1);
  return {passVoxels(vol) * passes, passes};
}

}  // namespace

std::string_view paintToolName(PaintMode mode) {
  return protocol::nameOf(protocol::kPaintToolNames,
                          mode == PaintMode::Color ? protocol::PaintTool::Color : protocol::PaintTool::MaskAdd);
}

PaintSettings paintSettingsOf(const protocol::StrokeBeginParams& p) {
  PaintSettings st;
  st.mode = enginePaintMode(p.paint->tool);
  if (st.mode == PaintMode::MaskAdd && p.paint->erase) st.mode = PaintMode::MaskErase;
  st.color = Rgb8{p.paint->color.r, p.paint->color.g, p.paint->color.b};
  st.radius = p.radius;
  st.strength = p.strength;
  st.hardness = p.paint->hardness;
  return st;
}

double brushVoxels(const Volume& vol, double radius, int images) {
  return cubeVoxels(vol, radius + vol.band()) * images;
}

std::size_t rememberedOverlap(std::span<const StrokeDab> memory, double reach) {
  const double cell = 2 * std::max(reach, 1.0);
  const auto key = [](std::int64_t x, std::int64_t y, std::int64_t z) {
    return std::uint64_t(x & 0x1FFFFF) | std::uint64_t(y & 0x1FFFFF) << 21 | std::uint64_t(z & 0x1FFFFF) << 42;
  };
  std::unordered_map<std::uint64_t, std::size_t> cells;
  std::vector<std::array<std::int64_t, 3>> occupied;
  for (const StrokeDab& d : memory) {
    const std::array<std::int64_t, 3> c{std::int64_t(std::floor(d.center.x / cell)), std::int64_t(std::floor(d.center.y / cell)),
                                        std::int64_t(std::floor(d.center.z / cell))};
    if (cells[key(c[0], c[1], c[2])]++ == 0) occupied.push_back(c);
  }
  std::size_t most = 0;
  for (const auto& c : occupied) {
    std::size_t n = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (const auto it = cells.find(key(c[0] + dx, c[1] + dy, c[2] + dz)); it != cells.end()) n += it->second;
    most = std::max(most, n);
  }
  return most;
}

double strokeDabVoxels(const Volume& vol, double radius, int images, double substeps, std::span<const StrokeDab> memory) {
  const double scan = kRememberedDabVoxels * double(rememberedOverlap(memory, radius + vol.band() + 1));
  return brushVoxels(vol, radius, images) * substeps * (1 + scan);
}

namespace {

using protocol::WarpTool;

double maxTravel(const WarpStroke& w) {
  return (w.tool == WarpTool::ElasticGrab ? kMaxElasticTravelPerRadius : kMaxWarpTravelPerRadius) * w.radius;
}

// v no longer than `most` (a hair under it, so that rounding stays within the engine's bound).
Vec3 clampLength(Vec3 v, double most) {
  const double l = length(v);
  return l <= most ? v : v * (most / l * (1 - 1e-12));
}

// A unit vector along d (finite, not zero), robust to components near the double range's ends.
Vec3 unitOf(Vec3 d) {
  const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  return normalized(d / m);
}

// The affine warps' amount of the drag D, clamped: twist radians, scale log2 of the factor, pinch.
double amountOf(const WarpStroke& w, Vec3 D) {
  const Vec3 u = w.direction ? unitOf(*w.direction) : length(D) > 0 ? D / length(D) : Vec3{};
  const double s = dot(D, u) / w.radius;
  switch (w.tool) {
    case WarpTool::Twist: return std::clamp(s * std::numbers::pi / 2, -2 * std::numbers::pi, 2 * std::numbers::pi);
    case WarpTool::LocalScale: return std::clamp(s, -2.0, 2.0);
    case WarpTool::Pinch: return std::clamp(s / 2, -1.0, 1.0);
    case WarpTool::Grab:
    case WarpTool::ElasticGrab:
    case WarpTool::SnakeHook:
    case WarpTool::PinchAlong: break;
  }
  return 0;
}

// What an anchored stroke's engine call gets for the pointer at p: the grabs' anchor and d, or
// the affine warps' amount, less what the base already holds.
struct WarpCall {
  Vec3 anchor, d;
  double amount = 0;
};

WarpCall anchoredCall(const WarpStroke& w, Vec3 anchor, Vec3 p) {
  const Vec3 D = clampLength((p - anchor) * w.strength, maxTravel(w));
  WarpCall c{anchor, {}, 0};
  if (w.tool == WarpTool::Grab || w.tool == WarpTool::ElasticGrab) {
    c.anchor = anchor + w.heldD;
    c.d = clampLength(D - w.heldD, maxTravel(w));
  } else {
    const double limit = w.tool == WarpTool::Twist ? 2 * std::numbers::pi : w.tool == WarpTool::LocalScale ? 2 : 1;
    c.amount = std::clamp(amountOf(w, D) - w.heldAmount, -limit, limit);
  }
  return c;
}

// One engine call's work (warpStrokeCost): its support's box grown by the resampler's margin,
// and its sub-steps from the engine's bound of |grad v| (level_set.hpp, grabSlopeBound and the
// others; a grab's landing factor, near 1, taken as 1). A snake hook move's support is the
// widest it can be (snakeHookSupportBound: a young tentacle's moves reach past the radius), as
// which moves are young depends on the moves before them.
double warpCallVoxels(const Volume& vol, const WarpStroke& w, const WarpCall& c) {
  const double margin = vol.band() + 3;
  const double r = w.tool == WarpTool::SnakeHook ? snakeHookSupportBound(w.radius) : w.radius;
  Vec3 half{r + margin, r + margin, r + margin};
  double lipschitz = 0;
  switch (w.tool) {
    case WarpTool::Grab:
    case WarpTool::SnakeHook:
      for (int a = 0; a < 3; ++a) half[a] += std::abs(c.d[a]) / 2;
      lipschitz = w.tool == WarpTool::Grab ? grabSlopeBound(length(c.d), r) : snakeHookSlopeBound(length(c.d), w.radius);
      break;
    case WarpTool::ElasticGrab:
      half = half + Vec3{2 * r, 2 * r, 2 * r};
      lipschitz = elasticGrabSlopeBound(length(c.d), r, w.volume);
      break;
    case WarpTool::Twist: lipschitz = twistSlopeBound(c.amount); break;
    case WarpTool::LocalScale: lipschitz = localScaleSlopeBound(std::exp2(c.amount)); break;
    case WarpTool::Pinch: lipschitz = pinchSlopeBound(c.amount); break;
    case WarpTool::PinchAlong:
      for (int a = 0; a < 3; ++a) half[a] += std::abs(c.d[a]) / 2;
      lipschitz = pinchAlongSlopeBound(length(c.d), c.amount, r);
      break;
  }
  double box = 1;
  for (int a = 0; a < 3; ++a) box *= std::min(double(vol.dims()[a]), 2 * half[a] + 1);
  const double substeps = std::max(1.0, std::ceil(lipschitz / kWarpStretchPerStep));
  return box * (1 + kWarpStepVoxels * substeps);
}

// A pinch path's moves (PROTOCOL.md, warp strokes): from each point to the next, in pieces of
// at most kMaxWarpTravelPerRadius radii (the engine's bound; a path's pinch barely depends on how
// it is cut), each piece's amount strength times the pressure of the dab it leads to. Calls
// move(from, to, amount) for each, and refuses (EngineError) a point outside the volume before
// any.
template <class Move>
void pinchPathMoves(const Volume& vol, const WarpStroke& w, Vec3 at, std::span<const Vec3> points,
                    std::span<const double> pressures, Move move) {
  const Int3 n = vol.dims();
  for (const Vec3 p : points)
    for (int a = 0; a < 3; ++a)
      if (!(p[a] >= 0 && p[a] <= n[a] - 1))
        throw EngineError(ErrorKind::OutOfDomain, "center", "a pinch path's dabs must lie in the volume");
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 p = points[i];
    const double amount = w.strength * (i < pressures.size() ? pressures[i] : 1.0);
    const int pieces = int(std::ceil(length(p - at) / maxTravel(w) * (1 + 1e-9)));
    if (amount > 0)
      for (int k = 0; k < pieces; ++k) move(at + (p - at) * (double(k) / pieces), at + (p - at) * (double(k + 1) / pieces), amount);
    at = p;
  }
}

}  // namespace

void checkWarpSettings(const WarpStroke& w) {
  const protocol::NumberParam& radius = protocol::radiusParamOf(w.tool);
  requireRange(w.radius, radius.minimum, radius.maximum, "radius");
  if (!(w.strength > 0 && w.strength <= 1)) throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  requireRange(w.volume, 0, 0.5, "volume");
  if (w.direction && (!isFinite(*w.direction) || *w.direction == Vec3{0, 0, 0}))
    throw EngineError(ErrorKind::InvalidArgument, "direction", "must be three finite numbers, not all zero");
}

void setWarpAnchor(WarpStroke& w, const Volume& base, Vec3 at) {
  const Int3 n = base.dims();
  // Also the carried point's test: the anchor is the journal's first dab, and a replay calls
  // this function with it, so a point this refuses must never be taken.
  const auto inDomain = [n](Vec3 p) {
    for (int a = 0; a < 3; ++a)
      if (!(p[a] >= 0 && p[a] <= n[a] - 1)) return false;
    return true;
  };
  if (!inDomain(at))
    throw EngineError(ErrorKind::OutOfDomain, "center", "the anchor (the stroke's first dab) must lie in the volume");
  double distance = std::abs(base.sample(at));
  if (!(distance <= kMaxWarpAnchorDistance) && distance < base.band()) {
    // Another sculptor's edit moved the surface under the splats the client picked on: take the
    // surface point nearest the pick, which is no farther than the pick's distance. Where a
    // solid meets a face of the grid, the zero set between the last voxel and the +band read
    // beyond it lies outside the domain: such a point is not taken.
    const Vec3 foot = base.towardSurface(at, kAnchorSnapSteps);
    if (inDomain(foot) && std::abs(base.sample(foot)) <= kWarpAnchorTolerance && length(foot - at) <= base.band()) {
      at = foot;
      distance = std::abs(base.sample(at));
    }
  }
  if (!(distance <= kMaxWarpAnchorDistance)) {
    std::ostringstream what;
    what << "the anchor (the stroke's first dab) must lie on the surface, within " << kMaxWarpAnchorDistance
         << " vu of it: it is " << (distance >= base.band() ? "at least " : "") << std::setprecision(3) << distance
         << " vu away";
    throw EngineError(ErrorKind::InvalidArgument, "center", what.str());
  }
  const Vec3 g = base.gradient(at);
  if (!isFinite(g) || !(length(g) > 0.5))
    throw EngineError(ErrorKind::InvalidArgument, "center", "the surface has no normal at the anchor");
  w.anchor = at;
  w.normal = g / length(g);
}

Edit applyWarpStroke(Volume& vol, const Volume& base, WarpStroke& w, std::span<const Vec3> points, ThreadPool& pool,
                     std::span<const double> pressures) {
  if (!w.anchor) throw EngineError(ErrorKind::InvalidArgument, "center", "the stroke has no anchor yet");
  Edit edit;
  if (points.empty()) return edit;
  if (w.tool == WarpTool::PinchAlong) {
    // Each move draws towards the plane through it along the surface's normal at its end (the
    // volume as the stroke has made it; the last normal where the field there has no slope).
    Vec3 normal = w.normal;
    pinchPathMoves(vol, w, *w.anchor, points, pressures, [&](Vec3 from, Vec3 to, double amount) {
      const Vec3 g = vol.gradient(to);
      if (isFinite(g) && length(g) > 0.5 && std::abs(vol.sample(to)) < vol.band()) normal = g / length(g);
      const Edit move = pinchAlong(vol, from, to, normal, amount, w.radius, pool);
      edit.append(move.changes, move.region);
    });
    w.anchor = points.back();
    w.normal = normal;
    return edit;
  }
  if (protocol::dabsArePath(w.tool)) {
    Vec3 at = *w.anchor;
    for (const Vec3 p : points) {
      const Vec3 d = clampLength((p - at) * w.strength, maxTravel(w));
      if (d == Vec3{0, 0, 0}) continue;
      const Edit move = snakeHook(vol, at, at + d, w.radius, pool);
      edit.append(move.changes, move.region);
      at = at + d;
    }
    w.anchor = at;
    return edit;
  }
  const WarpCall c = anchoredCall(w, *w.anchor, points.back());
  switch (w.tool) {
    case WarpTool::Grab: edit = grab(vol, base, c.anchor, c.d, w.radius, pool); break;
    case WarpTool::ElasticGrab: edit = elasticGrab(vol, base, c.anchor, c.d, w.radius, w.volume, pool); break;
    case WarpTool::Twist: edit = twist(vol, base, c.anchor, w.normal, c.amount, w.radius, pool); break;
    case WarpTool::LocalScale: edit = localScale(vol, base, c.anchor, std::exp2(c.amount), w.radius, pool); break;
    case WarpTool::Pinch: edit = pinch(vol, base, c.anchor, w.normal, c.amount, w.radius, pool); break;
    case WarpTool::SnakeHook:
    case WarpTool::PinchAlong: break;  // paths, above
  }
  w.pointer = points.back();
  return edit;
}

OpCost warpStrokeCost(const Volume& vol, const WarpStroke& w, std::optional<Vec3> anchor, std::span<const Vec3> points,
                      std::span<const double> pressures) {
  if (w.anchor) anchor = w.anchor;
  if (!anchor || points.empty()) return {0, 0};
  if (w.tool == WarpTool::PinchAlong) {
    // The anchor lies in the volume once it is taken (setWarpAnchor): one not known yet (a ray's
    // far stand-in) costs as the volume's farthest point in its direction.
    if (!isFinite(*anchor)) return {0, 0};
    Vec3 start = *anchor;
    for (int a = 0; a < 3; ++a) start[a] = std::clamp(start[a], 0.0, double(vol.dims()[a] - 1));
    OpCost cost;
    try {
      pinchPathMoves(vol, w, start, points, pressures, [&](Vec3 from, Vec3 to, double amount) {
        cost.voxels += warpCallVoxels(vol, w, WarpCall{from, to - from, amount});
        cost.passes += 1;
      });
    } catch (const EngineError&) {
      return {0, 0};  // refused before any work when applied
    }
    return cost;
  }
  if (!protocol::dabsArePath(w.tool)) return {warpCallVoxels(vol, w, anchoredCall(w, *anchor, points.back())), 1};
  OpCost cost;
  Vec3 at = *anchor;
  for (const Vec3 p : points) {
    const Vec3 d = clampLength((p - at) * w.strength, maxTravel(w));
    if (d == Vec3{0, 0, 0}) continue;
    cost.voxels += warpCallVoxels(vol, w, WarpCall{at, d, 0});
    cost.passes += 1;
    at = at + d;
  }
  return cost;
}

void rebaseWarp(WarpStroke& w) {
  if (protocol::dabsArePath(w.tool) || !w.anchor || !w.pointer) return;
  const Vec3 D = clampLength((*w.pointer - *w.anchor) * w.strength, maxTravel(w));
  if (w.tool == WarpTool::Grab || w.tool == WarpTool::ElasticGrab) w.heldD = D;
  else w.heldAmount = amountOf(w, D);
}

OpCost estimateCost(const Volume& vol, const Op& op) {
  return std::visit([&](const auto& o) { return cost(vol, o); }, op);
}

Edit applyOp(Volume& vol, const Op& op, ThreadPool& pool) {
  return std::visit([&](const auto& o) { return apply(vol, o, pool); }, op);
}

}  // namespace marzipan::service
