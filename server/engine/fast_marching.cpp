#include "fast_marching.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// The state build's AVX2 loop gives the SSE2 loop's bytes (simd_width.hpp).
#include "simd_width.hpp"
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include "errors.hpp"
#include "thread_pool.hpp"

namespace marzipan {

namespace {

using namespace march_flag;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kBucketsPerVu = 32.0f;
constexpr float kMonotoneRun = 0.2f;  // see MarchOrder::Second
// Buckets between checks of the caller's progress: a bucket of a tool's region takes well
// under a millisecond.
constexpr std::size_t kBucketsPerCheck = 4;
// A voxel's root lies at most 1 vu above its smallest usable neighbour (one axis at first order;
// more axes and Sethian's terms only lower it). So its first solve waits 1 vu after its first
// neighbour was taken: by then the other neighbours it uses are known too, and one solve does
// what one per neighbour did (0.9 solves per voxel taken instead of 2.7 on a sphere's band,
// the sources included). It is then taken at once, up to 0.6 vu after its value's bucket; a
// voxel taken meanwhile that it lowers is taken again (the retake rule), so the result stays
// that of an exact queue: on a sphere's band the distances agree with solving at every
// neighbour taken within 5e-7 vu, and 0.9% of the voxels are retaken (1.1% before).
constexpr std::size_t kDeferBuckets = std::size_t(kBucketsPerVu);
// Fewer candidates than this (a small tool's band) are marched on the calling thread, one side
// after the other: waking a pool thread would cost about as much as the march itself.
constexpr std::size_t kParallelCandidates = std::size_t(1) << 13;

// Each side's own byte per voxel of the grid, built from the shared flags when the side starts:
// what the side may read there, in one load. The shared flags stay read-only while both sides
// run, and each side writes only its own array, so neither writes a byte the other reads.
constexpr std::uint8_t kUse = 1;     // a usable upwind value: a source or bound of this side, or reached
constexpr std::uint8_t kOpen = 2;    // an unknown voxel of this side: the march may lower it
constexpr std::uint8_t kOther = 4;   // a source of the other side: a second point with its sign
constexpr std::uint8_t kTaken = 8;   // taken from the queue at least once (for the retake count)
constexpr std::uint8_t kInside = kInterior;  // copied from the flags: no bounds checks needed
constexpr std::uint8_t kPending = 32;  // a deferred first solve of this voxel is in the queue
constexpr std::uint8_t kSeen = 64;     // a solve of this voxel was deferred at least once
// The state byte's own type: not a character type, so a store to it cannot alias the marcher's
// pointers, strides and values, which the compiler would otherwise load again after every store
// (and the march stores a state byte at almost every step).
enum class State : std::uint8_t {};
// How far a root lies at least above its smallest usable neighbour a, less a bucket for the
// order within one. First order: 1 / sqrt(3) (three axes at a). Second order: a term of 9/4 has
// m >= a + 0.2 / 3 (the monotone run), and of the mixes of terms at a three such are lowest,
// 0.2 / 3 + 2 / sqrt(27).
constexpr float kMinRiseFirst = 0.5773f - 1.0f / kBucketsPerVu;
constexpr float kMinRiseSecond = 0.4516f - 1.0f / kBucketsPerVu;

struct Entry {
  std::uint32_t index;
  float dist;  // the voxel's value when pushed; negative: a deferred first solve
};
// One bucket of the queue: an array whose push is a store and a compare, inlined; its growth
// is not (rare: each thread keeps its buckets' storage from one march to the next), so that
// the marcher's loop holds no call on its common path. Its length is a 32-bit count, not an
// end pointer: a store of a pointer may alias any pointer for the compiler, which would then
// reload the marcher's own after every push. (A bucket holds a few entries per voxel at most,
// and a grid's voxels are indexed in 32 bits, see Entry: 2^32 entries would be 32 GiB.)
class Bucket {
 public:
  Bucket() = default;
  Bucket(const Bucket&) = delete;
  Bucket& operator=(const Bucket&) = delete;
  // A move keeps the storage's buffer, so begin_ stays valid; the source is left empty.
  Bucket(Bucket&& o) noexcept
      : storage_(std::move(o.storage_)),
        begin_(std::exchange(o.begin_, nullptr)),
        size_(std::exchange(o.size_, 0)),
        cap_(std::exchange(o.cap_, 0)) {}
  Bucket& operator=(Bucket&& o) noexcept {
    storage_ = std::move(o.storage_);
    begin_ = std::exchange(o.begin_, nullptr);
    size_ = std::exchange(o.size_, 0);
    cap_ = std::exchange(o.cap_, 0);
    return *this;
  }

