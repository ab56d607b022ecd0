#include "level_set.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <memory>
#include <thread>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// AVX2 kernels beside the SSE2 ones (simd_width.hpp).
#include "simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "chunked_pass.hpp"
#include "dense_grid.hpp"
#include "errors.hpp"
#include "progress.hpp"
#include "redistance.hpp"
#include "stencil.hpp"
#include "thread_pool.hpp"

namespace marzipan {

namespace {

// How the band moves during one application.
struct Motion {
  enum class Kind { Advect, Curvature };
  Kind kind = Kind::Advect;
  double speed = 0;      // s: signed; advection speed in vu per unit time, or curvature scale
  double dt = 0;         // time step of one sub-step
  int substeps = 1;
  double curvatureLimit = std::numeric_limits<double>::infinity();
};

// Advection: two sub-steps of dt |F| <= 0.5 vu (the CFL bound of the upwind scheme), so one
// application at speed 1 moves the surface 1 vu.
constexpr double kAdvectDt = 0.5;
constexpr int kAdvectSubsteps = 2;
// Curvature flow: explicit steps at the 7-point Laplacian's stability limit dt = 1/6.
constexpr double kCurvatureDt = 1.0 / 6.0;
// The smoothing brush takes this many such steps per application: one step moves a groove of
// radius 4 by a few hundredths of a vu, invisible, so a sculptor needed many passes
// (tests/engine/test_level_set.cpp, "one smoothing application ... fills a groove").
constexpr int kSmoothSubsteps = 32;
// Sharpening runs the flow backwards; |L| <= 1 per voxel keeps noise from blowing up.
constexpr double kSharpenCurvatureLimit = 1.0;

Motion advection(double speed) {
  return {.kind = Motion::Kind::Advect, .speed = speed, .dt = kAdvectDt, .substeps = kAdvectSubsteps};
}

Motion curvatureFlow(double scale, double limit = std::numeric_limits<double>::infinity(), int substeps = 1) {
  return {.kind = Motion::Kind::Curvature, .speed = scale, .dt = kCurvatureDt, .substeps = substeps, .curvatureLimit = limit};
}

// Ghost voxels a stencil reads beyond the evolved region (second-order ENO needs 2).
constexpr int kStencilReach = 2;

// A local tool checks the caller's Progress (progress.hpp) every so many band voxels, and
// counts one unit per call: these shares of it per group of dabs, the march the rest.
constexpr std::size_t kVoxelsPerCheck = std::size_t(1) << 16;
constexpr double kGatherShare = 0.1, kCollectShare = 0.05, kEvolveShare = 0.15, kRedistanceShare = 0.6;

double window1(double t) {
  if (t >= 1) return 0;
  const double u = 1 - t * t;
  return u * u;
}

// Godunov |grad phi| with second-order ENO one-sided differences, upwind for speed sign.
// Single precision: the field is stored in floats and the differences are of order 1. The
// scalar form below is the definition; with SSE2, advectionRuns does its float operations in
// its order in four lanes at once (four voxels along x), so the same bits.
#if defined(MARZIPAN_SSE2)
__m128 minmod4(__m128 a, __m128 b) {
  const __m128 abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 aSmaller = _mm_cmplt_ps(_mm_and_ps(a, abs), _mm_and_ps(b, abs));
  const __m128 smaller = _mm_or_ps(_mm_and_ps(aSmaller, a), _mm_andnot_ps(aSmaller, b));
  return _mm_andnot_ps(_mm_cmple_ps(_mm_mul_ps(a, b), _mm_setzero_ps()), smaller);
}
#else
float minmod(float a, float b) {
  if (a * b <= 0) return 0;
  return std::fabs(a) < std::fabs(b) ? a : b;
}

float upwindGradient(const float* v, std::size_t i, const std::size_t stride[3], bool outward) {
  float g2 = 0;
  for (int a = 0; a < 3; ++a) {
    const std::size_t s = stride[a];
    const float vm2 = v[i - 2 * s], vm1 = v[i - s], v0 = v[i], vp1 = v[i + s], vp2 = v[i + 2 * s];
    const float dm = (v0 - vm1) + 0.5f * minmod(v0 - 2 * vm1 + vm2, vp1 - 2 * v0 + vm1);
    const float dp = (vp1 - v0) - 0.5f * minmod(vp1 - 2 * v0 + vm1, vp2 - 2 * vp1 + v0);
    const float a1 = outward ? std::max(dm, 0.0f) : std::min(dm, 0.0f);
    const float a2 = outward ? std::min(dp, 0.0f) : std::max(dp, 0.0f);
    g2 += a1 * a1 + a2 * a2;
  }
  return std::sqrt(g2);
}
#endif

// A brush stroke's dab, prepared: its ROI (clipped to the domain) and window.
struct PreparedDab {
  Vec3 center;
  double weight;
  Box roi;
  Vec3 normal;  // StrokeDab::normal
};

// The speed scale of a swept brush at a band voxel p with foot point q and unit normal n: the
// largest window weight * W(q) over the message's dabs whose ROI holds p, less the largest the
// stroke already applied there (memory), or 0. With one dab and no memory it is W(q) itself.
// anchor: 0, or a stroke's signed height (+H add, -H remove): each dab's W is then read at q
// moved back along the dab's normal (else n) by (q - c).normal clamped between 0 and the anchor,
// and scaled by normal . n (level_set.hpp, strokes).
#if defined(MARZIPAN_SSE2)
// Dabs as lanes, one array per quantity, in a given order, followed by kPad dabs that are never
// counted (a lane at or past its list's end is masked by its position), so that two or four
// lanes may start at any dab and load in bounds.
struct LaneArrays {
  static constexpr std::size_t kPad = 3;
  std::vector<double> center[3], normal[3], weight, lo, hi;  // lo, hi: the ROI's x range [lo, hi)
  // dabs[row[k]] (row null: dabs[k]) in lane k, k < count; the normals only with a height.
  void fill(const std::vector<PreparedDab>& dabs, const std::uint32_t* row, std::size_t count, bool normals) {
    for (auto* v : {&center[0], &center[1], &center[2], &weight, &lo, &hi}) v->resize(count + kPad);
    if (normals)
      for (auto& v : normal) v.resize(count + kPad);
    for (std::size_t k = 0; k < count; ++k) {
      const PreparedDab& d = dabs[row ? row[k] : k];
      for (int a = 0; a < 3; ++a) center[a][k] = d.center[a];
      weight[k] = d.weight;
      lo[k] = d.roi.lo.x;
      hi[k] = d.roi.hi.x;
      if (normals)
        for (int a = 0; a < 3; ++a) normal[a][k] = d.normal[a];
    }
    for (std::size_t k = count; k < count + kPad; ++k) {
      for (int a = 0; a < 3; ++a) center[a][k] = 0;
      weight[k] = lo[k] = hi[k] = 0;
      if (normals)
        for (int a = 0; a < 3; ++a) normal[a][k] = 0;
    }
  }
};
#endif

class SweptWindow {
 public:
  SweptWindow(double radius, std::vector<PreparedDab> dabs, std::vector<PreparedDab> memory, double anchor = 0)
      : inverseRadius_(1.0 / radius), anchor_(anchor), dabs_(std::move(dabs)), memory_(std::move(memory)) {
    // The memory newest first: the voxels this message moves lie under its dabs, next to the
    // last ones the stroke applied, so the scalar search below mostly ends after a few (the
    // lanes re-sort it by x and start from the dab that reached the window at the voxel before).
    std::reverse(memory_.begin(), memory_.end());
#if defined(MARZIPAN_SSE2)
    // SSE2 searches the dabs whose ROI holds the voxel in full: ordered by their centres' x,
    // their ROIs' x ranges come in order too (Cursor::Lanes). With a height, only when every
    // dab has its own normal (a dab without one reads the voxel's: the scalar search).
    lanes_ = true;
    if (anchor_ != 0)
      for (const auto* v : {&dabs_, &memory_})
        for (const PreparedDab& d : *v) lanes_ = lanes_ && d.normal != Vec3{};
    if (lanes_) {
      for (auto* v : {&dabs_, &memory_})
        std::stable_sort(v->begin(), v->end(),
                         [](const PreparedDab& a, const PreparedDab& b) { return a.center.x < b.center.x; });
      allDabs_.fill(dabs_, nullptr, dabs_.size(), anchor_ != 0);
      allMemory_.fill(memory_, nullptr, memory_.size(), anchor_ != 0);
    }
#endif
    for (int k = 0; k < 2; ++k) {
      const std::vector<PreparedDab>& v = k == 0 ? dabs_ : memory_;
      for (auto* order : {&byLoY_[k], &byHiY_[k]}) {
        order->resize(v.size());
        for (std::size_t i = 0; i < v.size(); ++i) (*order)[i] = std::uint32_t(i);
      }
      std::sort(byLoY_[k].begin(), byLoY_[k].end(),
                [&](std::uint32_t a, std::uint32_t b) { return v[a].roi.lo.y < v[b].roi.lo.y; });
      std::sort(byHiY_[k].begin(), byHiY_[k].end(),
                [&](std::uint32_t a, std::uint32_t b) { return v[a].roi.hi.y < v[b].roi.hi.y; });
    }
  }

