// History (server/service/history.cpp): undo and redo restore exact digests through packed
// (zstd) steps, bytes() counts the packed sizes, the memory budget drops the oldest steps
// first, and a new step clears the redo list. The budget bounds the real memory of tiny steps.
#include <catch2/catch.hpp>

#include <malloc.h>
#include <zstd.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <vector>

#include "engine/csg.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/paint.hpp"
#include "engine/simd_width.hpp"
#include "engine/solids.hpp"
#include "service/history.hpp"
#include "../engine/support.hpp"

using namespace marzipan;
using service::History;

namespace {

constexpr int kN = 48;
constexpr double kC = (kN - 1) / 2.0;
const double kSurface = kC + 0.35 * kN;

Volume sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

// A mix of local and global steps, each recorded in h; returns the digest before each step
// and, last, the digest after all of them.
std::vector<std::uint64_t> runMix(Volume& v, History& h, ThreadPool& pool) {
  std::vector<std::uint64_t> digests{digest(v)};
  h.push(addBlob(v, {{kSurface, kC, kC}, 6, 1}, pool));
  digests.push_back(digest(v));
  h.push(applyCsg(v, {CsgOp::Subtract, ToolShape::Box, {kC, kSurface, kC}, 5, 1, 0}, pool));
  digests.push_back(digest(v));
  h.push(dilate(v, 1, pool));
  digests.push_back(digest(v));
  h.push(smooth(v, {{kC, kC, kSurface}, 7, 1}, pool));
  digests.push_back(digest(v));
  h.push(meanCurvatureFlow(v, 1, 1, pool));
  digests.push_back(digest(v));
  return digests;
}

}  // namespace

TEST_CASE("history: undo and redo restore the exact digests of a mix of steps", "[history]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  const auto digests = runMix(v, h, pool);
  REQUIRE(h.undoSteps() == 5);
  const std::size_t recorded = h.bytes();
  CHECK(recorded > 0);
  for (std::size_t i = 1; i < digests.size(); ++i) CHECK(digests[i] != digests[i - 1]);

  for (std::size_t i = digests.size() - 1; i > 0; --i) {
    REQUIRE(h.canUndo());
    REQUIRE(h.undo(v) != nullptr);
    CHECK(digest(v) == digests[i - 1]);
  }
  CHECK_FALSE(h.canUndo());
  CHECK(h.undo(v) == nullptr);
  CHECK(h.redoSteps() == 5);

  for (std::size_t i = 1; i < digests.size(); ++i) {
    REQUIRE(h.redo(v) != nullptr);
    CHECK(digest(v) == digests[i]);
  }
  CHECK_FALSE(h.canRedo());
  CHECK(h.redo(v) == nullptr);
  // The newest step was held unpacked (shared buffers) until it moved; now every step is packed.
  CHECK(h.bytes() < recorded);

  // Undo and redo again, now all from packed steps both ways.
  for (std::size_t i = digests.size() - 1; i > 0; --i) {
    REQUIRE(h.undo(v) != nullptr);
    CHECK(digest(v) == digests[i - 1]);
  }
  for (std::size_t i = 1; i < digests.size(); ++i) {
    REQUIRE(h.redo(v) != nullptr);
    CHECK(digest(v) == digests[i]);
  }
}

TEST_CASE("history: steps of channels (paint, mask) and of distances over painted clay undo and redo packed, exactly",
          "[history][paint]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  std::vector<std::uint64_t> digests{digest(v)};
  PaintSettings red;
  red.color = {200, 20, 10};
  red.radius = 6;
  h.push(paint(v, red, {kSurface, kC, kC}));
  digests.push_back(digest(v));
  // Over the paint: an add blob whose bricks carry channels on both sides.
  h.push(addBlob(v, {{kSurface, kC, kC}, 5, 1}, pool));
  digests.push_back(digest(v));
  PaintSettings mask;
  mask.mode = PaintMode::MaskAdd;
  mask.radius = 6;
  h.push(paint(v, mask, {kC, kSurface, kC}));
  digests.push_back(digest(v));
  h.push(maskInvert(v));
  digests.push_back(digest(v));
  for (std::size_t i = 1; i < digests.size(); ++i) CHECK(digests[i] != digests[i - 1]);
  // Every step but the newest is packed now; two rounds move each through both packings.
  for (int round = 0; round < 2; ++round) {
    for (std::size_t i = digests.size() - 1; i > 0; --i) {
      REQUIRE(h.undo(v) != nullptr);
      CHECK(digest(v) == digests[i - 1]);
    }
    CHECK(v.paintedBricks() == 0);
    for (std::size_t i = 1; i < digests.size(); ++i) {
      REQUIRE(h.redo(v) != nullptr);
      CHECK(digest(v) == digests[i]);
    }
  }
}

