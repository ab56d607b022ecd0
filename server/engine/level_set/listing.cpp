// Lists the band voxels an application moves, with their speeds: each band voxel of the
// region, its foot point q = p - d grad d (the velocity extension: the speed is read there, so
// it is constant along normals and phi - t F stays a distance field) and the tool's window at
// q (a brush's own, or a stroke's SweptWindow), as runs along x in grid index order
// (internal.hpp: MovedVoxels). With the march, this is most of a dab's time, and it runs once
// per band voxel, so everything it calls per voxel is in this file or inline in
// swept_window.hpp (a call per voxel cost 5-10%: the comments below). Built in fixed pieces on
// the pool, joined in order: the same list for any thread count. A speed set per voxel goes
// through setSpeed: where a tool whose speed depends on more than the window (a plane, the
// voxel's own normal) would compute it.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include "engine/simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "engine/level_set/internal.hpp"
#include "engine/level_set/swept_window.hpp"
#include "engine/stencil.hpp"

namespace marzipan::level_set {

namespace {

// A local tool checks the caller's Progress (progress.hpp) every so many band voxels.
constexpr std::size_t kVoxelsPerCheck = std::size_t(1) << 16;

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

// Flatten's and contrast's speed at a voxel with foot point f and window w > 0 (internal.hpp,
// Motion::towardsPlane): -speed * w * h (n . m), h clamped to [-1, 1]: farther from the plane a
// point moves as add blob's would, by speed * w (n . m), and the moves of a stroke's pieces add
// up as add blob's do, where a clamp of the speed itself let each piece move its full vu.
[[gnu::always_inline]] inline double planeSpeed(const Motion& m, const FootPoint& f, double w) {
  const double h = std::clamp(dot(f.point - m.planePoint, m.planeNormal), -1.0, 1.0);
  return -m.speed * w * h * dot(f.normal, m.planeNormal);
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

// A run's push, out of line like SweptWindow::Cursor's destructor (see there).
[[gnu::noinline]] void pushRun(std::vector<Run>& runs, Run r) { runs.push_back(r); }

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
    push(i);
  }
  // Grid voxel i, whose window is > 0, with its advection step (setSpeed's, computed by the caller).
  [[gnu::always_inline]] void addStep(std::size_t i, float step) {
    out.step[count] = step;
    push(i);
  }
  // Grid voxels i to i + 3, whose windows are > 0: the position of the first, where the caller
  // writes their four speed entries (or windows).
  [[gnu::always_inline]] std::size_t pushFour(std::size_t i) {
    if (run.count != 0 && run.index + run.count == i) {
      run.count += 4;
    } else {
      if (run.count != 0) pushRun(out.runs, run);
      run = {std::uint32_t(i), count, 4};
    }
    count += 4;
    return count - 4;
  }
  // Grid voxel i, whose window is > 0, at an advection speed of its own.
  void addSpeed(std::size_t i, double speed) {
    out.step[count] = float(m->dt * float(speed));
    push(i);
  }
  [[gnu::always_inline]] void push(std::size_t i) {
    // Consecutive indices share a row: region lies inside the grid, off its last column.
    if (run.count != 0 && run.index + run.count == i) {
      ++run.count;
    } else {
      if (run.count != 0) pushRun(out.runs, run);
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

// The first position at or after k in voxels (a list in grid index order, ending at `end`) that
// may lie in region, given that voxels.point[k], p, lies outside it: the list of a region grown
// by the band (BandVoxels) holds rows and slices that miss region, which the loops below skip by
// index alone (3 instructions a voxel, where each voxel's point test took 20 or more). Out of
// line: once per row end, not per voxel.
[[gnu::noinline]] std::size_t skipOutside(const DenseGrid& g, const Box& region, const BandVoxels& voxels,
                                          std::size_t k, std::size_t end, Int3 p) {
  const Int3 lo = region.lo, hi = region.hi;
  if (region.empty() || p.z >= hi.z) return end;
  Int3 next;  // the first voxel of region after p in index order
  if (p.z < lo.z) {
    next = lo;
  } else if (p.y < lo.y) {
    next = {lo.x, lo.y, p.z};
  } else if (p.y >= hi.y || (p.x >= hi.x && p.y + 1 == hi.y)) {
    if (p.z + 1 >= hi.z) return end;
    next = {lo.x, lo.y, p.z + 1};
  } else if (p.x < lo.x) {
    next = {lo.x, p.y, p.z};
  } else {
    next = {lo.x, p.y + 1, p.z};
  }
  const std::uint32_t target = std::uint32_t(g.index(next));
  const std::uint32_t* const index = voxels.index.data();
  while (k < end && index[k] < target) ++k;
  return k;
}

#if defined(MARZIPAN_AVX2)
// footPoint of four voxels of one row (grid indices i, x coordinates x; y, z the row's) in the
// lanes of AVX2 vectors, normals n and foot points q: footPoint's operations in its order
// (float differences widened, then double), so the same bits. Along a row the band's voxels
// mostly come in runs of consecutive indices (run: i[k] = i[0] + k), whose neighbours are then
// read four at a time.
__attribute__((target("avx2"))) inline void footPointsAvx2(const DenseGrid& g, const std::size_t i[4], bool run,
                                                           const int x[4], int y, int z, __m256d n[3], __m256d q[3]) {
  const float* const v = g.v.data();
  const std::ptrdiff_t sy = std::ptrdiff_t(g.sx), sz = std::ptrdiff_t(g.sxy);
  __m128 d, dx, dy, dz;
  if (run) {
    const float* a = v + i[0];
    d = _mm_loadu_ps(a);
    dx = _mm_sub_ps(_mm_loadu_ps(a + 1), _mm_loadu_ps(a - 1));
    dy = _mm_sub_ps(_mm_loadu_ps(a + sy), _mm_loadu_ps(a - sy));
    dz = _mm_sub_ps(_mm_loadu_ps(a + sz), _mm_loadu_ps(a - sz));
  } else {
    const float* a[4] = {v + i[0], v + i[1], v + i[2], v + i[3]};
    d = _mm_setr_ps(a[0][0], a[1][0], a[2][0], a[3][0]);
    dx = _mm_setr_ps(a[0][1] - a[0][-1], a[1][1] - a[1][-1], a[2][1] - a[2][-1], a[3][1] - a[3][-1]);
    dy = _mm_setr_ps(a[0][sy] - a[0][-sy], a[1][sy] - a[1][-sy], a[2][sy] - a[2][-sy], a[3][sy] - a[3][-sy]);
    dz = _mm_setr_ps(a[0][sz] - a[0][-sz], a[1][sz] - a[1][-sz], a[2][sz] - a[2][-sz], a[3][sz] - a[3][-sz]);
  }
  const __m256d half = _mm256_set1_pd(0.5), zero = _mm256_setzero_pd();
  const __m256d gx = _mm256_mul_pd(half, _mm256_cvtps_pd(dx)), gy = _mm256_mul_pd(half, _mm256_cvtps_pd(dy)),
                gz = _mm256_mul_pd(half, _mm256_cvtps_pd(dz));
  // normalized(): l = sqrt(x x + y y + z z), l > 0 ? g / l : 0.
  const __m256d l = _mm256_sqrt_pd(
      _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(gx, gx), _mm256_mul_pd(gy, gy)), _mm256_mul_pd(gz, gz)));
  const __m256d positive = _mm256_cmp_pd(l, zero, _CMP_GT_OQ), dist = _mm256_cvtps_pd(d);
  n[0] = _mm256_and_pd(positive, _mm256_div_pd(gx, l));
  n[1] = _mm256_and_pd(positive, _mm256_div_pd(gy, l));
  n[2] = _mm256_and_pd(positive, _mm256_div_pd(gz, l));
  q[0] = _mm256_sub_pd(_mm256_setr_pd(x[0], x[1], x[2], x[3]), _mm256_mul_pd(n[0], dist));
  q[1] = _mm256_sub_pd(_mm256_set1_pd(y), _mm256_mul_pd(n[1], dist));
  q[2] = _mm256_sub_pd(_mm256_set1_pd(z), _mm256_mul_pd(n[2], dist));
}

// Up to four voxels of one row that reach a stroke's window, waiting to be listed together.
struct RowBatch {
  std::size_t index[4];
  int x[4];
  int count = 0;
};

// The batch's windows (SweptWindow::rowWindowsAvx2, then the memory's part per voxel), appended
// in order. c is at the batch's row.
template <bool kAnchored>
__attribute__((target("avx2"))) void listBatchAvx2(const DenseGrid& g, const SweptWindow& window,
                                                   SweptWindow::Cursor& c, RowBatch& b, MovedAppender& add) {
  // The indices of a row's voxels grow: four of them span 3 only in a run.
  const bool run = b.count == 4 && b.index[3] == b.index[0] + 3;
  for (int k = b.count; k < 4; ++k) b.index[k] = b.index[b.count - 1], b.x[k] = b.x[b.count - 1];
  __m256d n[3], q[3];
  footPointsAvx2(g, b.index, run, b.x, c.y, c.z, n, q);
  alignas(32) double w[4];
  if constexpr (!kAnchored) {
    _mm256_store_pd(w, window.brush() ? window.brushWindowsAvx2(q, n) : window.rowWindowsAvx2<false>(b.x, q, n, c));
  } else {
    _mm256_store_pd(w, window.rowWindowsAvx2<true>(b.x, q, n, c));
  }
  if (!c.memory.empty()) {
    alignas(32) double qs[3][4], ns[3][4];
    for (int a = 0; a < 3; ++a) _mm256_store_pd(qs[a], q[a]), _mm256_store_pd(ns[a], n[a]);
    for (int k = 0; k < b.count; ++k) {
      if (!(w[k] > 0)) continue;
      const __m256d qa[3] = {_mm256_set1_pd(qs[0][k]), _mm256_set1_pd(qs[1][k]), _mm256_set1_pd(qs[2][k])};
      const __m256d na[3] = {_mm256_set1_pd(ns[0][k]), _mm256_set1_pd(ns[1][k]), _mm256_set1_pd(ns[2][k])};
      w[k] = window.memoryExcessAvx2<kAnchored>(b.x[k], qa, na, w[k], c);
    }
  }
  // A run of four that all move (most batches of a brush) is appended at once.
  const __m256d ws = _mm256_load_pd(w);
  const bool four = run && _mm256_movemask_pd(_mm256_cmp_pd(ws, _mm256_setzero_pd(), _CMP_GT_OQ)) == 15;
  const int count = b.count;
  b.count = 0;
  if (!add.m) {
    if (four) return _mm256_storeu_pd(add.out.window.data() + add.pushFour(b.index[0]), ws);
    for (int k = 0; k < count; ++k) add.add(b.index[k], w[k]);
    return;
  }
  // setSpeed's entries four at a time: float(speed * w), then float(dt * that) (an advection's
  // step) or dt * that in double (a curvature factor).
  const __m128 speed = _mm256_cvtpd_ps(_mm256_mul_pd(_mm256_set1_pd(add.m->speed), ws));
  const __m256d dt = _mm256_set1_pd(add.m->dt);
  if (add.m->kind == Motion::Kind::Advect) {
    const __m128 steps = _mm256_cvtpd_ps(_mm256_mul_pd(dt, _mm256_cvtps_pd(speed)));
    if (four) return _mm_storeu_ps(add.out.step.data() + add.pushFour(b.index[0]), steps);
    alignas(16) float step[4];
    _mm_store_ps(step, steps);
    for (int k = 0; k < count; ++k)
      if (w[k] > 0) add.addStep(b.index[k], step[k]);
  } else {
    const __m256d factors = _mm256_mul_pd(dt, _mm256_cvtps_pd(speed));
    if (four) return _mm256_storeu_pd(add.out.factor.data() + add.pushFour(b.index[0]), factors);
    for (int k = 0; k < count; ++k) add.add(b.index[k], w[k]);
  }
}

// collectMoved's loop where the window searches its lanes with AVX2 (SweptWindow::searchesAvx2):
// the voxels that reach the window, four of a row at a time (listBatchAvx2). The same voxels,
// foot points and windows in the same order as the search per voxel, so the same list. A row is
// placed once, at its first listed voxel: the window's row, and the grid indices of its voxels
// that lie in region and the window's hull; each voxel of the row is then tested by its index
// alone (a voxel's point test and row test took 45 instructions an entry along a stroke).
template <bool kAnchored>
__attribute__((target("avx2"))) void collectRowsAvx2(const DenseGrid& g, const Box& region, float band,
                                                     const SweptWindow& window, const BandVoxels& voxels,
                                                     std::size_t begin, std::size_t end, MovedVoxels& out,
                                                     const Motion* m, const ProgressShare& progress) {
  MovedAppender add(out, m, end - begin);
  SweptWindow::Cursor cursor;
  RowBatch batch;
  // Grid indices: the row's end, and its voxels [acceptLo, acceptHi) in region and the hull;
  // x of index i in the row is i - xToIndex.
  std::size_t rowEnd = 0, acceptLo = 0, acceptHi = 0, xToIndex = 0;
  for (std::size_t k = begin; k < end; ++k) {
    if (k % kVoxelsPerCheck == 0) progress.check();
    const std::size_t i = voxels.index[k];
    if (i >= rowEnd) {
      if (batch.count != 0) listBatchAvx2<kAnchored>(g, window, cursor, batch, add);
      const Int3 p = voxels.point[k];
      if (p.y < region.lo.y || p.y >= region.hi.y || p.z < region.lo.z || p.z >= region.hi.z) {
        k = skipOutside(g, region, voxels, k + 1, end, p) - 1;
        continue;
      }
      const std::size_t rowStart = i - std::size_t(p.x - g.box.lo.x);
      rowEnd = rowStart + g.sx;
      xToIndex = rowStart - std::size_t(g.box.lo.x);
      window.reaches(p, cursor);  // places the cursor at the row
      const int lo = std::max(region.lo.x, cursor.xLo), hi = std::min(region.hi.x, cursor.xHi);
      acceptLo = acceptHi = rowStart;
      if (lo < hi) acceptLo = xToIndex + std::size_t(lo), acceptHi = xToIndex + std::size_t(hi);
      // The loop below leaves the row only at acceptHi: never past the row's end, whatever box
      // the caller gathered.
      acceptHi = std::min(acceptHi, rowEnd);
    }
    if (i < acceptLo || i >= acceptHi) continue;
    // The row's entries in [acceptLo, acceptHi) follow each other in the list: taken in a loop
    // of their own, which holds only the band test and the batch (the row's tests and the
    // cursor kept it in memory, 33 instructions an entry).
    const float* const v = g.v.data();
    const std::uint32_t* const index = voxels.index.data();
    for (std::size_t j = index[k]; ; ) {
      if (std::fabs(v[j]) < band) {
        batch.index[batch.count] = j;
        batch.x[batch.count] = int(j - xToIndex);
        if (++batch.count == 4) listBatchAvx2<kAnchored>(g, window, cursor, batch, add);
      }
      if (++k == end) break;
      if (k % kVoxelsPerCheck == 0) progress.check();
      j = index[k];
      if (j >= acceptHi) break;
    }
    --k;  // the entry past the row's accepted ones is looked at again by the loop above
  }
  if (batch.count != 0) listBatchAvx2<kAnchored>(g, window, cursor, batch, add);
  add.finish();
}
#endif

// The band voxels voxels.index[begin, end) of region that m moves, appended to out with their
// speeds (the window at each one's foot point; none: W = 1); m null: with their windows instead.
void collectMoved(const DenseGrid& g, const Box& region, float band, const Motion* m, const SweptWindow* window,
                  const BandVoxels& voxels, std::size_t begin, std::size_t end, MovedVoxels& out,
                  const ProgressShare& progress) {
  if (m && m->towardsPlane) {
    // Flatten and contrast: the speed needs the foot point itself, so the window's search and
    // the foot point are the plain ones (the same windows bit for bit: the other paths give
    // the same, as test_swept_window.cpp checks).
    MovedAppender add(out, m, end - begin);
    SweptWindow::Cursor cursor;
    for (std::size_t k = begin; k < end; ++k) {
      if (k % kVoxelsPerCheck == 0) progress.check();
      const std::size_t i = voxels.index[k];
      if (!(std::fabs(g.v[i]) < band)) continue;
      const Int3 p = voxels.point[k];
      if (!region.contains(p)) {
        k = skipOutside(g, region, voxels, k + 1, end, p) - 1;
        continue;
      }
      if (!window->reaches(p, cursor)) continue;
      const FootPoint f = footPointCall(g, i, p);
      const double w = window->at(p, f.point, f.normal, cursor);
      if (w > 0) add.addSpeed(i, planeSpeed(*m, f, w));
    }
    add.finish();
    return;
  }
#if defined(MARZIPAN_AVX2)
  if (window && window->searchesAvx2()) {
    if (window->anchored()) return collectRowsAvx2<true>(g, region, band, *window, voxels, begin, end, out, m, progress);
    return collectRowsAvx2<false>(g, region, band, *window, voxels, begin, end, out, m, progress);
  }
#endif
  MovedAppender add(out, m, end - begin);
  SweptWindow::Cursor cursor;
#if defined(MARZIPAN_SSE2)
  // A brush's windows two voxels at a time where the window does not search with AVX2 (the
  // square root and divisions of the foot point are most of a voxel's cost); the voxels are
  // added in the same order. (With AVX2 a brush takes collectRowsAvx2: its runs' neighbours are
  // read four at a time, which a gather per voxel into lanes did not pay for.)
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
    if (!region.contains(p)) {
      k = skipOutside(g, region, voxels, k + 1, end, p) - 1;
      continue;
    }
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

}  // namespace

void gatherMask(const Volume& vol, const DenseGrid& g) {
  std::vector<std::uint8_t>& mask = toolScratch().mask;
  mask.clear();
  if (vol.paintedBricks() == 0) return;
  const Box inside = g.box.intersect(vol.domain());
  if (inside.empty()) return;
  const Box bricks = Bricks::bricksOf(inside);
  bool masked = false;
  for (int bz = bricks.lo.z; !masked && bz < bricks.hi.z; ++bz)
    for (int by = bricks.lo.y; !masked && by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; !masked && bx < bricks.hi.x; ++bx) {
        const BrickPaint* p = vol.brickPaint({bx, by, bz});
        masked = p && p->masked;
      }
  if (!masked) return;
  std::vector<Texel> texels(std::size_t(g.box.voxels()));
  vol.gatherTexels(g.box, texels.data());
  mask.resize(texels.size());
  for (std::size_t i = 0; i < texels.size(); ++i) mask[i] = texels[i].mask;
}

namespace {

// The mask (channels.hpp): each listed voxel of weight 255 stands still (speed, window 0), so the
// frozen surface does not move and nothing grows in the air beside it. A partial weight w is
// left to the write back (Volume::diff), which moves the voxel by (1 - w/255) of its move: scaled
// here as well, it would move by about (1 - w/255)^2.
void holdMasked(MovedVoxels& moved, const std::vector<std::uint8_t>& mask) {
  for (const Run& r : moved.runs)
    for (std::uint32_t j = 0; j < r.count; ++j) {
      if (mask[r.index + j] != 255) continue;
      const std::size_t k = r.first + j;
      if (!moved.window.empty()) moved.window[k] *= 0.0;
      if (!moved.factor.empty()) moved.factor[k] *= 0.0;
      if (!moved.step.empty()) moved.step[k] = float(double(moved.step[k]) * 0.0);
    }
}

}  // namespace

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
  if (!s.mask.empty()) holdMasked(moved, s.mask);
}

void withSpeeds(MovedVoxels& moved, const Motion& m) {
  sizeSpeeds(moved, &m, moved.count);
  for (std::size_t k = 0; k < moved.count; ++k) setSpeed(moved, k, m, moved.window[k]);
}

}  // namespace marzipan::level_set