  // A caller's walk over the voxels of a grid in index order (rows along x): the dabs whose ROI
  // holds the current row, listed once per row, and where the search starts, the dabs that
  // were the strongest at the voxel before. Once the strongest is known, the others stop at
  // their first factors. Neither changes the result: the same dabs are searched, and the
  // largest window does not depend on the order. (With SSE2, and with a height only when every
  // dab has its own normal, the message's dabs are searched two at a time in full instead, four
  // with AVX2: the early stops' branches cost more than they save; the memory's stop at the
  // first dab that reaches the message's window.)
  struct Cursor {
    int y = std::numeric_limits<int>::min(), z = 0;
    std::vector<std::uint32_t> dabs, memory;  // indices into dabs_ / memory_, in their order
    std::size_t dab = 0, remembered = 0;      // positions in those of the last strongest
    int xLo = 0, xHi = 0;                     // the hull along x of the row's dab ROIs
    bool listed = false;                      // whether the lists above are a row's
    int until = 0;                            // the lists hold for rows of slice z up to this y
    std::vector<std::uint32_t> rowDabs, rowMemory;  // scratch: the next row's lists
    int sliceZ = std::numeric_limits<int>::min();    // the slice whose dabs the next lists hold
    // The dabs (the memory) whose ROI holds slice sliceZ, and of those the ones whose ROI holds
    // the row last listed, kept as the rows go up: a row's list is read off a set that changes
    // only where a ROI begins or ends, rather than testing every dab of the slice (along a
    // stroke a ROI begins or ends at nearly every row, and those tests took a third of newRow's
    // time, newRow an eighth of the listing's).
    struct RowSet {
      struct Event {
        int y;  // where the dab's ROI begins (enter) or ends (leave) along y
        std::uint32_t dab;
      };
      std::vector<Event> enter, leave;          // the slice's dabs by their ROI's lo.y, by its hi.y
      std::size_t entered = 0, left = 0;        // how many of each lie at or below the row
      std::vector<std::uint64_t> holds;         // bit d: dab d's ROI holds the row
      int y = std::numeric_limits<int>::min();  // the row
    } sliceDabs, sliceMemory;
#if defined(MARZIPAN_SSE2)
    // The row's dabs and memory as lanes (lanes_), in the order of their centres' x
    // (boxAround's bounds and the domain's clipping only grow with the centre, and the dabs of a
    // stroke share its radius, so their ROIs' x ranges [lo, hi) are in order too; dabs with radii
    // of their own would break this. The dabs whose ROI holds a voxel of the row are then one
    // range of them, [first, last), which moves along the row). A row's dabs that are
    // consecutive in that order (the rule along a stroke) are read where all the dabs are
    // (SweptWindow's arrays), others from arrays of the row's own. A voxel's range is searched two
    // (SSE2) or four (AVX2) at a time (search); lanes past `last` are masked.
    struct Lanes {
      const LaneArrays* arrays = nullptr;
      std::size_t begin = 0, end = 0;   // the row's dabs: lanes [begin, end) of arrays
      std::size_t first = 0, last = 0;  // those whose ROI holds the voxel's x
      LaneArrays own;                   // the row's dabs when they are not consecutive
      // The lanes of the row's dabs `row` (indices into dabs, increasing), `all` holding all of them.
      void list(const std::vector<PreparedDab>& dabs, const std::vector<std::uint32_t>& row, const LaneArrays& all,
                bool normals) {
        if (row.empty() || row.back() - row.front() + 1 == row.size()) {
          arrays = &all;
          begin = row.empty() ? 0 : row.front();
          end = begin + row.size();
        } else {
          own.fill(dabs, row.data(), row.size(), normals);
          arrays = &own;
          begin = 0;
          end = row.size();
        }
        first = last = begin;
      }
      // Moves [first, last) to the dabs whose ROI holds x; x only grows along a row. Inlined:
      // called from AVX2 code with the upper halves of its registers in use, a call of its own
      // (legacy SSE code) took 10% of stroke_drag's CPU on a Zen 3 (the SSE-AVX mix).
      [[gnu::always_inline]] void at(int x) {
        const double xd = x;
        const double* lo = arrays->lo.data();
        const double* hi = arrays->hi.data();
        while (first < end && hi[first] <= xd) ++first;
        if (last < first) last = first;
        while (last < end && lo[last] <= xd) ++last;
      }
      // The dab (index into the list's dabs) in lane j, one of the row's `row`.
      std::uint32_t dab(const std::vector<std::uint32_t>& row, std::size_t j) const { return row[j - begin]; }
      // The lane of dab d (an index into the list's dabs) if it is one of the row's `row`, else kNoLane.
      std::size_t lane(const std::vector<std::uint32_t>& row, std::size_t d) const {
        const auto it = std::lower_bound(row.begin(), row.end(), d);
        return it != row.end() && *it == d ? begin + std::size_t(it - row.begin()) : kNoLane;
      }
    } dabLanes, memoryLanes;
    static constexpr std::size_t kNoLane = std::numeric_limits<std::size_t>::max();
    // The memory dab (index into memory_) last found to reach the message's
    // window at a voxel: tried first at the next (behind a stroke's new dabs, the memory
    // mostly reaches them, and one dab near the voxel shows it).
    std::size_t reached = std::numeric_limits<std::size_t>::max();
    std::size_t reachedLane = kNoLane;  // its lane in memoryLanes, if it is one of the row's
#endif
  };

  // False only where no dab's ROI holds p (the scale is 0 there whatever the foot point, so a
  // caller need not compute it).
  bool reaches(Int3 p, Cursor& c) const {
    row(p, c);
    return p.x >= c.xLo && p.x < c.xHi;
  }

  // A brush (one dab, no memory, no height): its dab, whose window alone is the scale, else null.
  const PreparedDab* brush() const {
    return dabs_.size() == 1 && memory_.empty() && anchor_ == 0 ? &dabs_[0] : nullptr;
  }
  double inverseRadius() const { return inverseRadius_; }

  // The scale, or a value <= 0 where the memory reaches this message's window (how far it
  // exceeds it does not matter: the voxel does not move).
  double at(Int3 p, Vec3 q, Vec3 n, Cursor& c) const {
    if (dabs_.size() == 1 && memory_.empty()) {  // a brush: nothing to search
      const double w = dabs_[0].roi.contains(p) ? window(dabs_[0], q, n, 0) : 0;
      return w > 0 ? w : 0;
    }
    return search(p, q, n, c);
  }

 private:
  // Positions c at p's row (called twice per voxel: the test inline, the change not).
  [[gnu::always_inline]] void row(Int3 p, Cursor& c) const {
    if (p.y != c.y || p.z != c.z) newRow(p, c);
  }

  [[gnu::noinline]] void newRow(Int3 p, Cursor& c) const {
    const bool stays = c.listed && p.z == c.z && p.y > c.y && p.y < c.until;
    c.y = p.y;
    c.z = p.z;
#if defined(MARZIPAN_SSE2)
    c.dabLanes.first = c.dabLanes.last = c.dabLanes.begin;
    c.memoryLanes.first = c.memoryLanes.last = c.memoryLanes.begin;
#endif
    if (stays) return;  // no ROI begins or ends between the listed row and this one
    // Most rows hold the dabs of the row before: the lists stay.
    if (p.z != c.sliceZ) {  // a row's dabs are searched among its slice's
      c.sliceZ = p.z;
      sliceDabs(dabs_, byLoY_[0], byHiY_[0], p.z, c.sliceDabs);
      sliceDabs(memory_, byLoY_[1], byHiY_[1], p.z, c.sliceMemory);
    }
    c.until = std::numeric_limits<int>::max();
    rowDabs(c.sliceDabs, p.y, c.rowDabs, c.until);
    rowDabs(c.sliceMemory, p.y, c.rowMemory, c.until);
    if (c.rowDabs == c.dabs && c.rowMemory == c.memory && c.listed) return;
    c.listed = true;
    std::swap(c.rowDabs, c.dabs);
    std::swap(c.rowMemory, c.memory);
    c.dab = c.remembered = 0;
    c.xLo = std::numeric_limits<int>::max();
    c.xHi = std::numeric_limits<int>::min();
    for (const std::uint32_t i : c.dabs) {
      c.xLo = std::min(c.xLo, dabs_[i].roi.lo.x);
      c.xHi = std::max(c.xHi, dabs_[i].roi.hi.x);
    }
#if defined(MARZIPAN_SSE2)
    if (lanes_) {
      c.dabLanes.list(dabs_, c.dabs, allDabs_, anchor_ != 0);
      c.memoryLanes.list(memory_, c.memory, allMemory_, anchor_ != 0);
      c.reachedLane = c.memoryLanes.lane(c.memory, c.reached);
    }
#endif
  }

#if defined(MARZIPAN_SSE2)
  // The windows of the lanes' dabs j and j + 1 at foot point q (qa, normal na), 0 for a lane at
  // or past l.last (masked by its position, whatever its ROI: a dab past the range whose ROI
  // holds the voxel's x, one of another row's in the shared arrays, or the pad): window's operations
  // in its order in each lane (the three factors multiplied out even after one is 0, which
  // leaves 0, and past the point where window would stop, which only lowers a value that is not
  // the largest; the clamp's zero may differ in sign, which moves no factor), so the largest is
  // the same bits.
  template <bool kAnchored>
  [[gnu::always_inline]] __m128d pairWindows(const Cursor::Lanes& l, std::size_t j, const __m128d qa[3],
                                             const __m128d na[3]) const {
    const LaneArrays& arr = *l.arrays;
    const __m128d one = _mm_set1_pd(1.0), zero = _mm_setzero_pd(), invR = _mm_set1_pd(inverseRadius_);
    const __m128d abs = _mm_castsi128_pd(_mm_set1_epi64x(0x7fffffffffffffff));
    __m128d w = _mm_loadu_pd(arr.weight.data() + j);
    if constexpr (!kAnchored) {
      for (int a = 0; a < 3; ++a) {
        const __m128d t = _mm_mul_pd(_mm_and_pd(_mm_sub_pd(qa[a], _mm_loadu_pd(arr.center[a].data() + j)), abs), invR);
        const __m128d u = _mm_sub_pd(one, _mm_mul_pd(t, t));
        w = _mm_mul_pd(w, _mm_andnot_pd(_mm_cmpge_pd(t, one), _mm_mul_pd(u, u)));
      }
    } else {
      const __m128d c[3] = {_mm_loadu_pd(arr.center[0].data() + j), _mm_loadu_pd(arr.center[1].data() + j),
                            _mm_loadu_pd(arr.center[2].data() + j)};
      const __m128d axis[3] = {_mm_loadu_pd(arr.normal[0].data() + j), _mm_loadu_pd(arr.normal[1].data() + j),
                               _mm_loadu_pd(arr.normal[2].data() + j)};
      const __m128d facing =
          _mm_add_pd(_mm_add_pd(_mm_mul_pd(axis[0], na[0]), _mm_mul_pd(axis[1], na[1])), _mm_mul_pd(axis[2], na[2]));
      w = _mm_mul_pd(w, _mm_max_pd(facing, zero));
      const __m128d along =
          _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_sub_pd(qa[0], c[0]), axis[0]), _mm_mul_pd(_mm_sub_pd(qa[1], c[1]), axis[1])),
                     _mm_mul_pd(_mm_sub_pd(qa[2], c[2]), axis[2]));
      const __m128d h = _mm_set1_pd(anchor_);
      const __m128d back = anchor_ > 0 ? _mm_min_pd(_mm_max_pd(along, zero), h) : _mm_min_pd(_mm_max_pd(along, h), zero);
      for (int a = 0; a < 3; ++a) {
        const __m128d x = _mm_sub_pd(qa[a], _mm_mul_pd(axis[a], back));
        const __m128d t = _mm_mul_pd(_mm_and_pd(_mm_sub_pd(x, c[a]), abs), invR);
        const __m128d u = _mm_sub_pd(one, _mm_mul_pd(t, t));
        w = _mm_mul_pd(w, _mm_andnot_pd(_mm_cmpge_pd(t, one), _mm_mul_pd(u, u)));
      }
    }
    const __m128d inside =
        _mm_cmplt_pd(_mm_add_pd(_mm_set1_pd(double(j)), _mm_setr_pd(0, 1)), _mm_set1_pd(double(l.last)));
    return _mm_and_pd(inside, w);
  }

  // The largest window over the message's dabs whose ROI holds p, or 0. Only the range of dabs
  // whose ROI holds p.x is read (a pair's second lane past it is masked by its position).
  template <bool kAnchored>
  double lanesLargest(Cursor::Lanes& l, int x, Vec3 q, Vec3 n) const {
    l.at(x);
    const __m128d qa[3] = {_mm_set1_pd(q.x), _mm_set1_pd(q.y), _mm_set1_pd(q.z)};
    const __m128d na[3] = {_mm_set1_pd(n.x), _mm_set1_pd(n.y), _mm_set1_pd(n.z)};
    __m128d best = _mm_setzero_pd();
    for (std::size_t j = l.first; j < l.last; j += 2) best = _mm_max_pd(best, pairWindows<kAnchored>(l, j, qa, na));
    return std::max(_mm_cvtsd_f64(best), _mm_cvtsd_f64(_mm_unpackhi_pd(best, best)));
  }

  // The memory's part of search: the largest window over the row's memory dabs whose ROI holds
  // p, or, as soon as one reaches w, that one's window (w less it is <= 0 like w less the
  // largest, and the voxel does not move). The dab that reached w last is tried first, alone:
  // window gives it the lanes' bits (or a value <= 0 where it stops early).
  template <bool kAnchored>
  double memoryLargest(Cursor& c, Int3 p, Vec3 q, Vec3 n, double w) const {
    if (c.reached < memory_.size()) {
      const PreparedDab& d = memory_[c.reached];
      if (d.roi.contains(p)) {
        const double m = window(d, q, n, 0);
        if (m >= w) return m;
      }
    }
    Cursor::Lanes& l = c.memoryLanes;
    l.at(p.x);
    const __m128d enough = _mm_set1_pd(w);
    const __m128d qa[3] = {_mm_set1_pd(q.x), _mm_set1_pd(q.y), _mm_set1_pd(q.z)};
    const __m128d na[3] = {_mm_set1_pd(n.x), _mm_set1_pd(n.y), _mm_set1_pd(n.z)};
    __m128d best = _mm_setzero_pd();
    for (std::size_t j = l.first; j < l.last; j += 2) {
      const __m128d m = pairWindows<kAnchored>(l, j, qa, na);
      if (const int hit = _mm_movemask_pd(_mm_cmpge_pd(m, enough))) {
        const std::size_t lane = hit & 1 ? 0 : 1;
        c.reached = l.dab(c.memory, j + lane);
        c.reachedLane = j + lane;
        return lane == 0 ? _mm_cvtsd_f64(m) : _mm_cvtsd_f64(_mm_unpackhi_pd(m, m));
      }
      best = _mm_max_pd(best, m);
    }
    return std::max(_mm_cvtsd_f64(best), _mm_cvtsd_f64(_mm_unpackhi_pd(best, best)));
  }
