// The warps' kept voxels (warp_passes.hpp, keptVoxels and grabTipFeet): the resampled voxels
// next to the zero set take their distances to the warped surface, the sources of the
// redistance, from the chain rule through the map or from foot points, and a grab's tip the
// distances to them after the march. Conventions are warp_passes.hpp's.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
// The scalar build (MARZIPAN_SCALAR_KERNELS) takes the lanes' mask without SSE2 (simd_width.hpp).
#include "engine/simd_width.hpp"
#if defined(MARZIPAN_SSE2)
#include <emmintrin.h>
#endif

#include "engine/level_set/warp_passes.hpp"

namespace marzipan::level_set::warp {

namespace {

// The changed voxels next to the zero set are the sources of the redistance. phi0(X(x)) is
// not a distance where the map stretches or squeezes, and central differences of the voxels
// cannot say by how much where it squeezes the band to a voxel or two: the gradient comes
// from the chain rule through the map instead, and the value is phi1 / |grad phi1|, bounded by
// the crossings on the voxel's edges as the redistance bounds its own normalisation.
//
// A grab (no plateau) shears its cone's sides: phi1 = phi0 o X is far from linear across a
// voxel there, and where the map squeezes the band the voxel reads +-band, flat. There each
// such voxel takes its distance to the zero set of phi1 itself, the continuous warped surface
// (X integrated at each point, phi0 trilinear): Newton steps along grad phi1 from the voxel
// find the foot point (phi1 / |grad phi1| is the first step's length); where phi1 is flat,
// the surface is found on the edge to the neighbour across it by bisection, and the foot point
// by Newton steps from the voxel's projection on the tangent plane there. On the tests'
// 3-radius grab the voxels next to the zero set were 0.1-0.3 vu off on those sides (exact
// 0.6-0.8): whole-volume gradient error 0.293 / 0.0116 against the exact field's 0.237 /
// 0.00175, 0.234 / 0.00223 with foot points (tests/engine/level_set/test_warp.cpp). Not for
// the path pinch, whose surface moved 0.24 vu.
//
// A snake hook's kept voxels take foot points around its tip only: within kTipFeetReach of
// the plateau's capsule (the ball, sunk into the tip, swept along the move), and only when
// the ball, the tip's radius, is at least kTipFeetBall. There phi1 / |grad phi1| left the
// tip sharper than the exact field's (the 200 vu tentacle's gradient error 0.187 above its
// foot, the exact tip's 0.036-0.050) and foot points hold it (0.077). Elsewhere they cost the
// path: on a thin tip (the ball 2.5 vu at radius 5) the tentacle cut inside a helix's curve
// 0.75 vu outside the path with foot points on the plateau alone (0.27 without), 1.28 vu
// with them on every kept voxel; and in the falloff's outer part (2 vu past the plateau, or
// everywhere) the radius 8 helix in moves of 2 vu left its path 0.31-0.32 vu (0.01 without).
// With the trilinear read (before 2026-11-30) exact distances at the tip moved its zero set
// inwards move after move (the 200 vu tentacle's path read 0.44 vu outside its surface).
// The reach is 1.4 vu (1 before 2026-11-30): on a straight tentacle (radius 8, ball 4) the
// tip's rim, 4 vu ahead of the anchor, was cut by the reach's edge: inside voxels with foot
// points next to outside ones 5.3-5.5 vu from the plateau's segment with phi1 / |grad phi1|,
// gradient error 0.147 there after 200 vu in moves of 2 vu (0.059 at 1.4; 0.12-0.16 at
// 1.25-1.35). And on the sides just behind the tip, which every move resamples while its
// support reaches them, phi1 / |grad phi1| moved the zero set out by about 0.002 vu a move
// (|grad phi1| read above 1 outside the convex side, below 1 inside, its central differences
// reaching the marched layer behind), and the redistance keeps those voxels: the sides' mean
// 0.009 in moves of 1 vu (the exact cylinder's 0.005-0.006). That same outward drift holds the
// helix's path (above) inside the clay: at 1.4 it read 0.13 vu outside, at 1.5 0.23 (with
// the young tentacle's wider support, snakeHookVelocity(), 0.010 vu inside at 1.4).
constexpr double kTipFeetReach = 1.4, kTipFeetBall = 3;
constexpr double kSlopeStep = 0.5;
// Newton steps to a foot point (at most: they stop once the next would be shorter than
// kFootConverged vu; a 3-radius grab's figures moved by under 1% with 5 or 8), the residual
// they must reach, and the bisections of a crossing (1/4096 of an edge).
// The second step's phi1 is not read when the steps' quadratic convergence puts the third
// below kFootSure of kFootConverged: a step of l after one of l0 predicts l^3 / l0^2 for the
// next (Newton's l_next ~ K l^2, K from the pair). The read was there to stop the steps, and in
// the benches' grabs and tentacles every such read did (40% of a grab's foot points, 75% of
// a tentacle tip's took the second step): a slope fewer. It is a prediction, not a proof: at 0.01, of
// the 142,766 skips in [warp]'s tests one would have taken a third step, of 1.3e-3 vu (predicted
// 2e-6), and its foot point lies that far from where it would (2026-11-30; the steps' own
// tolerance is kFootConverged). kFootSure was 0.01 until 2026-11-30 17:40 UTC,
// when a tentacle's tip still read again after 78 of its 249 foot points' second steps a move;
// at 0.1, 27 (1.2% fewer instructions a tentacle's move). Reading on after every second step (a
// probe), of the 32,415 skips at 0.1 in the tentacle bench 11 would have taken a third step,
// the longest 1.4e-3 vu, and of [warp]'s 189,134, 148, the longest 4.4e-3 vu ([warp]'s figures
// moved in their fifth or sixth digit: the 200 vu tentacle's gradient error 0.0697761 ->
// 0.0697744). At 1, 487 of the bench's and up to 0.011 vu. Not where the caller wants the
// slope at the foot point (grabTipFeet): the cubic read gives it with phi1, so the skip would
// save nothing there.
constexpr int kFootSteps = 3;
constexpr double kFootResidual = 0.05, kFootConverged = 1e-3, kFootSure = 0.1;
constexpr int kCrossingBisections = 12;
// A grab's tip, where the anchor lands (anchor + d), is the warped surface's most curved
// part, and the march from the kept voxels leaves the voxels a layer in from them short of
// their distance there: on the 3-radius grab's tip up to 0.1 vu above the exact inside, on the
// ridge between its sides, and the gradient error of the kept voxels next to them 0.122
// (the exact field's 0.098; tests/engine/level_set/test_warp.cpp). Within kGrabTipReach of it
// each voxel with a neighbour next to the zero set (but not itself one) takes, after the
// march, the distance to the nearest of the foot points that Newton steps find from each such
// neighbour, each moved to the voxel's projection on the tangent plane there when that foot
// point is nearer (0.087). Newton steps from the voxel itself may reach another side of the
// tip: a voxel there read 0.2 vu past its distance (0.097).
constexpr double kGrabTipReach = 3, kGrabTipFoot = 2.5;

// phi1 and its gradient at the voxel of index k (WarpedSurface::keptValues()).
struct Slope {
  std::size_t k;
  double phi;
  Vec3 g;
};
// A voxel next to the zero set, (x, y) of its slice and its index, and the resample's read of
// it through the flow (null where it did not: read through the lattice alone, or on a lattice
// node).
struct Candidate {
  int x, y;
  std::size_t k;
  const ExactRead* read;
};
// The kept pass's lists per slice, kept from one call to the next on the calling thread (as
// WarpScratch): allocated afresh, they were 1% of a tentacle's move.
struct KeptScratch {
  std::vector<std::vector<Candidate>> candidates;
  std::vector<std::vector<Slope>> exact;
  KeptVoxels kept;

