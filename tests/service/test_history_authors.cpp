// History (server/service/history.cpp) with authors: undoOf/redoOf take one author's step out
// of the middle of the history with exact digests (the volume as if the step had never been
// made), refuse naming the first step in the way, list the steps, and rebuild the volume at an
// earlier step without touching the live one: gathered at once, built anywhere, cancellable,
// and kept until the history changes under it.
#include <catch2/catch.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/progress.hpp"
#include "engine/solids.hpp"
#include "service/history.hpp"

using namespace marzipan;
using service::History;
using service::StepInfo;

namespace {

constexpr int kN = 96;
constexpr double kC = (kN - 1) / 2.0;
const double kSurface = 0.35 * kN;  // the sphere's radius, from kC

Volume sphere() {
  static const Volume s = makeSolid(SolidKind::Sphere, {kN, kN, kN});
  return s;
}

// Blobs of radius 4 on the six sides of the sphere, far enough apart that no two touch a
// common brick (a blob touches 9 vu around its centre; centres are 33.6 sqrt 2 = 47.5 vu apart at the closest).
enum Side { PlusX, MinusX, PlusY, MinusY, PlusZ, MinusZ };
Vec3 sidePoint(Side s) {
  Vec3 p{kC, kC, kC};
  p[s / 2] += (s % 2 ? -1 : 1) * kSurface;
  return p;
}

Edit blobAt(Volume& v, Side s, ThreadPool& pool, double dx = 0) {
  Vec3 p = sidePoint(s);
  p.y += dx;
  return addBlob(v, {p, 4, 1}, pool);
}

StepInfo by(const std::string& id, std::uint64_t revision, const std::string& tool = "blob") {
  StepInfo i;
  i.revision = revision;
  i.author = {id, "name of " + id};
  i.tool = tool;
  i.timeMs = 1'700'000'000'000 + std::int64_t(revision);
  return i;
}

// The digest of the sphere with these blobs applied in this order, on a fresh copy.
std::uint64_t only(const std::vector<Side>& sides, ThreadPool& pool) {
  Volume v = sphere();
  for (const Side s : sides) blobAt(v, s, pool);
  return digest(v);
}

}  // namespace

