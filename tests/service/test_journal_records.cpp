// Journal records (server/service/journal_records.cpp) of authored steps: a session whose
// changes carry their authors and times, with undo_mine/redo_mine records, recovers (snapshot
// + journal through SessionStore) to the same digest and revision after every record, with the
// same steps (authors, tools, times, revisions) when the history survives, through the history
// when it holds the undone step and from the step file when a snapshot cut it.
#include <catch2/catch.hpp>

#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/measures.hpp"
#include "engine/solids.hpp"
#include "engine/volume_file.hpp"
#include "protocol/cpp/ops.hpp"
#include "service/journal_records.hpp"
#include "service/session_store.hpp"
#include "storage_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using marzipan::service::testing::freshDir;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr int kN = 96;  // blobs on different sides share no brick (test_history_authors.cpp)
constexpr double kC = (kN - 1) / 2.0;
const double kR = 0.35 * kN;
const StepAuthor kA{"a", "Ada"}, kB{"b", "Bo"};

// What the hub does for each change, on a live session with a journal.
struct Writer {
  SessionStore& store;
  std::string id;
  Session live{makeSolid(SolidKind::Sphere, {kN, kN, kN})};
  std::unique_ptr<SessionLog> journal;
  std::int64_t clock = 1'795'000'000'000;

  Writer(SessionStore& s, std::string i) : store(s), id(std::move(i)) {
    live.setClock([this] { return clock += 1000; });
    journal = store.create(id, {"t", "v"}, live.volume());
  }
  void op(Vec3 c, const StepAuthor& by) {
    const protocol::Op o = protocol::BrushOp{protocol::BrushTool::AddBlob, BrushParams{c, 4, 1}};
    REQUIRE(live.apply(o, ThreadPool::serial(), by).changed);
    json rec{{"r", live.revision()}, {"op", protocol::toJson(o)}};
    stampRecord(rec, by, live.newestStep()->timeMs);
    journal->append(rec);
  }
  StrokeId begin(const StepAuthor& by) {
    const StrokeId s = live.beginStroke(protocol::BrushTool::AddBlob, 4, 1, {}, false, by);
    for (const auto& [sid, params] : live.openStrokeList())
      if (sid == s) journal->append(strokeBeginRecord(s, params));
    return s;
  }
  void dab(StrokeId s, Vec3 c, const StepAuthor& by) {
    REQUIRE(live.strokeDabs(s, {Dab{c, 1.0}}, ThreadPool::serial()).changed);
    json rec{{"r", live.revision()}, {"stroke", s}, {"dabs", {{c.x, c.y, c.z, 1.0}}}};
    stampRecord(rec, by, live.newestStep()->timeMs);
    journal->append(rec);
  }
  void end(StrokeId s) {
    live.endStroke(s);
    journal->append({{"stroke_end", s}});
  }
  void mine(bool undo, const StepAuthor& by) {
    const HistoryResult h = undo ? live.undoMine(by.id) : live.redoMine(by.id);
    REQUIRE(h.changed);
    const std::string file = store.saveStep(id, h.revision, h.restored);
    journal->append(authorMoveRecord(undo, h.revision, file, *h.step));
  }
  void snapshot() {
    std::vector<json> head;
    for (const auto& [sid, params] : live.openStrokeList()) head.push_back(strokeBeginRecord(sid, params));
    journal = store.snapshot(id, live.volume(), head);
  }
};

// Recovers `id` from the data directory alone and checks it against the live session.
void checkRecovered(const fs::path& dir, const Writer& w, bool sameSteps) {
  SessionStore store(dir);
  const Recovered r = store.recover(w.id, std::size_t(64) << 20, ThreadPool::serial());
  CHECK(r.session->revision() == w.live.revision());
  CHECK(r.session->digest() == w.live.digest());
  CHECK(digest(r.session->volume()) == w.live.digest());
  if (!sameSteps) return;
  const std::vector<StepInfo> got = r.session->steps(), want = w.live.steps();
  REQUIRE(got.size() == want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    INFO("step " << i);
    CHECK(got[i].revision == want[i].revision);
    CHECK(got[i].firstRevision == want[i].firstRevision);
    CHECK(got[i].author == want[i].author);
    CHECK(got[i].tool == want[i].tool);
    CHECK(got[i].timeMs == want[i].timeMs);
    CHECK(got[i].undone == want[i].undone);
  }
}

}  // namespace