  void start(std::size_t slices) {
    candidates.resize(slices), exact.resize(slices), kept.resize(slices);
    for (std::size_t i = 0; i < slices; ++i) candidates[i].clear(), exact[i].clear(), kept[i].clear();
  }
};
KeptScratch& keptScratch() {
  thread_local KeptScratch s;
  return s;
}

// The zero set of phi1 = phi0 o X, as the kept voxels next to it reach it: the slope of phi1
// through the map's Jacobian, Newton steps to a foot point, and the two passes that use them.
struct WarpedSurface : WarpPass {
  const bool footPoints;  // every kept voxel takes its foot point: a grab
  const double tipBall;   // a capsule's plateau (vu): a snake hook's tip
  const bool tipFeet;     // the kept voxels around the tip take foot points
  // The gradient of phi1 at `at`, DX^T grad phi0(X), grad phi0 by central differences of the
  // trilinear interpolant over +-kSlopeStep; and phi1 there when `phi` is given. `anywhere`: at
  // is not known to lie within the support grown by two voxels (a foot point). A grab's foot
  // points (cubicSlope) take instead the gradient of the cubic interpolant that phi1 reads next
  // to the zero set, from its own taps (Newton steps on phi1 with its own gradient), and fall
  // back to those central differences where it reads trilinearly: a fifth of the instructions
  // of a slope went to the central differences' six reads. Not a snake hook's tip: the cubic's
  // taps reach a voxel farther, into the clamped band across a thin tip, and a straight
  // tentacle's tip read gradient error 0.199 after 200 vu (0.075 with the central differences).
  const bool cubicSlope;

