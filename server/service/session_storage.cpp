// The in-memory SessionStorage (see session_storage.hpp).
#include "service/session_storage.hpp"

namespace marzipan::service {

namespace {

class MemoryStorage final : public SessionStorage {
 public:
  bool persistent() const override { return false; }
  std::string where() const override { return "memory"; }

  // One server, nothing shared: every lease is this server's and is never lost.
  bool acquire(const std::string&) override { return true; }
  bool renew(const std::string&) override { return true; }
  bool holds(const std::string&) override { return true; }
  void release(const std::string&) override {}
  std::chrono::milliseconds renewEvery() const override { return std::chrono::hours(1); }
  void onLost(std::function<void(const std::string&)>) override {}

  bool exists(const std::string&) const override { return false; }
  std::optional<SessionSecrets> secrets(const std::string&) const override { return std::nullopt; }
  std::unique_ptr<SessionLog> create(const std::string&, const SessionSecrets&, const Volume&) override { return nullptr; }
  std::unique_ptr<SessionLog> snapshot(const std::string&, const Volume&, const std::vector<nlohmann::json>&) override {
    return nullptr;
  }
  std::string saveStep(const std::string&, std::uint64_t, const std::vector<std::pair<Int3, BrickRef>>&) override {
    return {};
  }
  std::string saveUpload(const std::string&, std::uint64_t, std::span<const std::uint8_t>) override { return {}; }
  Recovered recover(const std::string& id, std::size_t, ThreadPool&) override {
    throw std::runtime_error("session " + id + " was kept in memory only: nothing to recover");
  }
  void remove(const std::string&) override {}
  std::vector<std::string> removeUntouched(std::chrono::seconds, const std::function<bool(const std::string&)>&) override {
    return {};
  }
};

}  // namespace

std::unique_ptr<SessionStorage> makeMemoryStorage() { return std::make_unique<MemoryStorage>(); }

}  // namespace marzipan::service