TEST_CASE("journal: undo_mine and redo_mine replay to the same digest, revision and steps", "[journal][authors]") {
  const fs::path dir = freshDir("mine");
  SessionStore store(dir);
  Writer w(store, "s");
  w.op({kC + kR, kC, kC}, kA);  // r1
  const StrokeId s = w.begin(kB);
  w.dab(s, {kC - kR, kC, kC}, kB);  // r2
  w.dab(s, {kC - kR, kC + 2, kC}, kB);  // r3
  w.end(s);
  w.op({kC, kC + kR, kC}, kA);  // r4
  checkRecovered(dir, w, true);

  // Through the history: every step was made after the snapshot; the others stay undoable.
  w.mine(true, kA);  // A's r4
  checkRecovered(dir, w, true);
  w.mine(true, kA);  // A's r1, under B's stroke
  checkRecovered(dir, w, true);
  w.mine(false, kA);  // redo A's r1
  checkRecovered(dir, w, true);
  w.mine(true, kB);  // B's stroke
  checkRecovered(dir, w, true);
  {
    SessionStore again(dir);
    const Recovered r = again.recover("s", std::size_t(64) << 20, ThreadPool::serial());
    CHECK(r.session->canUndo());
    CHECK(r.session->canRedo());
  }

  // After a snapshot the steps before it are gone from a recovered history: the undo_mine of
  // one of them replays from its file (and, like undo, leaves no history behind).
  w.snapshot();
  w.mine(true, kA);  // A's r1 again
  checkRecovered(dir, w, false);
  fs::remove_all(dir);
}

TEST_CASE("journal: an undo_mine of a stroke a snapshot cut in two replays the whole stroke", "[journal][authors]") {
  const fs::path dir = freshDir("cut");
  SessionStore store(dir);
  Writer w(store, "s");
  w.op({kC + kR, kC, kC}, kA);
  const StrokeId s = w.begin(kB);
  w.dab(s, {kC - kR, kC, kC}, kB);
  w.snapshot();
  // After the snapshot the stroke goes on in the same step (first revision 2)...
  w.dab(s, {kC - kR, kC + 2, kC}, kB);
  w.dab(s, {kC - kR, kC + 4, kC}, kB);
  w.end(s);
  w.op({kC, kC + kR, kC}, kA);
  REQUIRE(w.live.steps().at(1).firstRevision == 2);
  // ...while the recovered one holds only its part after the snapshot, as a step of B's too:
  // replaying B's undo through it would leave the stroke's first dab in place.
  w.mine(true, kB);
  Session withoutStroke(makeSolid(SolidKind::Sphere, {kN, kN, kN}));
  withoutStroke.apply(protocol::BrushOp{protocol::BrushTool::AddBlob, BrushParams{{kC + kR, kC, kC}, 4, 1}},
                      ThreadPool::serial());
  withoutStroke.apply(protocol::BrushOp{protocol::BrushTool::AddBlob, BrushParams{{kC, kC + kR, kC}, 4, 1}},
                      ThreadPool::serial());
  CHECK(w.live.digest() == withoutStroke.digest());
  checkRecovered(dir, w, false);
  fs::remove_all(dir);
}

TEST_CASE("journal: interleaved authored strokes replay into the same steps", "[journal][authors]") {
  const fs::path dir = freshDir("interleaved");
  SessionStore store(dir);
  Writer w(store, "s");
  const StrokeId a = w.begin(kA);
  const StrokeId b = w.begin(kB);
  for (int i = 0; i < 3; ++i) {
    w.dab(a, {kC + kR, kC + 2 * i, kC}, kA);
    w.dab(b, {kC - kR, kC + 2 * i, kC}, kB);
  }
  REQUIRE(w.live.steps().size() == 2);
  checkRecovered(dir, w, true);
  w.mine(true, kA);  // the whole of A's stroke, through the recovered history
  checkRecovered(dir, w, true);
  w.end(a);
  w.end(b);
  checkRecovered(dir, w, true);
  fs::remove_all(dir);
}

