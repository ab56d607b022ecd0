// Undo/redo of whole steps (see history.hpp).
#include "service/history.hpp"

#include "engine/progress.hpp"
#include "engine/simd_width.hpp"  // MARZIPAN_AVX2

#include <zstd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(MARZIPAN_AVX2)
#include <immintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>
#include <utility>

namespace marzipan::service {

namespace {

constexpr std::size_t kBrickBytes = sizeof(Brick);
static_assert(kBrickBytes == kBrickVoxels * 4, "a brick is 512 floats of 4 bytes");
// A step is packed on its session's strand between two edits: level 1 packs these differences
// as small as level 3 (4.53x against 4.50x on the pig's strokes) in a sixth of the time, and
// packing was 9% of a loaded server's CPU at level 3 with a fresh context per step.
constexpr int kZstdLevel = 1;
// The clamp of the prediction: any bound works (prediction and its inverse use the same), this
// one keeps 2a - b finite for any finite a, b of a field clamped to its band (at most 8 vu).
constexpr float kMaxBand = 8.0f;

// A brick of one side is stored against the same brick of the other side (its reference),
// which the volume holds whenever the step moves: an edit changes some voxels of a brick and
// leaves the rest, so most differences are zero or small. Where the reference is uniform, a
// voxel is predicted instead by linear extrapolation of the two before it along x (clamped
// to +-kMaxBand; far voxels are exactly +-band and predict themselves). Differences are taken
// on the floats' order-preserving 32-bit integers and zigzagged so that small ones of either
// sign have zero high bytes. A brick against a reference is written as a mask of its voxels
// whose difference is not zero (kMaskBytes) and then byte p of each of those differences in
// plane p; a predicted brick as byte p of every voxel's in plane p (kBrickBytes). The bricks'
// records, in order, become one zstd frame, but for the low planes (bytes 0 and 1) of the
// bricks against a reference, which follow it as they are, in the same order. Each step is a
// bijection on 32-bit words given the reference and the voxels already decoded: unpacking is
// exact. On the pig, 30-dab strokes: 4.5x against the other side, 2.6x with the predictor
// alone, 2.57x for raw floats. The mask leaves zstd the changed voxels alone (most of a brick
// is as it was): against all four planes of every voxel, packing took 30% fewer instructions
// and the frames came out 0.8-9% smaller (5.5% on the dab_message bench). The low planes of
// the changed voxels are close to noise, which zstd made no smaller: kept out of it, the steps
// take 0.8% less memory on the dab_message bench (2.5% on the pig's strokes) and the packing a
// quarter fewer instructions (docs/benchmark-log.md, capacity, 2026-11-30 06:20 and 12:40).
std::uint32_t ordered(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  // ~u for a set sign bit, else u with it set: u xor all ones or xor the sign bit, without a
  // branch, so that the loops over a brick vectorize.
  return u ^ (static_cast<std::uint32_t>(static_cast<std::int32_t>(u) >> 31) | 0x80000000u);
}

float unordered(std::uint32_t u) {
  u = (u & 0x80000000u) ? (u & 0x7fffffffu) : ~u;
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

std::uint32_t zigzag(std::uint32_t d) { return (d << 1) ^ static_cast<std::uint32_t>(static_cast<std::int32_t>(d) >> 31); }
std::uint32_t unzigzag(std::uint32_t z) { return (z >> 1) ^ (0u - (z & 1u)); }

// The prediction of voxel i of v: the reference's voxel, or from the voxels before it in its row.
std::uint32_t predict(const float* v, const float* reference, int i) {
  if (reference) return ordered(reference[i]);
  const int x = Bricks::local(i).x;
  if (x == 0) return ordered(0.0f);
  if (x == 1) return ordered(v[i - 1]);
  return ordered(std::clamp(2.0f * v[i - 1] - v[i - 2], -kMaxBand, kMaxBand));
}

constexpr std::size_t kMaskBytes = kBrickVoxels / 8;
constexpr int kLowPlanes = 2;  // the planes of a brick against a reference kept out of zstd

// The bytes of a brick's record that go through zstd, and of its low planes that do not.
struct RecordBytes {
  std::size_t packed = 0, low = 0;
};

#if defined(MARZIPAN_AVX2)
// The zigzagged differences z of v against reference and their mask (bit i: z[i] != 0), eight
// voxels at a time: the integer operations of ordered and zigzag, so the same words. Returns the
// count of differing voxels.
__attribute__((target("avx2,popcnt"))) int differencesAvx2(const float* v, const float* reference, std::uint32_t* z,
                                                            std::uint64_t* mask) {
  const __m256i sign = _mm256_set1_epi32(std::int32_t(0x80000000u)), zero = _mm256_setzero_si256();
  int count = 0;
  for (int w = 0; w < kBrickVoxels / 64; ++w) {
    std::uint64_t m = 0;
    for (int k = 0; k < 64; k += 8) {
      const int i = 64 * w + k;
      const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(v + i)),
                    b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(reference + i));
      const __m256i d = _mm256_sub_epi32(_mm256_xor_si256(a, _mm256_or_si256(_mm256_srai_epi32(a, 31), sign)),
                                         _mm256_xor_si256(b, _mm256_or_si256(_mm256_srai_epi32(b, 31), sign)));
      const __m256i zz = _mm256_xor_si256(_mm256_slli_epi32(d, 1), _mm256_srai_epi32(d, 31));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(z + i), zz);
      const int same = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(zz, zero)));
      m |= std::uint64_t(~same & 0xff) << k;
    }
    mask[w] = m;
    count += std::popcount(m);
  }
  return count;
}
#endif