  void push(Entry e) {
    if (size_ == cap_) grow();
    begin_[size_++] = e;
  }
  // Entries pushed while the bucket is read are appended (and may move it): read by index.
  std::size_t size() const { return size_; }
  Entry operator[](std::size_t k) const { return begin_[k]; }
  void clear() { size_ = 0; }

 private:
  [[gnu::noinline]] void grow() {
    storage_.resize(std::max<std::size_t>(64, 2 * storage_.size()));
    begin_ = storage_.data(), cap_ = std::uint32_t(storage_.size());
  }
  std::vector<Entry> storage_;
  Entry* begin_ = nullptr;
  std::uint32_t size_ = 0, cap_ = 0;
};
using Buckets = std::vector<Bucket>;

// A stencil term's weight c (1, or Sethian's 9/4) is carried as the integer q = 4c (4 or 9), and
// the solves look up what they need by it, or by the sum of two or three: exact (quarters), and
// no conversion on the way. kWeight[q] = q / 4, kInverse[q] = 1 / (q / 4) = 4 / q (a q of
// 4 or 9 alone: 1 / sqrt(c) in kRootInverse).
constexpr auto kWeight = [] {
  std::array<float, 28> t{};
  for (int k = 1; k < 28; ++k) t[std::size_t(k)] = float(k) / 4.0f;
  return t;
}();
constexpr auto kInverse = [] {
  std::array<float, 28> t{};
  for (int k = 1; k < 28; ++k) t[std::size_t(k)] = 4.0f / float(k);
  return t;
}();
constexpr auto kRootInverse = [] {
  std::array<float, 10> t{};
  t[4] = 1.0f, t[9] = 2.0f / 3.0f;
  return t;
}();

// The square root of d >= 0, correctly rounded (as std::sqrt's), without the errno branch the
// library call keeps for a negative d.
[[gnu::always_inline]] inline float rootOf(float d) {
#if defined(MARZIPAN_SSE2) && defined(__GNUC__)
  float r;
  asm("sqrtss %1, %0" : "=x"(r) : "x"(d));
  return r;
#else
  return std::sqrt(d);
#endif
}

// Solves sum_k c_k (u - m_k)^2 = 1 for the largest root, using the axes in increasing m and
// dropping those whose m is not below the root (Sethian's upwind rule); an axis with m =
// infinity is never used, and with none the root is infinity. q: 4 c. In float, as the result
// is stored: with every m measured from the smallest, no term cancels another.
inline float solveEikonal(float m[3], int q[3]) {
  // A sorting network of three compare-exchanges (ties keep their order; where two m are equal
  // their order does not matter anyway: both are taken, d = 0 lying below any root, and the
  // sums of their terms are exact).
  auto order = [&](int i, int j) __attribute__((always_inline)) {
    const bool swap = m[j] < m[i];
    const float mi = swap ? m[j] : m[i], mj = swap ? m[i] : m[j];
    const int qi = swap ? q[j] : q[i], qj = swap ? q[i] : q[j];
    m[i] = mi, m[j] = mj, q[i] = qi, q[j] = qj;
  };
  order(0, 1), order(1, 2), order(0, 1);
  const float m0 = m[0];
  float u = m0 + kRootInverse[std::uint32_t(q[0])];  // 32 bits: no range test
  if (!(m[1] < u)) return u;
  // The second axis: the sums start at (c0, 0, 0), and 0 + x is x for the x >= 0 here.
  float d = m[1] - m0;
  int qa = q[0] + q[1];
  float a = kWeight[std::uint32_t(qa)], cd = kWeight[std::uint32_t(q[1])] * d;
  float b = cd, cc = cd * d;
  float disc = b * b - a * (cc - 1.0f);
  if (!(disc >= 0.0f)) return u;  // only by rounding: the root lies beyond m[1]
  u = m0 + (b + rootOf(disc)) * kInverse[std::uint32_t(qa)];
  if (!(m[2] < u)) return u;
  d = m[2] - m0;
  qa += q[2];
  a = kWeight[std::uint32_t(qa)], cd = kWeight[std::uint32_t(q[2])] * d;
  b = b + cd, cc = cc + cd * d;
  disc = b * b - a * (cc - 1.0f);
  if (!(disc >= 0.0f)) return u;
  return m0 + (b + rootOf(disc)) * kInverse[std::uint32_t(qa)];
}

// A side's state byte of flags byte f (SideMarcher): what the side may read there.
[[gnu::always_inline]] inline std::uint8_t stateOf(std::uint8_t f, std::uint8_t negBit) {
  const bool own = (f & kNeg) == negBit, usable = (f & (kKnown | kIgnored)) == kKnown;
  const bool bound = f & kUpperBound;
  return std::uint8_t((f & kInterior) | (own && (usable || bound) ? kUse : 0) | (own && !(f & kFrozen) ? kOpen : 0) |
                      (!own && usable ? kOther : 0));
}

#if defined(MARZIPAN_AVX2)
// stateOf 32 bytes at a time: the grid is the gathered box, the band only a few percent of it.
// Each nibble of a flags byte looks up its part of the state byte (vpshufb): the low nibble
// kUse, kOpen and kOther of a usable or unfrozen voxel, and bit 7 for "own side"; the high
// nibble kInterior, and bit 7 for kUpperBound. An upper bound of its own side is usable:
// bit 7 of both, turned into kUse by an unsigned minimum with 1.
__attribute__((target("avx2"))) std::size_t buildStateAvx2(const std::uint8_t* flags, std::uint8_t negBit,
                                                           std::uint8_t* st, std::size_t n) {
  alignas(16) std::uint8_t lo[16], hi[16];
  for (int k = 0; k < 16; ++k) {
    const bool own = (k & kNeg) == negBit;
    lo[k] = std::uint8_t(stateOf(std::uint8_t(k), negBit) | (own ? 0x80 : 0));
    hi[k] = std::uint8_t(((k << 4) & kInterior) | ((k << 4) & kUpperBound));
  }
  const __m256i loTable = _mm256_broadcastsi128_si256(_mm_load_si128(reinterpret_cast<const __m128i*>(lo)));
  const __m256i hiTable = _mm256_broadcastsi128_si256(_mm_load_si128(reinterpret_cast<const __m128i*>(hi)));
  const __m256i nibble = _mm256_set1_epi8(0x0f), keep = _mm256_set1_epi8(char(kUse | kOpen | kOther | kInterior));
  const __m256i one = _mm256_set1_epi8(1);
  std::size_t i = 0;
  for (; i + 32 <= n; i += 32) {
    const __m256i f = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(flags + i));
    const __m256i l = _mm256_shuffle_epi8(loTable, _mm256_and_si256(f, nibble));
    const __m256i h = _mm256_shuffle_epi8(hiTable, _mm256_and_si256(_mm256_srli_epi16(f, 4), nibble));
    const __m256i s = _mm256_or_si256(_mm256_and_si256(_mm256_or_si256(l, h), keep),
                                      _mm256_min_epu8(_mm256_and_si256(l, h), one));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(st + i), s);
  }
  return i;
}
#endif

