// A dense scratch copy of a box of the field, where tools do their work before the result
// is scattered back into bricks. Index order x fastest: index = x + sx*(y + sy*z) in box-local
// coordinates. Units and sign as in volume.hpp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "geometry.hpp"

namespace marzipan {

struct ProgressShare;
class ThreadPool;
class Volume;

// An allocator whose resize() leaves new floats unset: a scratch grid that grows is then
// written whole by gatherFrom() before anything reads it, and zero-filling it first cost as
// much as the gather.
template <class T>
struct UninitializedAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <class U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

struct DenseGrid {
  Box box;
  Int3 size;
  std::size_t sx = 0, sxy = 0;  // strides of y and z
  std::vector<float, UninitializedAllocator<float>> v;

  DenseGrid() = default;
  explicit DenseGrid(const Box& b, float fillValue = 0.0f)
      : box(b), size(b.size()), sx(std::size_t(size.x)), sxy(std::size_t(size.x) * size.y),
        v(std::size_t(b.voxels()), fillValue) {}

  // The box's voxels copied out of a volume.
  static DenseGrid gather(const Volume& vol, const Box& b);
  // The same into this grid, reusing its storage (no fresh pages for a scratch grid). With a
  // progress, it is checked and advanced between slabs of whole brick layers along z
  // (progress.hpp). With a pool, a box of kParallelGatherVoxels or more is copied slab by slab on
  // its threads (a copy: the same values for any thread count).
  void gatherFrom(const Volume& vol, const Box& b);
  void gatherFrom(const Volume& vol, const Box& b, const ProgressShare& progress);
  void gatherFrom(const Volume& vol, const Box& b, const ProgressShare& progress, ThreadPool& pool);
  static constexpr std::int64_t kParallelGatherVoxels = std::int64_t(1) << 16;

  std::size_t index(Int3 p) const {  // p in volume coordinates, must lie in box
    return std::size_t(p.x - box.lo.x) + sx * std::size_t(p.y - box.lo.y) + sxy * std::size_t(p.z - box.lo.z);
  }
  Int3 point(std::size_t i) const {
    return {box.lo.x + int(i % sx), box.lo.y + int((i / sx) % std::size_t(size.y)), box.lo.z + int(i / sxy)};
  }
  std::size_t stride(int axis) const { return axis == 0 ? 1 : (axis == 1 ? sx : sxy); }
  float& operator[](std::size_t i) { return v[i]; }
  float operator[](std::size_t i) const { return v[i]; }
};

}  // namespace marzipan