// The zigzagged differences and their mask, as differencesAvx2, at the width simd_width allows.
int differences(const float* v, const float* reference, std::uint32_t* z, std::uint64_t* mask) {
#if defined(MARZIPAN_AVX2)
  if (simd_width::useAvx2()) return differencesAvx2(v, reference, z, mask);
#endif
  // In a loop the compiler vectorizes.
  for (int i = 0; i < kBrickVoxels; ++i) z[i] = zigzag(ordered(v[i]) - ordered(reference[i]));
  int count = 0;
  for (int w = 0; w < kBrickVoxels / 64; ++w) {
    std::uint64_t m = 0;
#if defined(__SSE2__)
    // 16 words at a time: their comparisons with zero, packed to bytes, as 16 bits.
    const __m128i zero = _mm_setzero_si128();
    for (int k = 0; k < 64; k += 16) {
      const __m128i* q = reinterpret_cast<const __m128i*>(z + 64 * w + k);
      const __m128i e0 = _mm_cmpeq_epi32(_mm_loadu_si128(q), zero), e1 = _mm_cmpeq_epi32(_mm_loadu_si128(q + 1), zero),
                    e2 = _mm_cmpeq_epi32(_mm_loadu_si128(q + 2), zero), e3 = _mm_cmpeq_epi32(_mm_loadu_si128(q + 3), zero);
      const int same = _mm_movemask_epi8(_mm_packs_epi16(_mm_packs_epi32(e0, e1), _mm_packs_epi32(e2, e3)));
      m |= std::uint64_t(~same & 0xffff) << k;
    }
#else
    for (int k = 0; k < 64; ++k) m |= std::uint64_t(z[64 * w + k] != 0) << k;
#endif
    mask[w] = m;
    count += std::popcount(m);
  }
  return count;
}

// Writes brick b's record at out, its low planes (against a reference) at low.
RecordBytes splitPlanes(const Brick& b, const float* reference, unsigned char* out, unsigned char* low) {
  if (reference) {
    // The differences first; then the mask and the bytes of the voxels that differ.
    std::uint32_t z[kBrickVoxels];
    std::uint64_t mask[kBrickVoxels / 64];
    const int count = differences(b.v, reference, z, mask);
    std::memcpy(out, mask, kMaskBytes);
    unsigned char* planes = out + kMaskBytes;
    int n = 0;
    for (int w = 0; w < kBrickVoxels / 64; ++w)
      for (std::uint64_t m = mask[w]; m; m &= m - 1, ++n) {
        const std::uint32_t d = z[64 * w + std::countr_zero(m)];
        for (int p = 0; p < kLowPlanes; ++p) low[p * count + n] = static_cast<unsigned char>(d >> (8 * p));
        for (int p = kLowPlanes; p < 4; ++p) planes[(p - kLowPlanes) * count + n] = static_cast<unsigned char>(d >> (8 * p));
      }
    return {kMaskBytes + (4 - kLowPlanes) * std::size_t(count), kLowPlanes * std::size_t(count)};
  }
  for (int i = 0; i < kBrickVoxels; ++i) {
    const std::uint32_t z = zigzag(ordered(b.v[i]) - predict(b.v, reference, i));
    for (int p = 0; p < 4; ++p) out[p * kBrickVoxels + i] = static_cast<unsigned char>(z >> (8 * p));
  }
  return {kBrickBytes, 0};
}

