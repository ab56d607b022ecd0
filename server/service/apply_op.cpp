// Dispatch of operation objects to the engine's tools (see apply_op.hpp).
#include "service/apply_op.hpp"

#include <variant>

#include "engine/csg.hpp"
#include "engine/errors.hpp"
#include "engine/level_set.hpp"

namespace marzipan::service {
namespace {

using namespace protocol;

Edit apply(Volume& vol, const BrushOp& op, ThreadPool& pool) {
  switch (op.tool) {
    case BrushTool::AddBlob:
      return addBlob(vol, op.params, pool);
    case BrushTool::RemoveBlob:
      return removeBlob(vol, op.params, pool);
    case BrushTool::Smooth:
      return smooth(vol, op.params, pool);
    case BrushTool::Sharpen:
      return sharpen(vol, op.params, pool);
  }
  throw EngineError(ErrorKind::InvalidArgument, "tool", "unknown brush tool");
}

Edit apply(Volume& vol, const GlobalSmoothOp& op, ThreadPool& pool) {
  return meanCurvatureFlow(vol, op.iterations, op.strength, pool);
}

Edit apply(Volume& vol, const CsgToolOp& op, ThreadPool& pool) { return applyCsg(vol, op.params, pool); }

Edit apply(Volume& vol, const MorphOp& op, ThreadPool& pool) {
  switch (op.kind) {
    case MorphKind::Erode:
      return erode(vol, op.radius, pool);
    case MorphKind::Dilate:
      return dilate(vol, op.radius, pool);
    case MorphKind::Open:
      return openSolid(vol, op.radius, pool);
    case MorphKind::Close:
      return closeSolid(vol, op.radius, pool);
  }
  throw EngineError(ErrorKind::InvalidArgument, "kind", "unknown morphology kind");
}

}  // namespace

Edit applyOp(Volume& vol, const Op& op, ThreadPool& pool) {
  return std::visit([&](const auto& o) { return apply(vol, o, pool); }, op);
}

Brush engineBrush(protocol::BrushTool tool) {
  switch (tool) {
    case protocol::BrushTool::AddBlob: return Brush::AddBlob;
    case protocol::BrushTool::RemoveBlob: return Brush::RemoveBlob;
    case protocol::BrushTool::Smooth: return Brush::Smooth;
    case protocol::BrushTool::Sharpen: return Brush::Sharpen;
  }
  throw EngineError(ErrorKind::InvalidArgument, "tool", "unknown brush tool");
}

}  // namespace marzipan::service
