// What the files of this folder share (README.md here maps them); nothing outside
// server/engine/level_set/ includes it (the engine's API is ../level_set.hpp). One application
// of a tool lists the band voxels it moves with their speeds (listing.cpp), then moves them by
// its Motion's sub-steps (moving.cpp, with the stepping kernels of kernels.hpp), all on one
// DenseGrid gathered around the region: grid indices and strides are the grid's (x fastest),
// points are volume coordinates, sign and units as in volume.hpp. The speed of each tool is
// tools.cpp's; a stroke's window (its dabs and memory) is swept_window.hpp's.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "engine/dense_grid.hpp"
#include "engine/geometry.hpp"
#include "engine/level_set.hpp"
#include "engine/progress.hpp"
#include "engine/redistance.hpp"
#include "engine/thread_pool.hpp"

namespace marzipan::level_set {

// How the band moves during one application.
struct Motion {
  enum class Kind { Advect, Curvature };
  Kind kind = Kind::Advect;
  double speed = 0;      // s: signed; advection speed in vu per unit time, or curvature scale
  double dt = 0;         // time step of one sub-step
  int substeps = 1;
  double curvatureLimit = std::numeric_limits<double>::infinity();
  // Advection towards a plane (flatten: speed > 0; contrast: < 0): each voxel's speed is
  // speed * W * -h (n . m), h = (q - planePoint) . m clamped to [-1, 1], m = planeNormal, at its
  // foot point q and normal n (listing.cpp, planeSpeed): |speed| <= 1 keeps the CFL bound.
  bool towardsPlane = false;
  Vec3 planePoint{}, planeNormal{};
};

// Advection: two sub-steps of dt |F| <= 0.5 vu (the CFL bound of the upwind scheme), so one
// application at speed 1 moves the surface 1 vu.
constexpr double kAdvectDt = 0.5;
constexpr int kAdvectSubsteps = 2;
// Curvature flow: explicit steps at the 7-point Laplacian's stability limit dt = 1/6.
constexpr double kCurvatureDt = 1.0 / 6.0;

inline Motion advection(double speed) {
  return {.kind = Motion::Kind::Advect, .speed = speed, .dt = kAdvectDt, .substeps = kAdvectSubsteps};
}

inline Motion curvatureFlow(double scale, double limit = std::numeric_limits<double>::infinity(), int substeps = 1) {
  return {.kind = Motion::Kind::Curvature, .speed = scale, .dt = kCurvatureDt, .substeps = substeps, .curvatureLimit = limit};
}

// Whether the redistance after one application of m may take the far voxels near the surface
// directly (redistance.hpp, RedistanceOptions::direct): m is an advection, whose speed every
// voxel reads at its foot point (or which is the same everywhere), so that the level sets near
// the surface move with it, and moves the surface by at most kMaxDirectMotion (speed times time;
// a plane's |h| is at most 1). A curvature step moves each level set by its own curvature.
inline bool movesBandTogether(const Motion& m) {
  return m.kind == Motion::Kind::Advect && std::fabs(m.speed) * m.dt * m.substeps <= kMaxDirectMotion;
}

// Ghost voxels a stencil reads beyond the evolved region (second-order ENO needs 2).
constexpr int kStencilReach = 2;

// The voxels evolve moves, in grid index order, cut into runs that follow each other along x
// (a band is mostly such runs): a run's voxels are read and written four at a time.
struct Run {
  std::uint32_t index;  // grid index of its first voxel
  std::uint32_t first;  // position of that voxel in the list
  std::uint32_t count;
};

// The voxels evolve moves, with their speeds.
// The per-voxel arrays are sized before they are filled (collectMoved writes them by index, a
// push_back per voxel cost as much again when the compiler did not inline it).
struct MovedVoxels {
  template <class T>
  using Array = std::vector<T, UninitializedAllocator<T>>;
  std::vector<Run> runs;
  Array<double> factor;  // curvature: dt * F per voxel, in list order
  Array<float> step;     // advection: float(dt * F) per voxel
  Array<double> window;  // listed without a motion: the window per voxel (withSpeeds)
  std::uint32_t count = 0;

