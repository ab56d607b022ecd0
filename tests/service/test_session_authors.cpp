// Session (server/service/session.cpp) with authors: undoMine/redoMine count revisions like
// undo and leave the other authors' steps exactly, a conflict names the step in the way and
// changes nothing, steps() lists authors, tools, times and revisions (a stroke spans several),
// and forkVolume gives the current or an earlier volume without touching the live one.
#include <catch2/catch.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/session.hpp"

using namespace marzipan;
using namespace marzipan::service;
using protocol::BrushTool;

namespace {

// As in test_history_authors.cpp: blobs of radius 4 on different sides of this sphere share no
// brick.
constexpr int kN = 96;
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;

const Volume& sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

const StepAuthor kA{"client-a", "Ada"}, kB{"client-b", "Bo"}, kC3{"client-c", "Cy"};

protocol::Op blobOp(Vec3 c) { return protocol::BrushOp{BrushTool::AddBlob, BrushParams{c, 4, 1}}; }
const Vec3 kPlusX{kC + kR, kC, kC}, kMinusX{kC - kR, kC, kC}, kPlusY{kC, kC + kR, kC};

// B's stroke on -x: two messages, one step.
void strokeOfB(Session& s, ThreadPool& pool, const StepAuthor& by = kB) {
  const StrokeId id = s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, by);
  s.strokeDabs(id, {Dab{kMinusX, std::nullopt}}, pool);
  s.strokeDabs(id, {Dab{Vec3{kC - kR, kC + 2, kC}, std::nullopt}}, pool);
  s.endStroke(id);
}

// A clock that ticks one second per step.
std::function<std::int64_t()> ticking() {
  auto t = std::make_shared<std::int64_t>(1'795'000'000'000);
  return [t] { return *t += 1000; };
}

}  // namespace