// st[i] = stateOf(flags[i], negBit) for i < n.
void buildState(const std::uint8_t* flags, std::uint8_t negBit, State* state, std::size_t n) {
  auto* st = reinterpret_cast<std::uint8_t*>(state);  // State's underlying type
  std::size_t i = 0;
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) i = buildStateAvx2(flags, negBit, st, n);
#endif
#if defined(MARZIPAN_SSE2)
  const __m128i negMask = _mm_set1_epi8(char(kNeg)), sideNeg = _mm_set1_epi8(char(negBit));
  const __m128i usableMask = _mm_set1_epi8(char(kKnown | kIgnored)), known = _mm_set1_epi8(char(kKnown));
  const __m128i frozen = _mm_set1_epi8(char(kFrozen)), zero = _mm_setzero_si128();
  const __m128i interior = _mm_set1_epi8(char(kInterior)), use = _mm_set1_epi8(char(kUse));
  const __m128i open = _mm_set1_epi8(char(kOpen)), other = _mm_set1_epi8(char(kOther));
  const __m128i upper = _mm_set1_epi8(char(kUpperBound));
  for (; i + 16 <= n; i += 16) {
    const __m128i f = _mm_loadu_si128(reinterpret_cast<const __m128i*>(flags + i));
    const __m128i own = _mm_cmpeq_epi8(_mm_and_si128(f, negMask), sideNeg);
    const __m128i usable = _mm_cmpeq_epi8(_mm_and_si128(f, usableMask), known);
    const __m128i unfrozen = _mm_cmpeq_epi8(_mm_and_si128(f, frozen), zero);
    const __m128i bound = _mm_cmpeq_epi8(_mm_and_si128(f, upper), upper);
    __m128i s = _mm_and_si128(f, interior);
    s = _mm_or_si128(s, _mm_and_si128(_mm_and_si128(own, _mm_or_si128(usable, bound)), use));
    s = _mm_or_si128(s, _mm_and_si128(_mm_and_si128(own, unfrozen), open));
    s = _mm_or_si128(s, _mm_and_si128(_mm_andnot_si128(own, usable), other));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(st + i), s);
  }