TEST_CASE("history: packed bricks unpack to the same bits", "[history]") {
  std::mt19937 rng(7);
  std::vector<Int3> coords;
  std::vector<BrickRef> refs;
  for (int i = 0; i < 8; ++i) {
    coords.push_back({i, 2 * i, 3});
    BrickRef r;
    if (i == 1) {
      r.inside = true;  // uniform inside
    } else if (i != 4) {  // 4: uniform outside
      auto b = std::make_shared<Brick>();
      for (int k = 0; k < kBrickVoxels; ++k) {
        // Any bit pattern, negative zero and denormals included, but also runs of +-band.
        const std::uint32_t bits = i == 2 ? 0x80000000u + k : rng();
        std::memcpy(&b->v[k], &bits, 4);
        if (i == 3 && k % 3) b->v[k] = (k % 2) ? 3.0f : -3.0f;
      }
      r.data = std::move(b);
    }
    refs.push_back(std::move(r));
  }
  // The other side: brick 0 and 5 against a changed copy of themselves (a third of the voxels
  // differ), 6 against an identical copy (none differ), 7 against other random bits (every
  // voxel differs), the rest against uniform bricks (the prediction along x).
  std::vector<BrickRef> others(refs.size());
  for (const std::size_t i : {0, 5, 6}) {
    auto b = std::make_shared<Brick>(*refs[i].data);
    if (i != 6)
      for (int k = 0; k < kBrickVoxels; k += 3) b->v[k] = -b->v[k];
    others[i].data = std::move(b);
  }
  {
    auto b = std::make_shared<Brick>();
    for (int k = 0; k < kBrickVoxels; ++k) {
      const std::uint32_t bits = rng() | 1u;
      std::memcpy(&b->v[k], &bits, 4);
    }
    for (int k = 0; k < kBrickVoxels; ++k)
      if (std::memcmp(&b->v[k], &refs[7].data->v[k], 4) == 0) b->v[k] = -b->v[k];
    others[7].data = std::move(b);
  }
  others[2].inside = true;
  std::vector<const BrickRef*> ptrs, against;
  for (const auto& r : refs) ptrs.push_back(&r);
  for (const auto& r : others) against.push_back(&r);
  const service::PackedBricks p = service::packBricks(coords, ptrs, against);
  CHECK(p.bricks.size() == 8);
  // The same bytes at both vector widths (the differences and their mask eight voxels at a time
  // in AVX2).
  const service::PackedBricks narrow = [&] {
    const test::WidestWidthAtExit restore;
    simd_width::limitWidth(simd_width::Width::Sse2);
    return service::packBricks(coords, ptrs, against);
  }();
  CHECK(narrow.frame == p.frame);
  CHECK(narrow.kinds == p.kinds);
  const std::vector<BrickRef> back = service::unpackBricks(p, against);
  REQUIRE(back.size() == refs.size());
  for (std::size_t i = 0; i < refs.size(); ++i) {
    INFO("brick " << i);
    REQUIRE(back[i].uniform() == refs[i].uniform());
    if (refs[i].uniform()) {
      CHECK(back[i].inside == refs[i].inside);
    } else {
      CHECK(back[i].data != refs[i].data);  // a buffer of its own
      CHECK(std::memcmp(back[i].data->v, refs[i].data->v, sizeof(Brick)) == 0);
    }
  }

  SECTION("a damaged frame is refused, not unpacked into wrong bricks") {
    service::PackedBricks bad = p;
    bad.frame.resize(bad.frame.size() / 2);
    CHECK_THROWS_AS(service::unpackBricks(bad, against), std::runtime_error);
  }
  SECTION("records that do not fit their frame are refused") {
    // One brick against its changed copy: a record of its mask (64 bytes) and the high bytes of
    // the differing voxels in the zstd frame, their low bytes (two planes) after it. The same
    // content recompressed unpacks; each damage below is refused by the records' own checks
    // (zstd accepts the frames).
    const service::PackedBricks one = service::packBricks({coords[0]}, {ptrs[0]}, {against[0]});
    const std::size_t packed = ZSTD_findFrameCompressedSize(one.frame.data(), one.frame.size());
    REQUIRE(packed < one.frame.size());
    std::vector<unsigned char> content(ZSTD_getFrameContentSize(one.frame.data(), packed));
    REQUIRE(ZSTD_decompress(content.data(), content.size(), one.frame.data(), packed) == content.size());
    const std::vector<unsigned char> low(one.frame.begin() + std::ptrdiff_t(packed), one.frame.end());
    // 171 of the 512 voxels changed (every third): 2 high and 2 low bytes each.
    REQUIRE(content.size() == 64 + 2 * 171);
    REQUIRE(low.size() == 2 * 171);
    const auto repacked = [&](const std::vector<unsigned char>& c, const std::vector<unsigned char>& l) {
      service::PackedBricks q = one;
      q.frame.resize(ZSTD_compressBound(c.size()));
      q.frame.resize(ZSTD_compress(q.frame.data(), q.frame.size(), c.data(), c.size(), 1));
      q.frame.insert(q.frame.end(), l.begin(), l.end());
      return q;
    };
    const std::vector<BrickRef> same = service::unpackBricks(repacked(content, low), {against[0]});
    REQUIRE(same.size() == 1);
    CHECK(std::memcmp(same[0].data->v, refs[0].data->v, sizeof(Brick)) == 0);
    std::vector<unsigned char> allChanged = content;  // a mask claiming every voxel, short of bytes
    std::fill(allChanged.begin(), allChanged.begin() + 64, 0xff);
    CHECK_THROWS_AS(service::unpackBricks(repacked(allChanged, low), {against[0]}), std::runtime_error);
    std::vector<unsigned char> trailing = content;
    trailing.push_back(0);
    CHECK_THROWS_AS(service::unpackBricks(repacked(trailing, low), {against[0]}), std::runtime_error);
    const std::vector<unsigned char> cut(content.begin(), content.begin() + 40);  // the mask cut short
    CHECK_THROWS_AS(service::unpackBricks(repacked(cut, low), {against[0]}), std::runtime_error);
    std::vector<unsigned char> lowTrailing = low;
    lowTrailing.push_back(0);
    CHECK_THROWS_AS(service::unpackBricks(repacked(content, lowTrailing), {against[0]}), std::runtime_error);
    const std::vector<unsigned char> lowCut(low.begin(), low.end() - 1);
    CHECK_THROWS_AS(service::unpackBricks(repacked(content, lowCut), {against[0]}), std::runtime_error);
    service::PackedBricks cutFrame = one;  // a byte of the zstd frame itself missing
    cutFrame.frame.erase(cutFrame.frame.begin() + std::ptrdiff_t(packed) - 1);
    CHECK_THROWS_AS(service::unpackBricks(cutFrame, {against[0]}), std::runtime_error);
  }
  SECTION("other references are refused, not unpacked into wrong bricks") {
    auto changed = std::make_shared<Brick>(*others[0].data);
    changed->v[0] += 1.0f;
    std::vector<BrickRef> wrong = others;
    wrong[0].data = std::move(changed);
    std::vector<const BrickRef*> wrongPtrs;
    for (const auto& r : wrong) wrongPtrs.push_back(&r);
    CHECK_THROWS_AS(service::unpackBricks(p, wrongPtrs), std::runtime_error);
    CHECK_THROWS_AS(service::unpackBricks(p, {against.begin(), against.end() - 1}), std::runtime_error);
  }
}

