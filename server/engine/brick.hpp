// Brick addressing and flat per-brick tables: how every kernel finds the brick of a voxel, the
// voxel within a brick, and a slot per brick, instead of writing the shifts and masks out.
//
// Conventions:
// - A brick is a cube of kBrickSide^3 voxels; brick b holds the voxels b * kBrickSide + l with
//   each coordinate of l in [0, kBrickSide). Brick coordinates are voxel coordinates divided by
//   kBrickSide rounded down, also below zero (voxel -1 is local voxel kBrickSide - 1 of brick -1),
//   which is what rings of padding around the domain need.
// - A brick's floats are indexed x + S*(y + S*z) over local coordinates (S = kBrickSide): x fastest.
// - The brick side is 2^kBrickLog2: that constant is the only place it is written. Everything
//   else (Volume, the kernels, the volume file, whose header records the side) derives from it;
//   the splat wire format fixes its own side (kSplatBrickSide), and splats.cpp refuses to build
//   when the two differ. tests/engine/test_brick.cpp instantiates the layout for other sides.
#pragma once

#include <cstddef>
#include <vector>

#include "geometry.hpp"

namespace marzipan {

// Addressing for bricks of (2^Log2)^3 voxels. The engine uses Bricks (below); other sides are
// instantiated by the tests, so that a change of kBrickLog2 is a change the tests have seen.
template <int Log2>
struct BrickLayout {
  // Up to 32 voxels a side: kernels pack one bit per voxel of a brick row into 32-bit words.
  static_assert(Log2 >= 1 && Log2 <= 5, "brick sides from 2 to 32 voxels");

  static constexpr int kLog2 = Log2;
  static constexpr int kSide = 1 << Log2;
  static constexpr int kMask = kSide - 1;
  static constexpr int kVoxels = kSide * kSide * kSide;
  static constexpr unsigned kRowBits = kSide == 32 ? ~0u : (1u << kSide) - 1;  // one bit per voxel of a row
  static constexpr double kCentre = 0.5 * (kSide - 1);      // local coordinate of a brick's centre

  // Index of local voxel (x, y, z), each in [0, kSide), in a brick's floats.
  static constexpr int index(int x, int y, int z) { return x + kSide * (y + kSide * z); }
  static constexpr int index(Int3 l) { return index(l.x, l.y, l.z); }
  // The local voxel of an index in [0, kVoxels).
  static constexpr Int3 local(int i) { return {i & kMask, (i >> Log2) & kMask, i >> (2 * Log2)}; }

  // The brick holding voxel p (rounding down, also for negative p) and p within it.
  static constexpr int brickOf(int c) { return c >> Log2; }  // arithmetic shift: C++20
  static constexpr int localOf(int c) { return c & kMask; }  // two's complement: C++20
  static constexpr Int3 brickOf(Int3 p) { return {brickOf(p.x), brickOf(p.y), brickOf(p.z)}; }
  static constexpr Int3 localOf(Int3 p) { return {localOf(p.x), localOf(p.y), localOf(p.z)}; }
  // Index of voxel p in the floats of brick brickOf(p).
  static constexpr int indexOf(Int3 p) { return index(localOf(p.x), localOf(p.y), localOf(p.z)); }

  // The first voxel of brick b, and the voxels it covers.
  static constexpr Int3 origin(Int3 b) { return {b.x * kSide, b.y * kSide, b.z * kSide}; }
  static constexpr Box box(Int3 b) {
    return {origin(b), {b.x * kSide + kSide, b.y * kSide + kSide, b.z * kSide + kSide}};
  }
  // The bricks needed to cover `dims` voxels from the origin (rounding up).
  static constexpr Int3 gridOf(Int3 dims) {
    return {(dims.x + kMask) >> Log2, (dims.y + kMask) >> Log2, (dims.z + kMask) >> Log2};
  }
  // The bricks meeting a non-empty voxel box [lo, hi), as a box of brick coordinates.
  static constexpr Box bricksOf(const Box& voxels) {
    return {brickOf(voxels.lo), {brickOf(voxels.hi.x - 1) + 1, brickOf(voxels.hi.y - 1) + 1, brickOf(voxels.hi.z - 1) + 1}};
  }
};

inline constexpr int kBrickLog2 = 3;
using Bricks = BrickLayout<kBrickLog2>;
inline constexpr int kBrickSide = Bricks::kSide;
inline constexpr int kBrickVoxels = Bricks::kVoxels;

// One T per brick of a grid of `grid` bricks and a ring of `ring` bricks around it: brick b is
// valid for -ring <= b < grid + ring per axis, stored x fastest. The flat table a kernel keeps
// when it visits bricks many times (a padding ring spares it the bounds checks at the edges).
template <class T>
class BrickGrid {
 public:
  BrickGrid() = default;
  BrickGrid(Int3 grid, int ring, const T& fill = T{})
      : grid_(grid),
        ring_(ring),
        sy_(std::size_t(grid.x + 2 * ring)),
        sz_(sy_ * std::size_t(grid.y + 2 * ring)),
        slots_(sz_ * std::size_t(grid.z + 2 * ring), fill) {}

  Int3 grid() const { return grid_; }
  int ring() const { return ring_; }
  std::size_t size() const { return slots_.size(); }
  // True when b is in the grid proper, the ring excluded.
  bool inGrid(Int3 b) const {
    return b.x >= 0 && b.y >= 0 && b.z >= 0 && b.x < grid_.x && b.y < grid_.y && b.z < grid_.z;
  }
  // True when b has a slot, the ring included.
  bool contains(Int3 b) const {
    return b.x >= -ring_ && b.y >= -ring_ && b.z >= -ring_ && b.x < grid_.x + ring_ && b.y < grid_.y + ring_ &&
           b.z < grid_.z + ring_;
  }
  std::size_t index(Int3 b) const {
    return std::size_t(b.x + ring_) + sy_ * std::size_t(b.y + ring_) + sz_ * std::size_t(b.z + ring_);
  }
  // Steps of index() per brick along y and z (along x it is 1).
  std::size_t strideY() const { return sy_; }
  std::size_t strideZ() const { return sz_; }
  T& operator[](Int3 b) { return slots_[index(b)]; }
  const T& operator[](Int3 b) const { return slots_[index(b)]; }
  T& operator[](std::size_t i) { return slots_[i]; }
  const T& operator[](std::size_t i) const { return slots_[i]; }
  T* data() { return slots_.data(); }
  const T* data() const { return slots_.data(); }

 private:
  Int3 grid_;
  int ring_ = 0;
  std::size_t sy_ = 0, sz_ = 0;
  std::vector<T> slots_;
};

}  // namespace marzipan
