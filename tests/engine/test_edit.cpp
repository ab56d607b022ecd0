// Edit::append (edit.hpp): folding a later step into an edit keeps, per brick, the first
// `before` and the last `after`, drops a brick that ends as it started, and keeps the bricks in
// the order they were first changed. Checked against that rule written out brick by brick, on
// random folds of diffs (each brick once) that meet the edit's bricks, leave some unchanged and
// bring others back to where they began.
#include <catch2/catch.hpp>

#include <algorithm>
#include <memory>
#include <random>
#include <vector>

#include "engine/edit.hpp"

using namespace marzipan;

namespace {

// The rule, one later change at a time: the last change of the brick so far takes its `after`,
// else the change is appended; then every brick whose after is its before is dropped.
std::vector<BrickChange> folded(std::vector<BrickChange> changes, const std::vector<BrickChange>& later) {
  for (const BrickChange& c : later) {
    BrickChange* last = nullptr;
    for (BrickChange& e : changes)
      if (e.brick == c.brick) last = &e;
    if (last) last->after = c.after;
    else changes.push_back(c);
  }
  std::erase_if(changes, [](const BrickChange& c) { return c.before == c.after; });
  return changes;
}

bool same(const std::vector<BrickChange>& a, const std::vector<BrickChange>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!(a[i].brick == b[i].brick && a[i].before == b[i].before && a[i].after == b[i].after)) return false;
  return true;
}

}  // namespace

TEST_CASE("append keeps each brick's first before and last after, in the order first changed", "[edit]") {
  // Six versions of a brick's data: a later step often writes back one an earlier step had.
  std::vector<BrickRef> versions;
  for (int v = 0; v < 6; ++v) versions.emplace_back(std::make_shared<const Brick>(), false);
  versions.emplace_back(nullptr, true);
  versions.emplace_back(nullptr, false);
  std::mt19937 rng{5};
  const auto pick = [&](int n) { return int(rng() % unsigned(n)); };
  int folds = 0, dropped = 0, met = 0;
  for (int round = 0; round < 400; ++round) {
    Edit edit;
    std::vector<BrickChange> expected;
    // Bricks from a small range, so that steps meet; a stroke of up to 12 applications.
    for (int step = 0, steps = 1 + pick(12); step < steps; ++step) {
      std::vector<BrickChange> later;
      // A diff's changes: each brick at most once (edit.cpp), some not changed at all.
      for (int k = 0, n = pick(20); k < n; ++k) {
        const Int3 b{pick(4), pick(3), pick(4) - 1};
        if (std::any_of(later.begin(), later.end(), [&](const BrickChange& c) { return c.brick == b; })) continue;
        const BrickRef before = versions[pick(int(versions.size()))];
        later.push_back({b, before, pick(5) == 0 ? before : versions[pick(int(versions.size()))]});
      }
      for (const BrickChange& c : later)
        met += std::any_of(expected.begin(), expected.end(), [&](const BrickChange& e) { return e.brick == c.brick; });
      const std::size_t before = expected.size() + later.size();
      expected = folded(expected, later);
      dropped += int(before - expected.size()) > 0;
      edit.append(later, Box{{0, 0, 0}, {1, 1, 1}});
      ++folds;
      INFO("round " << round << ", step " << step);
      REQUIRE(same(edit.changes, expected));
    }
  }
  // The folds met every case: bricks dropped, and later bricks the edit already held.
  CHECK(dropped > 100);
  CHECK(met > 1000);
  CHECK(folds > 1000);
}

TEST_CASE("append grows the region to hold both, an empty one adding nothing", "[edit]") {
  Edit e;
  e.append({}, Box{{2, 3, 4}, {5, 6, 7}});
  CHECK(e.region == Box{{2, 3, 4}, {5, 6, 7}});
  e.append({}, Box{});
  CHECK(e.region == Box{{2, 3, 4}, {5, 6, 7}});
  e.append({}, Box{{0, 4, 5}, {3, 9, 6}});
  CHECK(e.region == Box{{0, 3, 4}, {5, 9, 7}});
}
