// One application of a stroke (../level_set.hpp, strokes), which every brush is too (a stroke
// of one dab): the dabs are checked, cut into groups whose grids cannot meet, and each group
// is gathered into a DenseGrid, evolved under the tool's Motion (tools.cpp) scaled by its
// window (swept_window.hpp), in sub-steps of at most 1 vu with a height, redistanced in the
// shell the move may have changed, and scattered back. Every check comes before anything
// changes, and a throw in any group leaves the volume as it was. Progress (progress.hpp): one
// unit per call, shared by the groups (the shares below).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "engine/errors.hpp"
#include "engine/level_set/internal.hpp"
#include "engine/level_set/swept_window.hpp"
#include "engine/redistance.hpp"

namespace marzipan {

using level_set::advection;
using level_set::evolve;
using level_set::kStencilReach;
using level_set::listedBounds;
using level_set::listMoved;
using level_set::Motion;
using level_set::moveListed;
using level_set::MovedVoxels;
using level_set::PreparedDab;
using level_set::Run;
using level_set::strokeMotion;
using level_set::SweptWindow;
using level_set::ToolScratch;
using level_set::toolScratch;
using level_set::withSpeeds;

namespace {

// A local tool's one unit of progress per call, per group of dabs: these shares of it, the
// march the rest.
constexpr double kGatherShare = 0.1, kCollectShare = 0.05, kEvolveShare = 0.15, kRedistanceShare = 0.6;

// An advection's redistance is cut to the box of the voxels it moved by more than this (vu; a
// voxel moves by about its sub-steps times its step): near the edge of a dab's window W is
// (1 - t^2)^2 and nearly flat, so a rim of voxels moves by hundredths of a vu or less, and the
// band within reach of that rim was most of what the march took. There the surface moved by at
// most this much, so the far voxels the shell keeps are off by at most twice it (their own
// move, and the surface's: a distance moves no more than the surface does); and as the speed
// is read at the foot points (listing.cpp), phi - t F there is already the distance to the moved
// surface to first order, which leaves the second-order part: where W s = 0.01, |grad W s| is
// about 0.38 s / r, which changes |grad phi| by its square over 2 (0.001 at r 8, s 1). Measured (2026-11-29): 0.01 took 3.8% off an r 8 dab
// and kept the thirty blobs' crease at 0.296; 0.02 took 6% but read 0.2997 there, past its
// whole-volume redistance's 0.286 + 0.01 (test_tools.cpp). Curvature flow moves each voxel by
// its own curvature, which its factor does not bound: its box is that of every voxel it lists.
constexpr double kLeastMove = 0.01;

// The moves an advection leaves out of its box, brick by brick (DriftBook): a brick whose
// voxels left out may have moved by more than this since they were last redistanced has them
// taken into the box. Left out each time, the wide rim of a faint dab moves by less than
// kLeastMove but by as much as any other part over many (200 add blobs of radius 24 and
// strength 0.03 at one point: 0.8 vu), and the band beyond it drifted as the faint dabs' did
// (0.63 vu from a whole-volume redistance of the same zero set). Measured on those 200 dabs
// (2026-11-29, test_tools.cpp): 0.1 leaves the far band 0.054 from it, the near band 0.099 and a
// gradient error of 0.021; 0.01 as far but 0.16 and 0.068 near the surface, where a rim's kept
// voxels normalized over and over in the corners of its window step away from the rest (the
// 0.42 of redistancing every listed voxel each time, in part); 0.4 0.087 far.
constexpr double kDriftLimit = 0.1;

// The smallest box holding a and b (either may be empty).
Box hull(const Box& a, const Box& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return {{std::min(a.lo.x, b.lo.x), std::min(a.lo.y, b.lo.y), std::min(a.lo.z, b.lo.z)},
          {std::max(a.hi.x, b.hi.x), std::max(a.hi.y, b.hi.y), std::max(a.hi.z, b.hi.z)}};
}

// Whether every voxel of b lies in one of boxes.
bool covered(const Box& b, std::span<const Box> boxes) {
  for (const Box& n : boxes)
    if (b.intersect(n) == b) return true;
  // A box that several meet (a stroke's ROIs): voxel by voxel, at most a brick's.
  for (int z = b.lo.z; z < b.hi.z; ++z)
    for (int y = b.lo.y; y < b.hi.y; ++y)
      for (int x = b.lo.x; x < b.hi.x; ++x)
        if (std::none_of(boxes.begin(), boxes.end(), [&](const Box& n) { return n.contains({x, y, z}); }))
          return false;
  return true;
}

// The volume's drift (Volume::brickDrift) of a group's region as its steps change it: each
// step's moves left out of its box add up per brick, a brick's are taken into the box once they
// pass kDriftLimit, and a drift whose box was redistanced is gone. Per brick, not per voxel: a
// sum and a box (12 bytes a brick) where a float per voxel would double the field.
struct DriftBook {
  Box bricks;                   // the bricks of the group's region
  std::vector<BrickDrift> was;  // per brick of `bricks` (x fastest): the volume's
  std::vector<BrickDrift> now;  // and as the steps leave it
  std::vector<float> step;      // this step's largest |step| of the brick's voxels left out
  std::vector<Box> left;        // and their box

