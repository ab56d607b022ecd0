// What one tool application did to a volume: the bricks it replaced (old and new, for undo
// and redo) and the voxel region it may have touched (clipped to the domain).
#pragma once

#include <vector>

#include "geometry.hpp"
#include "volume.hpp"

namespace marzipan {

struct Edit {
  std::vector<BrickChange> changes;
  Box region;

  bool empty() const { return changes.empty(); }
  // Folds a later step of the same operation in: per brick the first `before` and the last
  // `after` survive, and a brick that ends as it started is dropped.
  void append(const std::vector<BrickChange>& later, const Box& laterRegion);
};

}  // namespace marzipan