// Reads the record of a brick at in, of at most `size` bytes, and its low planes at low, of at
// most `lowSize`, into b; returns their sizes, or a packed size of 0 when they do not fit.
RecordBytes joinPlanes(const unsigned char* in, std::size_t size, const unsigned char* low, std::size_t lowSize,
                       const float* reference, Brick& b) {
  if (reference) {
    if (size < kMaskBytes) return {};
    std::uint64_t mask[kBrickVoxels / 64];
    std::memcpy(mask, in, kMaskBytes);
    std::size_t count = 0;
    for (const std::uint64_t m : mask) count += std::size_t(std::popcount(m));
    if (size - kMaskBytes < (4 - kLowPlanes) * count || lowSize < kLowPlanes * count) return {};
    std::memcpy(b.v, reference, sizeof b.v);
    const unsigned char* planes = in + kMaskBytes;
    std::size_t n = 0;
    for (int w = 0; w < kBrickVoxels / 64; ++w)
      for (std::uint64_t m = mask[w]; m; m &= m - 1, ++n) {
        std::uint32_t z = 0;
        for (int p = 0; p < kLowPlanes; ++p) z |= std::uint32_t(low[p * count + n]) << (8 * p);
        for (int p = kLowPlanes; p < 4; ++p) z |= std::uint32_t(planes[(p - kLowPlanes) * count + n]) << (8 * p);
        const int i = 64 * w + std::countr_zero(m);
        b.v[i] = unordered(ordered(reference[i]) + unzigzag(z));
      }
    return {kMaskBytes + (4 - kLowPlanes) * count, kLowPlanes * count};
  }
  if (size < kBrickBytes) return {};
  for (int i = 0; i < kBrickVoxels; ++i) {
    std::uint32_t z = 0;
    for (int p = 0; p < 4; ++p) z |= std::uint32_t(in[p * kBrickVoxels + i]) << (8 * p);
    b.v[i] = unordered(predict(b.v, reference, i) + unzigzag(z));
  }
  return {kBrickBytes, 0};
}

// A cheap fingerprint of the references a step was packed against: unpacking against other
// bricks (a history out of step with its volume, a logic error) is refused, not decoded into
// wrong floats.
std::uint64_t fingerprint(const std::vector<const BrickRef*>& refs) {
  std::uint64_t h = 0;
  for (const BrickRef* r : refs) {
    h = h * 1099511628211ull + (r->data ? 2 : r->inside);
    if (!r->data) continue;
    for (int i = 0; i < kBrickVoxels; i += 8) {
      std::uint32_t u;
      std::memcpy(&u, &r->data->v[i], 4);
      h = h * 31 + u;
    }
  }
  return h;
}

// Buffers of up to this size stay with their thread (a stroke of 128^3 packs ~1 MiB).
constexpr std::size_t kKeptScratchBytes = std::size_t(8) << 20;

// A scratch buffer that grows without zeroing what will be written over.
struct ScratchBytes {
  std::unique_ptr<unsigned char[]> bytes;
  std::size_t size = 0;
  unsigned char* atLeast(std::size_t n) {
    if (size < n) {
      bytes = std::make_unique_for_overwrite<unsigned char[]>(n);
      size = n;
    }
    return bytes.get();
  }
  void release() {
    bytes.reset();
    size = 0;
  }
};

// One compression context and buffers per thread, reused: a fresh context costs its tables'
// initialisation, and fresh buffers page faults and zeroing, on every step.
struct Scratch {
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> cctx{ZSTD_createCCtx(), &ZSTD_freeCCtx};
  ScratchBytes planes, low, frame;
};

Scratch& scratch() {
  thread_local Scratch s;
  if (!s.cctx) throw std::runtime_error("zstd: cannot create a compression context");
  return s;
}

std::vector<const BrickRef*> pointers(const std::vector<BrickRef>& refs) {
  std::vector<const BrickRef*> out;
  for (const auto& r : refs) out.push_back(&r);
  return out;
}

// The bounding box of changed bricks, in brick coordinates (half-open); empty when none.
Box brickBounds(const std::vector<Int3>& bricks) {
  if (bricks.empty()) return {};
  Box b{bricks[0], bricks[0]};
  for (const Int3& c : bricks)
    for (int a = 0; a < 3; ++a) {
      b.lo[a] = std::min(b.lo[a], c[a]);
      b.hi[a] = std::max(b.hi[a], c[a]);
    }
  b.hi = {b.hi.x + 1, b.hi.y + 1, b.hi.z + 1};
  return b;
}

std::vector<Int3> bricksOf(const Edit& e) {
  std::vector<Int3> out;
  out.reserve(e.changes.size());
  for (const auto& c : e.changes) out.push_back(c.brick);
  return out;
}

