// service/hub/outbox.cpp: what a strand task sends is handed to each link as one sendAll, in
// order, before its connection's next message starts; outside a task a link is called at once.
#include <catch2/catch.hpp>

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/frames.hpp"
#include "service/hub.hpp"
#include "service/hub/outbox.hpp"
#include "hub_support.hpp"

using namespace marzipan;
using namespace marzipan::service;
using namespace marzipan::service::testing;

namespace {

// Every call a link gets, in order: "text:T", "binary:N" (bytes), "transient:T/K", "all:N",
// "close:C".
struct CallLog : ClientLink {
  std::string name;
  std::vector<std::string> calls;
  void sendText(std::string text) override { calls.push_back("text:" + text); }
  void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>> frame, bool latestWins) override {
    calls.push_back("binary:" + std::to_string(frame->size()) + (latestWins ? " latest" : ""));
  }
  void sendTransient(std::vector<Transient> texts) override {
    for (const Transient& t : texts) calls.push_back("transient:" + *t.text + "/" + std::to_string(t.key));
  }
  void sendAll(std::vector<Item> items) override {
    calls.push_back("all:" + std::to_string(items.size()));
    ClientLink::sendAll(std::move(items));
  }
  void close(int code, std::string) override { calls.push_back("close:" + std::to_string(code)); }
};

std::shared_ptr<const std::vector<std::uint8_t>> bytes(std::size_t n) {
  return std::make_shared<const std::vector<std::uint8_t>>(n, std::uint8_t(7));
}

bool isDelta(const std::variant<json, Bytes>& m) {
  const Bytes* b = std::get_if<Bytes>(&m);
  if (!b) return false;
  const auto d = protocol::decodeFrameHeader(*b);
  return d && d.frame->header.kind == protocol::FrameKind::SplatsDelta;
}

}  // namespace

TEST_CASE("outbox: outside a scope a held link calls its link at once", "[hub][outbox]") {
  auto log = std::make_shared<CallLog>();
  HeldLink link(log);
  link.sendText("a");
  link.sendBinary(bytes(3), true);
  link.sendTogether({{std::make_shared<const std::string>("b"), nullptr}, {nullptr, bytes(2)}});
  link.sendTransient({{std::make_shared<const std::string>("p"), 9}});
  CHECK(log->calls == std::vector<std::string>{"text:a", "binary:3 latest", "text:b", "binary:2", "transient:p/9"});
}

TEST_CASE("outbox: within a scope each link gets what it was sent as one sendAll, in order", "[hub][outbox]") {
  auto log1 = std::make_shared<CallLog>(), log2 = std::make_shared<CallLog>();
  HeldLink one(log1), two(log2);
  {
    const Outbox::Scope held;
    one.sendText("r");
    two.sendTogether({{std::make_shared<const std::string>("c"), nullptr}, {nullptr, bytes(5)}});
    one.sendTogether({{std::make_shared<const std::string>("c"), nullptr}, {nullptr, bytes(5)}});
    {
      const Outbox::Scope inner;  // adds to the outer scope: nothing leaves when it closes
      one.sendTransient({{std::make_shared<const std::string>("p"), 4}});
    }
    CHECK(log1->calls.empty());
    CHECK(log2->calls.empty());
  }
  CHECK(log1->calls == std::vector<std::string>{"all:4", "text:r", "text:c", "binary:5", "transient:p/4"});
  CHECK(log2->calls == std::vector<std::string>{"all:2", "text:c", "binary:5"});
  // Closed: at once again.
  one.sendText("x");
  CHECK(log1->calls.back() == "text:x");
}

namespace {

// Links of one carrier: each carry() call logged as the links it carried and their item counts.
struct LogCarrier : ClientLink::Carrier {
  std::vector<std::string> calls;
  void carry(std::vector<ClientLink::Delivery> deliveries) override {
    std::string call = "carry";
    for (auto& d : deliveries) {
      call += " " + static_cast<CallLog&>(*d.link).name + ":" + std::to_string(d.items.size());
      d.link->sendAll(std::move(d.items));
    }
    calls.push_back(call);
  }
};
struct CarriedLog : CallLog {
  CarriedLog(std::string n, LogCarrier* c) : carrierOf(c) { name = std::move(n); }
  Carrier* carrier() override { return carrierOf; }
  LogCarrier* carrierOf;
};

}  // namespace

