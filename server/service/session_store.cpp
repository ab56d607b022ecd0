// SessionStore (see session_store.hpp).
#include "service/session_store.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "engine/volume_file.hpp"

namespace fs = std::filesystem;

namespace marzipan::service {

void writeFileAtomically(const fs::path& path, const void* data, std::size_t size) {
  const fs::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  const char* p = static_cast<const char*>(data);
  std::size_t left = size;
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(e));
    }
    p += n;
    left -= std::size_t(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot flush " + tmp.string() + ": " + std::strerror(e));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error("cannot rename " + tmp.string() + ": " + std::strerror(e));
  }
}

SessionStore::SessionStore(fs::path dataDir) : dir_(std::move(dataDir)) {
  if (dir_.empty()) return;
  std::error_code ec;
  fs::create_directories(dir_ / "sessions", ec);
  if (ec) throw std::runtime_error("cannot create " + (dir_ / "sessions").string() + ": " + ec.message());
  ::chmod((dir_ / "sessions").c_str(), 0700);
}

fs::path SessionStore::sessionDir(const std::string& id) const { return dir_ / "sessions" / id; }

bool SessionStore::exists(const std::string& id) const {
  if (!enabled()) return false;
  std::error_code ec;
  return fs::exists(sessionDir(id) / "session.json", ec);
}

std::optional<SessionSecrets> SessionStore::secrets(const std::string& id) const {
  if (!exists(id)) return std::nullopt;
  std::ifstream in(sessionDir(id) / "session.json");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object() || !j.contains("token") || !j.contains("view_token") || !j["token"].is_string() ||
      !j["view_token"].is_string())
    throw std::runtime_error("unreadable " + (sessionDir(id) / "session.json").string());
  return SessionSecrets{j["token"].get<std::string>(), j["view_token"].get<std::string>()};
}

Volume SessionStore::load(const std::string& id) const { return loadVolumeFile((sessionDir(id) / "volume.mzv").string()); }

void SessionStore::save(const std::string& id, const SessionSecrets& secrets, const Volume& volume) const {
  const fs::path dir = sessionDir(id);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
  const std::vector<std::uint8_t> bytes = saveVolume(volume);
  writeFileAtomically(dir / "volume.mzv", bytes.data(), bytes.size());
  const std::string meta = nlohmann::json{{"token", secrets.token}, {"view_token", secrets.viewToken}}.dump();
  writeFileAtomically(dir / "session.json", meta.data(), meta.size());
}

}  // namespace marzipan::service
