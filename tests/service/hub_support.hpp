// Drives the hub without sockets: a CaptureLink records what the hub sends to one connection,
// a TestClient sends requests and waits for their answers, a GateLink holds the thread that
// answers a chosen request until the test lets it go, so that tests decide the order of the
// hub's threads instead of racing them. Every wait times out (20 s) so a hang fails the test
// instead of the run.
#pragma once

#include <catch2/catch.hpp>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/frames.hpp"
#include "service/hub.hpp"

namespace marzipan::service::testing {

using nlohmann::json;
using Bytes = std::vector<std::uint8_t>;

// How long a test waits for a message. ThreadSanitizer (tests/tsan.sh, clang) runs the engine
// about twelve times slower: the 64 whole-volume passes of a morph in the progress test took
// over 20 s there (2026-11-25).
#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define MARZIPAN_TEST_SLOW_SANITIZER 1
#endif
#endif
#if defined(MARZIPAN_TEST_SLOW_SANITIZER)
constexpr auto kWait = std::chrono::seconds(120);
#else
constexpr auto kWait = std::chrono::seconds(20);
#endif

// A hub of two workers that takes grids up to 128^3, journaling under dir when one is given.
inline HubOptions twoWorkerOptions(const std::filesystem::path& dir = {}) {
  HubOptions o;
  o.workers = 2;
  o.limits.maxGridSide = 128;
  if (!dir.empty()) o.dataDir = dir;
  return o;
}

// What one connection received, in order.
struct CaptureLink : ClientLink {
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<std::variant<json, Bytes>> messages;
  std::vector<std::thread::id> senders;  // the thread that sent each message
  // Per sendAll (one hand-over of what a piece of work sent, service/hub/outbox.hpp): the index
  // of its first message and how many it carried.
  std::vector<std::pair<std::size_t, std::size_t>> handOvers;
  int closeCode = 0;

  void sendAll(std::vector<Item> items) override {
    {
      const std::lock_guard lock(mutex);
      handOvers.emplace_back(messages.size(), items.size());
    }
    ClientLink::sendAll(std::move(items));
  }

  void sendText(std::string text) override {
    const std::lock_guard lock(mutex);
    messages.emplace_back(json::parse(text));
    senders.push_back(std::this_thread::get_id());
    cv.notify_all();
  }
  void sendBinary(std::shared_ptr<const Bytes> frame, bool) override {
    const std::lock_guard lock(mutex);
    messages.emplace_back(*frame);
    senders.push_back(std::this_thread::get_id());
    cv.notify_all();
  }
  void close(int code, std::string) override {
    const std::lock_guard lock(mutex);
    closeCode = code;
    cv.notify_all();
  }

  // Waits until pred holds for the message list; returns the index it found.
  template <class Pred>
  std::size_t waitFor(Pred pred, std::size_t from = 0) {
    std::unique_lock lock(mutex);
    std::size_t found = SIZE_MAX;
    const bool ok = cv.wait_for(lock, kWait, [&] {
      for (std::size_t i = from; i < messages.size(); ++i)
        if (pred(messages[i])) {
          found = i;
          return true;
        }
      return false;
    });
    if (!ok) FAIL("timed out waiting for a message");
    return found;
  }

  std::size_t size() {
    const std::lock_guard lock(mutex);
    return messages.size();
  }
  std::variant<json, Bytes> at(std::size_t i) {
    const std::lock_guard lock(mutex);
    return messages.at(i);
  }
};

inline bool isResponse(const std::variant<json, Bytes>& m, const json& id) {
  const json* j = std::get_if<json>(&m);
  return j && j->contains("id") && (*j)["id"] == id;
}

inline bool isNotification(const std::variant<json, Bytes>& m, const std::string& method) {
  const json* j = std::get_if<json>(&m);
  return j && !j->contains("id") && j->value("method", "") == method;
}

// Sends a request on c's connection without waiting for its answer (TestClient::call waits).
inline void sendRequest(Hub& hub, const std::shared_ptr<HubClient>& c, int id, const std::string& method,
                        const json& params = json::object()) {
  hub.text(c, json{{"jsonrpc", "2.0"}, {"id", id}, {"method", method}, {"params", params}}.dump());
}

struct TestClient {
  Hub& hub;
  std::shared_ptr<CaptureLink> link = std::make_shared<CaptureLink>();
  std::shared_ptr<HubClient> client;
  int nextId = 1;

  // `peer`: the connection's "address:port", as the network layer gives it.
  explicit TestClient(Hub& h, const std::string& peer = "test") : hub(h), client(h.connect(link, peer)) {}
  ~TestClient() { hub.disconnect(client); }

