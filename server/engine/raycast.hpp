// Ray-cast frames of the solid: depth and RGB8 pixels, for the viewer and for snapshots.
//
// Conventions:
// - World coordinates are voxel units (vu), as in volume.hpp; the surface is the zero set of the
//   trilinear interpolant of the voxels. The domain is closed: an inside region that touches the
//   domain's edge is capped half a voxel beyond it (points outside the domain read +band).
// - Camera: a pinhole at `eye` looking at `target`; `up` fixes the roll (it need not be
//   orthogonal to the view direction); fovY_degrees is the full vertical field of view; pixels
//   are square. Pixel (x, y) has x to the right and y downwards from the top-left corner, and its
//   ray passes through the pixel's centre.
// - Frame::rgb is width*height*3 bytes (R, G, B), rows from the top; Frame::depth is the
//   distance from the eye to the hit along the ray, in vu (+inf where the ray meets nothing).
// - Pixels are identical for any thread count: the frame is split into fixed 16x16 tiles and
//   every pixel is computed from its own rays and from pixels an earlier pass finished (a
//   preview's lattice pixels; a still frame's anti-aliasing pass reads the finished first pass).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "brick.hpp"
#include "geometry.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"
#include "protocol/cpp/values.hpp"  // Camera (and its validate()), Shading, kMaxFrameSide

namespace marzipan {

namespace raycasting {
struct RayKernel;  // raycast_kernel.hpp
}

// Interactive frames favour speed; still frames (shown once edits stop, render.frame, snapshots)
// shade from a smooth normal field (the central-difference gradients at the hit cell's corners,
// blended trilinearly: continuous across cells, so a smooth surface shows no voxel steps), take
// five ambient-occlusion samples instead of two, and anti-alias: pixels on a silhouette, a
// depth jump or a colour crease get four more rays on a rotated grid, averaged in linear light.
// Preview frames, streamed while a client edits or orbits, are Interactive frames reconstructed
// from fewer rays: the pixels with even x and y are traced, every other pixel takes the mean of
// its lattice neighbours where they agree (all missed; or all hit at close depths with close
// normals and colours) and is traced otherwise (raycast.cpp). A solid narrower than two pixels
// can vanish between lattice rays; the error against the Interactive frame is measured over
// whole frames in the tests.
enum class FrameQuality { Interactive, Still, Preview };

struct Frame {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // width*height*3
  std::vector<float> depth;       // width*height
};

// What the ray caster reads, built once per volume version: a flat table of brick pointers
// (uniform bricks point at shared constant bricks, so sampling never branches on them) padded by
// one ring of outside bricks; per brick, the box of its cells that may hold a zero of the
// interpolant (cells with a corner <= 0) and the Chebyshev distance, in bricks, to the nearest
// brick with such cells, in all directions and per octant of ray directions (among the bricks a
// ray going that way can still enter), which lets rays jump over empty space in large steps.
// It keeps a copy of the volume (cheap, see volume.hpp), so it stays valid while the original is
// edited; it is then simply a view of the older version. Building reads every stored voxel once
// (about 1-3 ms for a radius-100 sphere in 256^3). Immutable once built: any number of threads
// may render from it at once.
class RaycastAccel {
 public:
  explicit RaycastAccel(const Volume& volume, ThreadPool& pool = ThreadPool::serial());

  const Volume& volume() const { return volume_; }

 private:
  friend struct raycasting::RayKernel;
  struct BrickInfo {
    std::uint8_t reach;          // 0 for a brick with cells that may hold a zero; capped at 255
    std::uint8_t octant[8];      // the same among the bricks a ray can still enter, per octant
    std::uint8_t lo[3], hi[3];  // those cells, local coordinates; none when lo[0] > hi[0]
  };

  Volume volume_;
  // Both over the volume's bricks and one ring around them (the ring reads +band).
  BrickGrid<const float*> bricks_;
  BrickGrid<BrickInfo> info_;
  std::vector<std::shared_ptr<const Brick>> owned_;
};

// thicknessMinVu (> 0, vu) is used by Shading::Thickness only.
Frame render(const RaycastAccel& accel, const Camera& camera, Shading shading, ThreadPool& pool,
             FrameQuality quality = FrameQuality::Interactive, double thicknessMinVu = 1.0);
// Builds the accelerator for this one frame; keep a RaycastAccel to render a version repeatedly.
Frame render(const Volume& volume, const Camera& camera, Shading shading, ThreadPool& pool,
             FrameQuality quality = FrameQuality::Interactive, double thicknessMinVu = 1.0);

}  // namespace marzipan