TEST_CASE("history: undoOf takes an author's step out of the middle as if it had never been made",
          "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  // A at +x (r1), B at -x (r2), A at +y (r3), B at -y (r4): A's newest is packed in the middle.
  h.push(blobAt(v, PlusX, pool), by("A", 1));
  h.push(blobAt(v, MinusX, pool), by("B", 2));
  h.push(blobAt(v, PlusY, pool), by("A", 3));
  h.push(blobAt(v, MinusY, pool), by("B", 4));
  const std::uint64_t all = digest(v);
  REQUIRE(all == only({PlusX, MinusX, PlusY, MinusY}, pool));

  History::AuthorMove m = h.undoOf(v, "A");
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  REQUIRE(m.edit != nullptr);
  CHECK(m.step.revision == 3);
  CHECK(m.step.author.id == "A");
  CHECK(h.moved().revision == 3);
  CHECK(digest(v) == only({PlusX, MinusX, MinusY}, pool));
  CHECK(h.undoSteps() == 3);
  CHECK(h.redoSteps() == 1);

  m = h.undoOf(v, "A");  // A's r1, the oldest
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  CHECK(m.step.revision == 1);
  CHECK(digest(v) == only({MinusX, MinusY}, pool));

  CHECK(h.undoOf(v, "A").outcome == History::AuthorMove::Nothing);  // A has no step left
  CHECK(h.undoOf(v, "").outcome == History::AuthorMove::Nothing);
  CHECK(h.undoOf(v, "C").outcome == History::AuthorMove::Nothing);
  CHECK(digest(v) == only({MinusX, MinusY}, pool));

  // The timeline: B's two steps, then A's in the order redo brings them back (r1 first).
  const std::vector<StepInfo> steps = h.list();
  REQUIRE(steps.size() == 4);
  const std::uint64_t revisions[] = {2, 4, 1, 3};
  const bool undone[] = {false, false, true, true};
  for (std::size_t i = 0; i < 4; ++i) {
    INFO("step " << i);
    CHECK(steps[i].revision == revisions[i]);
    CHECK(steps[i].undone == undone[i]);
    CHECK(steps[i].author.name == "name of " + steps[i].author.id);
    CHECK(steps[i].tool == "blob");
    CHECK(steps[i].timeMs == 1'700'000'000'000 + std::int64_t(revisions[i]));
    CHECK(steps[i].firstRevision == revisions[i]);
    CHECK_FALSE(steps[i].region.empty());
    // The brick box holds the blob's centre brick.
    const Vec3 p = sidePoint(std::array<Side, 4>{MinusX, MinusY, PlusX, PlusY}[i]);
    CHECK(steps[i].bricks.contains(Int3{int(p.x) / 8, int(p.y) / 8, int(p.z) / 8}));
  }

  // B undoes B's newest, the newest of all (held unpacked).
  m = h.undoOf(v, "B");
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  CHECK(m.step.revision == 4);
  CHECK(digest(v) == only({MinusX}, pool));

  // Session-wide redo brings back the top of the redo list: B's r4.
  REQUIRE(h.redo(v) != nullptr);
  CHECK(h.moved().revision == 4);
  CHECK(digest(v) == only({MinusX, MinusY}, pool));
  // A redoes A's most recently undone step (r1), then the other (r3).
  m = h.redoOf(v, "A");
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  CHECK(m.step.revision == 1);
  CHECK(digest(v) == only({MinusX, MinusY, PlusX}, pool));
  m = h.redoOf(v, "A");
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  CHECK(m.step.revision == 3);
  CHECK(digest(v) == all);
  CHECK(h.redoOf(v, "A").outcome == History::AuthorMove::Nothing);

  // The history is consistent after all this: session-wide undo goes back to the sphere.
  while (h.canUndo()) REQUIRE(h.undo(v) != nullptr);
  CHECK(digest(v) == digest(sphere()));
  while (h.canRedo()) REQUIRE(h.redo(v) != nullptr);
  CHECK(digest(v) == all);
}

TEST_CASE("history: undoOf refuses when a later step touched its bricks, naming the first one",
          "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  // A at +x (r1); B overlaps it (r2); C elsewhere (r3); D overlaps A too (r4).
  h.push(blobAt(v, PlusX, pool), by("A", 1));
  h.push(blobAt(v, PlusX, pool, 3), by("B", 2));
  h.push(blobAt(v, MinusX, pool), by("C", 3));
  h.push(blobAt(v, PlusX, pool, -3), by("D", 4));
  const std::uint64_t all = digest(v);
  const std::size_t bytes = h.bytes();

  History::AuthorMove m = h.undoOf(v, "A");
  REQUIRE(m.outcome == History::AuthorMove::Conflict);
  CHECK(m.edit == nullptr);
  CHECK(m.step.revision == 1);
  CHECK(m.step.author.id == "A");
  CHECK(m.conflict.revision == 2);  // the first later step in the way, not D's
  CHECK(m.conflict.author.id == "B");
  CHECK(m.conflict.author.name == "name of B");
  // Refused: nothing changed.
  CHECK(digest(v) == all);
  CHECK(h.undoSteps() == 4);
  CHECK(h.redoSteps() == 0);
  CHECK(h.bytes() == bytes);

  m = h.undoOf(v, "B");
  REQUIRE(m.outcome == History::AuthorMove::Conflict);
  CHECK(m.conflict.author.id == "D");
  CHECK(m.conflict.revision == 4);

  // C's step commutes with everything after it.
  m = h.undoOf(v, "C");
  REQUIRE(m.outcome == History::AuthorMove::Moved);
  Volume expect = sphere();
  blobAt(expect, PlusX, pool);
  blobAt(expect, PlusX, pool, 3);
  blobAt(expect, PlusX, pool, -3);
  CHECK(digest(v) == digest(expect));

  // D undoes D's, then B can, then A can: each restored exactly.
  REQUIRE(h.undoOf(v, "D").outcome == History::AuthorMove::Moved);
  REQUIRE(h.undoOf(v, "B").outcome == History::AuthorMove::Moved);
  REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);
  CHECK(digest(v) == digest(sphere()));

  SECTION("redoOf refuses while a step above it on the redo list touched its bricks") {
    // Redo list, bottom to top: C, D, B, A. B's bricks meet A's, which comes back first.
    m = h.redoOf(v, "B");
    REQUIRE(m.outcome == History::AuthorMove::Conflict);
    CHECK(m.step.revision == 2);
    CHECK(m.conflict.revision == 1);
    CHECK(m.conflict.author.id == "A");
    CHECK(digest(v) == digest(sphere()));
    CHECK(h.redoSteps() == 4);
    // C's step lies under the others but touched none of their bricks.
    REQUIRE(h.redoOf(v, "C").outcome == History::AuthorMove::Moved);
    Volume c = sphere();
    blobAt(c, MinusX, pool);
    CHECK(digest(v) == digest(c));
    while (h.canRedo()) REQUIRE(h.redo(v) != nullptr);
    CHECK(digest(v) == all);
  }
  SECTION("a new step clears the redo list, authors' undone steps included") {
    h.push(blobAt(v, MinusZ, pool), by("C", 9));
    CHECK(h.redoSteps() == 0);
    CHECK(h.redoOf(v, "A").outcome == History::AuthorMove::Nothing);
  }
}

