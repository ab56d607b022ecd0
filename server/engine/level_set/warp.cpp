// The warps' driver (../level_set.hpp, warps; docs/method.md §3, Warps): applyWarp gathers the
// base around a field's support and runs the passes of warp_passes.hpp in turn, then
// redistances what changed and writes the result back; the fields are warp_fields.hpp's and
// the tools' entry points warp_tools.cpp's. Conventions are warp_passes.hpp's.
#include <algorithm>
#include <cmath>
#include <iterator>
#include <memory>
#include <utility>
#include <vector>

#include "engine/level_set/warp_passes.hpp"
#include "engine/redistance.hpp"

namespace marzipan::level_set::warp {

namespace {

// Shares of a call's progress unit.
constexpr double kGatherShare = 0.1, kLatticeShare = 0.2, kResampleShare = 0.3, kRedistanceShare = 0.3;

// The redistance's moved boxes are the boxes of the changed voxels of slabs of this many
// slices. With one box of them all, grown by a voxel (before 2026-11-29), a snake hook move of
// 2 vu at radius 8 took 5.07M instructions; with slabs of 1, 2, 4 or 8 slices 4.83M, 4.76M,
// 4.74M, 4.75M, with one box not grown 4.76M (its march and classification the smaller).
constexpr int kMovedSlab = 4;

// The box of the bricks where vol and base differ (empty when none): what earlier calls of the
// stroke changed. Only the bricks of the tiles vol does not share with base are looked at (the
// others are base's: vol was a copy of it), a layer of bricks per task: on a grab message's
// critical path this scan was the longest serial part.
Box changedSinceBase(const Volume& vol, const Volume& base, ThreadPool& pool) {
  const Int3 n = vol.brickDims();
  constexpr int T = Volume::kTileSide;
  std::vector<Box> layers(std::size_t(n.z));
  pool.parallelFor(std::size_t(n.z), [&](std::size_t z) {
    Box out{};
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        if (x % T == 0 && vol.sharesTile(base, {x, y, int(z)})) {
          x += T - 1;
          continue;
        }
        float uv = 0, ub = 0;
        const Int3 b{x, y, int(z)};
        const float* dv = vol.brickData(b, &uv);
        const float* db = base.brickData(b, &ub);
        if (dv == db && (dv || uv == ub) && vol.brickPaint(b) == base.brickPaint(b)) continue;
        out = unite(out, Bricks::box(b));
      }
    layers[z] = out;
  });
  Box out{};
  for (const Box& b : layers) out = unite(out, b);
  return out.intersect(vol.domain());
}

WarpScratch& warpScratch() {
  thread_local WarpScratch s;
  return s;
}

// The changes that take vol to base with `warped`'s distances over `region` and `texels`'s
// channels over their grid's box, within `all` (which holds both and every brick where vol
// differs from base), published. The distances are compared with base's (Volume::diff, whose
// mask holds them against base's, as one call of the stroke from base would), and each
// brick's `before` is vol's.
std::vector<BrickChange> writeBack(Volume& vol, const Volume& base, const Box& all, const Box& region,
                                   const DenseGrid& warped, const std::vector<Texel>& texels, ThreadPool& pool) {
  if (all.empty()) return {};
  DenseGrid out;
  out.gatherFrom(base, all, {}, pool);
  for (int z = region.lo.z; z < region.hi.z; ++z)
    for (int y = region.lo.y; y < region.hi.y; ++y)
      std::copy_n(&warped.v[warped.index({region.lo.x, y, z})], region.size().x, &out.v[out.index({region.lo.x, y, z})]);
  std::vector<BrickChange> found = base.diff(all, out.v.data(), out.box, pool);
  const Box bricks = Bricks::bricksOf(all);
  const Int3 nb = bricks.size();
  std::vector<std::vector<BrickChange>> layers(std::size_t(nb.z));
  std::size_t next = 0;  // found is in z, y, x order of the bricks
  std::vector<std::pair<std::size_t, std::size_t>> ranges(std::size_t(nb.z));
  for (int bz = 0; bz < nb.z; ++bz) {
    const std::size_t first = next;
    while (next < found.size() && found[next].brick.z == bricks.lo.z + bz) ++next;
    ranges[std::size_t(bz)] = {first, next};
  }
  const Texel plain = texelOf(base.baseColor());
  pool.parallelFor(std::size_t(nb.z), [&](std::size_t k) {
    const int bz = bricks.lo.z + int(k);
    std::size_t f = ranges[k].first;
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const Int3 b{bx, by, bz};
        BrickRef after;
        if (f < ranges[k].second && found[f].brick == b) {
          after = std::move(found[f++].after);
        } else {
          after = base.brick(b);
        }
        BrickRef before = vol.brick(b);
        if (after.data) {
          // The brick's channels: base's, with the warped ones where their grid reaches.
          const Box here = Bricks::box(b).intersect(warped.box);
          const BrickPaint* had = base.brickPaint(b);
          auto paint = std::make_shared<BrickPaint>();
          if (had) {
            *paint = *had;
          } else {
            std::fill(std::begin(paint->t), std::end(paint->t), plain);
          }
          const Int3 o = Bricks::origin(b);
          for (int z = here.lo.z; z < here.hi.z; ++z)
            for (int y = here.lo.y; y < here.hi.y; ++y)
              for (int x = here.lo.x; x < here.hi.x; ++x)
                paint->t[Bricks::index(x - o.x, y - o.y, z - o.z)] = texels[warped.index({x, y, z})];
          std::shared_ptr<const BrickPaint> now = vol.canonicalPaint(std::move(paint));
          // Equal channels keep the very BrickPaint they equal (no change where nothing moved).
          const auto same = [](const BrickPaint* a, const BrickPaint* c) {
            return a && c && std::equal(std::begin(a->t), std::end(a->t), std::begin(c->t));
          };
          if (now && same(now.get(), had)) now = base.brick(b).paint;
          if (now && same(now.get(), before.paint.get())) now = before.paint;
          after.paint = std::move(now);
        } else {
          after.paint = nullptr;
        }
        if (!(before == after)) layers[k].push_back({b, std::move(before), std::move(after)});
      }
  });
  std::vector<BrickChange> changes;
  for (auto& l : layers) std::move(l.begin(), l.end(), std::back_inserter(changes));
  vol.publish(changes, true);
  return changes;
}

}  // namespace

