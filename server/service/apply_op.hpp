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

}  // namespace marzipan::service
