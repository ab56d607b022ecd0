// PresenceCoalescer (server/service/presence.cpp) on a fake clock: at most one delivery per
// sender and receiver per 50 ms, always the newest update, never a backlog, never one's own.
#include <catch2/catch.hpp>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "service/presence.hpp"

using marzipan::service::PresenceCoalescer;
using marzipan::service::PresenceText;
using namespace std::chrono_literals;
using Clock = PresenceCoalescer::Clock;

namespace {

struct FakeClock {
  Clock::time_point t = Clock::time_point{} + 1000h;  // far from the clock's epoch
  std::function<Clock::time_point()> fn() {
    return [this] { return t; };
  }
};

PresenceCoalescer::Payload text(const std::string& s) { return std::make_shared<const PresenceText>(s); }

}  // namespace

TEST_CASE("presence: a 60 Hz sender reaches an eager receiver at most 20 times a second, newest each time",
          "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn());
  p.join(1);
  p.join(2);
  const Clock::time_point start = clock.t;
  std::vector<Clock::time_point> deliveries;
  std::uint64_t sent = 0, lastDelivered = 0;
  // 2 s of pointer moves at 60 Hz (every 16 or 17 ms), the receiver taking after each one.
  for (int i = 0; i < 120; ++i) {
    clock.t = start + std::chrono::milliseconds(i * 1000 / 60);
    REQUIRE(p.update(1, text("move " + std::to_string(i))));
    ++sent;
    for (const auto& d : p.take(2)) {
      CHECK(d.sender == 1);
      CHECK(d.seq == sent);  // the newest, never an older one
      CHECK(*d.payload->text() == "move " + std::to_string(i));
      deliveries.push_back(clock.t);
      lastDelivered = d.seq;
    }
    CHECK(p.take(1).empty());  // never one's own
  }
  // At most 20 per second: 2 s (0 .. 1983 ms) hold 40 intervals of 50 ms.
  CHECK(deliveries.size() <= 40);
  CHECK(deliveries.size() >= 36);  // and not much fewer: a delivery is due every 50 ms
  for (std::size_t i = 1; i < deliveries.size(); ++i) CHECK(deliveries[i] - deliveries[i - 1] >= 50ms);
  // The last moves came within 50 ms of a delivery: the newest of them is held, not lost.
  REQUIRE(lastDelivered < sent);
  CHECK(*p.nextDue(2) == deliveries.back() + 50ms);
  clock.t = deliveries.back() + 50ms;
  const auto held = p.take(2);
  REQUIRE(held.size() == 1);
  CHECK(held[0].seq == sent);
  // Nothing new: nothing to take, however late.
  clock.t += 10s;
  CHECK(p.take(2).empty());
  CHECK_FALSE(p.nextDue(2).has_value());
}

TEST_CASE("presence: a slow receiver gets only the newest update of each sender", "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn());
  for (PresenceCoalescer::ClientId c : {7, 8, 9}) p.join(c);
  for (int i = 0; i < 300; ++i) {
    clock.t += 5ms;
    p.update(7, text("seven " + std::to_string(i)));
    if (i % 3 == 0) p.update(8, text("eight " + std::to_string(i)));
  }
  const auto got = p.take(9);
  REQUIRE(got.size() == 2);
  CHECK(got[0].sender == 7);
  CHECK(got[0].seq == 300);
  CHECK(*got[0].payload->text() == "seven 299");
  CHECK(got[1].sender == 8);
  CHECK(got[1].seq == 100);
  CHECK(*got[1].payload->text() == "eight 297");
  // 7 gets 8's newest only, 8 gets 7's only; the payload buffer is shared, not copied.
  const auto to8 = p.take(8);
  REQUIRE(to8.size() == 1);
  CHECK(to8[0].sender == 7);
  CHECK(to8[0].payload == got[0].payload);
  CHECK(p.take(9).empty());
}

TEST_CASE("presence: nextDue tells when a held update may go, per receiver and overall", "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn(), 50ms);
  p.join(1);
  p.join(2);
  p.join(3);
  CHECK_FALSE(p.nextDue().has_value());
  p.update(1, text("a"));
  // Never delivered: due at once (a time already past).
  REQUIRE(p.nextDue(2).has_value());
  CHECK(*p.nextDue(2) <= clock.t);
  CHECK_FALSE(p.nextDue(1).has_value());  // nothing for the sender itself
  const Clock::time_point t0 = clock.t;
  REQUIRE(p.take(2).size() == 1);
  clock.t += 10ms;
  p.update(1, text("b"));
  CHECK(*p.nextDue(2) == t0 + 50ms);
  CHECK(*p.nextDue(3) <= clock.t);  // 3 has taken nothing yet
  CHECK(*p.nextDue() <= clock.t);
  REQUIRE(p.take(3).size() == 1);
  CHECK(*p.nextDue() == t0 + 50ms);
  clock.t = t0 + 49ms;
  CHECK(p.take(2).empty());
  clock.t = t0 + 50ms;
  const auto d = p.take(2);
  REQUIRE(d.size() == 1);
  CHECK(*d[0].payload->text() == "b");
  CHECK_FALSE(p.nextDue().has_value());
}