  void clear() {
    runs.clear();
    factor.clear();
    step.clear();
    window.clear();
    count = 0;
  }
  // Appends the voxels of a later part of the grid (a run that goes on across the seam is one).
  void append(const MovedVoxels& o) {
    for (const Run& r : o.runs) {
      if (!runs.empty() && runs.back().index + runs.back().count == r.index) {
        runs.back().count += r.count;
      } else {
        runs.push_back({r.index, r.first + count, r.count});
      }
    }
    factor.insert(factor.end(), o.factor.begin(), o.factor.end());
    step.insert(step.end(), o.step.begin(), o.step.end());
    window.insert(window.end(), o.window.begin(), o.window.end());
    count += o.count;
  }
};

// Scratch reused by the tools on each thread: fresh grids and lists each application cost
// page faults (the kernel clearing pages) as large as the work itself.
struct ToolScratch {
  DenseGrid grid;
  BandVoxels band;
  MovedVoxels moved;
  std::vector<MovedVoxels> movedPieces;  // evolve's list, built in pieces on the pool
  std::vector<std::size_t> blocks;       // evolve's blocks of runs: the first run of each, then runs.size()
  std::vector<std::size_t> slices;       // on one thread, smoothing's runs by z-slice: the first of each, then runs.size()
  std::vector<float> next;               // a sub-step's values, in list order
  std::vector<float, UninitializedAllocator<float>> other;  // evolve's second copy of the grid
  std::vector<Box> resetBoxes, normalizeBoxes;
  std::vector<Box> bandParts;  // a stroke's band list's parts (stroke.cpp)
  // The mask weight (channels.hpp) of each voxel of `grid`, x fastest; empty when no brick the
  // grid covers is masked (gatherMask). listMoved stops each listed voxel of weight 255.
  std::vector<std::uint8_t> mask;
};
// One per thread (inline: a single object across the folder's files).
inline ToolScratch& toolScratch() {
  thread_local ToolScratch s;
  return s;
}

class SweptWindow;  // swept_window.hpp

// --- listing.cpp ---------------------------------------------------------------------------
// Lists the band voxels of `region` (|phi| < band) that m moves in toolScratch().moved, with
// their speeds: m scaled by the window at each voxel's foot point (none: W = 1); m null: with
// their windows instead (withSpeeds adds the speeds). `voxels` lists the band of a box holding
// region, or at least of its part around the windows' ROIs (BandVoxels::collect with parts: a
// voxel outside them has no window); region must lie kStencilReach inside the grid. Built in fixed pieces on the pool,
// joined in order: thread-count independent. progress: checked per piece.
void listMoved(const DenseGrid& g, const Box& region, float band, const Motion* m, const SweptWindow* window,
               const BandVoxels& voxels, ThreadPool& pool, const ProgressShare& progress);
// Sets toolScratch().mask for a grid gathered from vol over g.box (or empties it: nothing there
// is masked, the rule, which costs one look-up per brick). Every caller of listMoved or evolve
// calls it after gathering, so that a grid never reads the mask of another.
void gatherMask(const Volume& vol, const DenseGrid& g);
// Gives a list made without a motion the speeds listMoved would have given it under m.
void withSpeeds(MovedVoxels& moved, const Motion& m);

// --- moving.cpp ----------------------------------------------------------------------------
// Moves the voxels of toolScratch().moved by their speeds under m. Work is split in fixed
// pieces, each voxel computed alone: thread-count independent. progress: checked per piece,
// advanced per sub-step.
void moveListed(DenseGrid& g, const Motion& m, ThreadPool& pool, const ProgressShare& progress);
// The smallest box (volume coordinates) holding every voxel of the list whose advection step
// exceeds leastStep in magnitude (every listed voxel when leastStep is 0 or the list has no
// steps); empty for none.
Box listedBounds(const DenseGrid& g, const MovedVoxels& moved, float leastStep = 0);
// Moves the band voxels of `region` (|phi| < band) by m, scaled by the window at each voxel's
// foot point (none: W = 1): listMoved, then moveListed.
void evolve(DenseGrid& g, const Box& region, float band, const Motion& m, const SweptWindow* window,
            const BandVoxels& voxels, ThreadPool& pool, const ProgressShare& progress = {});

// --- tools.cpp -----------------------------------------------------------------------------
// The Motion of each brush tool at its settings' strength (throws EngineError "tool" for a value that is none).
Motion strokeMotion(const StrokeSettings& st);
// The radius at which a tool's window W falls to 0 (its ROI's is st.radius): crease's is narrower.
double windowRadius(const StrokeSettings& st);
// A stroke's height signed by its tool (> 0 raises, < 0 lowers), 0 without one.
double signedHeight(const StrokeSettings& st);
// Throws EngineError for a dab the tool's own rules refuse (inflate's and clay's normals).
void checkToolDab(const StrokeSettings& st, const StrokeDab& d);

}  // namespace marzipan::level_set