TEST_CASE("outbox: links that share a carrier are handed theirs in one carry, the others alone", "[hub][outbox]") {
  LogCarrier carrier, other;
  auto a = std::make_shared<CarriedLog>("a", &carrier), b = std::make_shared<CarriedLog>("b", &carrier);
  auto c = std::make_shared<CarriedLog>("c", &other);
  auto alone = std::make_shared<CallLog>();
  HeldLink la(a), lb(b), lc(c), lAlone(alone);
  {
    const Outbox::Scope held;
    la.sendText("r");
    lAlone.sendText("x");
    lb.sendTogether({{std::make_shared<const std::string>("n"), nullptr}, {nullptr, bytes(5)}});
    lc.sendText("y");
    la.sendTogether({{std::make_shared<const std::string>("n"), nullptr}, {nullptr, bytes(5)}});
    CHECK(carrier.calls.empty());
  }
  CHECK(carrier.calls == std::vector<std::string>{"carry a:3 b:2"});
  CHECK(other.calls == std::vector<std::string>{"carry c:1"});
  CHECK(a->calls == std::vector<std::string>{"all:3", "text:r", "text:n", "binary:5"});
  CHECK(b->calls == std::vector<std::string>{"all:2", "text:n", "binary:5"});
  CHECK(alone->calls == std::vector<std::string>{"all:1", "text:x"});
}

TEST_CASE("outbox: a flush hands over what is held, a close goes after what was sent before it", "[hub][outbox]") {
  auto log = std::make_shared<CallLog>();
  HeldLink link(log);
  const Outbox::Scope held;
  link.sendText("a");
  Outbox::flush();
  CHECK(log->calls == std::vector<std::string>{"all:1", "text:a"});
  link.sendText("b");
  link.close(1008, "too far behind");
  CHECK(log->calls == std::vector<std::string>{"all:1", "text:a", "all:1", "text:b", "close:1008"});
  Outbox::flush();  // nothing held: no call
  CHECK(log->calls.size() == 5);
}

TEST_CASE("outbox: a stroke's response, notification and delta reach each client as one hand-over",
          "[hub][outbox]") {
  Hub hub(twoWorkerOptions());
  TestClient a(hub), b(hub);
  const json created = a.result("session.create", {{"size", {64, 64, 64}}, {"solid", "sphere"}});
  b.result("session.join", {{"session", created["session"]}, {"token", created["token"]}});
  const json stroke = a.result("stroke.begin", {{"tool", "add_blob"}, {"radius", 4}, {"height", 1}})["stroke"];
  const std::size_t markA = a.link->size(), markB = b.link->size();
  const json dabs = json::array({{{"ray", {{"origin", {32, 200, 31.5}}, {"direction", {0, -1, 0}}}}}});
  const json r = a.result("stroke.dabs", {{"stroke", stroke}, {"dabs", dabs}});
  REQUIRE(r["applied"] == 1);
  const std::size_t deltaA = a.link->waitFor(isDelta, markA), deltaB = b.link->waitFor(isDelta, markB);
  // The requester: its response, session.changed and the delta, handed over together.
  const auto handOverAt = [](CaptureLink& link, std::size_t first) {
    const std::lock_guard lock(link.mutex);
    for (const auto& h : link.handOvers)
      if (h.first == first) return h.second;
    return std::size_t(0);
  };
  REQUIRE(deltaA >= markA + 2);
  CHECK(isResponse(a.link->at(deltaA - 2), a.nextId - 1));
  CHECK(isNotification(a.link->at(deltaA - 1), "session.changed"));
  CHECK(handOverAt(*a.link, deltaA - 2) == 3);
  // The other client: the notification and the delta.
  CHECK(isNotification(b.link->at(deltaB - 1), "session.changed"));
  CHECK(handOverAt(*b.link, deltaB - 1) == 2);
}