TEST_CASE("presence: unknown clients are refused and leaving drops what was pending", "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn());
  CHECK_FALSE(p.update(5, text("x")));
  CHECK(p.take(5).empty());
  p.join(1);
  p.join(2);
  CHECK(p.clients() == 2);
  CHECK_FALSE(p.update(5, text("x")));
  CHECK(p.take(2).empty());
  p.update(1, text("here"));
  p.leave(1);
  CHECK(p.clients() == 1);
  CHECK(p.take(2).empty());
  CHECK_FALSE(p.nextDue().has_value());
  // Joining again starts afresh.
  p.join(1);
  CHECK(p.take(2).empty());
  p.update(1, text("back"));
  const auto d = p.take(2);
  REQUIRE(d.size() == 1);
  CHECK(d[0].seq == 1);
  p.leave(2);
  CHECK(p.take(2).empty());
}

TEST_CASE("presence: each sender has its own rate to each receiver", "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn());
  for (PresenceCoalescer::ClientId c = 1; c <= 16; ++c) p.join(c);
  // 16 clients moving at 60 Hz for one second, every receiver taking after every tick.
  std::vector<std::vector<int>> counts(17, std::vector<int>(17, 0));
  const Clock::time_point start = clock.t;
  for (int i = 0; i < 60; ++i) {
    clock.t = start + std::chrono::milliseconds(i * 1000 / 60);
    for (PresenceCoalescer::ClientId c = 1; c <= 16; ++c) p.update(c, text(std::to_string(c)));
    for (PresenceCoalescer::ClientId r = 1; r <= 16; ++r)
      for (const auto& d : p.take(r)) {
        CHECK(*d.payload->text() == std::to_string(d.sender));
        ++counts[r][d.sender];
      }
  }
  for (int r = 1; r <= 16; ++r)
    for (int s = 1; s <= 16; ++s) {
      INFO("receiver " << r << " sender " << s);
      if (r == s) CHECK(counts[r][s] == 0);
      else CHECK((counts[r][s] >= 18 && counts[r][s] <= 20));  // 0 .. 983 ms: 20 intervals
    }
}

TEST_CASE("presence: takeAll serves every receiver at one instant and encodes each taken update once", "[presence]") {
  FakeClock clock;
  PresenceCoalescer p(clock.fn());
  for (PresenceCoalescer::ClientId c = 1; c <= 4; ++c) p.join(c);
  int encoded = 0, made = 0;
  // 4 clients moving at 60 Hz for one second; the owner flushes whenever something is due, as
  // the hub's relay does, with takeAll.
  int flushes = 0;
  std::optional<Clock::time_point> lastFlush;
  const Clock::time_point start = clock.t;
  for (int i = 0; i < 60; ++i) {
    clock.t = start + std::chrono::milliseconds(i * 1000 / 60);
    for (PresenceCoalescer::ClientId c = 1; c <= 4; ++c) {
      const std::string body = std::to_string(c) + "@" + std::to_string(i);
      p.update(c, std::make_shared<const PresenceText>([&encoded, body] {
        ++encoded;
        return body;
      }));
      ++made;
    }
    const auto due = p.nextDue();
    REQUIRE(due.has_value());
    // Every pair was served at the last flush: all are due again together, one interval later.
    if (lastFlush) CHECK(*due == *lastFlush + 50ms);
    if (*due > clock.t) continue;
    lastFlush = clock.t;
    const auto taken = p.takeAll();
    ++flushes;
    // Every receiver at once, in order, each with the newest of the 3 others.
    REQUIRE(taken.size() == 4);
    for (std::size_t r = 0; r < taken.size(); ++r) {
      CHECK(taken[r].first == r + 1);
      REQUIRE(taken[r].second.size() == 3);
      for (const auto& d : taken[r].second) CHECK(*d.payload->text() == std::to_string(d.sender) + "@" + std::to_string(i));
    }
    // The same update goes to every receiver as one buffer: sender 2's to receivers 1 and 3.
    REQUIRE(taken[0].second[0].sender == 2);
    REQUIRE(taken[2].second[1].sender == 2);
    CHECK(taken[0].second[0].payload->text() == taken[2].second[1].payload->text());
  }
  // 0, 50, ..., 950 ms: 20 flushes, each taking one update of each of the 4 senders; only those
  // 80 of the 240 updates were ever encoded, each once however many receivers got it.
  CHECK(flushes == 20);
  CHECK(made == 240);
  CHECK(encoded == 80);
}