  explicit WarpedSurface(const WarpPass& w)
      : WarpPass(w), footPoints(isGrab(v)), tipBall(v.kind == Velocity::Kind::Capsule ? v.plateauBall : 0),
        tipFeet(tipBall >= kTipFeetBall), cubicSlope(footPoints) {}

  // Whether the kept voxel at p takes its foot point.
  bool feetAt(Vec3 p) const {
    if (footPoints) return true;
    if (!tipFeet) return false;
    const Vec3 r = p - v.anchor;
    const double t = v.segLength2 > 0 ? std::clamp(dot(r, v.seg) / v.segLength2, 0.0, 1.0) : 0.0;
    const Vec3 off = r - v.seg * t;
    return dot(off, off) <= (tipBall + kTipFeetReach) * (tipBall + kTipFeetReach);
  }
  // Whether the central differences at q read within the grid (the tests of
  // centralDifferences<false>, which then all pass, left out): a foot point's mostly do.
  bool stencilInGrid(Vec3 q) const {
    for (int a = 0; a < 3; ++a)
      if (!(q[a] - kSlopeStep - reads.lo[a] >= 0 && q[a] + kSlopeStep - reads.lo[a] < reads.size[a] - 1)) return false;
    return true;
  }
  Vec3 slopeOfWarped(Vec3 at, double* phi, bool anywhere) const {
    if (v.kind == Velocity::Kind::Capsule) {
      Vec3 along;
      const Vec3 q = v.capsuleInverse(at, steps, along);
      return slopeThrough(q, along, phi, anywhere);
    }
    double DX[3][3];
    const Vec3 q = v.inverseWithJacobian(at, steps, DX);
    return slopeThrough(q, DX, phi, anywhere);
  }
  // DX^T g, DX = I + segAxis along^T (a capsule's, Velocity::capsuleInverse()) or a matrix.
  Vec3 transposeTimes(const Vec3& along, Vec3 g) const { return g + along * dot(v.segAxis, g); }
  static Vec3 transposeTimes(const double (&DX)[3][3], Vec3 g) {
    Vec3 out;
    for (int a = 0; a < 3; ++a) out[a] = DX[0][a] * g.x + DX[1][a] * g.y + DX[2][a] * g.z;
    return out;
  }
  // slopeOfWarped() with X = q and its Jacobian DX at hand.
  template <class Jacobian>
  [[gnu::always_inline]] Vec3 slopeThrough(Vec3 q, const Jacobian& DX, double* phi, bool anywhere) const {
    Vec3 g0;
    double value;
    if (!(cubicSlope && anywhere)) {
      if (phi) *phi = readNearAnywhere(q);
      g0 = inGrid && (!anywhere || stencilInGrid(q)) ? centralDifferences<true>(reads, q, kSlopeStep, band)
                                                     : centralDifferences<false>(reads, q, kSlopeStep, band);
    } else if (tricubic<true>(reads, q, value, &g0)) {
      if (phi) *phi = value;
    } else {
      if (phi) *phi = trilinear(reads, q, band);
      g0 = centralDifferences<false>(reads, q, kSlopeStep, band);
    }
    return transposeTimes(DX, g0);
  }
  // Newton steps from `at` onto the zero set of phi1; false where phi1 is flat or they do not
  // converge. `slopeThere`, when given, gets the gradient of phi1 at the foot point found (the
  // last step's, nearerFoot()'s normal there); `start`, when given, holds phi1 and its gradient
  // at `at`.
  bool project(Vec3& at, Vec3* slopeThere = nullptr, const Slope* start = nullptr) const {
    double phi = start ? start->phi : 0;
    Vec3 g = start ? start->g : slopeOfWarped(at, &phi, true);
    double first = 0;  // the first step's length
    for (int step = 0; step < kFootSteps; ++step) {
      const double g2 = dot(g, g);
      if (!(g2 > 1e-12)) return false;
      if (step > 0 && phi * phi < kFootConverged * kFootConverged * g2) break;
      at = at - g * (phi / g2);
      const double taken = std::fabs(phi) / std::sqrt(g2);
      if (step == 0) first = taken;
      if (!slopeThere && step == 1 && taken * taken * taken < kFootSure * kFootConverged * first * first) return true;
      g = slopeOfWarped(at, &phi, true);
    }
    if (slopeThere) *slopeThere = g;
    return std::fabs(phi) < kFootResidual;
  }
  // The nearer to p of `onSurface`, a point of the zero set, and the foot point Newton steps
  // find from p's projection on the tangent plane there: the point alone lies off p's normal
  // where the surface curves. `slope`: the gradient of phi1 at onSurface, when known.
  Vec3 nearerFoot(Vec3 p, Vec3 onSurface, const Vec3* slope = nullptr) const {
    const Vec3 g = slope ? *slope : slopeOfWarped(onSurface, nullptr, true);
    if (dot(g, g) > 1e-12) {
      const Vec3 n = normalized(g);
      Vec3 onPlane = p - n * dot(p - onSurface, n);
      if (project(onPlane) && length(onPlane - p) <= length(onSurface - p)) return onPlane;
    }
    return onSurface;
  }

