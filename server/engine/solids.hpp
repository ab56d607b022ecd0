// Starting solids, each placed in a domain of the given size and sized to it (the smallest
// side N sets the scale), with correct distances within the band.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"
#include "protocol/cpp/values.hpp"  // SolidKind and its names

namespace marzipan {

// Centred in the domain, N = smallest side:
//  sphere radius 0.35N; box half side 0.25N; torus (around y) radii 0.28N and 0.1N;
//  cylinder (along y) radius 0.2N, half height 0.3N; dumbbell (along x) two spheres of radius
//  0.17N at +-0.27N joined by a handle of radius 0.06N; pig: body, head, snout, ears, four
//  legs and eye dents blended with a smooth union, standing on its legs (y up, facing +x).
Volume makeSolid(SolidKind kind, Int3 dims, float band = Volume::kDefaultBand,
                 ThreadPool& pool = ThreadPool::serial());

Volume makeSphere(Int3 dims, Vec3 center, double radius, float band = Volume::kDefaultBand);
Volume makeBox(Int3 dims, Vec3 center, Vec3 halfExtents, float band = Volume::kDefaultBand);

// Samples any signed distance function into a new volume. f may underestimate distances but
// must never overestimate them by more than 2 vu: a brick whose centre is further than that
// from the zero set is left uniform without sampling its voxels.
// exact = false redistances the result, for functions that are only bounds (blends).
Volume makeFromFunction(Int3 dims, const std::function<double(Vec3)>& f, bool exact,
                        float band = Volume::kDefaultBand, ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
