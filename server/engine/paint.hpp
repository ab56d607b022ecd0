// Paint and mask: the tools that change a volume's channels (channels.hpp) and never its
// distances (every brick keeps its very Brick; an Edit of paint changes only BrickRef::paint).
//
// Conventions: sign and units as in volume.hpp (vu; d < 0 inside); colours sRGB, weights 0..255.
// A dab paints every voxel p of a stored brick (the band, and the voxels clamped to +-band beside
// it, which a tool's redistance may bring into the band: a mask must hold them too) by the
// brush's alpha at its foot point q = p - d n (n the central-difference normal): colour is then
// constant along the normals through the band, as a velocity extension would leave it, so the
// surface between the voxels reads the colour painted on it whichever voxel a client or a splat
// takes it from.
// The alpha of a dab at q: strength * weight * F(|q - center| / radius), F = 1 up to `hardness`,
// then (1 - t^2)^2 with t running from 0 at hardness to 1 at the radius, 0 beyond.
// One application over several dabs takes, at each voxel, the largest alpha a over its dabs,
// less the largest m over `memory` (the dabs the stroke applied before): where a <= m nothing
// changes, elsewhere the voxel moves by e = (a - m) / (1 - m) of the way that is left,
//   colour  c += e (1 - w/255) (C - c)     (the voxel's own mask w protects it from paint too)
//   mask+   w += e (255 - w)
//   mask-   w -= e w
// each channel rounded to the nearest integer. So a stroke passed over the same spot again
// changes nothing, and a stroke sent in pieces paints as one (up to the rounding between pieces);
// an empty memory lets every application add (build-up, "accumulate").
// Results do not depend on the pool's thread count (each brick is computed alone, in order).
// Invalid parameters throw EngineError before anything changes.
#pragma once

#include <span>

#include "channels.hpp"
#include "edit.hpp"
#include "geometry.hpp"
#include "level_set.hpp"  // StrokeDab
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

enum class PaintMode { Color, MaskAdd, MaskErase };

struct PaintSettings {
  PaintMode mode = PaintMode::Color;
  Rgb8 color = kClayColor;  // Color only
  double radius = 8;        // vu, in [0.5, 1024]
  double strength = 1;      // in (0, 1]
  double hardness = 0.5;    // in [0, 1): the share of the radius painted at full strength
};

// The colour rule of a dab of alpha e at a texel: c += e (1 - w/255) (C - c), each channel
// rounded to the nearest integer; the weight stays. Other tools that paint (CSG's `color`) use it.
Texel tinted(Texel t, Rgb8 color, double e);

// Throws EngineError (field "radius", "strength" or "hardness").
void checkPaintSettings(const PaintSettings& st);

// One application of a paint or mask stroke over `dabs` (weights in (0, 1], their boxes of
// half side radius + band meeting the domain), remembering `memory`. Empty dabs: no change.
Edit paintStroke(Volume& vol, const PaintSettings& st, std::span<const StrokeDab> dabs,
                 std::span<const StrokeDab> memory, ThreadPool& pool = ThreadPool::serial());

// One dab at `center`, no memory.
Edit paint(Volume& vol, const PaintSettings& st, Vec3 center, ThreadPool& pool = ThreadPool::serial());

// The whole-volume mask operations, over every voxel of every stored brick (uniform bricks carry
// no channel, channels.hpp); colours stay. Clear: every weight 0. Fill: every weight 255.
// Invert: w -> 255 - w (an unpainted brick becomes fully masked). Each returns its changes
// (region: the domain); one that changes nothing returns an empty Edit. Progress: one unit.
Edit maskClear(Volume& vol);
Edit maskFill(Volume& vol);
Edit maskInvert(Volume& vol);

}  // namespace marzipan