  // Calls f(x, y, k) for each voxel of slice z of `moved` within its row's moving run that lies
  // on the zero set or has a neighbour across it, in index order.
  template <class F>
  [[gnu::always_inline]] void acrossZero(const Box& moved, const Runs& runs, int z, F f) const {
    // Most voxels have no neighbour across the zero set: four of a row are tested at once, and
    // only the lanes that have one are looked at, the rest of the row one by one. The same
    // comparisons as one by one. (A row's flags in a vector by a loop the compiler vectorized,
    // then a loop over all of them, took 0.5% more instructions a tentacle's move: the rows are
    // short.)
    using Four = float __attribute__((vector_size(16)));
    using Lanes = std::int32_t __attribute__((vector_size(16)));
    const auto load = [](const float* at) {
      Four out;
      std::memcpy(&out, at, sizeof out);
      return out;
    };
    const Four zero{0, 0, 0, 0};
    const std::ptrdiff_t sx = std::ptrdiff_t(s.warped.sx), sxy = std::ptrdiff_t(s.warped.sxy);
    for (int y = moved.lo.y; y < moved.hi.y; ++y) {
      const auto [r0, r1] = runs.at(y, z);
      const int x0 = std::max(r0, moved.lo.x), x1 = std::min(r1, moved.hi.x);
      if (x1 <= x0) continue;
      const std::size_t k0 = s.warped.index({x0, y, z});
      const float* w = s.warped.v.data() + k0;
      const std::ptrdiff_t n = x1 - x0;
      std::ptrdiff_t x = 0;
      for (; x + 4 <= n; x += 4) {
        const float* c = w + x;
        const Four here = load(c);
        const Lanes neg = here < zero;
        const Lanes across = (here == zero) | ((load(c - 1) < zero) ^ neg) | ((load(c + 1) < zero) ^ neg) |
                             ((load(c - sx) < zero) ^ neg) | ((load(c + sx) < zero) ^ neg) | ((load(c - sxy) < zero) ^ neg) |
                             ((load(c + sxy) < zero) ^ neg);
#if defined(MARZIPAN_SSE2)
        unsigned bits = unsigned(_mm_movemask_ps(__m128(across)));
#else
        unsigned bits = 0;
        for (int l = 0; l < 4; ++l) bits |= unsigned(across[l] != 0) << l;
#endif
        for (; bits; bits &= bits - 1) {
          const int l = std::countr_zero(bits);
          f(x0 + int(x) + l, y, k0 + std::size_t(x + l));
        }
      }
      for (; x < n; ++x) {
        const bool neg = w[x] < 0;
        if ((w[x] == 0) | ((w[x - 1] < 0) != neg) | ((w[x + 1] < 0) != neg) | ((w[x - sx] < 0) != neg) |
            ((w[x + sx] < 0) != neg) | ((w[x - sxy] < 0) != neg) | ((w[x + sxy] < 0) != neg))
          f(x0 + int(x), y, k0 + std::size_t(x));
      }
    }
  }