#endif
  for (; i < n; ++i) st[i] = stateOf(flags[i], negBit);
}

// One side of the surface. It reads its own state array, the values of its own side and of
// the other side's sources, and writes only its own side's unknown voxels and its state array:
// the two sides may run at the same time on one grid. Second: MarchOrder::Second (a constant,
// so that the solves test it not at all).
template <bool Second>
class SideMarcher {
 public:
  SideMarcher(DenseGrid& g, const std::uint8_t* flags, std::vector<State>& state, float band, std::uint8_t negBit,
              Buckets& buckets)
      : g_(g), v_(g.v.data()), band_(band), negBit_(negBit), buckets_(buckets) {
    stride_[0] = 1, stride_[1] = g.sx, stride_[2] = g.sxy;
    buckets_.resize(std::size_t(std::ceil(band * kBucketsPerVu)) + 1);
    last_ = buckets_.size() - 1;
    for (auto& b : buckets_) b.clear();
    queue_ = buckets_.data();
    state.resize(g.v.size());
    st_ = state.data();
    buildState(flags, negBit, st_, state.size());
  }

  // progress: this side's share, advanced as its buckets are taken.
  MarchStats run(std::span<const std::uint32_t> seeds, const ProgressShare& progress) {
    for (const std::uint32_t i : seeds) push(i, mag(i), 0);
    const double perBucket = 1.0 / double(buckets_.size());
    for (std::size_t b = 0; b < buckets_.size(); ++b) {
      if (b % kBucketsPerCheck == 0) {
        progress.check();
        if (b > 0) progress.advance(kBucketsPerCheck * perBucket);
      }
      current_ = b;
      // Entries pushed to this bucket while it is taken are appended: read its size each time.
      Bucket& bucket = queue_[b];
      for (std::size_t k = 0; k < bucket.size(); ++k) {
        const Entry e = bucket[k];
        if (e.dist < 0) {  // a deferred first solve
          const std::uint8_t s = st(e.index);
          setSt(e.index, std::uint8_t(s & ~kPending));
          const float u = update(e.index, s);
          if (u == kInf) continue;
          if (bucketOf(u) > b) {
            push(e.index, u, b);
          } else {
            accept(e.index, u);  // due already, as usual (see kDeferBuckets): taken now
          }
          continue;
        }
        if (e.dist != mag(e.index)) continue;  // superseded by a lower entry
        accept(e.index, e.dist);
      }
      bucket.clear();
    }
    progress.advance(double(buckets_.size() - (buckets_.size() - 1) / kBucketsPerCheck * kBucketsPerCheck) * perBucket);
    return {accepted_, retaken_, solved_};
  }

