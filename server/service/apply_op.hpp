// The one place where an operation object (protocol/cpp/ops.hpp) becomes an engine call.
// `marzipan batch` and the server both apply ops through here, so an op means the same thing
// offline and online. Conventions as in the engine: the volume is edited in place, the Edit
// holds the replaced bricks, and an EngineError (thrown before anything changes) propagates
// unchanged. The volume's revision is left to the caller, who owns the history.
#pragma once

#include <cstddef>
#include <span>

#include "engine/edit.hpp"
#include "engine/level_set.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "protocol/cpp/ops.hpp"
// engineBrush (the engine's Brush of a surface-speed tool), applyMorph, applyGlobalSmooth:
// generated from the tool registry (protocol/registry/tools.json) at build time.
#include "service/engine_tools.generated.hpp"

namespace marzipan::service {

Edit applyOp(Volume& vol, const protocol::Op& op, ThreadPool& pool);

// What an op will cost before it runs, for the server's per-request budget and progress.
// voxels: voxels processed, an upper estimate that goes with the time it takes: a local
// tool's region (the worst place: clipped to the domain, grown by the band), or for a
// whole-volume op the domain's voxels times its passes (0 for a volume without stored
// bricks). Every kind runs at about the same rate per voxel so counted: measured 2026-11-24
// on this 2-core VM (brushes serial as the server runs them, the others on 2 threads), quiet:
// add_blob/smooth/sharpen radius 140 on 256^3 0.64-0.75 s (2.2-2.6e7 voxels/s), add_blob
// radius 300 on the 512^3 sphere 4.0-5.2 s (2.6-3.3e7), csg_add radius 120 on 256^3 0.61 s
// (2.5e7) and radius 250 on 512^3 4.3-4.7 s (2.9e7), a smoothing pass of the 192^3 pig
// 0.26 s (2.7e7); busy (load 10) about 1e7 voxels per second.
// passes: progress units (engine/progress.hpp): the chunked whole-volume passes it makes, or
// 1 for a local op (the engine counts its phases in fractions of it).
struct OpCost {
  double voxels = 0;
  double passes = 0;
};
OpCost estimateCost(const Volume& vol, const protocol::Op& op);
// The same for one brush dab of this radius and its mirror images (1 to 8).
double brushVoxels(const Volume& vol, double radius, int images = 1);
// The most remembered dabs of a stroke whose region may hold one voxel (an upper bound: their
// centres lie within the voxel's neighbourhood of cells of a grid of twice the reach).
std::size_t rememberedOverlap(std::span<const StrokeDab> memory, double reach);
// One dab of a stroke message, as brushVoxels, with the stroke's height sub-steps and its
// memory: where remembered dabs are weaker than the message's, each voxel the message moves
// scans every remembered dab whose region holds it (engine applyStroke), kRememberedDabVoxels
// voxels' worth each: measured 2026-11-29 on this 2-core VM (tests/service/test_apply_op.cpp),
// a radius-12 dab on 96^3 took 0.42 ms alone and 39 ms over 4096 weak remembered dabs, 0.0225
// voxel per remembered dab; 0.03 keeps the estimate above the time.
double strokeDabVoxels(const Volume& vol, double radius, int images, double substeps,
                       std::span<const StrokeDab> memory);
inline constexpr double kRememberedDabVoxels = 0.03;

}  // namespace marzipan::service