  // The kept voxels within moved (keptVoxels()).
  const KeptVoxels& keptValues(Box& moved, const Runs& runs, ThreadPool& pool, const ProgressShare& progress) const {
    // A voxel squeezed next to the zero set may read +-band, its old value, and still be one of
    // them: every voxel the flow moves within a voxel of the changed ones is looked at.
    if (!moved.empty()) moved = moved.grown(1).intersect(work);
    const std::size_t slices = std::size_t(std::max(0, moved.size().z));
    // The voxels next to the zero set, and where the resample read them through the lattice alone
    // (|value| >= exactNear, WarpPass), their values through the flow at the voxel with the slope
    // there for the pass below, written before it: the bounds of the crossings read them as
    // their neighbours' values. Every such read is decided on the values the resample left. The
    // others' slopes come from the resample's reads (ExactRead), but for a voxel on a lattice
    // node (the node's flow, without the Jacobian).
    KeptScratch& scratch = keptScratch();
    scratch.start(slices);
    auto& candidates = scratch.candidates;
    auto& exact = scratch.exact;
    if (exactSlopes) {
      pool.parallelFor(slices, [&](std::size_t i) {
        progress.check();
        const int z = moved.lo.z + int(i);
        // The resample's reads through the flow in this slice (WarpPass::exactSlopes), in index
        // order as the candidates.
        const std::vector<ExactRead>& flowReads = s.exactReads[std::size_t(z - work.lo.z)];
        std::size_t r = 0;
        // slopeOfWarped() two voxels at a time, X integrated for both at once
        // (Velocity::capsuleInverse2(), each with its own bits, as the resample's reads): a
        // Slope waits, its voxel at waitingAt, for the next or for the slice's end.
        bool waiting = false;
        Vec3 waitingAt;
        acrossZero(moved, runs, z, [&](int x, int y, std::size_t k) {
          while (r < flowReads.size() && flowReads[r].k < k) ++r;
          const ExactRead* read = r < flowReads.size() && flowReads[r].k == k ? &flowReads[r] : nullptr;
          candidates[i].push_back({x, y, k, read});
          if (read || !(std::fabs(s.warped.v[k]) >= exactNear)) return;
          const Vec3 p{double(x), double(y), double(z)};
          if (!waiting) {
            exact[i].push_back({k, 0, {}});
            waitingAt = p, waiting = true;
            return;
          }
          Slope& before = exact[i].back();
          const Vec3 at[2] = {waitingAt, p};
          Vec3 to[2], along[2];
          v.capsuleInverse2(at, steps, to, along);
          before.g = slopeThrough(to[0], along[0], &before.phi, true);
          Slope e{k, 0, {}};
          e.g = slopeThrough(to[1], along[1], &e.phi, true);
          exact[i].push_back(e);
          waiting = false;
        });
        if (waiting) {
          Slope& last = exact[i].back();
          last.g = slopeOfWarped(waitingAt, &last.phi, true);
        }
      });
      for (const std::vector<Slope>& slice : exact)
        for (const Slope& e : slice) s.warped.v[e.k] = float(e.phi);
    }
    KeptVoxels& kept = scratch.kept;
    pool.parallelFor(slices, [&](std::size_t i) {
      progress.check();
      const int z = moved.lo.z + int(i);
      auto& out = kept[i];
      std::size_t next = 0;  // exact[i]'s first not yet passed
      const auto keep = [&](int x, int y, std::size_t k, const ExactRead* read) __attribute__((always_inline)) {
        const Slope* known = next < exact[i].size() && exact[i][next].k == k ? &exact[i][next++] : nullptr;
        const float value = s.warped.v[k];
        const bool neg = value < 0;
        const Vec3 p{double(x), double(y), double(z)};
        double bound = 1;
        for (int a = 0; a < 3; ++a)
          for (const std::size_t j : {k - s.warped.stride(a), k + s.warped.stride(a)}) {
            const float nb = s.warped.v[j];
            if ((nb < 0) != neg) bound = std::min(bound, double(value) / (double(value) - nb));
          }
        if (bound == 1 && value != 0) return;  // not next to the zero set
        Slope fromRead;
        if (read) {
          fromRead = {k, read->phi, slopeThrough(read->q, read->along, nullptr, false)};
          known = &fromRead;
        }
        const bool feet = feetAt(p);
        double mag;
        if (!feet) {
          const double len = length(known ? known->g : slopeOfWarped(p, nullptr, false));
          mag = len > 1e-6 ? std::min(std::fabs(double(value)) / len, bound) : bound;
        } else {
          // The surface crosses an edge of the voxel: its foot point lies within a voxel (one
          // farther is another part of the surface, reached along a curving gradient).
          Vec3 foot = p;
          if (!(std::fabs(value) < band && project(foot, nullptr, known) && length(foot - p) <= 1)) {
            // The neighbour across whose edge the linear crossing is nearest (at `bound`).
            Vec3 other = p;
            for (int a = 0; a < 3; ++a)
              for (const int side : {-1, 1}) {
                const float nb = s.warped.v[std::size_t(std::ptrdiff_t(k) + side * std::ptrdiff_t(s.warped.stride(a)))];
                if ((nb < 0) != neg && double(value) / (double(value) - nb) == bound) other = p, other[a] += side;
              }
            double lo = 0, hi = 1;
            for (int halving = 0; halving < kCrossingBisections; ++halving) {
              const double mid = 0.5 * (lo + hi);
              ((readNearAnywhere(v.flow(p + (other - p) * mid, steps, -1)) < 0) == neg ? lo : hi) = mid;
            }
            foot = nearerFoot(p, p + (other - p) * (0.5 * (lo + hi)));
          }
          mag = length(foot - p);
        }
        out.emplace_back(k, float(std::copysign(mag, double(value))));
      };
      if (exactSlopes) {
        for (const auto& [x, y, k, read] : candidates[i]) keep(x, y, k, read);
      } else {
        acrossZero(moved, runs, z, [&](int x, int y, std::size_t k) { keep(x, y, k, nullptr); });
      }
    });
    return kept;
  }