  void start(const Volume& vol, const Box& region) {
    bricks = Bricks::bricksOf(region);
    was.resize(std::size_t(bricks.voxels()));
    vol.brickDrifts(bricks, was.data());
    now = was;
    step.resize(was.size());
    left.resize(was.size());
  }
  std::size_t slot(Int3 p) const {  // the brick of voxel p, which lies in the region
    const Int3 b = Bricks::brickOf(p), size = bricks.size();
    return std::size_t(b.x - bricks.lo.x) +
           std::size_t(size.x) * (std::size_t(b.y - bricks.lo.y) + std::size_t(size.y) * std::size_t(b.z - bricks.lo.z));
  }
  // Each brick's listed voxels outside `box` (all when it is empty): their largest step and box.
  void leaveOut(const DenseGrid& g, const MovedVoxels& moved, const Box& box) {
    std::fill(step.begin(), step.end(), 0.0f);
    std::fill(left.begin(), left.end(), Box{});
    // The runs come in index order, about one to a row: the next row is counted on, another
    // found by division, and a run inside the box, most of them, costs two compares.
    const int rowX = g.box.lo.x;  // x at a row's first index
    const bool boxHasX = box.lo.x < box.hi.x;
    const std::size_t loX = boxHasX ? std::size_t(std::clamp(box.lo.x - rowX, 0, g.size.x)) : 0;
    const std::size_t hiX = boxHasX ? std::size_t(std::clamp(box.hi.x - rowX, 0, g.size.x)) : 0;
    std::size_t rowStart = 0, rowEnd = 0, insideLo = 0, insideHi = 0;  // grid indices: the row, its part in box
    int y = 0, z = 0;
    bool known = false;
    for (const Run& r : moved.runs) {
      if (r.index >= insideLo && r.index + r.count <= insideHi) continue;
      if (r.index >= rowEnd) {
        if (known && r.index < rowEnd + g.sx) {
          rowStart = rowEnd;
          if (++y == g.box.hi.y) y = g.box.lo.y, ++z;
        } else {
          const std::size_t row = r.index / g.sx;
          rowStart = row * g.sx;
          y = g.box.lo.y + int(row % std::size_t(g.size.y));
          z = g.box.lo.z + int(row / std::size_t(g.size.y));
          known = true;
        }
        rowEnd = rowStart + g.sx;
        insideLo = insideHi = 0;
        if (y >= box.lo.y && y < box.hi.y && z >= box.lo.z && z < box.hi.z) {
          insideLo = rowStart + loX;
          insideHi = rowStart + hiX;
          if (r.index >= insideLo && r.index + r.count <= insideHi) continue;
        }
      }
      const int x0 = rowX + int(r.index - rowStart), count = int(r.count);
      // The run's voxels [in0, in1) inside box.
      const int in0 = std::clamp(int(std::int64_t(insideLo) - std::int64_t(r.index)), 0, count);
      const int in1 = std::clamp(int(std::int64_t(insideHi) - std::int64_t(r.index)), in0, count);
      const float* const steps = moved.step.data() + r.first;
      for (const auto& [begin, end] : {std::pair{0, in0}, std::pair{in1, count}})
        for (int j = begin; j < end;) {
          const int stop = std::min(end, j + kBrickSide - Bricks::localOf(x0 + j));
          float most = 0;
          for (int i = j; i < stop; ++i) most = std::max(most, std::fabs(steps[i]));
          if (most > 0) {
            const std::size_t k = slot({x0 + j, y, z});
            step[k] = std::max(step[k], most);
            left[k] = hull(left[k], Box{{x0 + j, y, z}, {x0 + stop, y + 1, z + 1}});
          }
          j = stop;
        }
    }
  }
  // Widens `listed` by the voxels left out and the drift of each brick whose moves pass
  // kDriftLimit with this step's; whether any did.
  bool take(Box& listed, const Box& region, int substeps) const {
    bool taken = false;
    for (std::size_t k = 0; k < now.size(); ++k) {
      if (!(step[k] > 0) || !(double(now[k].move) + double(step[k]) * substeps > kDriftLimit)) continue;
      listed = hull(hull(listed, left[k]), now[k].box.intersect(region));
      taken = true;
    }
    return taken;
  }
  // After this step's redistance of `boxes`: a drift whose box they cover is gone, and the
  // moves left out add.
  void settle(std::span<const Box> boxes, int substeps) {
    for (std::size_t k = 0; k < now.size(); ++k) {
      BrickDrift& d = now[k];
      if (d.none() && !(step[k] > 0)) continue;
      const float move = float(double(step[k]) * substeps);
      if (d.none() || covered(d.box, boxes)) {
        d = {move, left[k]};
      } else {
        d = {d.move + move, hull(d.box, left[k])};
      }
    }
  }
  // The bricks whose drift changed, to the volume.
  void publish(Volume& vol) {
    changed.clear();
    std::size_t k = 0;
    for (int z = bricks.lo.z; z < bricks.hi.z; ++z)
      for (int y = bricks.lo.y; y < bricks.hi.y; ++y)
        for (int x = bricks.lo.x; x < bricks.hi.x; ++x, ++k)
          if (!(now[k] == was[k])) changed.push_back({{x, y, z}, now[k]});
    vol.setBrickDrift(changed);
  }