 private:
  float mag(std::size_t i) const { return std::fabs(v_[i]); }
  std::uint8_t st(std::size_t i) const { return std::uint8_t(st_[i]); }
  void setSt(std::size_t i, std::uint8_t s) { st_[i] = State(s); }
  // d * kBucketsPerVu rounded down; d lies in [0, band], so the product fits in 32 bits (whose
  // conversion needs no range test, unlike 64 bits unsigned).
  static std::size_t bucketOf(float d) { return std::uint32_t(d * kBucketsPerVu); }

  // Box-local coordinates of voxel i, by 32-bit divisions (indices fit: see Entry).
  Int3 local(std::size_t i) const {
    const auto k = std::uint32_t(i), sx = std::uint32_t(stride_[1]), sxy = std::uint32_t(stride_[2]);
    const std::uint32_t z = k / sxy, r = k - z * sxy, y = r / sx;
    return {int(r - y * sx), int(y), int(z)};
  }

  void push(std::size_t i, float d, std::size_t minBucket) {
    const std::size_t b = std::max(minBucket, bucketOf(d));
    queue_[std::min(b, last_)].push({std::uint32_t(i), d});
  }

  // Voxel i is taken at distance d: its value becomes usable, and its open neighbours above it
  // are solved again (a neighbour at or below it would drop it from its stencil: the upwind
  // rule). One that has no value yet is not solved now: its first solve is deferred by
  // kDeferBuckets, and every neighbour taken meanwhile joins it. One that has a value is solved
  // at once, as it is due before the deferral would end. One whose neighbours taken so far all
  // lie within the least rise of a root (kMinRiseSecond) of the band's end is not solved at
  // all: its root would lie beyond it.
  [[gnu::always_inline]] inline void accept(std::size_t i, float d) {
    ++accepted_;
    const std::uint8_t si = st(i);
    retaken_ += (si & kTaken) ? 1 : 0;
    setSt(i, std::uint8_t(si | kUse | kTaken));
    // The neighbours to solve now are listed first and solved after, in the same order (a
    // solve writes only its own voxel, which no other visit reads).
    std::size_t todo[6];
    std::uint8_t todoState[6];
    int count = 0;
    const float band = band_;
    const bool early = d < beyond_;
    Bucket& deferred = queue_[std::min(std::max(current_, bucketOf(d) + kDeferBuckets), last_)];
    auto visit = [&](std::size_t n) __attribute__((always_inline)) {
      // The state first: the other side may be writing a voxel that is not open on this one.
      const std::uint8_t s = st(n);
      if ((s & (kOpen | kPending)) != kOpen) return;
      const float m = mag(n);
      if (!(m > d)) return;
      if (m < band) {
        todoState[count] = s;
        todo[count++] = n;
      } else if ((s & kSeen) || early) {
        setSt(n, std::uint8_t(s | kPending | kSeen));
        deferred.push({std::uint32_t(n), -1.0f});
      }
    };
    if (si & kInside) {
      const std::size_t sy = stride_[1], sz = stride_[2];
      visit(i - 1), visit(i + 1), visit(i - sy), visit(i + sy), visit(i - sz), visit(i + sz);
    } else {
      const Int3 p = local(i);
      for (int a = 0; a < 3; ++a) {
        if (p[a] > 0) visit(i - stride_[a]);
        if (p[a] + 1 < g_.size[a]) visit(i + stride_[a]);
      }
    }
    for (int t = 0; t < count; ++t) {
      const float u = update(todo[t], todoState[t]);
      if (u != kInf) push(todo[t], u, current_);
    }
  }

