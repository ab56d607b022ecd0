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
#include <limits>
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
using level_set::PreparedDab;
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
    scratch.band.collect(g, region.grown(1), band, share.part(kCollectShare));
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
    for (int step = 0; step < steps; ++step) {
      if (step == 0 && height != 0) {
        moveListed(g, m, pool, share.part(kEvolveShare / steps));
      } else {
        // The previous sub-step's march changed the band: list it again (counted in the first).
        if (step > 0) scratch.band.collect(g, region.grown(1), band, share.part(0));
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
      scratch.resetBoxes.clear();
      scratch.normalizeBoxes.clear();
      for (const Box& roi : rois)
        if (const Box b = roi.intersect(listed); !b.empty()) {
          scratch.normalizeBoxes.push_back(b);
          scratch.resetBoxes.push_back(b.grown(reach).intersect(vol.domain()));
        }
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
