// The one place where an operation object (protocol/cpp/ops.hpp) becomes an engine call.
// `marzipan batch` and the server both apply ops through here, so an op means the same thing
// offline and online. Conventions as in the engine: the volume is edited in place, the Edit
// holds the replaced bricks, and an EngineError (thrown before anything changes) propagates
// unchanged. The volume's revision is left to the caller, who owns the history.
#pragma once

#include "engine/edit.hpp"
#include "engine/level_set.hpp"
#include "engine/thread_pool.hpp"
#include "engine/volume.hpp"
#include "protocol/cpp/ops.hpp"

namespace marzipan::service {

Edit applyOp(Volume& vol, const protocol::Op& op, ThreadPool& pool);

// The engine's name of a brush tool (for strokes, which call the engine's applyStroke).
Brush engineBrush(protocol::BrushTool tool);

// What an op will cost before it runs, for the server's per-request budget and progress.
// voxels: voxels processed, an upper estimate that goes with the time it takes: a local
// tool's region (the worst place: clipped to the domain, grown by the band), or for a
// whole-volume op the domain's voxels times its passes (0 for a volume without stored bricks).
// About 1e7 voxels per second either way on a 2-core VM (2026-11-24).
// passes: the chunked whole-volume passes it makes (progress units, engine/progress.hpp); 0
// for a local op.
struct OpCost {
  double voxels = 0;
  double passes = 0;
};
OpCost estimateCost(const Volume& vol, const protocol::Op& op);
// The same for one brush dab of this radius and its mirror images (1 to 8).
double brushVoxels(const Volume& vol, double radius, int images = 1);

}  // namespace marzipan::service