TEST_CASE("history: volumeAt rebuilds the volume at an earlier step and leaves the live one alone",
          "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  std::vector<std::uint64_t> at{digest(v)};
  const Side sides[] = {PlusX, MinusX, PlusY, MinusY, PlusZ};
  for (std::uint64_t r = 1; r <= 5; ++r) {
    h.push(blobAt(v, sides[r - 1], pool), by(r % 2 ? "A" : "B", 10 * r));
    at.push_back(digest(v));
  }
  const Volume before = v;
  for (std::uint64_t r = 1; r <= 5; ++r) {
    INFO("revision " << 10 * r);
    const std::optional<Volume> past = h.volumeAt(v, 10 * r);
    REQUIRE(past.has_value());
    CHECK(digest(*past) == at[r]);
    CHECK(past->revision() == 10 * r);
  }
  CHECK_FALSE(h.volumeAt(v, 7).has_value());
  CHECK_FALSE(h.volumeAt(v, 0).has_value());
  // The live volume is the same, brick for brick (the same buffers).
  CHECK(digest(v) == at[5]);
  const Int3 bd = v.brickDims();
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) REQUIRE(v.brick({x, y, z}) == before.brick({x, y, z}));

  // With A's r30 taken out, the volume at r40 is the one where it was never made; at r20 the
  // same as before.
  REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // A's newest: r50
  REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // r30
  CHECK(digest(*h.volumeAt(v, 20)) == at[2]);
  CHECK(digest(*h.volumeAt(v, 40)) == only({PlusX, MinusX, MinusY}, pool));
  CHECK_FALSE(h.volumeAt(v, 30).has_value());  // undone: not a step of the present
  CHECK(h.find(40).has_value());
  CHECK_FALSE(h.find(30).has_value());
  // And the history still undoes exactly.
  while (h.canUndo()) h.undo(v);
  CHECK(digest(v) == at[0]);
}