bool boxesMeet(const Box& a, const Box& b) {
  for (int i = 0; i < 3; ++i)
    if (a.hi[i] <= b.lo[i] || b.hi[i] <= a.lo[i]) return false;
  return !a.empty() && !b.empty();
}

// Brick coordinates are below 2^21 (a side is at most kMaxDomainSide voxels).
std::uint64_t brickKey(Int3 b) {
  return std::uint64_t(std::uint32_t(b.x)) | (std::uint64_t(std::uint32_t(b.y)) << 21) |
         (std::uint64_t(std::uint32_t(b.z)) << 42);
}

}  // namespace

std::size_t PackedBricks::bytes() const {
  std::size_t channels = paints.capacity() * sizeof(std::shared_ptr<const BrickPaint>);
  for (const auto& p : paints) channels += p ? sizeof(BrickPaint) : 0;
  return bricks.capacity() * sizeof(Int3) + kinds.capacity() + frame.capacity() + channels;
}

PackedBricks packBricks(const std::vector<Int3>& bricks, const std::vector<const BrickRef*>& refs,
                        const std::vector<const BrickRef*>& against) {
  PackedBricks p;
  p.bricks = bricks;
  p.kinds.reserve(refs.size());
  p.against = fingerprint(against);
  if (std::any_of(refs.begin(), refs.end(), [](const BrickRef* r) { return r->paint != nullptr; })) {
    p.paints.reserve(refs.size());
    for (const BrickRef* r : refs) p.paints.push_back(r->paint);
  }
  std::size_t dataBricks = 0;
  for (const BrickRef* r : refs) dataBricks += r->data != nullptr;
  if (dataBricks == 0) {
    for (const BrickRef* r : refs) p.kinds.push_back(r->inside ? PackedBricks::kInside : PackedBricks::kOutside);
    return p;
  }
  Scratch& z = scratch();
  const std::size_t bound = dataBricks * (kMaskBytes + kBrickBytes), lowBound = dataBricks * kLowPlanes * kBrickVoxels;
  unsigned char* const planes = z.planes.atLeast(bound);
  unsigned char* const low = z.low.atLeast(lowBound);
  RecordBytes size;
  for (std::size_t i = 0; i < refs.size(); ++i) {
    const BrickRef* r = refs[i];
    if (!r->data) {
      p.kinds.push_back(r->inside ? PackedBricks::kInside : PackedBricks::kOutside);
      continue;
    }
    p.kinds.push_back(PackedBricks::kData);
    const RecordBytes s = splitPlanes(*r->data, against[i]->data ? against[i]->data->v : nullptr,
                                      planes + size.packed, low + size.low);
    size.packed += s.packed;
    size.low += s.low;
  }
  const std::size_t frameBound = ZSTD_compressBound(size.packed);
  unsigned char* const frame = z.frame.atLeast(frameBound);
  const std::size_t n = ZSTD_compressCCtx(z.cctx.get(), frame, frameBound, planes, size.packed, kZstdLevel);
  if (ZSTD_isError(n)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(n));
  p.frame.reserve(n + size.low);  // exactly these bytes, no slack (and not zeroed first)
  p.frame.insert(p.frame.end(), frame, frame + n);
  p.frame.insert(p.frame.end(), low, low + size.low);
  if (bound > kKeptScratchBytes) {
    // A whole-volume step: do not keep its buffers for the life of the thread.
    z.planes.release();
    z.low.release();
    z.frame.release();
  }
  return p;
}

