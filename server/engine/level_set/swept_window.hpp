// A stroke's speed scale at a band voxel (../level_set.hpp, strokes): the largest window
// weight * W(q) over the message's dabs whose ROI holds the voxel, less the largest its memory
// (the dabs the stroke already applied) reaches there. This is the stroke memory: what lets a
// stroke move each point of the surface by its strongest dab, however its dabs were grouped
// into messages. One SweptWindow per application and group of dabs. Points in vu (voxel p at
// the point p), ROIs half-open boxes. Every width (the scalar search, SSE2 and AVX2 lanes:
// simd_width.hpp) gives the same largest window bit for bit; the members under MARZIPAN_SSE2
// exist only in the vector build, which is why the scalar build (MARZIPAN_SCALAR_KERNELS)
// compiles this whole folder again (tests/CMakeLists.txt).
//
// Wholly in this header, though it is most of a stroke's code: listing.cpp reads it once per
// band voxel, and its loops must see every member, also the ones that run once per row (newRow,
// search): with those in a file of their own, GCC could no longer tell what the call changes,
// kept less in registers across it, and listing a stroke with a height took 1.4% more
// instructions (callgrind, stroke16_height4, 2026-11-29).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "engine/simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "engine/geometry.hpp"

namespace marzipan::level_set {

// W's factor along one axis at t = |q_a - c_a| / radius.
inline double window1(double t) {
  if (t >= 1) return 0;
  const double u = 1 - t * t;
  return u * u;
}

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
// moved back along the dab's normal by (q - c).normal clamped between 0 and the anchor (a dab
// without a normal: along n by all of (q - c).n), and scaled by normal . n (level_set.hpp,
// strokes).
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
    // Out of line, as listing.cpp's pushRun: inlined into listing.cpp's loops (which the code
    // of level_set.cpp did not do before it was split into this folder), the two grew those
    // loops by a third and made them run up to 0.8% more instructions (callgrind, stroke_scrub
    // and stroke16_height4, 2026-11-29).
    [[gnu::noinline]] ~Cursor() {}
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
      // The lanes of the row's dabs `row` (indices into prepared, increasing), `all` holding all of them.
      void list(const std::vector<PreparedDab>& prepared, const std::vector<std::uint32_t>& row, const LaneArrays& all,
                bool normals) {
        if (row.empty() || row.back() - row.front() + 1 == row.size()) {
          arrays = &all;
          begin = row.empty() ? 0 : row.front();
          end = begin + row.size();
        } else {
          own.fill(prepared, row.data(), row.size(), normals);
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
  // Whether search takes searchAvx2 now (then a caller compiled for AVX2 may list four voxels
  // of a row at a time itself, rowWindowsAvx2 then memoryExcessAvx2, with the foot points in
  // registers rather than passed through two calls: search's bits). A brush too, whose one dab
  // needs no search and no mask: brushWindowsAvx2 (a 70^3 add blob 30.1M -> 28.5M instructions
  // against listing.cpp's SSE2 pairs, 2026-11-30).
  bool searchesAvx2() const {
    return lanes_ && simd_width::useAvx2();
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
    return memoryExcessAvx2<kAnchored>(p.x, qa, na, w, c);
  }

  // lanesAvx2's message part for four voxels of c's row at once (x: theirs, ascending; a batch
  // of fewer repeats its last), a voxel a lane, with their foot points q and normals n in lanes:
  // each dab of the row whose ROI holds one of their x is read once for the four, each lane
  // masked by whether the dab's ROI holds its x. Per voxel and dab the operations of
  // quadWindows, and the largest of the same values (in another order: only a zero's sign could
  // differ, and every window here is >= +0), so the same bits. Along a stroke a voxel lies in
  // about eight ROIs, so four voxels read each dab about as often as lanesAvx2 reads four dabs a
  // voxel, without its setup per voxel. The memory is memoryExcessAvx2's.
  template <bool kAnchored>
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline __m256d rowWindowsAvx2(const int x[4], const __m256d q[3],
                                                                                    const __m256d n[3],
                                                                                    Cursor& c) const {
    Cursor::Lanes& l = c.dabLanes;
    l.at(x[0]);
    const std::size_t from = l.first, holdsFirst = l.last;
    l.at(x[3]);
    const std::size_t to = l.last;
    // The dabs [whole, wholeEnd) hold all four x (their ROIs' hi past x[3], lo at or before
    // x[0]): read without the mask. Those before and after are masked.
    const std::size_t whole = l.first, wholeEnd = std::max(whole, holdsFirst);
    const LaneArrays& arr = *l.arrays;
    const __m256d zero = _mm256_setzero_pd();
    const __m256d xs = _mm256_setr_pd(x[0], x[1], x[2], x[3]);
    const auto window = [&](std::size_t j) __attribute__((always_inline, target("avx2"))) {
      return dabWindowsAvx2<kAnchored>(arr, j, q, n);
    };
    const auto masked = [&](std::size_t j) __attribute__((always_inline, target("avx2"))) {
      const __m256d inside = _mm256_and_pd(_mm256_cmp_pd(_mm256_broadcast_sd(arr.lo.data() + j), xs, _CMP_LE_OS),
                                           _mm256_cmp_pd(xs, _mm256_broadcast_sd(arr.hi.data() + j), _CMP_LT_OS));
      return _mm256_and_pd(inside, window(j));
    };
    __m256d best = zero;
    for (std::size_t j = from; j < whole; ++j) best = _mm256_max_pd(best, masked(j));
    for (std::size_t j = whole; j < wholeEnd; ++j) best = _mm256_max_pd(best, window(j));
    for (std::size_t j = wholeEnd; j < to; ++j) best = _mm256_max_pd(best, masked(j));
    return best;
  }

  // rowWindowsAvx2 for a brush (brush() not null) at four voxels of a row its ROI holds (the
  // cursor's row, x in [xLo, xHi)): its one dab's window, read without a search or a mask (the
  // value rowWindowsAvx2 takes the largest of with +0, which every window here is at least).
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline __m256d brushWindowsAvx2(const __m256d q[3],
                                                                                      const __m256d n[3]) const {
    return dabWindowsAvx2<false>(allDabs_, 0, q, n);
  }

  // lanesAvx2's memory part: w (> 0, the message's largest window at voxel x of c's row, foot
  // point qa, normal na) less the memory's largest there, or less the first memory window found
  // to reach it.
  template <bool kAnchored>
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline double memoryExcessAvx2(int x, const __m256d qa[3],
                                                                                      const __m256d na[3], double w,
                                                                                      Cursor& c) const {
    const __m256d back[2] = {_mm256_set1_pd(std::min(0.0, anchor_)), _mm256_set1_pd(std::max(0.0, anchor_))};
    const __m256d four = _mm256_set1_pd(4.0), offsets = _mm256_setr_pd(0, 1, 2, 3);
    Cursor::Lanes& ml = c.memoryLanes;
    ml.at(x);
    const __m256d enough = _mm256_set1_pd(w), memoryLast = _mm256_set1_pd(double(ml.last));
    double excess;
    // The lanes from the one that reached w at a voxel before, in lanes rather than by window():
    // that call of legacy-SSE code from here took 7% of stroke_drag's CPU on a Zen 3 (the SSE-AVX
    // mix). Its lanes past ml.last are masked: any lane that reaches w is one whose ROI holds p.
    if (const std::size_t j = c.reachedLane; j >= ml.first && j < ml.last) {
      const __m256d inside = _mm256_cmp_pd(_mm256_add_pd(_mm256_set1_pd(double(j)), offsets), memoryLast, _CMP_LT_OS);
      if (reaching(c, j, quadWindows<kAnchored>(ml, j, qa, na, back, inside), enough, w, excess)) return excess;
    }
    __m256d best = _mm256_setzero_pd();
    __m256d at = _mm256_add_pd(_mm256_set1_pd(double(ml.first)), offsets);
    for (std::size_t j = ml.first; j < ml.last; j += 4, at = _mm256_add_pd(at, four)) {
      const __m256d m = quadWindows<kAnchored>(ml, j, qa, na, back, _mm256_cmp_pd(at, memoryLast, _CMP_LT_OS));
      if (reaching(c, j, m, enough, w, excess)) return excess;
      best = _mm256_max_pd(best, m);
    }
    return w - largestLane(best);
  }

 private:
  // Dab j of arr's window at four voxels (a lane each) with foot points q and normals n:
  // quadWindows' operations for one dab (rowWindowsAvx2's per dab and voxel).
  template <bool kAnchored>
  [[gnu::always_inline]] __attribute__((target("avx2"))) inline __m256d dabWindowsAvx2(const LaneArrays& arr,
                                                                                    std::size_t j,
                                                                                    const __m256d q[3],
                                                                                    const __m256d n[3]) const {
    const __m256d one = _mm256_set1_pd(1.0), zero = _mm256_setzero_pd(), invR = _mm256_set1_pd(inverseRadius_);
    __m256d w = _mm256_broadcast_sd(arr.weight.data() + j);
    const __m256d centre[3] = {_mm256_broadcast_sd(arr.center[0].data() + j),
                               _mm256_broadcast_sd(arr.center[1].data() + j),
                               _mm256_broadcast_sd(arr.center[2].data() + j)};
    __m256d at[3] = {q[0], q[1], q[2]};
    if constexpr (kAnchored) {
      const __m256d back[2] = {_mm256_set1_pd(std::min(0.0, anchor_)), _mm256_set1_pd(std::max(0.0, anchor_))};
      const __m256d axis[3] = {_mm256_broadcast_sd(arr.normal[0].data() + j),
                               _mm256_broadcast_sd(arr.normal[1].data() + j),
                               _mm256_broadcast_sd(arr.normal[2].data() + j)};
      const __m256d facing = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(axis[0], n[0]), _mm256_mul_pd(axis[1], n[1])),
                                           _mm256_mul_pd(axis[2], n[2]));
      w = _mm256_mul_pd(w, _mm256_max_pd(facing, zero));
      const __m256d along = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(_mm256_sub_pd(q[0], centre[0]), axis[0]),
                                                        _mm256_mul_pd(_mm256_sub_pd(q[1], centre[1]), axis[1])),
                                          _mm256_mul_pd(_mm256_sub_pd(q[2], centre[2]), axis[2]));
      const __m256d moved = _mm256_min_pd(_mm256_max_pd(along, back[0]), back[1]);
      for (int a = 0; a < 3; ++a) at[a] = _mm256_sub_pd(q[a], _mm256_mul_pd(axis[a], moved));
    }
    // quadWindows' factor without its absolute value: t t is the same bits for -t (rounding
    // is symmetric), and t >= 1 exactly where fl(t t) >= 1, where u = 1 - t t <= 0.
    for (int a = 0; a < 3; ++a) {
      const __m256d t = _mm256_mul_pd(_mm256_sub_pd(at[a], centre[a]), invR);
      const __m256d u = _mm256_sub_pd(one, _mm256_mul_pd(t, t));
      w = _mm256_mul_pd(w, _mm256_and_pd(_mm256_cmp_pd(u, zero, _CMP_GT_OQ), _mm256_mul_pd(u, u)));
    }
    return w;
  }
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
      x = d.normal == Vec3{} ? q - axis * along
                             : q - axis * (anchor_ > 0 ? std::clamp(along, 0.0, anchor_) : std::clamp(along, anchor_, 0.0));
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

}  // namespace marzipan::level_set