  // Solves voxel n (unknown, this side, state s) from its usable neighbours and lowers it to the
  // root: returns the root, to be queued, or infinity when n is not lowered.
  [[gnu::always_inline]] inline float update(std::size_t n, std::uint8_t s) {
    ++solved_;
    const float u = (s & kInside) ? solveInside(n) : solveBorder(n);
    // Compared as stored, or a root rounded up would be pushed again forever.
    if (!(u < mag(n) && u < band_)) return kInf;
    v_[n] = negBit_ ? -u : u;
    return u;
  }

  // One axis of n's stencil: the smaller usable neighbour on it (ties: the lower one), as the
  // term c (u - m)^2 (given as q = 4 c) with c = 1, or Sethian's second-order term c = 9/4 with
  // m = a + (a - b) / 3 where the voxel b beyond it is known and the run is monotone.
  // m = infinity when the axis has no usable neighbour. A source of the other sign serves as
  // b with its sign: the signed field is smooth across the surface, and without it the first
  // layer off the surface would be only first order, its bias showing in every curvature.
  // Inside: n is at least 2 voxels from every face of the grid, so every load is in the grid
  // and the selection needs no branch.
  [[gnu::always_inline]] inline void axisInside(std::size_t n, std::size_t s, float& m, int& q) const {
    const float lo = (st(n - s) & kUse) ? mag(n - s) : kInf;
    const float hi = (st(n + s) & kUse) ? mag(n + s) : kInf;
    const bool up = hi < lo;
    const float a = up ? hi : lo;
    const std::size_t n2 = up ? n + 2 * s : n - 2 * s;
    const std::uint8_t s2 = st(n2);
    // Read only where the state allows: elsewhere the other side may be writing.
    const float x = (s2 & (kUse | kOther)) ? mag(n2) : kInf;
    const float b = (s2 & kOther) ? -x : x;
    second(a, b, m, q);
  }
  [[gnu::always_inline]] inline void second(float a, float b, float& m, int& q) const {
    const bool two = Second && a - b >= kMonotoneRun;  // false for b = infinity
    m = two ? a + (a - b) * (1.0f / 3.0f) : a;
    q = two ? 9 : 4;  // 4 c
  }

  [[gnu::always_inline]] inline float solveInside(std::size_t n) const {
    float m[3];
    int q[3];
    axisInside(n, 1, m[0], q[0]), axisInside(n, stride_[1], m[1], q[1]), axisInside(n, stride_[2], m[2], q[2]);
    return solveEikonal(m, q);
  }

  // Out of line (a border voxel is the rare case), and pure: it only reads, so the compiler
  // keeps what it holds in registers across the call.
  [[gnu::noinline, gnu::pure]] float solveBorder(std::size_t n) const {
    const Int3 p = local(n);
    float m[3];
    int q[3];
    for (int a = 0; a < 3; ++a) {
      const std::size_t s = stride_[a];
      const float lo = p[a] > 0 && (st(n - s) & kUse) ? mag(n - s) : kInf;
      const float hi = p[a] + 1 < g_.size[a] && (st(n + s) & kUse) ? mag(n + s) : kInf;
      const bool up = hi < lo;
      const int at2 = p[a] + (up ? 2 : -2);
      float b = kInf;
      if (at2 >= 0 && at2 < g_.size[a]) {
        const std::size_t n2 = up ? n + 2 * s : n - 2 * s;
        if (st(n2) & kUse) {
          b = mag(n2);
        } else if (st(n2) & kOther) {
          b = -mag(n2);
        }
      }
      second(up ? hi : lo, b, m[a], q[a]);
    }
    return solveEikonal(m, q);
  }

  DenseGrid& g_;
  float* v_;
  State* st_ = nullptr;
  float band_;
  std::uint8_t negBit_;
  Buckets& buckets_;
  Bucket* queue_;  // buckets_' first: one load less per push than through the vector
  std::size_t last_;  // the last bucket, which takes everything beyond it
  std::size_t stride_[3];
  std::size_t current_ = 0;
  float beyond_ = band_ - (Second ? kMinRiseSecond : kMinRiseFirst);  // see accept()
  // MarchStats' counts, apart: side by side, the compiler pairs the two counts accept()
  // advances into one vector addition, which costs more than the two.
  std::size_t accepted_ = 0;
  std::size_t solved_ = 0;
  std::size_t retaken_ = 0;
};