std::vector<BrickRef> unpackBricks(const PackedBricks& p, const std::vector<const BrickRef*>& against) {
  if (against.size() != p.kinds.size() || fingerprint(against) != p.against)
    throw std::runtime_error("undo history: a step unpacked against other bricks than it was packed against");
  std::size_t dataBricks = 0;
  for (const auto k : p.kinds) dataBricks += k == PackedBricks::kData;
  const auto damaged = [] { return std::runtime_error("zstd: an undo step does not unpack to its bricks"); };
  std::vector<unsigned char> planes;
  // The zstd frame's own headers say where it ends and the low planes begin: a field for it
  // would make every packed side's shared block 16 bytes larger (kStepBytes).
  const std::size_t packed = p.frame.empty() ? 0 : ZSTD_findFrameCompressedSize(p.frame.data(), p.frame.size());
  if (ZSTD_isError(packed)) throw damaged();
  const unsigned char* low = p.frame.data() + packed;
  const std::size_t lowSize = p.frame.size() - packed;
  if (dataBricks) {
    const unsigned long long size = ZSTD_getFrameContentSize(p.frame.data(), packed);
    if (size == ZSTD_CONTENTSIZE_ERROR || size == ZSTD_CONTENTSIZE_UNKNOWN || size > dataBricks * (kMaskBytes + kBrickBytes))
      throw damaged();
    planes.resize(std::size_t(size));
    const std::size_t n = ZSTD_decompress(planes.data(), planes.size(), p.frame.data(), packed);
    if (ZSTD_isError(n) || n != planes.size()) throw damaged();
  }
  std::vector<BrickRef> out;
  out.reserve(p.kinds.size());
  RecordBytes next;
  for (std::size_t i = 0; i < p.kinds.size(); ++i) {
    BrickRef r;
    if (p.kinds[i] == PackedBricks::kData) {
      auto b = std::make_shared_for_overwrite<Brick>();  // joinPlanes sets every voxel
      const RecordBytes used = joinPlanes(planes.data() + next.packed, planes.size() - next.packed, low + next.low,
                                          lowSize - next.low, against[i]->data ? against[i]->data->v : nullptr, *b);
      if (used.packed == 0) throw damaged();
      next.packed += used.packed;
      next.low += used.low;
      r.data = std::move(b);
    } else {
      r.inside = p.kinds[i] == PackedBricks::kInside;
    }
    if (!p.paints.empty()) r.paint = p.paints[i];
    out.push_back(std::move(r));
  }
  if (next.packed != planes.size() || next.low != lowSize) throw damaged();
  return out;
}

namespace {

// Heap bytes of a string: none while it fits in the object itself (the short-string buffer).
std::size_t heapBytes(const std::string& s) {
  const char* self = reinterpret_cast<const char*>(&s);
  return s.data() >= self && s.data() < self + sizeof s ? 0 : s.capacity() + 1;
}

// The side of a step the volume does not hold, with the volume's side, as changes (before,
// after): the step's own Edit when unpacked, else its packed side unpacked against `at`.
Edit sidesOf(const std::optional<Edit>& edit, const PackedBricks* packed, const Box& region,
             const std::function<BrickRef(const Int3&)>& at, bool undoSide) {
  if (edit) return *edit;
  Edit e;
  e.region = region;
  std::vector<BrickRef> live;
  live.reserve(packed->bricks.size());
  for (const Int3& b : packed->bricks) live.push_back(at(b));
  const std::vector<BrickRef> other = unpackBricks(*packed, pointers(live));
  for (std::size_t i = 0; i < other.size(); ++i) {
    if (undoSide) e.changes.push_back({packed->bricks[i], other[i], live[i]});
    else e.changes.push_back({packed->bricks[i], live[i], other[i]});
  }
  return e;
}

// The bricks a step changed.
const std::vector<Int3>& packedBricks(const std::shared_ptr<const PackedBricks>& p) {
  static const std::vector<Int3> none;
  return p ? p->bricks : none;
}

}  // namespace

std::size_t History::Step::bytes() const {
  const std::size_t fixed =
      kStepBytes + heapBytes(info.author.id) + heapBytes(info.author.name) + heapBytes(info.tool);
  if (!edit) return fixed + (packed ? packed->bytes() : 0);
  std::size_t buffers = 0, channels = 0;
  for (const auto& c : edit->changes) {
    buffers += (c.before.data != nullptr) + (c.after.data != nullptr);
    channels += (c.before.paint != nullptr) + (c.after.paint != nullptr);
  }
  return fixed + buffers * kBytesPerBrick + channels * sizeof(BrickPaint) + edit->changes.capacity() * sizeof(BrickChange);
}

Volume Rebuild::run() const {
  Volume v = base_;
  Progress* progress = Progress::current();
  // Newest first: each step's bricks then hold its `after`, which its packing refers to.
  for (const Later& s : later_) {
    if (progress) progress->check();
    const auto at = [&](const Int3& b) { return v.brick(b); };
    v.publish(sidesOf(s.edit, s.packed.get(), s.region, at, true).changes, false);
    if (progress) progress->advance(1);
  }
  v.setRevision(revision_);
  return v;
}

History::History(std::size_t budgetBytes) : budget_(budgetBytes) { rewritten(); }

void History::pack(Step& s) {
  if (!s.edit) return;
  std::vector<Int3> bricks;
  std::vector<const BrickRef*> before, after;
  for (const auto& c : s.edit->changes) {
    bricks.push_back(c.brick);
    before.push_back(&c.before);
    after.push_back(&c.after);
  }
  auto packed = std::make_shared<const PackedBricks>(packBricks(bricks, before, after));
  remove(s);
  s.packed = std::move(packed);
  s.edit.reset();
  add(s);
}