#endif

#if defined(MARZIPAN_AVX2)
  // pairWindows for the lanes' dabs j to j + 3 (AVX2): each lane the same operations in the same
  // order, so the same bits. The caller gives the lanes before l.last (inside) and the clamp's
  // bounds (back: [0, H] adding, [-H, 0] removing).
  template <bool kAnchored>
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline __m256d quadWindows(const Cursor::Lanes& l, std::size_t j,
                                                                                  const __m256d qa[3], const __m256d na[3],
                                                                                  const __m256d back[2],
                                                                                  __m256d inside) const {
    const LaneArrays& arr = *l.arrays;
    const __m256d one = _mm256_set1_pd(1.0), zero = _mm256_setzero_pd(), invR = _mm256_set1_pd(inverseRadius_);
    const __m256d abs = _mm256_castsi256_pd(_mm256_set1_epi64x(0x7fffffffffffffff));
    __m256d w = _mm256_loadu_pd(arr.weight.data() + j);
    if constexpr (!kAnchored) {
      for (int a = 0; a < 3; ++a) {
        const __m256d t =
            _mm256_mul_pd(_mm256_and_pd(_mm256_sub_pd(qa[a], _mm256_loadu_pd(arr.center[a].data() + j)), abs), invR);
        const __m256d u = _mm256_sub_pd(one, _mm256_mul_pd(t, t));
        w = _mm256_mul_pd(w, _mm256_andnot_pd(_mm256_cmp_pd(t, one, _CMP_GE_OS), _mm256_mul_pd(u, u)));
      }
    } else {
      const __m256d c[3] = {_mm256_loadu_pd(arr.center[0].data() + j), _mm256_loadu_pd(arr.center[1].data() + j),
                            _mm256_loadu_pd(arr.center[2].data() + j)};
      const __m256d axis[3] = {_mm256_loadu_pd(arr.normal[0].data() + j), _mm256_loadu_pd(arr.normal[1].data() + j),
                               _mm256_loadu_pd(arr.normal[2].data() + j)};
      const __m256d facing = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(axis[0], na[0]), _mm256_mul_pd(axis[1], na[1])),
                                           _mm256_mul_pd(axis[2], na[2]));
      w = _mm256_mul_pd(w, _mm256_max_pd(facing, zero));
      const __m256d along = _mm256_add_pd(
          _mm256_add_pd(_mm256_mul_pd(_mm256_sub_pd(qa[0], c[0]), axis[0]), _mm256_mul_pd(_mm256_sub_pd(qa[1], c[1]), axis[1])),
          _mm256_mul_pd(_mm256_sub_pd(qa[2], c[2]), axis[2]));
      const __m256d moved = _mm256_min_pd(_mm256_max_pd(along, back[0]), back[1]);
      for (int a = 0; a < 3; ++a) {
        const __m256d x = _mm256_sub_pd(qa[a], _mm256_mul_pd(axis[a], moved));
        const __m256d t = _mm256_mul_pd(_mm256_and_pd(_mm256_sub_pd(x, c[a]), abs), invR);
        const __m256d u = _mm256_sub_pd(one, _mm256_mul_pd(t, t));
        w = _mm256_mul_pd(w, _mm256_andnot_pd(_mm256_cmp_pd(t, one, _CMP_GE_OS), _mm256_mul_pd(u, u)));
      }
    }
    return _mm256_and_pd(inside, w);
  }

  // Whether one of the memory's windows m in lanes j to j + 3 reaches w: then excess is w less
  // the first such, and c remembers its dab.
  [[gnu::always_inline]] __attribute__((target("avx2"))) static inline bool reaching(Cursor& c, std::size_t j, __m256d m,
                                                                                 __m256d enough, double w,
                                                                                 double& excess) {
    const int hit = _mm256_movemask_pd(_mm256_cmp_pd(m, enough, _CMP_GE_OS));
    if (!hit) return false;
    const std::size_t lane = j + std::size_t(__builtin_ctz(unsigned(hit)));
    c.reached = c.memoryLanes.dab(c.memory, lane);
    c.reachedLane = lane;
    alignas(32) double lanes[4];
    _mm256_store_pd(lanes, m);
    excess = w - lanes[lane - j];
    return true;
  }

  // The largest of the four lanes.
  [[gnu::always_inline]] __attribute__((target("avx2"))) static inline double largestLane(__m256d v) {
    const __m128d m = _mm_max_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    return std::max(_mm_cvtsd_f64(m), _mm_cvtsd_f64(_mm_unpackhi_pd(m, m)));
  }

  template <bool kAnchored>
  [[gnu::noinline]] __attribute__((target("avx2"))) double searchAvx2(Int3 p, Vec3 q, Vec3 n, Cursor& c) const {
    return lanesAvx2<kAnchored>(p, q, n, c);
  }

 public:
  // Whether search takes searchAvx2 now (then a caller compiled for AVX2 may call lanesAvx2
  // itself, with the foot point in registers rather than passed through two calls).
  bool searchesAvx2() const {
    return lanes_ && simd_width::useAvx2() && !(dabs_.size() == 1 && memory_.empty());
  }
  bool anchored() const { return anchor_ != 0; }

  // search with four lanes, c already at p's row (reaches): lanesLargest and memoryLargest four
  // dabs at a time. The largest window is the same whatever the grouping (only the sign of a
  // zero may differ, and a window <= 0 moves nothing). The memory stops at a dab that reaches w,
  // not always memoryLargest's: the result is then <= 0 all the same, and the voxel does not move.
  template <bool kAnchored>
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline double lanesAvx2(Int3 p, Vec3 q, Vec3 n,
                                                                               Cursor& c) const {
    const __m256d qa[3] = {_mm256_set1_pd(q.x), _mm256_set1_pd(q.y), _mm256_set1_pd(q.z)};
    const __m256d na[3] = {_mm256_set1_pd(n.x), _mm256_set1_pd(n.y), _mm256_set1_pd(n.z)};
    // std::min(0.0, H) and std::max(0.0, H) are +0 where H has the other sign, the zero the
    // clamps of pairWindows use, in the same operand order.
    const __m256d back[2] = {_mm256_set1_pd(std::min(0.0, anchor_)), _mm256_set1_pd(std::max(0.0, anchor_))};
    const __m256d four = _mm256_set1_pd(4.0), offsets = _mm256_setr_pd(0, 1, 2, 3);
    Cursor::Lanes& l = c.dabLanes;
    l.at(p.x);
    __m256d best = _mm256_setzero_pd();
    const __m256d last = _mm256_set1_pd(double(l.last));
    __m256d at = _mm256_add_pd(_mm256_set1_pd(double(l.first)), offsets);  // each lane's position
    for (std::size_t j = l.first; j < l.last; j += 4, at = _mm256_add_pd(at, four))
      best = _mm256_max_pd(best, quadWindows<kAnchored>(l, j, qa, na, back, _mm256_cmp_pd(at, last, _CMP_LT_OS)));
    const double w = largestLane(best);
    if (w <= 0 || c.memory.empty()) return w;
    Cursor::Lanes& ml = c.memoryLanes;
    ml.at(p.x);
    const __m256d enough = _mm256_set1_pd(w), memoryLast = _mm256_set1_pd(double(ml.last));
    double excess;
    // The lanes from the one that reached w at a voxel before, in lanes rather than by window():
    // that call of legacy-SSE code from here took 7% of stroke_drag's CPU on a Zen 3 (the SSE-AVX
    // mix). Its lanes past ml.last are masked: any lane that reaches w is one whose ROI holds p.
    if (const std::size_t j = c.reachedLane; j >= ml.first && j < ml.last) {
      const __m256d inside = _mm256_cmp_pd(_mm256_add_pd(_mm256_set1_pd(double(j)), offsets), memoryLast, _CMP_LT_OS);
      if (reaching(c, j, quadWindows<kAnchored>(ml, j, qa, na, back, inside), enough, w, excess)) return excess;
    }
    best = _mm256_setzero_pd();
    at = _mm256_add_pd(_mm256_set1_pd(double(ml.first)), offsets);
    for (std::size_t j = ml.first; j < ml.last; j += 4, at = _mm256_add_pd(at, four)) {
      const __m256d m = quadWindows<kAnchored>(ml, j, qa, na, back, _mm256_cmp_pd(at, memoryLast, _CMP_LT_OS));
      if (reaching(c, j, m, enough, w, excess)) return excess;
      best = _mm256_max_pd(best, m);
    }
    return w - largestLane(best);
  }

 private:
#endif

#if defined(MARZIPAN_SSE2)
  // search's lanes with a height (a call of its own keeps search's frame as light as before).
  [[gnu::noinline]] double searchAnchored(Int3 p, Vec3 q, Vec3 n, Cursor& c) const {
    const double w = lanesLargest<true>(c.dabLanes, p.x, q, n);
    if (w <= 0 || c.memory.empty()) return w;
    return w - memoryLargest<true>(c, p, q, n, w);
  }
#endif

  [[gnu::noinline]] double search(Int3 p, Vec3 q, Vec3 n, Cursor& c) const {
    row(p, c);
#if defined(MARZIPAN_AVX2)
    if (lanes_ && simd_width::useAvx2())
      return anchor_ == 0 ? searchAvx2<false>(p, q, n, c) : searchAvx2<true>(p, q, n, c);
#endif
#if defined(MARZIPAN_SSE2)
    if (anchor_ == 0) {  // lanes_ holds
      const double w = lanesLargest<false>(c.dabLanes, p.x, q, n);
      if (w <= 0 || c.memory.empty()) return w;
      return w - memoryLargest<false>(c, p, q, n, w);
    }
    if (lanes_) return searchAnchored(p, q, n, c);
#endif
    const double w = strongest(dabs_, c.dabs, p.x, q, n, std::numeric_limits<double>::infinity(), c.dab);
    if (w <= 0 || c.memory.empty()) return w;
    return w - strongest(memory_, c.memory, p.x, q, n, w, c.remembered);
  }

  // s: the dabs of `dabs` whose ROI holds slice z (byLoY, byHiY: all of them by their ROI's lo.y,
  // by its hi.y), none of them yet holding a row.
  static void sliceDabs(const std::vector<PreparedDab>& dabs, const std::vector<std::uint32_t>& byLoY,
                        const std::vector<std::uint32_t>& byHiY, int z, Cursor::RowSet& s) {
    s.enter.clear();
    s.leave.clear();
    for (const std::uint32_t i : byLoY)
      if (const Box& b = dabs[i].roi; z >= b.lo.z && z < b.hi.z) s.enter.push_back({b.lo.y, i});
    for (const std::uint32_t i : byHiY)
      if (const Box& b = dabs[i].roi; z >= b.lo.z && z < b.hi.z) s.leave.push_back({b.hi.y, i});
    s.entered = s.left = 0;
    s.holds.assign((dabs.size() + 63) / 64, 0);
    s.y = std::numeric_limits<int>::min();
  }

  // The dabs of s's slice whose ROI holds row y, in their order, and `until` lowered to the
  // first y past it where a ROI begins or ends in the slice (rows of the slice before it hold
  // the same dabs). The rows mostly come up the slice; one further down starts it over.
  static void rowDabs(Cursor::RowSet& s, int y, std::vector<std::uint32_t>& out, int& until) {
    if (y < s.y) {
      s.entered = s.left = 0;
      std::fill(s.holds.begin(), s.holds.end(), 0);
    }
    s.y = y;
    // Every ROI that begins at or below y, then every one that ends there: one that lies wholly
    // below y goes in and out.
    for (; s.entered < s.enter.size() && s.enter[s.entered].y <= y; ++s.entered) {
      const std::uint32_t d = s.enter[s.entered].dab;
      s.holds[d >> 6] |= std::uint64_t(1) << (d & 63);
    }
    for (; s.left < s.leave.size() && s.leave[s.left].y <= y; ++s.left) {
      const std::uint32_t d = s.leave[s.left].dab;
      s.holds[d >> 6] &= ~(std::uint64_t(1) << (d & 63));
    }
    if (s.entered < s.enter.size()) until = std::min(until, s.enter[s.entered].y);
    if (s.left < s.leave.size()) until = std::min(until, s.leave[s.left].y);
    out.clear();
    for (std::size_t w = 0; w < s.holds.size(); ++w)
      for (std::uint64_t bits = s.holds[w]; bits != 0; bits &= bits - 1)
        out.push_back(std::uint32_t(w * 64 + std::size_t(__builtin_ctzll(bits))));
  }

  // Dab d's window weight * W at foot point q (normal n), or a value <= best as soon as it
  // falls to best. Its factors are in [0, 1] (up to the rounding of a dot product of unit
  // vectors, taken before the test) and rounding is monotone, so the rest cannot lift it above.
  double window(const PreparedDab& d, Vec3 q, Vec3 n, double best) const {
    double w = d.weight;
    Vec3 x = q;
    if (anchor_ != 0) {
      const Vec3 axis = d.normal == Vec3{} ? n : d.normal;
      // Moving the surface along the axis by s is moving it along its normal by s (axis . n).
      w *= std::max(0.0, dot(axis, n));
      if (!(w > best)) return w;
      const double along = dot(q - d.center, axis);
      x = q - axis * (anchor_ > 0 ? std::clamp(along, 0.0, anchor_) : std::clamp(along, anchor_, 0.0));
    }
    for (int a = 0; a < 3 && w > best; ++a) w *= window1(std::fabs(x[a] - d.center[a]) * inverseRadius_);
    return w;
  }

  // The largest window over the dabs of the row (`row`, indices into dabs) whose ROI holds x,
  // or a value >= enough as soon as one reaches it, searched from row[first] on (first becomes
  // the strongest one found).
  double strongest(const std::vector<PreparedDab>& dabs, const std::vector<std::uint32_t>& row, int x0, Vec3 q, Vec3 n,
                   double enough, std::size_t& first) const {
    double best = 0;
    std::size_t strongestDab = first;
    for (std::size_t k = 0; k < row.size(); ++k) {
      const std::size_t i = k == 0 ? first : (k <= first ? k - 1 : k);
      const PreparedDab& d = dabs[row[i]];
      if (x0 < d.roi.lo.x || x0 >= d.roi.hi.x) continue;
      const double w = window(d, q, n, best);
      if (w > best) {
        best = w;
        strongestDab = i;
      }
      if (best >= enough) break;
    }
    first = strongestDab;
    return best;
  }

  double inverseRadius_, anchor_;
  std::vector<PreparedDab> dabs_, memory_;
  bool lanes_ = false;  // SSE2 searches the lanes (Cursor::Lanes)
  // Indices into dabs_ ([0]) and memory_ ([1]) by their ROI's lo.y, and by its hi.y (RowSet).
  std::vector<std::uint32_t> byLoY_[2], byHiY_[2];
#if defined(MARZIPAN_SSE2)
  LaneArrays allDabs_, allMemory_;  // lanes_: dabs_ and memory_ as lanes
#endif
};

// The unit normal (central differences) and foot point p - d n of grid voxel i at p: the window
// is read there, so that it is constant along normals (velocity extension).
struct FootPoint {
  Vec3 normal, point;
};
[[gnu::always_inline]] inline FootPoint footPoint(const DenseGrid& g, std::size_t i, Int3 p) {
  const Vec3 n =
      normalized(GradStencil::inArray(g.v.data() + i, 1, std::ptrdiff_t(g.sx), std::ptrdiff_t(g.sxy)).gradient());
  return {n, Vec3{double(p.x), double(p.y), double(p.z)} - n * double(g.v[i])};
}
// footPoint in a call of its own: inlined into collectMoved's loop, it slowed the brush's
// windows there (a dab: +5% instructions).
[[gnu::noinline]] FootPoint footPointCall(const DenseGrid& g, std::size_t i, Int3 p) { return footPoint(g, i, p); }

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
};
ToolScratch& toolScratch() {
  thread_local ToolScratch s;
  return s;
}

#if defined(MARZIPAN_SSE2)
// Writes the first n (1..3) lanes of x: a run's last voxels, whose neighbours past the run may
// be another block's.
void storePartial(float* out, __m128 x, std::uint32_t n) {
  if (n == 1) {
    _mm_store_ss(out, x);
    return;
  }
  _mm_storel_pi(reinterpret_cast<__m64*>(out), x);
  if (n == 3) _mm_store_ss(out + 2, _mm_movehl_ps(x, x));
}
#endif

// The walk of a sub-step over runs [r, end): voxel j of a run goes to dst[run.first + j] (dst:
// a list-ordered array) or dst[run.index + j] (dst: a grid). lanes(i, k) computes the voxels
// from grid index i = run.index + j, list position k = run.first + j on: with SSE2 four at once
// (an __m128; past the run's end it may read up to 3 voxels and 3 list entries more, which the
// callers provide, and only the run's own are stored), without one (a float). Kernels hold what
// they read by value: a store of a vector may alias anything, so the compiler would reload
// whatever they reach by reference after each one.
template <class Lanes>
void overRuns(const Run* r, const Run* end, float* dst, bool dstIsGrid, Lanes lanes) {
  for (; r != end; ++r) {
    const std::size_t index = r->index, first = r->first, count = r->count;
    float* const out = dst + (dstIsGrid ? index : first);
    std::size_t j = 0;
#if defined(MARZIPAN_SSE2)
    for (; j + 4 <= count; j += 4) _mm_storeu_ps(out + j, lanes(index + j, first + j));
    if (j < count) storePartial(out + j, lanes(index + j, first + j), std::uint32_t(count - j));
#else
    for (; j < count; ++j) out[j] = lanes(index + j, first + j);
#endif
  }
}

#if defined(MARZIPAN_AVX2)
// overRuns eight at once (lanes.eight, an __m256) while 5 or more voxels of a run are left,
// then four (lanes(i, k)): past a run's end it reads no further than overRuns.
template <class Lanes>
__attribute__((target("avx2"))) void overRunsAvx2(const Run* r, const Run* end, float* dst, bool dstIsGrid,
                                                  Lanes lanes) {
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (; r != end; ++r) {
    const std::size_t index = r->index, first = r->first, count = r->count;
    float* const out = dst + (dstIsGrid ? index : first);
    std::size_t j = 0;
    for (; j + 8 <= count; j += 8) _mm256_storeu_ps(out + j, lanes.eight(index + j, first + j));
    const std::size_t left = count - j;
    if (left > 4) {
      const __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(int(left)), lane);
      _mm256_maskstore_ps(out + j, mask, lanes.eight(index + j, first + j));
    } else if (left == 4) {
      _mm_storeu_ps(out + j, lanes(index + j, first + j));
    } else if (left > 0) {
      storePartial(out + j, lanes(index + j, first + j), std::uint32_t(left));
    }
  }
}
#endif