TEST_CASE("journal: a stroke message that adds nothing leaves the stroke's memory as recovery rebuilds it",
          "[journal][stroke]") {
  // A message that changes nothing has no record, so the replay of the stroke's later
  // messages never remembers its dabs: the live stroke must not either, or where their windows
  // reach beyond the rest of the memory (a height's windows move with the surface) a later
  // message would add less live than in the replay.
  const fs::path dir = freshDir("noop");
  SessionStore store(dir);
  Writer w(store, "s");
  const StrokeId s = w.begin(kA);
  w.dab(s, {kC + kR, kC, kC}, kA);
  const std::uint64_t revision = w.live.revision();
  REQUIRE_FALSE(w.live.strokeDabs(s, {Dab{Vec3{kC + kR, kC, kC}, 0.5}}, ThreadPool::serial()).changed);
  CHECK(w.live.revision() == revision);
  w.dab(s, {kC + kR, kC + 3, kC}, kA);
  checkRecovered(dir, w, true);
  std::size_t remembered = 0;
  for (const auto& [id, params] : w.live.openStrokeList())
    if (id == s) remembered = params.memory.size();
  CHECK(remembered == 2);  // the two dabs the journal holds
  fs::remove_all(dir);
}

TEST_CASE("journal: a step file keeps each brick's channels, and files without any are what they were", "[journal][paint]") {
  auto data = std::make_shared<Brick>();
  for (int i = 0; i < kBrickVoxels; ++i) data->v[i] = float(i % 7) - 3.0f;
  auto paint = std::make_shared<BrickPaint>();
  for (int i = 0; i < kBrickVoxels; ++i) paint->t[i] = Texel{std::uint8_t(i), std::uint8_t(255 - i % 256), 7, std::uint8_t(i % 3 ? 0 : 200)};
  paint->masked = true;
  std::vector<std::pair<Int3, BrickRef>> bricks{
      {{1, 2, 3}, BrickRef{data, false, paint}}, {{4, 5, 6}, BrickRef{data, false}}, {{0, 0, 1}, BrickRef{nullptr, true}}};
  const std::vector<std::uint8_t> bytes = encodeStep(bricks);
  // 8 header bytes, three brick headers of 13, two bricks of floats, one of texels, the CRC.
  CHECK(bytes.size() == 8 + 3 * 13 + 2 * sizeof(Brick) + 4 * std::size_t(kBrickVoxels) + 4);
  const auto back = decodeStep(bytes, "test");
  REQUIRE(back.size() == 3);
  REQUIRE(back[0].second.paint);
  CHECK(std::memcmp(back[0].second.paint->t, paint->t, sizeof(paint->t)) == 0);
  CHECK(back[0].second.paint->masked);
  CHECK(std::memcmp(back[0].second.data->v, data->v, sizeof(Brick)) == 0);
  CHECK_FALSE(back[1].second.paint);
  CHECK(back[2].second.inside);
  // Without channels the file is version 1's, byte for byte: kind 2 bricks only.
  const std::vector<std::uint8_t> plain = encodeStep({bricks[1], bricks[2]});
  CHECK(plain.size() == 8 + 2 * 13 + sizeof(Brick) + 4);
  CHECK(plain[8 + 12] == 2);
  // A kind beyond 3 is refused.
  std::vector<std::uint8_t> bad = plain;
  bad[8 + 12] = 4;
  const std::uint32_t crc = crc32Ieee({bad.data(), bad.size() - 4});
  for (int k = 0; k < 4; ++k) bad[bad.size() - 4 + std::size_t(k)] = std::uint8_t(crc >> (8 * k));
  CHECK_THROWS_AS(decodeStep(bad, "bad"), std::runtime_error);
}