  // Sends a request and returns its response (the whole message).
  json call(const std::string& method, const json& params = json::object()) {
    const int id = nextId++;
    const std::size_t mark = link->size();
    sendRequest(hub, client, id, method, params);
    return std::get<json>(link->at(link->waitFor([&](const auto& m) { return isResponse(m, id); }, mark)));
  }
  json result(const std::string& method, const json& params = json::object()) {
    const json r = call(method, params);
    INFO(r.dump());
    REQUIRE(r.contains("result"));
    return r["result"];
  }
  // The error object of a call that must fail, and its code.
  json errorObject(const std::string& method, const json& params = json::object()) {
    const json r = call(method, params);
    INFO(r.dump());
    REQUIRE(r.contains("error"));
    return r["error"];
  }
  int error(const std::string& method, const json& params = json::object()) {
    return errorObject(method, params)["code"].get<int>();
  }
  // The session's digest, as session.stats gives it.
  std::string digest() { return result("session.stats")["digest"]; }
  json rawResponse(const std::string& text, const json& id) {
    const std::size_t mark = link->size();
    hub.text(client, text);
    return std::get<json>(link->at(link->waitFor([&](const auto& m) { return isResponse(m, id); }, mark)));
  }
};

// Holds the worker that answers request `gate` at its binary frame, then at its result, until
// the test lets each go (opened), so that edits can run on the strand in between. A strand task
// sends its responses from inside itself (HubCore::finish flushes them before the connection's
// next message is taken): holding a response sent there holds the session's strand. With
// `order`, records the id of every response it is sent, in one list shared by several links:
// the order of the strand's tasks when each of them answered on the strand.
struct SendOrder {
  std::mutex mutex;
  std::vector<std::pair<const void*, json>> sent;  // (link, response id)
};

struct GateLink : CaptureLink {
  std::mutex gateMutex;
  std::condition_variable gateCv;
  std::atomic<int> gate{-1};
  std::atomic<bool> gateProgress{false};
  bool atFrame = false, atResult = false, frameOpen = false, resultOpen = false;
  std::shared_ptr<SendOrder> order;

  // Called on the hub's threads: no Catch assertions here (Catch is not thread-safe).
  void sendBinary(std::shared_ptr<const Bytes> frame, bool droppable) override {
    if (const auto d = protocol::decodeFrameHeader(*frame); d && int(d.frame->header.requestId) == gate)
      hold(atFrame, frameOpen);
    CaptureLink::sendBinary(frame, droppable);
  }
  void sendText(std::string text) override {
    const json j = json::parse(text);
    if (order && j.contains("id")) {
      const std::lock_guard lock(order->mutex);
      order->sent.emplace_back(this, j["id"]);
    }
    if (j.contains("id") ? j["id"] == gate.load() : j.value("method", "") == "op.progress" && gateProgress.exchange(false))
      hold(atResult, resultOpen);
    CaptureLink::sendText(std::move(text));
  }
  void hold(bool& at, bool& open) {
    std::unique_lock lock(gateMutex);
    at = true;
    gateCv.notify_all();
    gateCv.wait(lock, [&] { return open; });
  }
  // On the test's thread.
  void waitUntil(bool& flag) {
    std::unique_lock lock(gateMutex);
    if (!gateCv.wait_for(lock, kWait, [&] { return flag; })) FAIL("timed out waiting at a gate");
  }
  void set(bool& flag) {
    const std::lock_guard lock(gateMutex);
    flag = true;
    gateCv.notify_all();
  }
  // Holds the next answer to `id` anew.
  void gateAt(int id) {
    const std::lock_guard lock(gateMutex);
    atFrame = atResult = frameOpen = resultOpen = false;
    gate = id;
  }
  // Holds the thread that sends the next op.progress (a long operation's, mid-way), as an
  // answer (atResult, resultOpen).
  void gateAtProgress() {
    const std::lock_guard lock(gateMutex);
    atFrame = atResult = frameOpen = resultOpen = false;
    gate = -1;
    gateProgress = true;
  }
  // Lets everything go and holds nothing more: a failed check must not leave the hub's worker
  // held when the hub shuts down.
  void openAll() {
    const std::lock_guard lock(gateMutex);
    gate = -1;
    gateProgress = false;
    frameOpen = resultOpen = true;
    gateCv.notify_all();
  }
};

// Opens the links' gates when the test leaves, by a failed REQUIRE too (declare after the hub).
struct OpenOnExit {
  std::vector<std::shared_ptr<GateLink>> links;
  ~OpenOnExit() {
    for (const auto& l : links) l->openAll();
  }
};

}  // namespace marzipan::service::testing