void History::enforceBudget() {
  while (!undo_.empty() && bytes_ > budget_) {
    remove(undo_.front());
    undo_.pop_front();
    ++dropped_;
  }
  // Only a smaller budget can leave redo steps over it: the furthest future goes first.
  while (!redo_.empty() && bytes_ > budget_) {
    remove(redo_.front());
    redo_.pop_front();
    ++dropped_;
  }
}

History::StepId History::push(Edit step, StepInfo info, const std::function<bool(StepId)>& growing) {
  if (step.empty()) return 0;
  for (const auto& s : redo_) remove(s);
  redo_.clear();
  if (!undo_.empty() && !(growing && growing(undo_.back().id))) pack(undo_.back());
  const StepId id = nextId_++;
  const Box region = step.region;
  info.region = region;
  info.bricks = brickBounds(bricksOf(step));
  if (info.firstRevision == 0) info.firstRevision = info.revision;
  info.undone = false;
  undo_.push_back({id, region, std::move(info), std::move(step), nullptr});
  add(undo_.back());
  enforceBudget();
  return id;
}

bool History::amend(StepId id, const Edit& more, std::uint64_t revision) {
  if (id == 0 || undo_.empty() || !redo_.empty() || undo_.back().id != id || !undo_.back().edit) return false;
  Step& s = undo_.back();
  remove(s);
  s.edit->append(more.changes, more.region);
  s.region = s.edit->region;
  s.info.region = s.region;
  s.info.bricks = brickBounds(bricksOf(*s.edit));
  if (revision != 0) s.info.revision = revision;
  if (s.edit->empty()) {
    // The step now ends where it started: nothing is left to undo.
    undo_.pop_back();
    return true;
  }
  add(s);
  enforceBudget();
  return true;
}

Edit History::sides(const Step& s, const std::function<BrickRef(const Int3&)>& at, bool undoSide) const {
  return sidesOf(s.edit, s.packed.get(), s.region, at, undoSide);
}

namespace {

// The first of steps[from..to) that changed one of these bricks (inside `bounds`).
template <class Steps>
std::optional<std::size_t> firstTouching(const Steps& steps, const std::vector<Int3>& bricks, const Box& bounds,
                                         std::size_t from, std::size_t to) {
  std::unordered_set<std::uint64_t> keys;
  for (const Int3& b : bricks) keys.insert(brickKey(b));
  for (std::size_t j = from; j < to; ++j) {
    if (!boxesMeet(steps[j].info.bricks, bounds)) continue;
    const auto& s = steps[j];
    if (s.edit) {
      for (const auto& c : s.edit->changes)
        if (keys.count(brickKey(c.brick))) return j;
    } else {
      for (const Int3& b : packedBricks(s.packed))
        if (keys.count(brickKey(b))) return j;
    }
  }
  return std::nullopt;
}

}  // namespace

bool History::fold(StepId id, const Edit& more, const Volume& vol, std::uint64_t revision) {
  if (id == 0 || !redo_.empty()) return false;
  std::size_t i = undo_.size();
  while (i > 0 && undo_[i - 1].id != id) --i;
  if (i == 0) return false;
  --i;
  if (i + 1 == undo_.size() && undo_[i].edit) return amend(id, more, revision);
  const std::vector<Int3> moreBricks = bricksOf(more);
  if (firstTouching(undo_, moreBricks, brickBounds(moreBricks), i + 1, undo_.size())) return false;
  Step& s = undo_[i];
  if (!s.edit) {
    Edit e;
    // The step's `after` bricks, which its `before` was packed against. The volume before
    // `more` is `more`'s `before` where it changed a brick (no later step touched those), vol
    // elsewhere; the later steps are then taken back over it, newest first, so that each one's
    // own `after` is what it is read against, and every brick holds what step i left.
    std::unordered_map<std::uint64_t, BrickRef> earlier;
    for (const auto& c : more.changes) earlier[brickKey(c.brick)] = c.before;
    const auto at = [&](const Int3& b) {
      const auto it = earlier.find(brickKey(b));
      return it != earlier.end() ? it->second : vol.brick(b);
    };
    for (std::size_t j = undo_.size(); j-- > i + 1;)
      for (const BrickChange& c : sides(undo_[j], at, true).changes) earlier[brickKey(c.brick)] = c.before;
    std::vector<BrickRef> after;
    for (const Int3& b : s.packed->bricks) after.push_back(at(b));
    const std::vector<BrickRef> before = unpackBricks(*s.packed, pointers(after));
    e.region = s.region;
    for (std::size_t k = 0; k < before.size(); ++k) e.changes.push_back({s.packed->bricks[k], before[k], after[k]});
    remove(s);
    s.edit = std::move(e);
    s.packed = nullptr;
    add(s);
  }
  // Step i's bricks change under newer steps: the version after each of them changes too.
  rewritten();
  remove(s);
  s.edit->append(more.changes, more.region);
  if (s.edit->empty()) {
    // The step now ends where it started: nothing is left to undo.
    undo_.erase(undo_.begin() + std::ptrdiff_t(i));
    return true;
  }
  s.info.region = s.region = s.edit->region;
  s.info.bricks = brickBounds(bricksOf(*s.edit));
  if (revision != 0) s.info.revision = revision;
  add(s);
  enforceBudget();
  return true;
}