#if defined(MARZIPAN_SSE2)
// curvatureRuns' lanes: operator() four voxels (SSE2), eight() eight (AVX2), each lane the
// definition's operations in its order.
struct CurvatureLanes {
  const float* v;
  const double* factor;
  std::ptrdiff_t sy, sz;
  double limit;
  bool limited;

  __m128 operator()(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const double* f = factor + k;
    const __m128d six = _mm_set1_pd(6.0);
    __m128 sum = _mm_add_ps(_mm_loadu_ps(q + 1), _mm_loadu_ps(q - 1));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q + sy));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q - sy));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q + sz));
    sum = _mm_add_ps(sum, _mm_loadu_ps(q - sz));
    const __m128 c = _mm_loadu_ps(q);
    const __m128d c0 = _mm_cvtps_pd(c), c1 = _mm_cvtps_pd(_mm_movehl_ps(c, c));
    __m128d lap0 = _mm_sub_pd(_mm_cvtps_pd(sum), _mm_mul_pd(six, c0));
    __m128d lap1 = _mm_sub_pd(_mm_cvtps_pd(_mm_movehl_ps(sum, sum)), _mm_mul_pd(six, c1));
    if (limited) {
      // std::clamp(x, lo, hi) is (x < lo ? lo : hi < x ? hi : x): max(lo, x), then min(hi, .).
      const __m128d lo = _mm_set1_pd(-limit), hi = _mm_set1_pd(limit);
      lap0 = _mm_min_pd(hi, _mm_max_pd(lo, lap0));
      lap1 = _mm_min_pd(hi, _mm_max_pd(lo, lap1));
    }
    const __m128d out0 = _mm_add_pd(c0, _mm_mul_pd(_mm_loadu_pd(f), lap0));
    const __m128d out1 = _mm_add_pd(c1, _mm_mul_pd(_mm_loadu_pd(f + 2), lap1));
    return _mm_movelh_ps(_mm_cvtpd_ps(out0), _mm_cvtpd_ps(out1));
  }

#if defined(MARZIPAN_AVX2)
  __attribute__((target("avx2"))) __m256 eight(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const double* f = factor + k;
    const __m256d six = _mm256_set1_pd(6.0);
    __m256 sum = _mm256_add_ps(_mm256_loadu_ps(q + 1), _mm256_loadu_ps(q - 1));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q + sy));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q - sy));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q + sz));
    sum = _mm256_add_ps(sum, _mm256_loadu_ps(q - sz));
    const __m256 c = _mm256_loadu_ps(q);
    const __m256d c0 = _mm256_cvtps_pd(_mm256_castps256_ps128(c)), c1 = _mm256_cvtps_pd(_mm256_extractf128_ps(c, 1));
    __m256d lap0 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(sum)), _mm256_mul_pd(six, c0));
    __m256d lap1 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(sum, 1)), _mm256_mul_pd(six, c1));
    if (limited) {
      const __m256d lo = _mm256_set1_pd(-limit), hi = _mm256_set1_pd(limit);
      lap0 = _mm256_min_pd(hi, _mm256_max_pd(lo, lap0));
      lap1 = _mm256_min_pd(hi, _mm256_max_pd(lo, lap1));
    }
    const __m256d out0 = _mm256_add_pd(c0, _mm256_mul_pd(_mm256_loadu_pd(f), lap0));
    const __m256d out1 = _mm256_add_pd(c1, _mm256_mul_pd(_mm256_loadu_pd(f + 4), lap1));
    return _mm256_set_m128(_mm256_cvtpd_ps(out1), _mm256_cvtpd_ps(out0));
  }
#endif
};

#if defined(MARZIPAN_AVX2)
__attribute__((target("avx2"))) __m256 minmod8(__m256 a, __m256 b) {
  const __m256 abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 aSmaller = _mm256_cmp_ps(_mm256_and_ps(a, abs), _mm256_and_ps(b, abs), _CMP_LT_OS);
  const __m256 smaller = _mm256_or_ps(_mm256_and_ps(aSmaller, a), _mm256_andnot_ps(aSmaller, b));
  return _mm256_andnot_ps(_mm256_cmp_ps(_mm256_mul_ps(a, b), _mm256_setzero_ps(), _CMP_LE_OS), smaller);
}
#endif

// advectionRuns' lanes: four voxels along x (SSE2) or eight (AVX2), each lane doing
// upwindGradient's float operations in its order (the axes summed x, y, z onto 0).
// std::max(x, 0) is (x < 0 ? 0 : x), which is _mm_max_ps(0, x) bit for bit (also -0 and NaN);
// std::min(x, 0) likewise _mm_min_ps(0, x).
struct AdvectionLanes {
  const float* v;
  const float* step;
  std::size_t s[3];

  __m128 operator()(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), zero = _mm_setzero_ps();
    const __m128 dtF = _mm_loadu_ps(step + k);
    const __m128 outward = _mm_cmpgt_ps(dtF, zero);
    const __m128 v0 = _mm_loadu_ps(q);
    __m128 g2 = zero;
    for (int a = 0; a < 3; ++a) {
      const __m128 vm2 = _mm_loadu_ps(q - 2 * s[a]), vm1 = _mm_loadu_ps(q - s[a]);
      const __m128 vp1 = _mm_loadu_ps(q + s[a]), vp2 = _mm_loadu_ps(q + 2 * s[a]);
      const __m128 centre = _mm_add_ps(_mm_sub_ps(vp1, _mm_mul_ps(two, v0)), vm1);
      const __m128 dm = _mm_add_ps(_mm_sub_ps(v0, vm1),
                                   _mm_mul_ps(half, minmod4(_mm_add_ps(_mm_sub_ps(v0, _mm_mul_ps(two, vm1)), vm2), centre)));
      const __m128 dp = _mm_sub_ps(_mm_sub_ps(vp1, v0),
                                   _mm_mul_ps(half, minmod4(centre, _mm_add_ps(_mm_sub_ps(vp2, _mm_mul_ps(two, vp1)), v0))));
      const __m128 a1 = _mm_or_ps(_mm_and_ps(outward, _mm_max_ps(zero, dm)), _mm_andnot_ps(outward, _mm_min_ps(zero, dm)));
      const __m128 a2 = _mm_or_ps(_mm_and_ps(outward, _mm_min_ps(zero, dp)), _mm_andnot_ps(outward, _mm_max_ps(zero, dp)));
      g2 = _mm_add_ps(g2, _mm_add_ps(_mm_mul_ps(a1, a1), _mm_mul_ps(a2, a2)));
    }
    return _mm_sub_ps(v0, _mm_mul_ps(dtF, _mm_sqrt_ps(g2)));
  }

#if defined(MARZIPAN_AVX2)
  __attribute__((target("avx2"))) __m256 eight(std::size_t i, std::size_t k) const {
    const float* q = v + i;
    const __m256 two = _mm256_set1_ps(2.0f), half = _mm256_set1_ps(0.5f), zero = _mm256_setzero_ps();
    const __m256 dtF = _mm256_loadu_ps(step + k);
    const __m256 outward = _mm256_cmp_ps(dtF, zero, _CMP_GT_OS);
    const __m256 v0 = _mm256_loadu_ps(q);
    __m256 g2 = zero;
    for (int a = 0; a < 3; ++a) {
      const __m256 vm2 = _mm256_loadu_ps(q - 2 * s[a]), vm1 = _mm256_loadu_ps(q - s[a]);
      const __m256 vp1 = _mm256_loadu_ps(q + s[a]), vp2 = _mm256_loadu_ps(q + 2 * s[a]);
      const __m256 centre = _mm256_add_ps(_mm256_sub_ps(vp1, _mm256_mul_ps(two, v0)), vm1);
      const __m256 dm = _mm256_add_ps(
          _mm256_sub_ps(v0, vm1),
          _mm256_mul_ps(half, minmod8(_mm256_add_ps(_mm256_sub_ps(v0, _mm256_mul_ps(two, vm1)), vm2), centre)));
      const __m256 dp = _mm256_sub_ps(
          _mm256_sub_ps(vp1, v0),
          _mm256_mul_ps(half, minmod8(centre, _mm256_add_ps(_mm256_sub_ps(vp2, _mm256_mul_ps(two, vp1)), v0))));
      const __m256 a1 = _mm256_or_ps(_mm256_and_ps(outward, _mm256_max_ps(zero, dm)),
                                     _mm256_andnot_ps(outward, _mm256_min_ps(zero, dm)));
      const __m256 a2 = _mm256_or_ps(_mm256_and_ps(outward, _mm256_min_ps(zero, dp)),
                                     _mm256_andnot_ps(outward, _mm256_max_ps(zero, dp)));
      g2 = _mm256_add_ps(g2, _mm256_add_ps(_mm256_mul_ps(a1, a1), _mm256_mul_ps(a2, a2)));
    }
    return _mm256_sub_ps(v0, _mm256_mul_ps(dtF, _mm256_sqrt_ps(g2)));
  }
#endif
};
#endif

// One explicit curvature step over runs [r, end): dst[run.first + j] (dst: a list-ordered
// array) or dst[run.index + j] (dst: a grid) = phi + dt F L, L = the 7-point Laplacian, from v.
// The neighbours are summed in float in this order and the rest is done in double, as
//   double lap = p[1] + p[-1] + p[sy] + p[-sy] + p[sz] + p[-sz] - 6.0 * p[0];
//   return float(p[0] + factor * std::clamp(lap, -limit, limit));
// would, voxel by voxel (the lanes do the same operations, so the same bits). A run's last
// lanes read up to 3 voxels past it (evolve's region lies kStencilReach inside the grid, so they
// are in it) and factor up to 3 entries past the list (evolve pads it).
void curvatureRuns(const float* v, float* dst, bool dstIsGrid, const Run* r, const Run* end, const double* factor,
                   std::ptrdiff_t sy, std::ptrdiff_t sz, double limit) {
  const bool limited = std::isfinite(limit);  // clamping to +-infinity changes nothing
#if defined(MARZIPAN_SSE2)
  const CurvatureLanes lanes{v, factor, sy, sz, limit, limited};
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return overRunsAvx2(r, end, dst, dstIsGrid, lanes);
#endif
  overRuns(r, end, dst, dstIsGrid, lanes);
#else
  overRuns(r, end, dst, dstIsGrid, [=](std::size_t i, std::size_t k) {
    const float* q = v + i;
    double lap = q[1] + q[-1] + q[sy] + q[-sy] + q[sz] + q[-sz] - 6.0 * q[0];
    if (limited) lap = std::clamp(lap, -limit, limit);
    return float(q[0] + factor[k] * lap);
  });
#endif
}

