// The channels a volume's band voxels carry next to their distance: a colour and a mask weight.
//
// Conventions:
// - Colour: sRGB, 8 bits a channel (the bytes a client draws, not linear light). Mask: 8 bits,
//   0 = free, 255 = frozen; a geometry tool moves a voxel of weight w by (1 - w / 255) of what it
//   would (volume.hpp, diff), so clay of weight 255 keeps its distances bit for bit.
// - Storage: a BrickPaint holds the channels of one stored brick (index as the brick's floats,
//   brick.hpp), shared and immutable like the brick, in a slot of its own with the same
//   addressing. A brick without one reads the volume's base colour and weight 0, and so does
//   every uniform brick (uniform bricks never carry paint: they hold no band voxel). A volume
//   that is never painted stores no channel at all; a BrickPaint whose every texel is the base
//   colour with weight 0 is stored as none (Volume::canonicalPaint), so equal fields give equal
//   bricks, files and digests whatever their history.
// - The mask lives on the band, as the colour does: clay that a tool makes in free air or cuts
//   deep inside (a CSG shape or a warp reaching past the band, into uniform bricks) is not
//   held back there; the frozen surface itself and its band keep their bits.
// - The base colour defaults to kClayColor, the clay the clients draw: the web client's
//   albedo (0.72, 0.46, 0.33) in linear light (web-client/render/gl-program.js, raycast.cpp's
//   Material), encoded to sRGB and rounded: (221, 181, 155).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>

#include "brick.hpp"

namespace marzipan {

struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

inline constexpr Rgb8 kClayColor{221, 181, 155};

// One voxel's channels.
struct Texel {
  std::uint8_t r = 0, g = 0, b = 0, mask = 0;
  friend bool operator==(const Texel&, const Texel&) = default;
  Rgb8 color() const { return {r, g, b}; }
};

inline constexpr Texel texelOf(Rgb8 c, std::uint8_t mask = 0) { return {c.r, c.g, c.b, mask}; }

struct BrickPaint {
  Texel t[kBrickVoxels];  // index Bricks::index(local voxel)
  // Some texel has a weight above 0: set by Volume::canonicalPaint, which every stored
  // BrickPaint passes through, so that geometry edits test one flag, not 512 weights.
  bool masked = false;
};

// Rewriting a stored brick's channels, copy on write: `now` is null until the first texel that
// changes, then a copy of `was` (the brick's channels as published; null: every texel `base`).
// The texel voxel i holds so far:
inline Texel texelSoFar(const BrickPaint* now, const BrickPaint* was, Texel base, int i) {
  return now ? now->t[i] : was ? was->t[i] : base;
}
// Sets voxel i's texel to t, making the copy first if there is none yet.
inline void setTexel(std::shared_ptr<BrickPaint>& now, const BrickPaint* was, Texel base, int i, Texel t) {
  if (!now) {
    now = std::make_shared<BrickPaint>();
    if (was) {
      *now = *was;
    } else {
      // Doubling copies: a loop of 4-byte struct stores does not vectorize.
      now->t[0] = base;
      for (int n = 1; n < kBrickVoxels; n *= 2) std::memcpy(now->t + n, now->t, sizeof(Texel) * std::size_t(std::min(n, kBrickVoxels - n)));
    }
  }
  now->t[i] = t;
}

}  // namespace marzipan
