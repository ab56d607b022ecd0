// Constructive tools (METHOD.md section 2): combine the solid with a tool shape by
// add = min(d, t), subtract = max(d, -t), intersect = max(d, t), optionally with a smooth
// blend of radius `blend`, then redistance the touched band so it stays a distance field.
// Sign and units as in volume.hpp; the volume is modified in place.
#pragma once

#include <optional>
#include <string_view>

#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

enum class CsgOp { Add, Subtract, Intersect };
enum class ToolShape { Sphere, Box, Cylinder };

std::optional<ToolShape> toolShapeFromName(std::string_view name);  // "sphere", "box", "cylinder"

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

// Intersect removes everything outside the tool, so its region is the whole volume.
Edit applyCsg(Volume& vol, const CsgParams& p, ThreadPool& pool = ThreadPool::serial());

// The tool's own signed distance at a point.
double toolDistance(const CsgParams& p, Vec3 x);

}  // namespace marzipan