// One upwind advection step over runs [r, end): next[run.first + j] = phi - step |grad phi|,
// step = float(dt F), |grad phi| by upwindGradient (outward where step > 0; where step is
// +-0 the direction does not change the result). Reads past a run's end as curvatureRuns.
void advectionRuns(const float* v, float* next, const Run* r, const Run* end, const float* step,
                   const std::size_t stride[3]) {
#if defined(MARZIPAN_SSE2)
  const AdvectionLanes lanes{v, step, {stride[0], stride[1], stride[2]}};
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return overRunsAvx2(r, end, next, false, lanes);
#endif
  overRuns(r, end, next, false, lanes);
#else
  overRuns(r, end, next, false, [=](std::size_t i, std::size_t k) {
    return v[i] - step[k] * upwindGradient(v, i, stride, step[k] > 0);
  });
#endif
}

// The m.substeps curvature steps of evolve between g.v and s.other, on the pool without waking
// it for each step. The steps read the runs' slices and the slices next to them (a run's last
// lanes up to 4 voxels past it): each piece copies its part of that into s.other before its
// first step, the pieces next to it only read there once they have done theirs. The runs are cut into pieces of whole z-slices; a
// voxel's neighbours then lie in its own piece or the two next to it. Step j of piece p reads
// the grid that holds step j - 1 and writes the other, over step j - 2: it may run once its
// neighbours have done step j - 1 (what it reads is there, and they are done reading step
// j - 2), so neighbours only ever run the same step at once, reading one grid and writing
// the other at their own voxels. Threads take whichever piece is ready, lowest step first;
// each voxel's value is computed as in a plain loop over the steps, so the result is the
// same for any thread count and any order.
void curvatureSteps(DenseGrid& g, ToolScratch& s, const Motion& m, ThreadPool& pool, const ProgressShare& progress) {
  const std::vector<Run>& runs = s.moved.runs;
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  float* const grids[2] = {g.v.data(), s.other.data()};
  constexpr std::size_t kPieceVoxels = 2048;
  std::vector<std::size_t>& pieces = s.blocks;  // the first run of each piece, then runs.size()
  pieces.clear();
  for (std::size_t r = 0, inPiece = kPieceVoxels; r < runs.size(); ++r) {
    if (inPiece >= kPieceVoxels && (r == 0 || runs[r].index / g.sxy != runs[r - 1].index / g.sxy)) {
      pieces.push_back(r);
      inPiece = 0;
    }
    inPiece += runs[r].count;
  }
  pieces.push_back(runs.size());
  const int count = int(pieces.size()) - 1, steps = m.substeps;
  // Piece p copies [copyFrom(p), copyFrom(p + 1)): from the slice before the runs (the first)
  // or its first run's slice, to the next piece's, or past the last run's slice (the last).
  auto copyFrom = [&](int p) {
    if (p == 0) return std::size_t(runs.front().index) - g.sxy;
    if (p == count) return std::size_t(runs.back().index) + runs.back().count + 4 + g.sxy;
    return runs[pieces[std::size_t(p)]].index / g.sxy * g.sxy;
  };
  auto runStep = [&](int p, int step, bool copy) {  // step 0-based: reads grids[step % 2]
    if (step == 0 && copy)
      std::copy(g.v.begin() + std::ptrdiff_t(copyFrom(p)), g.v.begin() + std::ptrdiff_t(copyFrom(p + 1)),
                s.other.begin() + std::ptrdiff_t(copyFrom(p)));
    curvatureRuns(grids[step % 2], grids[(step + 1) % 2], true, runs.data() + pieces[std::size_t(p)],
                  runs.data() + pieces[std::size_t(p) + 1], s.moved.factor.data(), sy, sz, m.curvatureLimit);
  };
  // Below 8192 voxels (a brush of radius ~10) a step is a few microseconds: the threads would
  // mostly wait for each other, and a woken thread that loses its core holds up the rest.
  constexpr std::uint32_t kParallelVoxels = 8192;
  const int participants = s.moved.count < kParallelVoxels ? 1 : std::min(pool.threads(), count);
  if (participants <= 1) {
    // On one thread s.other needs, before the first step, only what the steps read there and
    // do not write: the listed voxels' neighbours and the lanes past a run's end (x - 1 to
    // x + count + 3 along the run's row, x to x + count + 2 along the four rows next to it),
    // not the whole slices (a 70^3 brush's grid is 1.9 MB, its band's neighbourhood a fraction).
    // Pieces of four, which may copy up to 3 more voxels past those (in the grid: the region
    // lies kStencilReach inside it).
    auto copyRow = [&](std::size_t from, std::size_t n) {
      const float* src = g.v.data() + from;
      float* dst = s.other.data() + from;
#if defined(MARZIPAN_SSE2)
      for (std::size_t k = 0; k < n; k += 4) _mm_storeu_ps(dst + k, _mm_loadu_ps(src + k));
#else
      std::copy_n(src, n, dst);
#endif
    };
    for (const Run& r : runs) {
      copyRow(r.index - 1, r.count + 5);
      for (const std::size_t o : {r.index - g.sx, r.index + g.sx, r.index - g.sxy, r.index + g.sxy})
        copyRow(o, r.count + 3);
    }
    // The steps in bands of kWave, each band one sweep over the z-slices: step b + j of slice
    // piece q runs at time q + 2j, after its neighbours' step b + j - 1 (time q + 2j - 1) and
    // before their step b + j + 1 (time q + 2j + 1 or later), which is the rule above. A sweep
    // then keeps about 2 kWave slices of both copies in the cache, where step by step each
    // step read the whole band's neighbourhood (megabytes at 70^3) from memory again.
    constexpr int kWave = 4;
    std::vector<std::size_t>& slices = s.slices;
    slices.clear();
    for (std::size_t r = 0; r < runs.size(); ++r)
      if (r == 0 || runs[r].index / g.sxy != runs[r - 1].index / g.sxy) slices.push_back(r);
    slices.push_back(runs.size());
    const int n = int(slices.size()) - 1;
    for (int b = 0; b < steps; b += kWave) {
      progress.check();
      const int k = std::min(kWave, steps - b);
      for (int t = 0; t < n + 2 * (k - 1); ++t)
        for (int j = 0; j < k; ++j)
          if (const int q = t - 2 * j; q >= 0 && q < n) {
            const int step = b + j;
            curvatureRuns(grids[step % 2], grids[(step + 1) % 2], true, runs.data() + slices[std::size_t(q)],
                          runs.data() + slices[std::size_t(q) + 1], s.moved.factor.data(), sy, sz, m.curvatureLimit);
          }
      progress.advance(double(k) / steps);
    }
    return;
  }
  // done[p]: steps piece p has finished; claimed[p]: a thread is running its next step.
  std::unique_ptr<std::atomic<int>[]> done(new std::atomic<int>[std::size_t(count)]);
  std::unique_ptr<std::atomic<bool>[]> claimed(new std::atomic<bool>[std::size_t(count)]);
  for (int p = 0; p < count; ++p) {
    done[std::size_t(p)].store(0, std::memory_order_relaxed);
    claimed[std::size_t(p)].store(false, std::memory_order_relaxed);
  }
  std::atomic<int> finished{0};
  std::atomic<bool> failed{false};
  auto ready = [&](int p, int d) {
    return (p == 0 || done[std::size_t(p - 1)].load(std::memory_order_acquire) >= d) &&
           (p + 1 == count || done[std::size_t(p + 1)].load(std::memory_order_acquire) >= d);
  };
  pool.parallelFor(std::size_t(participants), [&](std::size_t) {
    int idle = 0;
    while (finished.load(std::memory_order_acquire) < count && !failed.load(std::memory_order_relaxed)) {
      int best = -1, bestStep = steps;
      for (int p = 0; p < count; ++p) {
        const int d = done[std::size_t(p)].load(std::memory_order_acquire);
        if (d < bestStep && !claimed[std::size_t(p)].load(std::memory_order_relaxed) && ready(p, d)) {
          best = p;
          bestStep = d;
        }
      }
      bool mine = false;
      if (best >= 0 && claimed[std::size_t(best)].compare_exchange_strong(mine, true, std::memory_order_acq_rel)) {
        // Another thread may have run a step of it between the scan and the claim.
        const int d = done[std::size_t(best)].load(std::memory_order_acquire);
        // Whatever throws (a cancel, the progress report), the claim is let go and the other
        // threads stop instead of waiting for this piece.
        try {
          if (d < steps && ready(best, d)) {
            progress.check();
            runStep(best, d, true);
            done[std::size_t(best)].store(d + 1, std::memory_order_release);
            if (d + 1 == steps) finished.fetch_add(1, std::memory_order_acq_rel);
            claimed[std::size_t(best)].store(false, std::memory_order_release);
            progress.advance(1.0 / (double(steps) * count));
            idle = 0;
          } else {
            claimed[std::size_t(best)].store(false, std::memory_order_release);
          }
        } catch (...) {
          failed.store(true, std::memory_order_relaxed);
          claimed[std::size_t(best)].store(false, std::memory_order_release);
          throw;
        }
        continue;
      }
      // Nothing ready: the pieces next to the ones left are being worked on by another thread.
      if (++idle < 64) {
#if defined(MARZIPAN_SSE2)
        _mm_pause();
#endif
      } else {
        std::this_thread::yield();
      }
    }
  });
}