 private:
  std::vector<std::pair<Int3, BrickDrift>> changed;
};

DriftBook& driftBook() {
  thread_local DriftBook book;
  return book;
}

void checkStroke(const Volume& vol, const StrokeSettings& st, std::span<const StrokeDab> dabs) {
  checkStrokeSettings(st);
  for (const StrokeDab& d : dabs) {
    if (!isFinite(d.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
    if (!(d.weight > 0 && d.weight <= 1)) throw EngineError(ErrorKind::InvalidArgument, "weight", "must be in (0, 1]");
    if (!isFinite(d.normal) || (d.normal != Vec3{} && !(std::fabs(dot(d.normal, d.normal) - 1) <= 1e-6)))
      throw EngineError(ErrorKind::InvalidArgument, "normal", "must be a unit vector or zero");
    level_set::checkToolDab(st, d);
    if (boxAround(d.center, {st.radius, st.radius, st.radius}).intersect(vol.domain()).empty())
      throw EngineError(ErrorKind::OutOfDomain, "center", "the tool's region lies outside the volume");
  }
}

}  // namespace

void checkStrokeDab(const Volume& vol, const StrokeSettings& st, const StrokeDab& dab) {
  checkStroke(vol, st, {&dab, 1});
}

Edit applyStroke(Volume& vol, const StrokeSettings& st, std::span<const StrokeDab> dabs,
                 std::span<const StrokeDab> memory, ThreadPool& pool) {
  checkStroke(vol, st, dabs);
  // With a height: the signed height, the window's anchor and each sub-step's speed scale.
  const double height = level_set::signedHeight(st);
  const float band = vol.band();
  const double r = st.radius;
  // The surface moves only inside the dabs' ROIs (W = 0 on their boundaries, voxels outside
  // are not evolved), so the new zero set differs from the old only in the cells touching them:
  // a voxel band + 1 or more from every ROI (band or more from those cells) keeps its distance,
  // and a band voxel nearer may now be closer to the moved surface than to the old one. That
  // shell is redistanced too, where it may have changed (redistance.hpp, movedBoxes), from the
  // kept voxels inside and outside the ROIs; the old field beyond it is the source the march
  // continues from (its distances are still right there).
  const int reach = int(std::ceil(band + 1)) - 1;
  // One more voxel for the kept-voxel test at the region's edge, and the stencils' reach.
  const int gatherMargin = std::max(reach + 1, kStencilReach);
  std::vector<PreparedDab> prepared;
  for (const StrokeDab& d : dabs)
    // Every ROI (the memory's too) is the box of the stroke's one radius around its dab, clipped:
    // ordered by centre x, their x ranges never go back, so the dabs whose ROI holds an x are one
    // range of that order, which the window search's lanes rely on.
    prepared.push_back({d.center, d.weight, boxAround(d.center, {r, r, r}).intersect(vol.domain()), d.normal});

  // Dabs far apart (mirror images, a fast stroke) are worked on in separate grids: groups whose
  // gathered boxes do not meet the others' written regions are independent, so this is the
  // same as one grid over all of them.
  struct Group {
    Box box;  // bounding box of the group's ROIs
    std::vector<std::size_t> dabs;
  };
  std::vector<Group> groups;
  for (std::size_t i = 0; i < prepared.size(); ++i) {
    Group g{prepared[i].roi, {i}};
    for (bool merged = true; merged;) {
      merged = false;
      for (std::size_t k = 0; k < groups.size(); ++k) {
        if (groups[k].box.grown(reach + gatherMargin).intersect(g.box).empty()) continue;
        for (int a = 0; a < 3; ++a) {
          g.box.lo[a] = std::min(g.box.lo[a], groups[k].box.lo[a]);
          g.box.hi[a] = std::max(g.box.hi[a], groups[k].box.hi[a]);
        }
        g.dabs.insert(g.dabs.begin(), groups[k].dabs.begin(), groups[k].dabs.end());
        groups.erase(groups.begin() + std::ptrdiff_t(k));
        merged = true;
        break;
      }
    }
    std::sort(g.dabs.begin(), g.dabs.end());
    groups.push_back(std::move(g));
  }

  // Each group counts groupUnits of the caller's Progress (progress.hpp).
  Progress* const progress = Progress::current();
  const double groupUnits = 1.0 / double(groups.size());
  Edit total;
  auto applyGroup = [&](const Group& group) {
    const ProgressShare share{progress, groupUnits};
    std::vector<PreparedDab> mine, remembered;
    for (const std::size_t i : group.dabs) mine.push_back(prepared[i]);
    for (const StrokeDab& d : memory) {
      const Box roi = boxAround(d.center, {r, r, r}).intersect(vol.domain());
      if (!roi.intersect(group.box).empty()) remembered.push_back({d.center, d.weight, roi, d.normal});
    }
    const Box region = group.box.grown(reach).intersect(vol.domain());
    ToolScratch& scratch = toolScratch();
    DenseGrid& g = scratch.grid;
    g.gatherFrom(vol, group.box.grown(gatherMargin), share.part(kGatherShare), pool);
    level_set::gatherMask(vol, g);
    const std::vector<Box> rois = [&] {
      std::vector<Box> b;
      for (const PreparedDab& d : mine) b.push_back(d.roi);
      return b;
    }();
    // Only the band the application may move (its ROIs) or redistance (its reset boxes lie in
    // the ROIs grown by reach, and its march's seeds next to them): along a slanted stroke much
    // of the box lies further from every ROI (redistance.hpp, RedistanceOptions::band).
    std::vector<Box>& bandParts = scratch.bandParts;
    bandParts.clear();
    for (const Box& roi : rois) bandParts.push_back(roi.grown(reach + 1));
    scratch.band.collect(g, region.grown(1), bandParts, band, share.part(kCollectShare));
    const SweptWindow window(level_set::windowRadius(st), std::move(mine), std::move(remembered), height);
    // A height moves the surface up to |height| * the largest window: sub-steps of <= 1 vu.
    int steps = 1;
    Motion m = strokeMotion(st);
    if (height != 0) {
      // The first sub-step's list, made once: its largest window sets the sub-steps.
      listMoved(g, group.box, band, nullptr, &window, scratch.band, pool, share.part(0));
      double largest = 0;
      for (const double w : scratch.moved.window) largest = std::max(largest, w);
      const double most = std::fabs(height) * largest;
      if (!(most > 0)) {
        // Nothing to add here: the stroke already stands at its height (no redistance either).
        share.advance(1 - kGatherShare - kCollectShare);
        return;
      }
      steps = std::max(1, int(std::ceil(most - 1e-9)));
      m = advection(height / steps);
      withSpeeds(scratch.moved, m);
    }
    // An advection's moves left out of its box are kept per brick (DriftBook); a curvature
    // step's box holds every voxel it lists and leaves the drift as it was.
    DriftBook* const drift = m.kind == Motion::Kind::Advect ? &driftBook() : nullptr;
    if (drift) drift->start(vol, region);
    for (int step = 0; step < steps; ++step) {
      if (step == 0 && height != 0) {
        moveListed(g, m, pool, share.part(kEvolveShare / steps));
      } else {
        // The previous sub-step's march changed the band: list it again (counted in the first).
        if (step > 0) scratch.band.collect(g, region.grown(1), bandParts, band, share.part(0));
        evolve(g, group.box, band, m, &window, scratch.band, pool, share.part(kEvolveShare / steps));
      }
      // Evolve changed only the voxels it listed: inside the ROIs, and with a memory only where
      // this application's window exceeds the stroke's. Elsewhere the field is as it was, a
      // distance to a surface that did not move there: the ROIs are cut to the box of the
      // listed voxels (along a slanted stroke that box holds most of them; a stroke passing
      // over what it already added lists nothing, and nothing is redistanced).
      const float least = m.kind == Motion::Kind::Advect ? float(kLeastMove / m.substeps) : 0.0f;
      Box listed = listedBounds(g, scratch.moved, least);
      // No voxel moved by more than kLeastMove: the box of every listed voxel, as without it.
      // Applications that each move less (a faint dab, a stroke's faint end) would otherwise
      // never be redistanced, and the inner edge of the band, whose upwind differences read the
      // clamped -band and move too little, would drift: 200 add blobs of strength 0.005 at one
      // centre left it 0.99 vu from a whole-volume redistance (0.51 with the march each time).
      if (listed.empty() && least > 0) listed = listedBounds(g, scratch.moved);
      // Every listed voxel lies in a ROI, so those in `listed` are in the boxes below.
      if (drift) {
        drift->leaveOut(g, scratch.moved, listed);
        if (drift->take(listed, region, m.substeps)) drift->leaveOut(g, scratch.moved, listed);
      }
      scratch.resetBoxes.clear();
      scratch.normalizeBoxes.clear();
      for (const Box& roi : rois)
        if (const Box b = roi.intersect(listed); !b.empty()) {
          scratch.normalizeBoxes.push_back(b);
          scratch.resetBoxes.push_back(b.grown(reach).intersect(vol.domain()));
        }
      if (drift) drift->settle(scratch.normalizeBoxes, m.substeps);
      if (scratch.normalizeBoxes.empty()) {  // nothing moved: the field stands
        share.advance(kRedistanceShare / steps);
        continue;
      }
      RedistanceOptions options;
      options.resetBoxes = scratch.resetBoxes;
      options.normalizeBoxes = scratch.normalizeBoxes;
      options.movedBoxes = scratch.normalizeBoxes;
      // Normalizing the kept voxels moves a sharp crest outward by ~0.003 vu each time (measured
      // on a ridge of 4 vu at radius 8): harmless once per application, but a stroke with a
      // height passes over its crest again and again with little or nothing left to add. Its
      // kept values come from moves of at most 1 vu and are left as they are.
      if (height != 0) options.normalizeKept = false;
      options.direct = level_set::movesBandTogether(m);
      options.band = &scratch.band;
      options.progress = share.part(kRedistanceShare / steps);
      redistanceRegion(g, region, band, Outside::Source, options, pool);
    }
    share.check();  // the last check: nothing below stops part way
    total.append(vol.scatter(region, g.v.data(), g.box, pool), region);
    if (drift) drift->publish(vol);
    share.advance(1 - kGatherShare - kCollectShare - kEvolveShare - kRedistanceShare);
  };
  // A huge ROI's scratch is not worth keeping for the next dab (also when this one throws).
  struct TrimScratch {
    ~TrimScratch() {
      constexpr std::size_t kKeptScratchVoxels = std::size_t(1) << 22;
      if (toolScratch().grid.v.capacity() > kKeptScratchVoxels) toolScratch().grid = DenseGrid();
      if (toolScratch().other.capacity() > kKeptScratchVoxels) toolScratch().other = {};
      trimRedistanceScratch(kKeptScratchVoxels);
    }
  } trim;
  if (groups.empty()) return total;
  if (groups.size() == 1) {
    applyGroup(groups.front());  // a throw comes before its scatter: vol is untouched
    return total;
  }
  // A throw in a later group (cancelled, out of memory) puts back the groups already
  // scattered, so that a failed call changes nothing (a Volume copy shares its bricks).
  Volume before = vol;
  try {
    for (const Group& group : groups) applyGroup(group);
  } catch (...) {
    vol = std::move(before);
    throw;
  }
  return total;
}

}  // namespace marzipan