TEST_CASE("history: steps are held packed 4x smaller than their bricks, and the budget counts that", "[history]") {
  ThreadPool pool(2);
  // What the load tool's sculptors leave on the 128^3 pig: strokes of blobs along its back,
  // each step one stroke.dabs message.
  static const Volume pig = makeSolid(SolidKind::Pig, {128, 128, 128});
  std::vector<Vec3> centres;
  for (int x = 40; x <= 88; x += 4) {
    int y = 127;
    while (y > 0 && pig.at(x, y, 64) > 0) --y;
    REQUIRE(y > 0);
    centres.push_back({double(x), double(y), 64});
  }
  const auto sculpt = [&](Volume& v, History& h, std::vector<std::uint64_t>* digests,
                          std::size_t* bothSides) {
    // The before bricks as shared 2 KB buffers would cost (what undo needs), and what the
    // history charged when it kept both sides as shared buffers (each distinct buffer once).
    std::size_t rawBefore = 0;
    std::set<const Brick*> buffers;
    std::vector<Edit> alive;  // packing frees the buffers: keep them so that addresses stay distinct
    for (const Vec3& c : centres) {
      Edit e = addBlob(v, {c, 8, 0.7}, pool);
      for (const auto& ch : e.changes) {
        rawBefore += ch.before.data ? History::kBytesPerBrick : 0;
        for (const BrickRef* r : {&ch.before, &ch.after})
          if (r->data) buffers.insert(r->data.get());
      }
      alive.push_back(e);
      REQUIRE(h.push(std::move(e)) != 0);
      if (digests) digests->push_back(digest(v));
    }
    if (bothSides) *bothSides = buffers.size() * History::kBytesPerBrick;
    return rawBefore;
  };
  Volume v = pig;
  History h(SIZE_MAX);
  std::vector<std::uint64_t> digests{digest(v)};
  std::size_t bothSides = 0;
  const std::size_t raw = sculpt(v, h, &digests, &bothSides);
  h.undo(v);
  h.redo(v);  // every step packed now
  CHECK(digest(v) == digests.back());
  INFO("before bricks " << raw << ", both sides " << bothSides << ", packed " << h.bytes());
  CHECK(h.bytes() * 4 <= raw);
  CHECK(h.bytes() * 4 <= bothSides);

  // A budget the raw bricks would overflow twice holds every packed step: the accounting is
  // the packed size (the newest step, unpacked, included).
  Volume w = pig;
  History capped(raw / 2);
  sculpt(w, capped, nullptr, nullptr);
  CHECK(capped.droppedSteps() == 0);
  CHECK(capped.undoSteps() == centres.size());
  CHECK(capped.bytes() <= raw / 2);
  for (std::size_t i = digests.size() - 1; i > 0; --i) {
    REQUIRE(capped.undo(w) != nullptr);
    CHECK(digest(w) == digests[i - 1]);
  }
}

