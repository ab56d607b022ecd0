// Constructive tools (docs/method.md §2): combine the solid with a tool shape by
// add = min(d, t), subtract = max(d, -t), intersect = max(d, t), optionally with a smooth
// blend of radius `blend`, then redistance the touched band so it stays a distance field.
// Sign and units as in volume.hpp; the volume is modified in place. The calling thread's
// Progress (progress.hpp) is checked throughout and advanced by one unit; a cancelled call
// throws Cancelled and changes nothing. Results do not depend on the pool's thread count.
// Channels (channels.hpp): the mask holds as in every tool (Volume::scatter; an intersection
// clears what lies beyond its reach by Volume::clearOutside, which holds it too). Colour
// follows the surface (Volume::extendChannels); with `color`, every band voxel of the result
// whose distance comes from the tool (its term wins: t < d for add, -t > d for subtract, t > d
// for intersect) is then painted as a paint dab of alpha 1 would (c += (1 - w/255) (C - c),
// rounded): what a union adds, the walls a subtraction or an intersection cuts. Without it, a
// subtraction's new walls take the cut solid's colour by extension.
#pragma once

#include <optional>

#include "channels.hpp"
#include "edit.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"
#include "protocol/cpp/values.hpp"  // CsgOp, ToolShape, CsgParams

namespace marzipan {

// Intersect removes everything outside the tool, so its region is the whole volume.
Edit applyCsg(Volume& vol, const CsgParams& p, ThreadPool& pool = ThreadPool::serial(),
              std::optional<Rgb8> color = std::nullopt);

// The tool's own signed distance at a point.
double toolDistance(const CsgParams& p, Vec3 x);

}  // namespace marzipan