TEST_CASE("session: undoMine undoes the caller's newest step and leaves the others' exactly", "[session][authors]") {
  ThreadPool pool(2);
  Session s(sphere());
  s.setClock(ticking());
  s.apply(blobOp(kPlusX), pool, kA);  // r1
  strokeOfB(s, pool);                 // r2, r3: one step
  s.apply(blobOp(kPlusY), pool, kA);  // r4
  REQUIRE(s.revision() == 4);

  std::vector<StepInfo> steps = s.steps();
  REQUIRE(steps.size() == 3);
  CHECK(steps[0].revision == 1);
  CHECK(steps[0].firstRevision == 1);
  CHECK(steps[0].author == kA);
  CHECK(steps[0].tool == "add_blob");
  CHECK(steps[0].timeMs == 1'795'000'001'000);
  CHECK(steps[1].firstRevision == 2);
  CHECK(steps[1].revision == 3);
  CHECK(steps[1].author == kB);
  CHECK(steps[1].timeMs == 1'795'000'002'000);  // the stroke's first message
  CHECK(steps[2].revision == 4);
  CHECK(steps[2].timeMs == 1'795'000'003'000);
  CHECK(s.newestStep()->revision == 4);

  // The same session without A's steps, step for step.
  Session onlyB(sphere());
  strokeOfB(onlyB, pool);
  Session bAndFirstA(sphere());
  bAndFirstA.apply(blobOp(kPlusX), pool, kA);
  strokeOfB(bAndFirstA, pool);

  HistoryResult h = s.undoMine(kA.id);
  REQUIRE(h.changed);
  CHECK_FALSE(h.conflict.has_value());
  REQUIRE(h.step.has_value());
  CHECK(h.step->revision == 4);
  CHECK(h.revision == 5);
  CHECK(s.revision() == 5);
  CHECK(s.volume().revision() == 5);
  CHECK(h.canRedo);
  CHECK_FALSE(h.bricks.empty());
  CHECK_FALSE(h.restored.empty());
  CHECK(s.digest() == digest(s.volume()));  // the digest kept brick by brick
  CHECK(s.digest() == digest(bAndFirstA.volume()));

  h = s.undoMine(kA.id);  // A's first step, under B's stroke in the history
  REQUIRE(h.changed);
  CHECK(h.step->revision == 1);
  CHECK(s.revision() == 6);
  CHECK(s.digest() == digest(onlyB.volume()));
  CHECK(s.digest() == digest(s.volume()));

  // Nothing of A's is left to undo: no change, no conflict.
  h = s.undoMine(kA.id);
  CHECK_FALSE(h.changed);
  CHECK_FALSE(h.conflict.has_value());
  CHECK(s.revision() == 6);
  CHECK_FALSE(s.undoMine("").changed);

  SECTION("redoMine brings A's steps back, newest undone first") {
    h = s.redoMine(kA.id);
    REQUIRE(h.changed);
    CHECK(h.step->revision == 1);
    CHECK(s.revision() == 7);
    CHECK(s.digest() == digest(bAndFirstA.volume()));
    REQUIRE(s.redoMine(kA.id).changed);
    Session all(sphere());
    all.apply(blobOp(kPlusX), pool, kA);
    strokeOfB(all, pool);
    all.apply(blobOp(kPlusY), pool, kA);
    CHECK(s.digest() == digest(all.volume()));
    CHECK_FALSE(s.redoMine(kA.id).changed);
  }

  SECTION("a later step of someone else on the same bricks refuses B's undo, naming it") {
    s.apply(blobOp(Vec3{kC - kR, kC - 2, kC}), pool, kC3);  // r7, over B's stroke
    const std::uint64_t d = s.digest();
    h = s.undoMine(kB.id);
    CHECK_FALSE(h.changed);
    REQUIRE(h.conflict.has_value());
    CHECK(h.conflict->author == kC3);
    CHECK(h.conflict->revision == 7);
    REQUIRE(h.step.has_value());
    CHECK(h.step->revision == 3);
    CHECK(h.step->firstRevision == 2);
    CHECK(h.revision == 7);
    CHECK(s.revision() == 7);
    CHECK(s.digest() == d);
    // The new step cleared the redo list, A's undone steps with it.
    CHECK_FALSE(s.redoMine(kA.id).changed);
    CHECK_FALSE(s.canRedo());
    // Once C's step is undone (session-wide), B's own undo goes through.
    REQUIRE(s.undo().changed);
    REQUIRE(s.undoMine(kB.id).changed);
    CHECK(s.digest() == digest(sphere()));
  }
}

TEST_CASE("session: forkVolume gives the current or an earlier volume, sharing bricks", "[session][authors]") {
  ThreadPool pool(2);
  Session s(sphere());
  std::vector<std::uint64_t> digests{s.digest()};
  s.apply(blobOp(kPlusX), pool, kA);
  digests.push_back(s.digest());
  strokeOfB(s, pool);
  digests.push_back(s.digest());
  s.apply(blobOp(kPlusY), pool, kA);
  digests.push_back(s.digest());
  const Volume live = s.snapshot();

  const Volume now = s.forkVolume();
  CHECK(digest(now) == digests[3]);
  CHECK(now.revision() == 4);
  CHECK(digest(*s.volumeAt(4)) == digests[3]);
  CHECK(digest(s.forkVolume(1)) == digests[1]);
  CHECK(s.forkVolume(1).revision() == 1);
  CHECK(digest(s.forkVolume(3)) == digests[2]);
  CHECK_FALSE(s.volumeAt(2).has_value());  // inside B's stroke: not a step's end
  for (const std::uint64_t bad : {std::uint64_t(0), std::uint64_t(2), std::uint64_t(5), std::uint64_t(99)}) {
    INFO("revision " << bad);
    try {
      s.forkVolume(bad);
      FAIL("no ServiceError");
    } catch (const ServiceError& e) {
      CHECK(e.code() == protocol::RpcCode::InvalidParams);
      CHECK(e.field() == "revision");
    }
  }
  // The live session is untouched: same digest, same brick buffers.
  CHECK(s.digest() == digests[3]);
  CHECK(s.revision() == 4);
  const Int3 bd = live.brickDims();
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) REQUIRE(s.volume().brick({x, y, z}) == live.brick({x, y, z}));

  // A fork from r1 is a session of its own: its revision goes on from 1, its history is empty,
  // and its edits leave the original alone.
  Session fork(s.forkVolume(1));
  CHECK(fork.revision() == 1);
  CHECK(fork.digest() == digests[1]);
  CHECK_FALSE(fork.canUndo());
  fork.apply(blobOp(kMinusX), pool, kB);
  CHECK(fork.revision() == 2);
  CHECK(s.digest() == digests[3]);
  CHECK(digest(s.volume()) == digests[3]);
  // Forking from the present shares every brick: no voxel is copied.
  const Volume f = s.forkVolume();
  std::size_t shared = 0, data = 0;
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) {
        const BrickRef r = f.brick({x, y, z});
        if (!r.data) continue;
        ++data;
        shared += r.data == s.volume().brick({x, y, z}).data;
      }
  CHECK(data > 0);
  CHECK(shared == data);
}