std::size_t History::unpackedSteps() const {
  return std::size_t(std::count_if(undo_.begin(), undo_.end(), [](const Step& s) { return s.edit.has_value(); }));
}

void History::seal(StepId id) {
  for (std::size_t i = 0; i + 1 < undo_.size(); ++i)
    if (undo_[i].id == id) pack(undo_[i]);
}

// Both moves build the step's other side and the new packing before changing anything, so a
// failure (out of memory) leaves the history and the volume as they were.
const Edit* History::moveToRedo(std::size_t i, Volume& vol) {
  Step& s = undo_[i];
  Edit e = sides(s, vol, true);
  std::vector<Int3> bricks;
  std::vector<const BrickRef*> before, after;
  for (const auto& c : e.changes) {
    bricks.push_back(c.brick);
    before.push_back(&c.before);
    after.push_back(&c.after);
  }
  auto packed = std::make_shared<const PackedBricks>(packBricks(bricks, after, before));
  // A step taken out from under newer ones: the versions after those no longer hold it.
  if (i + 1 != undo_.size()) rewritten();
  remove(s);
  s.edit.reset();
  s.packed = std::move(packed);
  redo_.push_back(std::move(s));
  undo_.erase(undo_.begin() + std::ptrdiff_t(i));
  add(redo_.back());
  vol.publish(e.changes, false);
  movedInfo_ = redo_.back().info;
  moved_ = std::move(e);
  return &moved_;
}

const Edit* History::moveToUndo(std::size_t i, Volume& vol) {
  Edit e = sides(redo_[i], vol, false);
  std::vector<const BrickRef*> before, after;
  for (const auto& c : e.changes) {
    before.push_back(&c.before);
    after.push_back(&c.after);
  }
  auto packed = std::make_shared<const PackedBricks>(packBricks(redo_[i].packed->bricks, before, after));
  // Only the newest undo step may stay unpacked (redoOf can leave one under a redo list).
  if (!undo_.empty()) pack(undo_.back());
  Step& s = redo_[i];
  remove(s);
  s.packed = std::move(packed);
  undo_.push_back(std::move(s));
  redo_.erase(redo_.begin() + std::ptrdiff_t(i));
  add(undo_.back());
  vol.publish(e.changes, true);
  movedInfo_ = undo_.back().info;
  moved_ = std::move(e);
  return &moved_;
}

const Edit* History::undo(Volume& vol) {
  if (undo_.empty()) return nullptr;
  return moveToRedo(undo_.size() - 1, vol);
}

const Edit* History::redo(Volume& vol) {
  if (redo_.empty()) return nullptr;
  return moveToUndo(redo_.size() - 1, vol);
}

namespace {

// The first of steps[from..to) that changed one of steps[mine]'s bricks.
template <class Steps>
std::optional<std::size_t> firstMeeting(const Steps& steps, std::size_t mine, std::size_t from, std::size_t to) {
  const auto& m = steps[mine];
  return firstTouching(steps, m.edit ? bricksOf(*m.edit) : packedBricks(m.packed), m.info.bricks, from, to);
}

// The author's newest step of `steps` moved by move(index), unless a later step of the same
// list touched one of its bricks: the oldest such step holds them now and is in the way (on
// the redo list, the steps above come back first).
template <class Steps, class Move>
History::AuthorMove moveNewestOf(const Steps& steps, const std::string& author, Move&& move) {
  History::AuthorMove r;
  if (author.empty()) return r;
  std::size_t i = steps.size();
  while (i > 0 && steps[i - 1].info.author.id != author) --i;
  if (i == 0) return r;
  --i;
  if (const auto j = firstMeeting(steps, i, i + 1, steps.size())) {
    r.outcome = History::AuthorMove::Conflict;
    r.step = steps[i].info;
    r.conflict = steps[*j].info;
    return r;
  }
  r.edit = move(i);
  r.outcome = History::AuthorMove::Moved;
  return r;
}

}  // namespace

