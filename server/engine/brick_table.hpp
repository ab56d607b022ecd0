// A volume's brick slots looked up once into one flat table (brick.hpp's BrickGrid) with a ring
// of one brick of air around the grid: what kernels read when they visit every brick, or each
// brick several times (splat extraction, connected components), instead of walking the
// volume's tiles per look-up. Sign, units and layout as in volume.hpp and brick.hpp.
#pragma once

#include <cstdint>

#include "brick.hpp"
#include "volume.hpp"

namespace marzipan {

class BrickTable {
 public:
  enum class Kind : std::uint8_t { Outside, Inside, Stored };

  // Borrows the bricks: vol (or a copy of it, copies share bricks) must outlive the table.
  explicit BrickTable(const Volume& vol);

  const Volume& volume() const { return vol_; }
  bool inGrid(Int3 b) const { return slots_.inGrid(b); }
  // The brick's voxels, or null with *uniform set to its value (-band inside, +band outside).
  // b may lie in the ring (one brick around the grid), which is air: null and +band.
  const float* data(Int3 b, float* uniform) const {
    const Slot& s = slots_[b];
    *uniform = s.inside ? -band_ : band_;
    return s.data;
  }
  // Outside in the ring.
  Kind kind(Int3 b) const {
    const Slot& s = slots_[b];
    return s.data ? Kind::Stored : s.inside ? Kind::Inside : Kind::Outside;
  }
  // The voxel at p; +band outside the domain, like Volume::at.
  float at(Int3 p) const;

 private:
  struct Slot {
    const float* data = nullptr;
    bool inside = false;
  };
  const Volume& vol_;
  float band_;
  Int3 dims_;
  BrickGrid<Slot> slots_;
};

}  // namespace marzipan