TEST_CASE("session: an author's stroke stays one step while another sculpts elsewhere", "[session][authors]") {
  ThreadPool pool(2);
  Session s(sphere());
  const StrokeId a = s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, kA);
  const StrokeId b = s.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, kB);
  // Interleaved messages: A on +x, B on -x.
  for (int i = 0; i < 3; ++i) {
    s.strokeDabs(a, {Dab{Vec3{kC + kR, kC + 2 * i, kC}, std::nullopt}}, pool);
    s.strokeDabs(b, {Dab{Vec3{kC - kR, kC + 2 * i, kC}, std::nullopt}}, pool);
  }
  CHECK(s.revision() == 6);
  std::vector<StepInfo> steps = s.steps();
  REQUIRE(steps.size() == 2);
  CHECK(steps[0].author == kA);
  CHECK(steps[0].firstRevision == 1);
  CHECK(steps[0].revision == 5);
  CHECK(steps[1].author == kB);
  CHECK(steps[1].firstRevision == 2);
  CHECK(steps[1].revision == 6);

  // B's stroke alone, in one session without A.
  Session onlyB(sphere());
  const StrokeId ob = onlyB.beginStroke(BrushTool::AddBlob, 4, 1, {}, false, kB);
  for (int i = 0; i < 3; ++i) onlyB.strokeDabs(ob, {Dab{Vec3{kC - kR, kC + 2 * i, kC}, std::nullopt}}, pool);

  SECTION("A's undo takes the whole stroke") {
    const HistoryResult h = s.undoMine(kA.id);
    REQUIRE(h.changed);
    CHECK(h.step->firstRevision == 1);
    CHECK(s.digest() == digest(onlyB.volume()));
    // A's next message starts a new step (something is undone): it clears the redo list. (Its
    // dab lies between two the stroke remembers: where it exceeds them, it adds.)
    REQUIRE(s.strokeDabs(a, {Dab{Vec3{kC + kR, kC + 1, kC}, std::nullopt}}, pool).changed);
    CHECK(s.steps().size() == 2);
    CHECK_FALSE(s.canRedo());
  }
  SECTION("someone else's step on the bricks A's next message changes starts a new step") {
    s.apply(blobOp(Vec3{kC + kR, kC + 8, kC}), pool, kC3);  // r7
    s.strokeDabs(a, {Dab{Vec3{kC + kR, kC + 7, kC}, std::nullopt}}, pool);  // r8
    steps = s.steps();
    REQUIRE(steps.size() == 4);
    CHECK(steps[3].author == kA);
    CHECK(steps[3].firstRevision == 8);
    // A's undo takes that new step only; the next one is blocked by C's.
    REQUIRE(s.undoMine(kA.id).changed);
    const HistoryResult h = s.undoMine(kA.id);
    CHECK_FALSE(h.changed);
    REQUIRE(h.conflict.has_value());
    CHECK(h.conflict->author == kC3);
    CHECK(h.conflict->revision == 7);
  }
}