History::AuthorMove History::undoOf(Volume& vol, const std::string& author) {
  AuthorMove r = moveNewestOf(undo_, author, [&](std::size_t i) { return moveToRedo(i, vol); });
  if (r.outcome == AuthorMove::Moved) r.step = movedInfo_;
  return r;
}

History::AuthorMove History::redoOf(Volume& vol, const std::string& author) {
  AuthorMove r = moveNewestOf(redo_, author, [&](std::size_t i) { return moveToUndo(i, vol); });
  if (r.outcome == AuthorMove::Moved) r.step = movedInfo_;
  return r;
}

std::vector<StepInfo> History::list() const {
  std::vector<StepInfo> out;
  out.reserve(steps());
  for (const Step& s : undo_) out.push_back(s.info);
  for (auto it = redo_.rbegin(); it != redo_.rend(); ++it) {
    out.push_back(it->info);
    out.back().undone = true;
  }
  return out;
}

History::Page History::page(std::optional<std::uint64_t> before, std::size_t limit) const {
  const std::size_t total = steps();
  const auto at = [&](std::size_t k) -> const Step& {
    return k < redo_.size() ? redo_[k] : undo_[undo_.size() - 1 - (k - redo_.size())];
  };
  Page p;
  std::size_t from = 0;
  if (before) {
    while (from < total && at(from).info.revision != *before) ++from;
    if (from == total) {
      p.found = false;
      return p;
    }
    ++from;
  }
  const std::size_t to = std::min(total, from + limit);
  p.steps.reserve(to - from);
  for (std::size_t k = from; k < to; ++k) {
    p.steps.push_back(at(k).info);
    p.steps.back().undone = k < redo_.size();
  }
  p.more = to < total;
  return p;
}

std::optional<StepInfo> History::newest() const {
  if (undo_.empty()) return std::nullopt;
  return undo_.back().info;
}

std::optional<StepInfo> History::find(std::uint64_t revision) const {
  for (const Step& s : undo_)
    if (s.info.revision == revision) return s.info;
  return std::nullopt;
}

std::size_t History::undoIndex(std::uint64_t revision) const {
  std::size_t i = 0;
  while (i < undo_.size() && undo_[i].info.revision != revision) ++i;
  return i;
}

namespace {

// Generations are unique across histories: a Rebuild gathered from one session's history is
// never kept by another (a session rolled back to its journal has a new History).
std::uint64_t nextGeneration() {
  static std::atomic<std::uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace

void History::rewritten() {
  generation_ = nextGeneration();
  kept_.reset();
}

std::optional<Rebuild> History::rebuildAt(const Volume& live, std::uint64_t revision) const {
  const std::size_t i = undoIndex(revision);
  if (i == undo_.size()) return std::nullopt;
  Rebuild r(live);
  r.revision_ = revision;
  r.generation_ = generation_;
  r.later_.reserve(undo_.size() - i - 1);
  for (std::size_t j = undo_.size(); j-- > i + 1;) {
    const Step& s = undo_[j];
    r.later_.push_back({s.edit, s.packed, s.region});
    const std::size_t bricks = s.edit ? s.edit->changes.size() : s.packed->bricks.size();
    r.voxels_ += double(bricks) * kBrickVoxels;
  }
  return r;
}

std::optional<Volume> History::keptAt(std::uint64_t revision) const {
  if (!kept_ || kept_->revision != revision || kept_->generation != generation_) return std::nullopt;
  // An amended or undone newest step no longer names this revision.
  if (undoIndex(revision) == undo_.size()) return std::nullopt;
  return kept_->volume;
}

void History::keep(const Rebuild& r, const Volume& built) const {
  if (r.generation_ != generation_) return;
  kept_.reset();
  kept_.emplace(Kept{r.revision_, r.generation_, built});
}

std::optional<Volume> History::volumeAt(const Volume& live, std::uint64_t revision) const {
  if (std::optional<Volume> v = keptAt(revision)) return v;
  const std::optional<Rebuild> r = rebuildAt(live, revision);
  if (!r) return std::nullopt;
  Volume v = r->run();
  keep(*r, v);
  return v;
}

void History::clear() {
  undo_.clear();
  redo_.clear();
  bytes_ = 0;
  moved_ = Edit{};
  movedInfo_ = {};
  rewritten();
}

void History::setBudget(std::size_t budgetBytes) {
  budget_ = budgetBytes;
  enforceBudget();
}

}  // namespace marzipan::service
