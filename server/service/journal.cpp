// Journal (see journal.hpp).
#include "service/journal.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "engine/volume_file.hpp"

namespace marzipan::service {

namespace {

std::string crcHex(std::string_view text) {
  const std::uint32_t crc =
      crc32Ieee({reinterpret_cast<const std::uint8_t*>(text.data()), text.size()});
  char hex[9];
  std::snprintf(hex, sizeof hex, "%08x", crc);
  return hex;
}

}  // namespace

void writeAll(int fd, std::string_view bytes, const std::filesystem::path& path) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : ENOSPC;  // a write of 0 bytes: the device took nothing
      throw std::runtime_error("cannot write " + path.string() + ": " + std::strerror(e));
    }
    done += std::size_t(n);
  }
}

std::string journalLine(const nlohmann::json& record) {
  const std::string text = record.dump();
  return crcHex(text) + " " + text + "\n";
}

Journal::Journal(std::filesystem::path path, std::chrono::milliseconds syncInterval)
    : path_(std::move(path)), syncInterval_(syncInterval), lastSync_(std::chrono::steady_clock::now()) {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
  if (fd_ < 0) throw std::runtime_error("cannot open journal " + path_.string() + ": " + std::strerror(errno));
  records_ = read(path_, false, {}).size();
}

Journal::~Journal() {
  if (fd_ < 0) return;
  if (dirty_) ::fsync(fd_);
  ::close(fd_);
}

void Journal::append(const nlohmann::json& record) {
  const std::string line = journalLine(record);
  // A record that fails to be written or synced must not stay: the change it describes is
  // refused, and a later read must not find it.
  const off_t before = ::lseek(fd_, 0, SEEK_END);
  struct Undo {
    int fd;
    off_t at;
    bool armed = true;
    ~Undo() {
      if (armed && at >= 0 && ::ftruncate(fd, at) == 0) ::fsync(fd);
    }
  } undo{fd_, before};
  writeAll(fd_, line, path_);
  dirty_ = true;
  if (syncInterval_.count() == 0 || std::chrono::steady_clock::now() - lastSync_ >= syncInterval_) sync();
  undo.armed = false;
  ++records_;
}

void Journal::sync() {
  if (!dirty_) return;
  if (::fsync(fd_) != 0) throw std::runtime_error("cannot sync journal " + path_.string() + ": " + std::strerror(errno));
  dirty_ = false;
  lastSync_ = std::chrono::steady_clock::now();
}

std::vector<nlohmann::json> Journal::read(const std::filesystem::path& path, bool truncate,
                                          const std::function<void(const std::string&)>& warn) {
  std::vector<nlohmann::json> out;
  std::ifstream in(path, std::ios::binary);
  if (!in) return out;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::size_t at = 0;
  while (at < text.size()) {
    const std::size_t eol = text.find('\n', at);
    bool ok = eol != std::string::npos && eol - at > 9 && text[at + 8] == ' ';
    nlohmann::json record;
    if (ok) {
      const std::string_view body(text.data() + at + 9, eol - at - 9);
      ok = crcHex(body) == std::string_view(text.data() + at, 8);
      if (ok) {
        record = nlohmann::json::parse(body, nullptr, false);
        ok = record.is_object();
      }
    }
    if (!ok) {
      if (warn)
        warn("journal " + path.string() + ": dropping " + std::to_string(text.size() - at) + " bytes after record " +
             std::to_string(out.size()) + (eol == std::string::npos ? " (a torn last record)" : " (a corrupt record)"));
      if (truncate) std::filesystem::resize_file(path, at);
      break;
    }
    out.push_back(std::move(record));
    at = eol + 1;
  }
  return out;
}

}  // namespace marzipan::service