// Sources (and upper bounds) of a side that border one of its unknown voxels other than upper
// bounds: only these can lower anything. An upper bound is lowered only by the part of the
// surface that moved, which reaches it through the other unknown voxels.
[[gnu::always_inline]] inline bool feeds(const DenseGrid& g, const std::uint8_t* flags, std::size_t i) {
  const std::uint8_t side = flags[i] & kNeg;
  const std::size_t stride[3] = {1, g.sx, g.sxy};
  auto open = [&](std::size_t n) { return (flags[n] & (kFrozen | kNeg | kUpperBound)) == side; };
  if (flags[i] & kInterior) {
    for (int a = 0; a < 3; ++a)
      if (open(i - stride[a]) || open(i + stride[a])) return true;
    return false;
  }
  // Box-local coordinates by 32-bit divisions (indices fit: see Entry).
  const auto k = std::uint32_t(i), sx = std::uint32_t(g.sx), sxy = std::uint32_t(g.sxy);
  const std::uint32_t z = k / sxy, r = k - z * sxy, y = r / sx;
  const int p[3] = {int(r - y * sx), int(y), int(z)};
  for (int a = 0; a < 3; ++a) {
    if (p[a] > 0 && open(i - stride[a])) return true;
    if (p[a] + 1 < g.size[a] && open(i + stride[a])) return true;
  }
  return false;
}

// Whether a flags byte is that of a source or an upper bound (which seed their side when
// within the band and feeding), by table: one load for a test of two bit fields.
constexpr auto kMaySeed = [] {
  std::array<bool, 256> t{};
  for (int f = 0; f < 256; ++f) t[std::size_t(f)] = (f & (kKnown | kIgnored)) == kKnown || (f & kUpperBound);
  return t;
}();

// Appends to seeds[side] the candidates that seed their side (usable, within the band, and
// feeding), in their order; OneSide: only those of side onlyNeg, to seeds[0], reading a value
// only of a voxel of that side, as the other side may be marching. seeds: grown, never
// shrunk, to hold every candidate, so that an append is a store; counts: each list's length.
template <bool OneSide>
void pickSeeds(const DenseGrid& g, const std::uint8_t* flags, std::span<const std::uint32_t> candidates, float band,
               std::uint8_t onlyNeg, std::vector<std::uint32_t>* seeds, std::size_t* counts) {
  constexpr int lists = OneSide ? 1 : 2;
  for (int k = 0; k < lists; ++k)
    if (seeds[k].size() < candidates.size()) seeds[k].resize(candidates.size());
  std::uint32_t* out[2] = {seeds[0].data(), seeds[lists - 1].data()};
  std::size_t count[2] = {0, 0};
  const float* v = g.v.data();
  for (const std::uint32_t i : candidates) {
    const std::uint8_t fi = flags[i];
    if (OneSide && (fi & kNeg) != onlyNeg) continue;
    if (kMaySeed[fi] && std::fabs(v[i]) < band && feeds(g, flags, i)) {
      const int list = !OneSide && (fi & kNeg) ? 1 : 0;
      out[list][count[list]++] = i;
    }
  }
  counts[0] = count[0], counts[1] = count[1];
}

// Per-thread scratch, reused across calls: tools march thousands of times, and fresh
// multi-megabyte arrays each time cost as much in page faults as the marching itself.
struct Scratch {
  std::vector<std::uint8_t> flags;    // fastMarch's classification
  std::vector<State> state[2];  // each side's own (SideMarcher)
  std::vector<std::uint32_t> candidates;
  std::vector<std::uint32_t> seeds[2];
  Buckets buckets[2];
};
Scratch& scratch() {
  thread_local Scratch s;
  return s;
}

}  // namespace