TEST_CASE("history: fold grows an earlier step when no later step touched the new bricks", "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  const History::StepId a = h.push(blobAt(v, PlusX, pool), by("A", 1));
  h.push(blobAt(v, MinusX, pool), by("B", 2));
  // A's step is packed under B's now; A's stroke goes on at +x.
  REQUIRE(h.fold(a, blobAt(v, PlusX, pool, 2), v, 3));
  REQUIRE(h.fold(a, blobAt(v, PlusX, pool, 4), v, 4));
  CHECK(h.undoSteps() == 2);
  const std::vector<StepInfo> steps = h.list();
  CHECK(steps[0].revision == 4);
  CHECK(steps[0].firstRevision == 1);
  const std::uint64_t all = digest(v);
  // Folded, the step stays unpacked until sealed (its stroke ended).
  const std::size_t unpacked = h.bytes();
  h.seal(a);
  CHECK(h.bytes() < unpacked);

  // Undone as one step: the volume with B's step alone.
  REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);
  CHECK(digest(v) == only({MinusX}, pool));
  // Nothing folds while something is undone (the caller then takes the change back here).
  const Edit refused = blobAt(v, PlusY, pool);
  CHECK_FALSE(h.fold(a, refused, v, 6));
  v.publish(refused.changes, false);
  REQUIRE(h.redo(v) != nullptr);
  CHECK(digest(v) == all);
  while (h.canUndo()) h.undo(v);
  CHECK(digest(v) == digest(sphere()));

  SECTION("a later step on the new bricks refuses the fold") {
    Volume w = sphere();
    History g;
    const History::StepId first = g.push(blobAt(w, PlusX, pool), by("A", 1));
    g.push(blobAt(w, PlusX, pool, 6), by("C", 2));
    const std::uint64_t before = digest(w);
    const Edit more = blobAt(w, PlusX, pool, 3);
    CHECK_FALSE(g.fold(first, more, w, 3));
    CHECK(g.undoSteps() == 2);
    w.publish(more.changes, false);
    CHECK(digest(w) == before);
    while (g.canUndo()) g.undo(w);
    CHECK(digest(w) == digest(sphere()));
  }
}

TEST_CASE("history: a step pushed over a growing one leaves that one unpacked until sealed", "[history][authors]") {
  ThreadPool pool(2);
  // The same steps twice: once with A's step said to be growing (an open stroke's) at B's push.
  Volume v = sphere(), w = sphere();
  History grown, packed;
  const History::StepId a = grown.push(blobAt(v, PlusX, pool), by("A", 1));
  const History::StepId a2 = packed.push(blobAt(w, PlusX, pool), by("A", 1));
  grown.push(blobAt(v, MinusX, pool), by("B", 2), [a](History::StepId s) { return s == a; });
  packed.push(blobAt(w, MinusX, pool), by("B", 2));
  // Unpacked: its shared brick buffers, several times what its packed frame holds.
  CHECK(grown.bytes() > packed.bytes() + packed.bytes() / 2);
  // A's stroke goes on: both fold the same (the packed one unpacks for it), and both stay
  // unpacked until the stroke ends.
  REQUIRE(grown.fold(a, blobAt(v, PlusX, pool, 2), v, 3));
  REQUIRE(packed.fold(a2, blobAt(w, PlusX, pool, 2), w, 3));
  CHECK(digest(v) == digest(w));
  CHECK(grown.bytes() == packed.bytes());
  grown.seal(a);
  packed.seal(a2);
  CHECK(grown.bytes() == packed.bytes());
  while (grown.canUndo()) grown.undo(v);
  CHECK(digest(v) == digest(sphere()));
}

// The load tool found this: a stroke's step packed under another sculptor's new step that
// overlaps some of its bricks, then folded elsewhere, was unpacked against the volume's bricks
// (the later step's) instead of its own `after`, and every dab failed with an internal error.
TEST_CASE("history: fold grows a packed step whose other bricks a later step changed", "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  // A blob of radius 4 reaches 9 vu: A's first dab covers brick rows y 4..7, B's (12 vu up)
  // rows 6..8, A's next dab (12 vu down) rows 3..5, which B does not touch.
  const History::StepId a = h.push(blobAt(v, PlusX, pool), by("A", 1));
  const std::uint64_t afterA = digest(v);
  h.push(blobAt(v, PlusX, pool, 12), by("B", 2));
  const std::uint64_t afterB = digest(v);
  REQUIRE(h.fold(a, blobAt(v, PlusX, pool, -12), v, 3));
  CHECK(h.undoSteps() == 2);
  const std::uint64_t all = digest(v);
  h.seal(a);

  // A's step is in B's way for undo mine, so the session-wide undo takes both back exactly.
  CHECK(h.undoOf(v, "A").outcome == History::AuthorMove::Conflict);
  REQUIRE(h.undo(v) != nullptr);
  REQUIRE(h.undo(v) != nullptr);
  CHECK(digest(v) == digest(sphere()));
  REQUIRE(h.redo(v) != nullptr);
  CHECK(digest(v) != afterA);  // the fold is part of A's step
  REQUIRE(h.redo(v) != nullptr);
  CHECK(digest(v) == all);
  CHECK(afterB != all);
}