#if defined(MARZIPAN_SSE2)
// A brush's window at the foot points of two voxels (grid indices i, points p), in the lanes of
// SSE2 vectors: footPoint's and SweptWindow::at's double operations in their order (the three
// factors multiplied out even after one is 0, which leaves 0), so the same bits.
void brushWindows(const DenseGrid& g, const std::size_t i[2], const Int3 p[2], const PreparedDab& d,
                  double inverseRadius, double w[2]) {
  const float* a = g.v.data() + i[0];
  const float* b = g.v.data() + i[1];
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  const __m128d half = _mm_set1_pd(0.5), one = _mm_set1_pd(1.0), zero = _mm_setzero_pd();
  // GradStencil::inArray(...).gradient(): float differences, then 0.5 * in double.
  const __m128d gx = _mm_mul_pd(half, _mm_setr_pd(double(a[1] - a[-1]), double(b[1] - b[-1])));
  const __m128d gy = _mm_mul_pd(half, _mm_setr_pd(double(a[sy] - a[-sy]), double(b[sy] - b[-sy])));
  const __m128d gz = _mm_mul_pd(half, _mm_setr_pd(double(a[sz] - a[-sz]), double(b[sz] - b[-sz])));
  // normalized(): l = sqrt(x x + y y + z z), l > 0 ? g / l : 0.
  const __m128d l = _mm_sqrt_pd(_mm_add_pd(_mm_add_pd(_mm_mul_pd(gx, gx), _mm_mul_pd(gy, gy)), _mm_mul_pd(gz, gz)));
  const __m128d positive = _mm_cmpgt_pd(l, zero);
  const __m128d dist = _mm_setr_pd(double(a[0]), double(b[0]));
  const __m128d q[3] = {
      _mm_sub_pd(_mm_setr_pd(p[0].x, p[1].x), _mm_mul_pd(_mm_and_pd(positive, _mm_div_pd(gx, l)), dist)),
      _mm_sub_pd(_mm_setr_pd(p[0].y, p[1].y), _mm_mul_pd(_mm_and_pd(positive, _mm_div_pd(gy, l)), dist)),
      _mm_sub_pd(_mm_setr_pd(p[0].z, p[1].z), _mm_mul_pd(_mm_and_pd(positive, _mm_div_pd(gz, l)), dist))};
  const __m128d abs = _mm_castsi128_pd(_mm_set1_epi64x(0x7fffffffffffffff)), invR = _mm_set1_pd(inverseRadius);
  __m128d weight = _mm_set1_pd(d.weight);
  for (int axis = 0; axis < 3; ++axis) {
    // window1(t): t >= 1 ? 0 : (1 - t t)^2.
    const __m128d t = _mm_mul_pd(_mm_and_pd(_mm_sub_pd(q[axis], _mm_set1_pd(d.center[axis])), abs), invR);
    const __m128d u = _mm_sub_pd(one, _mm_mul_pd(t, t));
    weight = _mm_mul_pd(weight, _mm_andnot_pd(_mm_cmpge_pd(t, one), _mm_mul_pd(u, u)));
  }
  _mm_storeu_pd(w, weight);
  for (int k = 0; k < 2; ++k) w[k] = d.roi.contains(p[k]) && w[k] > 0 ? w[k] : 0;
}
#endif

// The speed entry `at` of a voxel whose window is w > 0 under motion m (inlined: it runs once
// per band voxel, as collectMoved's add).
[[gnu::always_inline]] inline void setSpeed(MovedVoxels& out, std::size_t at, const Motion& m, double w) {
  const double speed = float(m.speed * w);
  if (m.kind == Motion::Kind::Curvature) {
    out.factor[at] = m.dt * speed;
  } else {
    out.step[at] = float(m.dt * speed);
  }
}

// Sizes the array a list of `count` voxels under m (null: their windows) fills.
void sizeSpeeds(MovedVoxels& out, const Motion* m, std::size_t count) {
  if (!m) {
    out.window.resize(count);
  } else if (m->kind == Motion::Kind::Curvature) {
    out.factor.resize(count);
  } else {
    out.step.resize(count);
  }
}

// Appends listed voxels to a MovedVoxels: the run being extended and the count, kept out of
// `out` (in registers) while a loop adds.
struct MovedAppender {
  MovedVoxels& out;
  const Motion* m;
  Run run{0, 0, 0};
  std::uint32_t count;

  // Room for `more` voxels.
  MovedAppender(MovedVoxels& o, const Motion* motion, std::size_t more) : out(o), m(motion), count(o.count) {
    if (!out.runs.empty()) {
      run = out.runs.back();
      out.runs.pop_back();
    }
    sizeSpeeds(out, m, count + more);
  }
  // Grid voxel i with window w (nothing when w <= 0). Inlined: once per band voxel of a
  // whole-volume pass, a call cost as much as its body.
  [[gnu::always_inline]] void add(std::size_t i, double w) {
    if (w <= 0) return;
    if (m) {
      setSpeed(out, count, *m, w);
    } else {
      out.window[count] = w;
    }
    // Consecutive indices share a row: region lies inside the grid, off its last column.
    if (run.count != 0 && run.index + run.count == i) {
      ++run.count;
    } else {
      if (run.count != 0) out.runs.push_back(run);
      run = {std::uint32_t(i), count, 1};
    }
    ++count;
  }
  void finish() {
    if (run.count != 0) out.runs.push_back(run);
    out.count = count;
    sizeSpeeds(out, m, count);
  }
};

#if defined(MARZIPAN_AVX2)
// collectMoved's loop where the window searches its lanes with AVX2 (SweptWindow::searchesAvx2):
// the same voxels, foot points and search (footPoint and lanesAvx2 inlined), so the same list.
template <bool kAnchored>
__attribute__((target("avx2"))) void collectLanesAvx2(const DenseGrid& g, const Box& region, float band,
                                                      const SweptWindow& window, const BandVoxels& voxels,
                                                      std::size_t begin, std::size_t end, MovedVoxels& out,
                                                      const Motion* m, const ProgressShare& progress) {
  MovedAppender add(out, m, end - begin);
  SweptWindow::Cursor cursor;
  for (std::size_t k = begin; k < end; ++k) {
    if (k % kVoxelsPerCheck == 0) progress.check();
    const std::size_t i = voxels.index[k];
    if (!(std::fabs(g.v[i]) < band)) continue;
    const Int3 p = voxels.point[k];
    if (!region.contains(p) || !window.reaches(p, cursor)) continue;
    const FootPoint f = footPoint(g, i, p);
    add.add(i, window.lanesAvx2<kAnchored>(p, f.point, f.normal, cursor));
  }
  add.finish();
}
#endif

// The band voxels voxels.index[begin, end) of region that m moves, appended to out with their
// speeds (the window at each one's foot point; none: W = 1); m null: with their windows instead.
void collectMoved(const DenseGrid& g, const Box& region, float band, const Motion* m, const SweptWindow* window,
                  const BandVoxels& voxels, std::size_t begin, std::size_t end, MovedVoxels& out,
                  const ProgressShare& progress) {
#if defined(MARZIPAN_AVX2)
  if (window && window->searchesAvx2()) {
    if (window->anchored()) return collectLanesAvx2<true>(g, region, band, *window, voxels, begin, end, out, m, progress);
    return collectLanesAvx2<false>(g, region, band, *window, voxels, begin, end, out, m, progress);
  }
#endif
  MovedAppender add(out, m, end - begin);
  SweptWindow::Cursor cursor;
#if defined(MARZIPAN_SSE2)
  // A brush's windows two voxels at a time (the square root and divisions of the foot point
  // are most of a voxel's cost); the voxels are added in the same order. (Four at a time with
  // AVX2 took as long: gathering the neighbours into lanes cost what the lanes saved.)
  const PreparedDab* const brush = window ? window->brush() : nullptr;
  std::size_t pending[2];
  Int3 pendingPoint[2];
  int pendingCount = 0;
#endif
  for (std::size_t k = begin; k < end; ++k) {
    if (k % kVoxelsPerCheck == 0) progress.check();
    const std::size_t i = voxels.index[k];
    if (!(std::fabs(g.v[i]) < band)) continue;
    const Int3 p = voxels.point[k];
    if (!region.contains(p)) continue;
#if defined(MARZIPAN_SSE2)
    if (brush) {
      pending[pendingCount] = i;
      pendingPoint[pendingCount] = p;
      if (++pendingCount == 2) {
        double w[2];
        brushWindows(g, pending, pendingPoint, *brush, window->inverseRadius(), w);
        add.add(pending[0], w[0]);
        add.add(pending[1], w[1]);
        pendingCount = 0;
      }
      continue;
    }
#endif
    double w = 1;
    if (window) {
      if (!window->reaches(p, cursor)) continue;
      const FootPoint f = footPointCall(g, i, p);
      w = window->at(p, f.point, f.normal, cursor);
    }
    add.add(i, w);
  }
#if defined(MARZIPAN_SSE2)
  if (pendingCount == 1) {
    const FootPoint f = footPointCall(g, pending[0], pendingPoint[0]);
    add.add(pending[0], window->at(pendingPoint[0], f.point, f.normal, cursor));
  }
#endif
  add.finish();
}

// Lists the band voxels of `region` (|phi| < band) that m moves in toolScratch().moved, with
// their speeds: m scaled by the window at each voxel's foot point (none: W = 1); m null: with
// their windows instead (withSpeeds adds the speeds). `voxels` lists the band of a box holding
// region; region must lie kStencilReach inside the grid. Built in fixed pieces on the pool,
// joined in order: thread-count independent. progress: checked per piece.
void listMoved(const DenseGrid& g, const Box& region, float band, const Motion* m, const SweptWindow* window,
               const BandVoxels& voxels, ThreadPool& pool, const ProgressShare& progress) {
  ToolScratch& s = toolScratch();
  MovedVoxels& moved = s.moved;
  moved.clear();
  // The list in pieces on the pool when there are threads and enough voxels to pay for waking
  // them (the foot point and the window cost more per voxel than a sub-step); joined in order,
  // the pieces are the list a single pass builds.
  constexpr std::size_t kListPiece = 8192;
  const std::size_t listPieces = (voxels.index.size() + kListPiece - 1) / kListPiece;
  if (pool.threads() > 1 && listPieces >= 2) {
    if (s.movedPieces.size() < listPieces) s.movedPieces.resize(listPieces);
    pool.parallelFor(listPieces, [&](std::size_t c) {
      MovedVoxels& piece = s.movedPieces[c];
      piece.clear();
      collectMoved(g, region, band, m, window, voxels, c * kListPiece,
                   std::min(voxels.index.size(), (c + 1) * kListPiece), piece, progress);
    });
    for (std::size_t c = 0; c < listPieces; ++c) moved.append(s.movedPieces[c]);
  } else {
    collectMoved(g, region, band, m, window, voxels, 0, voxels.index.size(), moved, progress);
  }
}

// Gives a list made without a motion the speeds listMoved would have given it under m.
void withSpeeds(MovedVoxels& moved, const Motion& m) {
  sizeSpeeds(moved, &m, moved.count);
  for (std::size_t k = 0; k < moved.count; ++k) setSpeed(moved, k, m, moved.window[k]);
}

