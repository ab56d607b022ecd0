// SharedState (see shared_state.hpp): the session registry and the connection bounds. No Boost.
#include "net/shared_state.hpp"

#include "service/hub.hpp"

namespace marzipan::net {

SharedState::SharedState(const HttpServerOptions& o, Metrics& m) : options(o), files(o.webRoot), metrics(m) {
  for (const auto& [prefix, dir] : o.mounts) mounts.emplace_back(prefix, StaticFiles(dir));
}

void SharedState::log(const std::string& line) const {
  if (options.log) return options.log(line);
  logToStderr(line);
}

bool SharedState::join(const std::shared_ptr<HttpSession>& session) {
  const std::lock_guard lock(mutex_);
  if (stopping_) return false;
  if (sessions_.size() >= 2 * live_ + 64) std::erase_if(sessions_, [](const auto& w) { return w.expired(); });
  sessions_.push_back(session);
  ++live_;
  return true;
}

void SharedState::leave() {
  const std::lock_guard lock(mutex_);
  --live_;
  if (live_ == 0) idle_.notify_all();
}

bool SharedState::joinWs(const std::shared_ptr<WsSession>& ws) {
  const std::lock_guard lock(mutex_);
  if (stopping_) return false;
  if (websockets_.size() >= 2 * liveWs_ + 64) std::erase_if(websockets_, [](const auto& w) { return w.expired(); });
  websockets_.push_back(ws);
  ++liveWs_;
  ++live_;
  return true;
}

void SharedState::leaveWs() {
  const std::lock_guard lock(mutex_);
  --liveWs_;
  --live_;
  if (live_ == 0) idle_.notify_all();
}

bool SharedState::isStopping() {
  const std::lock_guard lock(mutex_);
  return stopping_;
}

std::shared_ptr<void> SharedState::takeSlot(const std::string& address) {
  const service::HubLimits limits = options.hub ? options.hub->limits() : service::HubLimits{};
  {
    const std::lock_guard lock(mutex_);
    std::size_t& mine = perAddress_[address];
    if (connections_ >= limits.maxConnections || mine >= limits.maxConnectionsPerAddress) {
      if (mine == 0) perAddress_.erase(address);
      return nullptr;
    }
    ++mine;
    ++connections_;
  }
  return std::shared_ptr<void>(new char, [self = shared_from_this(), address](void* p) {
    delete static_cast<char*>(p);
    const std::lock_guard lock(self->mutex_);
    --self->connections_;
    if (--self->perAddress_[address] == 0) self->perAddress_.erase(address);
  });
}

SharedState::Live SharedState::startStopping() {
  const std::lock_guard lock(mutex_);
  stopping_ = true;
  return {sessions_, websockets_};
}

void SharedState::acceptorClosed() {
  const std::lock_guard lock(mutex_);
  acceptorClosed_ = true;
  idle_.notify_all();
}

void SharedState::waitUntilIdle(std::chrono::milliseconds grace) {
  std::unique_lock lock(mutex_);
  idle_.wait_for(lock, grace, [this] { return live_ == 0 && acceptorClosed_; });
}

}  // namespace marzipan::net