TEST_CASE("history: an earlier version is gathered at once, built off the history, cancellable, and kept",
          "[history][authors]") {
  ThreadPool pool(2);
  Volume v = sphere();
  History h;
  std::vector<std::uint64_t> at{digest(v)};
  const Side sides[] = {PlusX, MinusX, PlusY, MinusY, PlusZ};
  std::size_t laterBricks = 0;
  for (std::uint64_t r = 1; r <= 5; ++r) {
    Edit e = blobAt(v, sides[r - 1], pool);
    if (r > 1) laterBricks += e.changes.size();
    h.push(std::move(e), by(r % 2 ? "A" : "B", 10 * r));
    at.push_back(digest(v));
  }
  std::optional<service::Rebuild> r10 = h.rebuildAt(v, 10);
  REQUIRE(r10.has_value());
  CHECK(r10->steps() == 4);
  CHECK(r10->voxels() == double(laterBricks) * kBrickVoxels);
  CHECK_FALSE(h.rebuildAt(v, 7).has_value());
  CHECK_FALSE(h.keptAt(10).has_value());

  SECTION("built after the live volume and the history moved on, it is still the version at 10") {
    h.push(blobAt(v, MinusZ, pool), by("B", 60));
    const Volume built = r10->run();
    CHECK(digest(built) == at[1]);
    CHECK(built.revision() == 10);
    h.keep(*r10, built);
    REQUIRE(h.keptAt(10).has_value());
    CHECK(digest(*h.keptAt(10)) == at[1]);
    // Newer steps, and undoing or redoing the newest, leave it right: it stays.
    h.undo(v);
    h.redo(v);
    CHECK(h.keptAt(10).has_value());
    CHECK(digest(*h.volumeAt(v, 10)) == at[1]);
    // A's r30 taken out from under newer steps: the versions after it change, it goes.
    REQUIRE(h.undoOf(v, "B").outcome == History::AuthorMove::Moved);  // B's newest, r60
    REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // r50, the newest now
    CHECK(h.keptAt(10).has_value());
    REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // r30, under r40
    CHECK_FALSE(h.keptAt(10).has_value());
    CHECK(digest(*h.volumeAt(v, 10)) == at[1]);
  }
  SECTION("a Rebuild gathered before the history was rewritten is not kept") {
    REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // r50
    REQUIRE(h.undoOf(v, "A").outcome == History::AuthorMove::Moved);  // r30, under r40
    h.keep(*r10, r10->run());
    CHECK_FALSE(h.keptAt(10).has_value());
  }
  SECTION("the kept version names a step: not once that step is undone") {
    std::optional<service::Rebuild> r50 = h.rebuildAt(v, 50);
    REQUIRE(r50.has_value());
    CHECK(r50->steps() == 0);
    h.keep(*r50, r50->run());
    CHECK(h.keptAt(50).has_value());
    h.undo(v);
    CHECK_FALSE(h.keptAt(50).has_value());
    CHECK_FALSE(h.volumeAt(v, 50).has_value());
  }
  SECTION("cancelled through the thread's Progress, it stops before a step") {
    Progress progress;
    progress.cancel();
    const Progress::Scope scope(progress);
    CHECK_THROWS_AS(r10->run(), Cancelled);
  }
}