// Moves the voxels of toolScratch().moved by their speeds under m. Work is split in fixed
// pieces, each voxel computed alone: thread-count independent. progress: checked per piece,
// advanced per sub-step.
void moveListed(DenseGrid& g, const Motion& m, ThreadPool& pool, const ProgressShare& progress) {
  ToolScratch& s = toolScratch();
  MovedVoxels& moved = s.moved;
  const std::vector<Run>& runs = moved.runs;
  const bool curvature = m.kind == Motion::Kind::Curvature;
  const std::size_t stride[3] = {1, g.sx, g.sxy};
  if (runs.empty()) {
    progress.advance(1);
    return;
  }
  // The kernels read up to 3 entries past the last run.
  moved.factor.resize(moved.factor.size() + 3, 0.0);
  moved.step.resize(moved.step.size() + 3, 0.0f);
  std::vector<float>& next = s.next;
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  // Many curvature sub-steps (smoothing's 32): each reads one copy of the grid and writes the
  // other, which holds the same values off the list, instead of writing a list and copying it
  // back every sub-step. An even count ends in g.v. (curvatureSteps runs the curvature kernel
  // only: advection in as many sub-steps takes the blocks below.)
  if (curvature && m.substeps > 2 && m.substeps % 2 == 0) {
    s.other.resize(g.v.size());
    curvatureSteps(g, s, m, pool, progress);
    return;
  }
  // Fixed blocks of whole runs, each of at least kBlock voxels but the last.
  constexpr std::size_t kBlock = 4096;
  std::vector<std::size_t>& blocks = s.blocks;
  blocks.clear();
  for (std::size_t r = 0, inBlock = kBlock; r < runs.size(); ++r) {
    if (inBlock >= kBlock) {
      blocks.push_back(r);
      inBlock = 0;
    }
    inBlock += runs[r].count;
  }
  blocks.push_back(runs.size());
  next.resize(moved.count);
  for (int step = 0; step < m.substeps; ++step) {
    pool.parallelFor(blocks.size() - 1, [&](std::size_t b) {
      progress.check();
      const Run* first = runs.data() + blocks[b];
      const Run* last = runs.data() + blocks[b + 1];
      if (curvature) {
        curvatureRuns(g.v.data(), next.data(), false, first, last, moved.factor.data(), sy, sz, m.curvatureLimit);
      } else {
        advectionRuns(g.v.data(), next.data(), first, last, moved.step.data(), stride);
      }
    });
    for (const Run& r : runs) std::copy_n(next.data() + r.first, r.count, g.v.data() + r.index);
    progress.advance(1.0 / m.substeps);
  }
}

// The smallest box (volume coordinates) holding every voxel of the list; empty for none.
Box listedBounds(const DenseGrid& g, const MovedVoxels& moved) {
  Box b{{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(), std::numeric_limits<int>::max()},
        {std::numeric_limits<int>::min(), std::numeric_limits<int>::min(), std::numeric_limits<int>::min()}};
  for (const Run& r : moved.runs) {
    const Int3 first = g.point(r.index);  // a run lies in one row
    b.lo = {std::min(b.lo.x, first.x), std::min(b.lo.y, first.y), std::min(b.lo.z, first.z)};
    b.hi = {std::max(b.hi.x, first.x + int(r.count)), std::max(b.hi.y, first.y + 1), std::max(b.hi.z, first.z + 1)};
  }
  return b;
}

// Moves the band voxels of `region` (|phi| < band) by m, scaled by the window at each voxel's
// foot point (none: W = 1): listMoved, then moveListed.
void evolve(DenseGrid& g, const Box& region, float band, const Motion& m, const SweptWindow* window,
            const BandVoxels& voxels, ThreadPool& pool, const ProgressShare& progress = {}) {
  listMoved(g, region, band, &m, window, voxels, pool, progress);
  moveListed(g, m, pool, progress);
}

void checkStroke(const Volume& vol, const StrokeSettings& st, std::span<const StrokeDab> dabs) {
  checkStrokeSettings(st);
  for (const StrokeDab& d : dabs) {
    if (!isFinite(d.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
    if (!(d.weight > 0 && d.weight <= 1)) throw EngineError(ErrorKind::InvalidArgument, "weight", "must be in (0, 1]");
    if (!isFinite(d.normal) || (d.normal != Vec3{} && !(std::fabs(dot(d.normal, d.normal) - 1) <= 1e-6)))
      throw EngineError(ErrorKind::InvalidArgument, "normal", "must be a unit vector or zero");
    if (boxAround(d.center, {st.radius, st.radius, st.radius}).intersect(vol.domain()).empty())
      throw EngineError(ErrorKind::OutOfDomain, "center", "the tool's region lies outside the volume");
  }
}

Motion strokeMotion(const StrokeSettings& st) {
  switch (st.tool) {
    case Brush::AddBlob: return advection(st.strength);
    case Brush::RemoveBlob: return advection(-st.strength);
    case Brush::Smooth: return curvatureFlow(st.strength, std::numeric_limits<double>::infinity(), kSmoothSubsteps);
    case Brush::Sharpen: return curvatureFlow(-st.strength, kSharpenCurvatureLimit);
  }
  throw EngineError(ErrorKind::InvalidArgument, "tool", "unknown brush tool");
}

}  // namespace

void checkStrokeSettings(const StrokeSettings& st) {
  requireRange(st.radius, 0.5, kMaxDomainSide, "radius");
  requireFinite(st.strength, "strength");
  if (!(st.strength > 0 && st.strength <= 1))
    throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  if (st.height) {
    if (st.tool != Brush::AddBlob && st.tool != Brush::RemoveBlob)
      throw EngineError(ErrorKind::InvalidArgument, "height", "is only for add_blob and remove_blob");
    const double most = std::min(st.radius * kMaxStrokeHeightPerRadius, kMaxStrokeHeight);
    if (!(std::isfinite(*st.height) && *st.height > 0 && *st.height <= most))
      throw EngineError(ErrorKind::InvalidArgument, "height", "must be in (0, min(radius / 2, 64)] vu");
  }
}

void checkStrokeDab(const Volume& vol, const StrokeSettings& st, const StrokeDab& dab) {
  checkStroke(vol, st, {&dab, 1});
}

Edit applyStroke(Volume& vol, const StrokeSettings& st, std::span<const StrokeDab> dabs,
                 std::span<const StrokeDab> memory, ThreadPool& pool) {
  checkStroke(vol, st, dabs);
  // With a height: the signed height, the window's anchor and each sub-step's speed scale.
  const double height = !st.height ? 0 : st.tool == Brush::AddBlob ? *st.height : -*st.height;
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
    const std::vector<Box> rois = [&] {
      std::vector<Box> b;
      for (const PreparedDab& d : mine) b.push_back(d.roi);
      return b;
    }();
    scratch.band.collect(g, region.grown(1), band, share.part(kCollectShare));
    const SweptWindow window(r, std::move(mine), std::move(remembered), height);
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
      const Box listed = listedBounds(g, scratch.moved);
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

namespace {

// One global application: every chunk evolves its whole grid but a stencil-wide ghost ring,
// then redistances it. The margin covers the sub-steps' stencils, the kept voxels' neighbours
// and the band, so each chunk's interior comes out as if the volume were one grid.
Edit applyGlobal(Volume& vol, const Motion& m, ThreadPool& pool) {
  const float band = vol.band();
  const int margin = int(std::ceil(band)) + 2 + kStencilReach * (m.substeps + 1);
  Edit e;
  e.region = vol.domain();
  const Volume& source = vol;  // read by the chunks, unchanged until the pass publishes
  e.changes = chunkedPass(vol, margin, pool, [&](DenseGrid& g, const Box&, ThreadPool& inner) {
    const Box region = g.box.grown(-kStencilReach);
    BandVoxels& voxels = toolScratch().band;
    voxels.collect(g, region.grown(1), band, source);
    evolve(g, region, band, m, nullptr, voxels, inner);
    RedistanceOptions options;
    options.band = &voxels;
    redistanceRegion(g, region, band, Outside::Ignored, options, inner);
  });
  return e;
}

Edit morph(Volume& vol, double k, double sign, ThreadPool& pool) {
  const int steps = int(std::ceil(k - 1e-9));
  const Motion m = advection(sign * k / steps);
  Edit total;
  for (int s = 0; s < steps; ++s) {
    Edit e = applyGlobal(vol, m, pool);
    total.append(e.changes, e.region);
  }
  return total;
}

void checkMorphRadius(double k, const char* field) { requireRange(k, 1e-3, 64, field); }

}  // namespace

namespace {

Edit applyBrush(Volume& vol, Brush tool, const BrushParams& p, ThreadPool& pool) {
  if (!isFinite(p.center)) throw EngineError(ErrorKind::InvalidArgument, "center", "must be three finite numbers");
  const StrokeDab dab{p.center, 1.0};
  return applyStroke(vol, {tool, p.radius, p.strength}, {&dab, 1}, {}, pool);
}

}  // namespace

Edit addBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::AddBlob, p, pool);
}

Edit removeBlob(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::RemoveBlob, p, pool);
}

Edit smooth(Volume& vol, const BrushParams& p, ThreadPool& pool) { return applyBrush(vol, Brush::Smooth, p, pool); }

Edit sharpen(Volume& vol, const BrushParams& p, ThreadPool& pool) {
  return applyBrush(vol, Brush::Sharpen, p, pool);
}

Edit meanCurvatureFlow(Volume& vol, int iterations, double strength, ThreadPool& pool) {
  requireRange(iterations, 1, 100000, "iterations");
  requireFinite(strength, "strength");
  if (!(strength > 0 && strength <= 1)) throw EngineError(ErrorKind::InvalidArgument, "strength", "must be in (0, 1]");
  const Motion m = curvatureFlow(strength);
  Edit total;
  for (int it = 0; it < iterations; ++it) {
    Edit e = applyGlobal(vol, m, pool);
    total.append(e.changes, e.region);
  }
  return total;
}

Edit dilate(Volume& vol, double k, ThreadPool& pool) {
  checkMorphRadius(k, "radius");
  return morph(vol, k, +1, pool);
}

Edit erode(Volume& vol, double k, ThreadPool& pool) {
  checkMorphRadius(k, "radius");
  return morph(vol, k, -1, pool);
}

Edit openSolid(Volume& vol, double r, ThreadPool& pool) {
  checkMorphRadius(r, "radius");
  Edit e = morph(vol, r, -1, pool);
  Edit d = morph(vol, r, +1, pool);
  e.append(d.changes, d.region);
  return e;
}

Edit closeSolid(Volume& vol, double r, ThreadPool& pool) {
  checkMorphRadius(r, "radius");
  Edit e = morph(vol, r, +1, pool);
  Edit d = morph(vol, r, -1, pool);
  e.append(d.changes, d.region);
  return e;
}

Edit advectInSubsteps(Volume& vol, double distance, int substeps, ThreadPool& pool) {
  requireRange(substeps, 1, 64, "substeps");
  requireFinite(distance, "distance");
  if (!(distance != 0 && std::fabs(distance) / substeps <= kAdvectDt))
    throw EngineError(ErrorKind::InvalidArgument, "distance", "must be nonzero and at most 0.5 vu per sub-step");
  Motion m = advection(distance / (kAdvectDt * substeps));
  m.substeps = substeps;
  return applyGlobal(vol, m, pool);
}

}  // namespace marzipan