  // grabTipFeet().
  void grabTip(const Box& within) const {
    const Vec3 tip = v.anchor + v.seg;
    Box b;
    for (int a = 0; a < 3; ++a) b.lo[a] = int(std::floor(tip[a] - kGrabTipReach)), b.hi[a] = int(std::ceil(tip[a] + kGrabTipReach)) + 1;
    b = b.intersect(within).intersect(s.warped.box.grown(-2));
    const auto nextToZero = [&](std::size_t k) {
      const bool neg = s.warped.v[k] < 0;
      bool across = s.warped.v[k] == 0;
      for (int a = 0; a < 3; ++a)
        for (const std::size_t j : {k - s.warped.stride(a), k + s.warped.stride(a)}) across = across || ((s.warped.v[j] < 0) != neg);
      return across;
    };
    // The foot point Newton steps find from a neighbour and the slope there, found once for
    // the up to six voxels that ask for it: per voxel of b grown by one, unknown until asked.
    struct NeighbourFoot {
      enum class State : std::uint8_t { Unknown, None, Found } state = State::Unknown;
      Vec3 foot, slope;
    };
    const Box around = b.grown(1);
    const Int3 aroundSize = around.size();
    std::vector<NeighbourFoot> neighbourFeet(around.empty() ? 0 : std::size_t(around.voxels()));
    const auto neighbourFoot = [&](Int3 c) -> const NeighbourFoot& {
      NeighbourFoot& f = neighbourFeet[std::size_t(c.x - around.lo.x) +
                                       std::size_t(aroundSize.x) * (std::size_t(c.y - around.lo.y) + std::size_t(aroundSize.y) * std::size_t(c.z - around.lo.z))];
      if (f.state == NeighbourFoot::State::Unknown) {
        f.foot = {double(c.x), double(c.y), double(c.z)};
        f.state = project(f.foot, &f.slope) ? NeighbourFoot::State::Found : NeighbourFoot::State::None;
      }
      return f;
    };
    std::vector<std::pair<std::size_t, float>> feet;
    for (int z = b.lo.z; z < b.hi.z; ++z)
      for (int y = b.lo.y; y < b.hi.y; ++y)
        for (int x = b.lo.x; x < b.hi.x; ++x) {
          const Vec3 p{double(x), double(y), double(z)};
          if (length(p - tip) > kGrabTipReach) continue;
          const std::size_t k = s.warped.index({x, y, z});
          if (nextToZero(k)) continue;
          double nearest = kGrabTipFoot;
          bool found = false;
          for (int a = 0; a < 3; ++a)
            for (const int side : {-1, 1}) {
              const std::size_t j = std::size_t(std::ptrdiff_t(k) + side * std::ptrdiff_t(s.warped.stride(a)));
              if (!nextToZero(j)) continue;
              Int3 c{x, y, z};
              c[a] += side;
              const NeighbourFoot& onSurface = neighbourFoot(c);
              if (onSurface.state != NeighbourFoot::State::Found) continue;
              const Vec3 foot = nearerFoot(p, onSurface.foot, &onSurface.slope);
              if (length(foot - p) < nearest) nearest = length(foot - p), found = true;
            }
          if (found) feet.emplace_back(k, float(std::copysign(nearest, double(s.warped.v[k]))));
        }
    for (const auto& [k, value] : feet) s.warped.v[k] = value;
  }
};

}  // namespace

const KeptVoxels& keptVoxels(const WarpPass& w, Box& moved, const Runs& runs, ThreadPool& pool, const ProgressShare& progress) {
  return WarpedSurface(w).keptValues(moved, runs, pool, progress);
}

void grabTipFeet(const WarpPass& w, const Box& within) { WarpedSurface(w).grabTip(within); }

}  // namespace marzipan::level_set::warp
