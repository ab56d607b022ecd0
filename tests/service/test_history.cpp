// History (server/service/history.cpp): undo and redo restore exact digests, the memory budget
// drops the oldest steps first, and a new step clears the redo list.
#include <catch2/catch.hpp>

#include <cstdint>
#include <vector>

#include "engine/csg.hpp"
#include "engine/level_set.hpp"
#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "service/history.hpp"

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
  CHECK(h.bytes() > 0);
  for (std::size_t i = 1; i < digests.size(); ++i) CHECK(digests[i] != digests[i - 1]);

  for (std::size_t i = digests.size() - 1; i > 0; --i) {
    REQUIRE(h.canUndo());
    REQUIRE(h.undo(v) != nullptr);
    CHECK(digest(v) == digests[i - 1]);
  }
  CHECK_FALSE(h.canUndo());
  CHECK(h.undo(v) == nullptr);
  CHECK(h.redoSteps() == 5);
  const std::size_t bytes = h.bytes();

  for (std::size_t i = 1; i < digests.size(); ++i) {
    REQUIRE(h.redo(v) != nullptr);
    CHECK(digest(v) == digests[i]);
  }
  CHECK_FALSE(h.canRedo());
  CHECK(h.redo(v) == nullptr);
  CHECK(h.bytes() == bytes);  // moving steps between the lists costs nothing
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
  // Each step's size, measured with an unlimited budget.
  std::vector<std::size_t> sizes;
  {
    Volume v = sphere();
    History h(SIZE_MAX);
    for (int i = 0; i < 6; ++i) {
      const std::size_t before = h.bytes();
      h.push(addBlob(v, {{kSurface, kC - 15 + 6 * i, kC}, 4, 1}, pool));
      sizes.push_back(h.bytes() - before);
      REQUIRE(sizes.back() > 0);
    }
  }
  // Room for about the last three.
  const std::size_t budget = sizes[3] + sizes[4] + sizes[5] + History::kBytesPerBrick;
  Volume v = sphere();
  History h(budget);
  std::vector<std::uint64_t> digests{digest(v)};
  for (int i = 0; i < 6; ++i) {
    h.push(addBlob(v, {{kSurface, kC - 15 + 6 * i, kC}, 4, 1}, pool));
    digests.push_back(digest(v));
    CHECK(h.bytes() <= budget);
  }
  CHECK(h.droppedSteps() >= 2);
  CHECK(h.undoSteps() + h.droppedSteps() == 6);
  const std::size_t kept = h.undoSteps();
  REQUIRE(kept >= 1);
  for (std::size_t i = 0; i < kept; ++i) REQUIRE(h.undo(v) != nullptr);
  CHECK_FALSE(h.canUndo());
  // The kept steps are the newest: undoing them all lands on the state after the dropped ones.
  CHECK(digest(v) == digests[6 - kept]);

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