TEST_CASE("history: a new step after undos clears the redo list", "[history]") {
  ThreadPool pool(1);
  Volume v = sphere();
  History h;
  runMix(v, h, pool);
  h.undo(v);
  h.undo(v);
  REQUIRE(h.redoSteps() == 2);
  const std::uint64_t base = digest(v);
  h.push(removeBlob(v, {{kC, kC, kC - 0.35 * kN}, 5, 1}, pool));
  CHECK(h.redoSteps() == 0);
  CHECK_FALSE(h.canRedo());
  CHECK(h.undoSteps() == 4);
  h.undo(v);
  CHECK(digest(v) == base);
}

TEST_CASE("history: an empty edit records nothing", "[history]") {
  History h;
  CHECK(h.push(Edit{}) == 0);
  CHECK(h.steps() == 0);
  CHECK(h.bytes() == 0);
}

TEST_CASE("history: amend folds later changes into the newest step only", "[history]") {
  ThreadPool pool(1);
  Volume v = sphere();
  History h;
  const std::uint64_t start = digest(v);
  const auto id = h.push(addBlob(v, {{kSurface, kC, kC}, 5, 1}, pool));
  for (int i = 1; i < 5; ++i) REQUIRE(h.amend(id, addBlob(v, {{kSurface, kC + 2 * i, kC}, 5, 1}, pool)));
  CHECK(h.undoSteps() == 1);
  const std::uint64_t end = digest(v);
  h.undo(v);
  CHECK(digest(v) == start);
  CHECK_FALSE(h.amend(id, Edit{}));  // undone: not the newest step any more
  h.redo(v);
  CHECK(digest(v) == end);
  const auto other = h.push(addBlob(v, {{kC, kSurface, kC}, 5, 1}, pool));
  CHECK(other != id);
  CHECK_FALSE(h.amend(id, addBlob(v, {{kC, kC, kSurface}, 5, 1}, pool)));
  CHECK(h.undoSteps() == 2);
}

