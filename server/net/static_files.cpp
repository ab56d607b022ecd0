// Target → file mapping of the web root; the refusal rules are stated in static_files.hpp.
#include "net/static_files.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>

namespace fs = std::filesystem;

namespace marzipan::net {

namespace {

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool forbiddenByte(unsigned char c) { return c < 0x20 || c == 0x7f || c == '\\'; }

// The target's path with escapes decoded, or nothing when a rule of static_files.hpp refuses it.
std::optional<std::string> decodePath(std::string_view target) {
  target = target.substr(0, target.find_first_of("?#"));
  if (target.empty() || target.front() != '/') return std::nullopt;
  std::string decoded;
  decoded.reserve(target.size());
  for (std::size_t i = 0; i < target.size(); ++i) {
    const char c = target[i];
    if (c != '%') {
      if (forbiddenByte(static_cast<unsigned char>(c))) return std::nullopt;
      decoded.push_back(c);
      continue;
    }
    if (i + 2 >= target.size()) return std::nullopt;
    const int hi = hexValue(target[i + 1]), lo = hexValue(target[i + 2]);
    if (hi < 0 || lo < 0) return std::nullopt;
    const auto byte = static_cast<unsigned char>(hi * 16 + lo);
    if (forbiddenByte(byte) || byte == '.' || byte == '/') return std::nullopt;
    decoded.push_back(static_cast<char>(byte));
    i += 2;
  }
  return decoded;
}

// True when `path` equals `root` or lies below it; both canonical.
bool inside(const fs::path& root, const fs::path& path) {
  auto r = root.begin();
  auto p = path.begin();
  for (; r != root.end(); ++r, ++p) {
    if (p == path.end() || *r != *p) return false;
  }
  return true;
}

}  // namespace

StaticFiles::StaticFiles(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw std::runtime_error("web root " + root.string() + " is not a directory");
  root_ = fs::canonical(root);
}

StaticFile StaticFiles::resolve(std::string_view target) const {
  const std::optional<std::string> decoded = decodePath(target);
  if (!decoded) return {};
  fs::path relative;
  std::string_view rest = std::string_view(*decoded).substr(1);
  while (!rest.empty()) {
    const std::size_t slash = rest.find('/');
    const std::string_view segment = rest.substr(0, slash);
    if (segment.empty() || segment.front() == '.') return {};
    relative /= fs::path(std::string(segment));
    if (slash == std::string_view::npos) break;
    rest.remove_prefix(slash + 1);
  }

  std::error_code ec;
  fs::path candidate = root_ / relative;
  if (fs::is_directory(candidate, ec)) candidate /= "index.html";
  const fs::path canonical = fs::weakly_canonical(candidate, ec);
  if (ec) return {StaticStatus::notFound, {}, {}};
  if (!inside(root_, canonical)) return {};
  if (!fs::is_regular_file(canonical, ec)) return {StaticStatus::notFound, {}, {}};
  return {StaticStatus::found, canonical, mimeTypeFor(canonical)};
}

std::string_view mimeTypeFor(const fs::path& file) {
  static constexpr std::array<std::pair<std::string_view, std::string_view>, 14> kTypes{{
      {".html", "text/html; charset=utf-8"},
      {".htm", "text/html; charset=utf-8"},
      {".js", "text/javascript; charset=utf-8"},
      {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},
      {".json", "application/json"},
      {".map", "application/json"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".jpeg", "image/jpeg"},
      {".svg", "image/svg+xml"},
      {".wasm", "application/wasm"},
      {".ico", "image/vnd.microsoft.icon"},
      {".txt", "text/plain; charset=utf-8"},
  }};
  std::string extension = file.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const auto& [ext, type] : kTypes) {
    if (ext == extension) return type;
  }
  return "application/octet-stream";
}

}  // namespace marzipan::net
