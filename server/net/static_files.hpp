// Static files of the web root: maps an HTTP request target to a file under the root, or
// refuses it. Beast-free and pure apart from reading the file system, so tests call it directly.
//
// Conventions: a target is the raw request-target of a request line ("/js/app.mjs?v=2"); its
// query and fragment are ignored. Refused without touching the file system: a target that does
// not start with '/'; NUL, control bytes or backslashes, raw or percent-encoded; percent-encoded
// '.', '/' (%2e %2f %5c %00, any case); malformed escapes; empty segments ("//"); and any segment
// that starts with '.' (so "..", "." and hidden files such as ".git"). Other escapes are decoded
// ("%20" is a space). What passes is looked up under the canonical root; a path whose canonical
// form (symlinks followed) lies outside the canonical root is refused too. A directory, "/"
// included, maps to its index.html.
#pragma once

#include <filesystem>
#include <string_view>

namespace marzipan::net {

enum class StaticStatus { found, notFound, refused };

struct StaticFile {
  StaticStatus status = StaticStatus::refused;
  std::filesystem::path path;  // canonical path of the regular file, when found
  std::string_view mimeType;   // its Content-Type, when found
};

class StaticFiles {
 public:
  // @param[in] root the web root; throws std::runtime_error when it is not a directory.
  explicit StaticFiles(const std::filesystem::path& root);

  const std::filesystem::path& root() const { return root_; }  // canonical
  StaticFile resolve(std::string_view target) const;

 private:
  std::filesystem::path root_;
};

// Content-Type by extension (case-insensitive); application/octet-stream when unknown.
std::string_view mimeTypeFor(const std::filesystem::path& file);

}  // namespace marzipan::net
