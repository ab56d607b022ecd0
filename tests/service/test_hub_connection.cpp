// service/hub/connection.hpp: a connection's queue keeps arrival order and refuses past its
// bounds (messages waiting, requests per second, bytes waiting), and one owner at a time.
#include <catch2/catch.hpp>

#include <chrono>
#include <string>

#include "service/hub/connection.hpp"

using namespace marzipan::service;
using namespace std::chrono_literals;

namespace {

Incoming text(std::string s, Clock::time_point at) { return {std::move(s), at}; }

HubLimits roomy() {
  HubLimits l;
  l.maxPendingMessages = 1000;
  l.maxRequestsPerSecond = 1000;
  return l;
}

}  // namespace

TEST_CASE("the queue hands out messages in arrival order, with one owner at a time", "[hub][connection]") {
  ConnectionQueue q;
  const auto t = Clock::now() + 1s;
  Incoming a = text("a", t), b = text("bb", t), out;
  const auto first = q.push(a, roomy(), t);
  CHECK((first.queued && first.start && first.refusal.empty()));
  const auto second = q.push(b, roomy(), t);
  CHECK((second.queued && !second.start));  // the first push's owner takes it
  REQUIRE(q.take(out) == ConnectionQueue::Next::Message);
  CHECK(std::get<std::string>(out.message) == "a");
  CHECK(q.finished() == ConnectionQueue::Next::Message);
  REQUIRE(q.take(out) == ConnectionQueue::Next::Message);
  CHECK(std::get<std::string>(out.message) == "bb");
  CHECK(q.finished() == ConnectionQueue::Next::Idle);
  Incoming c = text("c", t);
  CHECK(q.push(c, roomy(), t).start);  // let go: the next push starts an owner again
  CHECK(q.take(out) == ConnectionQueue::Next::Message);
  CHECK(q.take(out) == ConnectionQueue::Next::Idle);
}

TEST_CASE("the queue refuses past max_pending_messages and keeps the refused message", "[hub][connection]") {
  ConnectionQueue q;
  HubLimits l = roomy();
  l.maxPendingMessages = 3;
  const auto t = Clock::now() + 1s;
  for (int i = 0; i < 3; ++i) {
    Incoming in = text("x", t);
    REQUIRE(q.push(in, l, t).queued);
  }
  Incoming over = text("{\"id\":4}", t);
  const auto refused = q.push(over, l, t);
  CHECK_FALSE(refused.queued);
  CHECK(refused.refusal == "too many requests in flight on this connection (3); wait for answers before sending more");
  CHECK(std::get<std::string>(over.message) == "{\"id\":4}");  // left for the caller to answer
  Incoming out;
  REQUIRE(q.take(out) == ConnectionQueue::Next::Message);
  CHECK(q.push(over, l, t).queued);  // one answered: room for one more
}

TEST_CASE("the request rate is a token bucket of two seconds' worth", "[hub][connection]") {
  ConnectionQueue q;
  HubLimits l = roomy();
  l.maxRequestsPerSecond = 10;
  const auto t = Clock::now() + 1s;
  const auto pushAt = [&](Clock::time_point at) {
    Incoming in = text("x", at);
    return q.push(in, l, at);
  };
  for (int i = 0; i < 20; ++i) REQUIRE(pushAt(t).queued);  // a burst of 2 s x 10/s
  const auto refused = pushAt(t);
  CHECK_FALSE(refused.queued);
  CHECK(refused.refusal == "more than 10 requests per second on this connection; slow down");
  // Half a second later five more tokens have come back, and no more.
  for (int i = 0; i < 5; ++i) REQUIRE(pushAt(t + 500ms).queued);
  CHECK_FALSE(pushAt(t + 500ms).queued);
  // A long pause refills to the burst, not beyond.
  int accepted = 0;
  while (pushAt(t + 60s).queued) ++accepted;
  CHECK(accepted == 20);
}

TEST_CASE("the bytes waiting are bounded by max_text_bytes + max_binary_bytes", "[hub][connection]") {
  ConnectionQueue q;
  HubLimits l = roomy();
  l.maxTextBytes = 10;
  l.maxBinaryBytes = 20;
  const auto t = Clock::now() + 1s;
  Incoming big{Bytes(25), t}, six = text("123456", t), five = text("12345", t);
  REQUIRE(q.push(big, l, t).queued);
  const auto refused = q.push(six, l, t);
  CHECK_FALSE(refused.queued);
  CHECK(refused.refusal == "too many bytes waiting on this connection; wait for answers before sending more");
  CHECK(q.push(five, l, t).queued);  // exactly 30
  Incoming out;
  REQUIRE(q.take(out) == ConnectionQueue::Next::Message);
  CHECK(out.size() == 25);
  CHECK(q.push(six, l, t).queued);  // the upload's bytes left the queue with it
}

TEST_CASE("a closed queue drops what waits, whoever owns it then cleans up", "[hub][connection]") {
  const auto t = Clock::now() + 1s;
  SECTION("closed while an owner handles a message: the owner cleans up") {
    ConnectionQueue q;
    Incoming a = text("a", t), b = text("b", t), out;
    REQUIRE(q.push(a, roomy(), t).start);
    REQUIRE(q.push(b, roomy(), t).queued);
    REQUIRE(q.take(out) == ConnectionQueue::Next::Message);
    CHECK_FALSE(q.close());  // owned: not the caller's to clean up
    CHECK_FALSE(q.close());  // idempotent
    CHECK(q.closed());
    CHECK(q.finished() == ConnectionQueue::Next::Closed);
    CHECK(q.take(out) == ConnectionQueue::Next::Closed);
  }
  SECTION("closed while idle: the caller owns it, and nothing more is queued") {
    ConnectionQueue q;
    CHECK(q.close());
    Incoming late = text("late", t);
    const auto a = q.push(late, roomy(), t);
    CHECK((!a.queued && !a.start && a.refusal.empty()));
  }
}