Edit applyWarp(Volume& vol, const Volume& base, const Velocity& v, ThreadPool& pool) {
  const float band = base.band();
  // As in applyStroke: a voxel band + 1 or more from every changed one keeps its distance; one
  // more voxel for the kept-voxel test at the region's edge and the stencils.
  const int reach = int(std::ceil(band + 1)) - 1;
  const int margin = reach + 2;
  const Box work = v.support().intersect(vol.domain());

  const ProgressShare share{Progress::current(), 1};
  WarpScratch& s = warpScratch();
  const Box gridBox = work.grown(margin);
  s.base.gatherFrom(base, gridBox, share.part(kGatherShare), pool);
  s.warped.box = s.base.box;
  s.warped.size = s.base.size;
  s.warped.sx = s.base.sx;
  s.warped.sxy = s.base.sxy;
  s.warped.v.assign(s.base.v.begin(), s.base.v.end());
  const bool painted = base.paintedBricks() != 0 || vol.paintedBricks() != 0;
  const WarpPass pass(v, s, work, band, painted);
  if (pass.cells) s.lattice.findBlocks(base, s.base, work.grown(kBlockReach), band, pool);
  s.lattice.build(v, work, pass.cells, pool, share.part(kLatticeShare));

  // Channels (../../channels.hpp), for a painted volume only: the colour is read back through
  // the same inverse map as the distance (the texel of the voxel nearest X(x)), so it moves
  // with the clay; the mask weight stays with its voxel. A voxel x of weight w moves by
  // (1 - w / 255) of what it would: its colour here, its distance where the result is written
  // (Volume::diff, against base). And clay does not pass through frozen clay: x keeps base's
  // distance and colour when a voxel of weight 255 lies on the clay's way from X(x) to x (x's
  // own left out), as a level-set tool stops the voxels of weight 255 (listing.cpp): a grab's
  // deep inside, which no mask reaches, is not carried through a frozen band into the air.
  bool masked = false;
  if (painted) {
    s.texels.resize(std::size_t(gridBox.voxels()));
    base.gatherTexels(gridBox, s.texels.data());
    s.warpedTexels = s.texels;
    for (const Texel& t : s.texels) masked = masked || t.mask != 0;
  }

  // Each pair of slices z of `work` (a layer of the lattice's cells) resamples its voxels and
  // notes, per slice, the box of those that changed, and of those whose channels changed.
  const int slices = work.size().z;
  std::vector<Box> changed(std::size_t(std::max(0, slices))), recoloured(changed.size());
  Runs runs(work);
  const ProgressShare resampling = share.part(kResampleShare);
  resample(pass, base, painted, masked, runs, changed, recoloured, pool, resampling);
  Box moved{}, texelsMoved{};
  for (const Box& c : changed) moved = unite(moved, c);
  for (const Box& c : recoloured) texelsMoved = unite(texelsMoved, c);
  const KeptVoxels& kept = keptVoxels(pass, moved, runs, pool, resampling);
  // The kept voxels' values, and the boxes of the voxels that changed, per slab of kMovedSlab
  // slices: the redistance's moved boxes (the surface moved only through the cells touching
  // them), its region those grown by the reach.
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const int z = moved.lo.z + int(i);
    for (const auto& [k, value] : kept[i]) {
      s.warped.v[k] = value;
      if (value == s.base.v[k]) continue;
      const std::size_t rest = k - std::size_t(z - s.warped.box.lo.z) * s.warped.sxy;
      const int y = s.warped.box.lo.y + int(rest / s.warped.sx), x = s.warped.box.lo.x + int(rest % s.warped.sx);
      Box& c = changed[std::size_t(z - work.lo.z)];
      if (c.empty()) c = {{x, y, z}, {x + 1, y + 1, z + 1}};
      c.lo.x = std::min(c.lo.x, x), c.lo.y = std::min(c.lo.y, y);
      c.hi.x = std::max(c.hi.x, x + 1), c.hi.y = std::max(c.hi.y, y + 1);
    }
  }
  std::vector<Box> movedBoxes;
  Box changedBox{};
  for (int i = 0; i < slices; i += kMovedSlab) {
    Box b{};
    for (int j = i; j < std::min(slices, i + kMovedSlab); ++j) b = unite(b, changed[std::size_t(j)]);
    if (!b.empty()) movedBoxes.push_back(b), changedBox = unite(changedBox, b);
  }

  Box region{};
  if (!changedBox.empty()) {
    region = changedBox.grown(reach).intersect(vol.domain());
    const Box resetBoxes[] = {region};
    RedistanceOptions options;
    options.resetBoxes = resetBoxes;
    options.movedBoxes = movedBoxes;
    options.normalizeKept = false;
    // The resample and the kept pass just ran on the pool: a tentacle's move (some 4,800
    // candidates, below the march's own threshold) 1.99x -> 1.74x an r 8 dab's wall time on
    // two threads (2026-11-30; docs/benchmark-log.md, Warps).
    options.parallelSides = true;
    options.progress = share.part(kRedistanceShare);
    redistanceRegion(s.warped, region, band, Outside::Source, options, pool);
    if (isGrab(v)) grabTipFeet(pass, region);
  }
  share.check();  // the last check: nothing below stops part way

  // Earlier calls of the stroke may have changed bricks beyond this region: base's values go
  // back there. When base is vol itself (a snake hook's move) there are none, and the scan of
  // every brick of the volume is spared.
  const Box earlier = &vol == &base ? Box{} : changedSinceBase(vol, base, pool);
  Edit edit;
  if (painted) {
    const Box all = unite(unite(region, texelsMoved), earlier);
    edit.append(writeBack(vol, base, all, region, s.warped, s.warpedTexels, pool), all);
  } else if (earlier.empty() || unite(region, earlier) == region) {
    if (!region.empty()) edit.append(vol.scatter(region, s.warped.v.data(), s.warped.box, pool), region);
  } else {
    const Box all = unite(region, earlier);
    DenseGrid out;
    out.gatherFrom(base, all, {}, pool);
    for (int z = region.lo.z; z < region.hi.z; ++z)
      for (int y = region.lo.y; y < region.hi.y; ++y)
        std::copy_n(&s.warped.v[s.warped.index({region.lo.x, y, z})], region.size().x, &out.v[out.index({region.lo.x, y, z})]);
    edit.append(vol.scatter(all, out.v.data(), out.box, pool), all);
  }
  share.advance(1 - kGatherShare - kLatticeShare - kResampleShare - kRedistanceShare);
  return edit;
}

}  // namespace marzipan::level_set::warp
