// Dispatch of operation objects to the engine's tools (see apply_op.hpp).
#include "service/apply_op.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>
#include <variant>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"

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

Edit apply(Volume& vol, const CsgToolOp& op, ThreadPool& pool) { return applyCsg(vol, op.params, pool); }

Edit apply(Volume& vol, const MorphOp& op, ThreadPool& pool) { return applyMorph(vol, op.kind, op.radius, pool); }

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

OpCost cost(const Volume& vol, const MorphOp& op) {
  const bool twice = op.kind == MorphKind::Open || op.kind == MorphKind::Close;
  const double passes = morphPasses(op.radius) * (twice ? 2 : 1);
  return {passVoxels(vol) * passes, passes};
}

}  // namespace

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

OpCost estimateCost(const Volume& vol, const Op& op) {
  return std::visit([&](const auto& o) { return cost(vol, o); }, op);
}

Edit applyOp(Volume& vol, const Op& op, ThreadPool& pool) {
  return std::visit([&](const auto& o) { return apply(vol, o, pool); }, op);
}

}  // namespace marzipan::service