std::size_t marchScratchBytes() {
  const Scratch& s = scratch();
  std::size_t bytes = s.flags.capacity() + s.state[0].capacity() + s.state[1].capacity() +
                      4 * (s.candidates.capacity() + s.seeds[0].capacity() + s.seeds[1].capacity());
  for (const Buckets& b : s.buckets) bytes += b.capacity() * sizeof(Bucket);
  return bytes;
}

void trimMarchScratch(std::size_t voxels) {
  Scratch& s = scratch();
  if (s.flags.capacity() > voxels || s.state[0].capacity() > voxels || s.state[1].capacity() > voxels ||
      s.candidates.capacity() > voxels)
    s = Scratch();
}

MarchStats fastMarchClassified(DenseGrid& g, const std::vector<std::uint8_t>& flags,
                               std::span<const std::uint32_t> candidates, float band, MarchOrder order,
                               ThreadPool& pool, ProgressShare progress, bool parallelSides) {
  requireRange(band, kMinMarchBand, kMaxMarchBand, "band");
  Scratch& s = scratch();
  const std::uint8_t* f = flags.data();
  const bool second = order == MarchOrder::Second;
  MarchStats side[2];
  auto march = [&](std::size_t k, std::span<const std::uint32_t> seeds) {
    const std::uint8_t negBit = k ? kNeg : 0;
    if (second) {
      SideMarcher<true> m(g, f, s.state[k], band, negBit, s.buckets[k]);
      side[k] = m.run(seeds, progress.part(0.5));
    } else {
      SideMarcher<false> m(g, f, s.state[k], band, negBit, s.buckets[k]);
      side[k] = m.run(seeds, progress.part(0.5));
    }
  };
  if (pool.threads() > 1 && (parallelSides || candidates.size() >= kParallelCandidates)) {
    // Each side picks its own seeds, so that neither waits for the other.
    pool.parallelFor(2, [&](std::size_t k) {
      std::size_t count[2];
      pickSeeds<true>(g, f, candidates, band, k ? kNeg : 0, &s.seeds[k], count);
      march(k, {s.seeds[k].data(), count[0]});
    });
  } else {
    std::size_t count[2];
    pickSeeds<false>(g, f, candidates, band, 0, s.seeds, count);
    march(0, {s.seeds[0].data(), count[0]});
    march(1, {s.seeds[1].data(), count[1]});
  }
  return {side[0].accepted + side[1].accepted, side[0].retaken + side[1].retaken, side[0].solved + side[1].solved};
}

MarchStats fastMarch(DenseGrid& g, const std::vector<MarchState>& state, float band, MarchOrder order) {
  requireRange(band, kMinMarchBand, kMaxMarchBand, "band");
  Scratch& s = scratch();
  s.flags.resize(g.v.size());
  s.candidates.clear();
  float* v = g.v.data();
  std::uint8_t* flags = s.flags.data();
  const int sx = g.size.x, sy = g.size.y, sz = g.size.z;
  const int xLo = std::min(2, sx), xHi = std::max(xLo, sx - 2);  // interior columns [xLo, xHi)
  std::size_t row = 0;
  for (int z = 0; z < sz; ++z)
    for (int y = 0; y < sy; ++y, row += std::size_t(sx)) {
      const std::uint8_t inner = z >= 2 && z + 2 < sz && y >= 2 && y + 2 < sy ? kInterior : 0;
      for (int x = 0; x < sx; ++x) {
        const std::size_t i = row + std::size_t(x);
        const std::uint8_t st = std::uint8_t(state[i]);
        const bool neg = v[i] < 0;
        flags[i] = std::uint8_t(st | (neg ? kNeg : 0) | (x >= xLo && x < xHi ? inner : 0));
        if (state[i] == MarchState::Unknown) {
          v[i] = neg ? -band : band;
        } else if (state[i] == MarchState::Source && std::fabs(v[i]) < band) {
          s.candidates.push_back(std::uint32_t(i));
        }
      }
    }
  return fastMarchClassified(g, s.flags, s.candidates, band, order, ThreadPool::serial());
}


}  // namespace marzipan
