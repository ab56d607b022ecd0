// The measures of a solid as JSON: the one shape that session.stats (protocol/PROTOCOL.md) and
// `marzipan batch --stats` (README, "The stats line") share.
//   inside_volume (vu^3), surface_area (vu^2), components,
//   bounds {empty, lo: [x, y, z], hi: [x, y, z]} of the zero set in vu (lo and hi are zeros when
//   empty), gradient_error {max, mean, voxels}, digest (16 hex digits)
// Written into an object the caller owns, after the keys it has put there, so that a caller using
// ordered JSON keeps this order.
#pragma once

#include "engine/measures.hpp"

namespace marzipan::service {

template <class Json>
void putMeasures(Json& out, const Measures& m) {
  const auto vec3 = [](Vec3 v) { return Json::array({v.x, v.y, v.z}); };
  out["inside_volume"] = m.insideVolume;
  out["surface_area"] = m.surfaceArea;
  out["components"] = m.components;
  out["bounds"] = Json{{"empty", m.bounds.empty}, {"lo", vec3(m.bounds.lo)}, {"hi", vec3(m.bounds.hi)}};
  out["gradient_error"] = Json{{"max", m.gradientError.max}, {"mean", m.gradientError.mean}, {"voxels", m.gradientError.voxels}};
  out["digest"] = m.digest;
}

}  // namespace marzipan::service