TEST_CASE("history: over budget the oldest steps are dropped first", "[history]") {
  ThreadPool pool(2);
  constexpr int kSteps = 12;
  const auto blob = [](int i) { return BrushParams{{kSurface, kC - 11 + 2 * i, kC}, 4, 1}; };
  // All of them, measured with an unlimited budget: the newest step unpacked (its shared
  // buffers), the older ones packed. Room for the newest and about half of the others.
  std::size_t total = 0, newest = 0;
  {
    Volume v = sphere();
    History h(SIZE_MAX);
    for (int i = 0; i < kSteps; ++i) {
      Edit e = addBlob(v, blob(i), pool);
      newest = e.changes.size() * sizeof(BrickChange);
      for (const auto& c : e.changes) newest += History::kBytesPerBrick * (!!c.before.data + !!c.after.data);
      h.push(std::move(e));
    }
    total = h.bytes();
    REQUIRE(h.droppedSteps() == 0);
  }
  REQUIRE(total > newest);
  const std::size_t budget = newest + (total - newest) / 2;
  Volume v = sphere();
  History h(budget);
  std::vector<std::uint64_t> digests{digest(v)};
  for (int i = 0; i < kSteps; ++i) {
    h.push(addBlob(v, blob(i), pool));
    digests.push_back(digest(v));
    CHECK(h.bytes() <= budget);
  }
  CHECK(h.droppedSteps() >= 1);
  CHECK(h.undoSteps() + h.droppedSteps() == kSteps);
  const std::size_t kept = h.undoSteps();
  REQUIRE(kept >= 1);
  for (std::size_t i = 0; i < kept; ++i) REQUIRE(h.undo(v) != nullptr);
  CHECK_FALSE(h.canUndo());
  // The kept steps are the newest: undoing them all lands on the state after the dropped ones.
  CHECK(digest(v) == digests[kSteps - kept]);

  SECTION("a smaller budget drops more, even the newest") {
    h.setBudget(0);
    CHECK(h.steps() == 0);
    CHECK(h.bytes() == 0);
    CHECK_FALSE(h.canRedo());
  }
}

TEST_CASE("history: a single step larger than the budget is not kept", "[history]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h(4 * History::kBytesPerBrick);
  h.push(dilate(v, 1, pool));
  CHECK_FALSE(h.canUndo());
  CHECK(h.droppedSteps() == 1);
  CHECK(h.bytes() == 0);
}

TEST_CASE("history: tiny steps count what they really hold, so the budget bounds the heap", "[history]") {
  // Issue 31 item 3: a step of one uniform brick (a blob in empty space) was counted ~13 bytes
  // (its coordinates and kind) for 536 on the heap, so a 256 KiB budget held ~20000 steps and
  // ~11 MB. Each step is one brick turned from outside to inside, the author's name long
  // enough to be on the heap.
  constexpr std::size_t kBudget = std::size_t(256) << 10;
  constexpr int kSteps = 20000;
  const auto heap = [] { return std::size_t(mallinfo2().uordblks); };
  const std::size_t before = heap();
  std::size_t after = 0, counted = 0, held = 0;
  {
    History h(kBudget);
    for (int i = 0; i < kSteps; ++i) {
      Edit e;
      e.region = {{0, 0, 0}, {8, 8, 8}};
      e.changes.push_back({Int3{i % 8, (i / 8) % 8, 0}, BrickRef{nullptr, i % 2 == 1}, BrickRef{nullptr, i % 2 == 0}});
      service::StepInfo info;
      info.revision = std::uint64_t(i + 1);
      info.author = {std::to_string(i % 16), "a sculptor with a long display name " + std::to_string(i % 16)};
      info.tool = "add_blob";
      h.push(std::move(e), info);
    }
    after = heap();
    counted = h.bytes();
    held = h.undoSteps();
    CHECK(counted <= kBudget);
  }
  const std::size_t real = after - before;
  INFO("steps held " << held << ", counted " << counted << " bytes, heap " << real << " bytes");
  CHECK(held < std::size_t(kSteps) / 10);
  // What is counted covers what is held (the deque's blocks and the allocator's headers
  // included: 536 bytes a step on 2026-11-29), and not by much more.
  CHECK(real <= counted);
  CHECK(counted <= 2 * real);
}
