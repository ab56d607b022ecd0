// static_files: every escape attempt refused, good targets mapped, MIME types by extension.
#include <catch2/catch.hpp>

#include <stdexcept>
#include <string>

#include "net/static_files.hpp"
#include "support.hpp"

using marzipan::net::mimeTypeFor;
using marzipan::net::StaticFiles;
using marzipan::net::StaticStatus;
namespace fs = std::filesystem;

namespace {

// DIR/root/ with files, a subdirectory with its own index, an empty directory, a hidden file,
// symlinks inside and out of the root; DIR/outside/ beside it holds a secret.
// One DIR per test case, so that ctest may run them in parallel.
fs::path makeTree(const std::string& name) {
  const fs::path dir = marzipan::test::scratch(name);
  const fs::path root = dir / "root";
  fs::create_directories(root / "css");
  fs::create_directories(root / "sub");
  fs::create_directories(root / "empty");
  fs::create_directories(dir / "outside");
  marzipan::test::writeText(root / "index.html", "<!DOCTYPE html>");
  marzipan::test::writeText(root / "app.mjs", "export {};");
  marzipan::test::writeText(root / "css" / "site.css", "body{}");
  marzipan::test::writeText(root / "sub" / "index.html", "sub");
  marzipan::test::writeText(root / "a b.txt", "space");
  marzipan::test::writeText(root / ".hidden", "hidden");
  marzipan::test::writeText(dir / "outside" / "secret.txt", "secret");
  fs::create_symlink("../outside", root / "escape");
  fs::create_symlink("../outside/secret.txt", root / "secret-link.txt");
  fs::create_symlink(dir / "outside" / "secret.txt", root / "absolute-link.txt");
  fs::create_symlink("index.html", root / "inner-link.html");
  return root;
}

}  // namespace

TEST_CASE("static files: escape attempts are refused", "[net][static]") {
  const StaticFiles files(makeTree("static-refused"));
  const std::string targets[] = {
      "/../etc/passwd", "/..", "/../", "/css/../index.html", "/%2e%2e/", "/%2E%2E/etc/passwd", "/.%2e/index.html",
      "/%2e/index.html", "/css%2fsite.css", "/%2F", "/%5c..%5cindex.html", "/%5C", "/css\\site.css", "/\\",
      "/index.html%00", std::string("/index.html\0.txt", 16), "/%01", "/a\tb", "//etc/passwd", "/css//site.css",
      "relative.html", "", "http://localhost/index.html", "*", "/.hidden", "/./index.html", "/.",
      "/escape/secret.txt", "/escape/", "/escape", "/secret-link.txt", "/absolute-link.txt", "/%zz", "/%2", "/%",
      "/%g0"};
  for (const std::string& target : targets) {
    INFO("target: " << target);
    CHECK(files.resolve(target).status == StaticStatus::refused);
  }
}

TEST_CASE("static files: good targets map to files under the root", "[net][static]") {
  const fs::path root = makeTree("static-found");
  const StaticFiles files(root);
  const fs::path canonicalRoot = fs::canonical(root);
  struct Case {
    std::string target;
    fs::path file;
    std::string_view type;
  };
  const Case cases[] = {
      {"/", "index.html", "text/html; charset=utf-8"},
      {"/index.html", "index.html", "text/html; charset=utf-8"},
      {"/index.html?v=2#top", "index.html", "text/html; charset=utf-8"},
      {"/?q=../../etc/passwd", "index.html", "text/html; charset=utf-8"},
      {"/app.mjs", "app.mjs", "text/javascript; charset=utf-8"},
      {"/css/site.css", "css/site.css", "text/css; charset=utf-8"},
      {"/sub/", "sub/index.html", "text/html; charset=utf-8"},
      {"/sub", "sub/index.html", "text/html; charset=utf-8"},
      {"/a%20b.txt", "a b.txt", "text/plain; charset=utf-8"},
      {"/%61pp.mjs", "app.mjs", "text/javascript; charset=utf-8"},
      {"/inner-link.html", "index.html", "text/html; charset=utf-8"},
  };
  for (const Case& c : cases) {
    INFO("target: " << c.target);
    const auto resolved = files.resolve(c.target);
    REQUIRE(resolved.status == StaticStatus::found);
    CHECK(resolved.path == canonicalRoot / c.file);
    CHECK(resolved.mimeType == c.type);
  }
}

TEST_CASE("static files: missing files and directories without index are not found", "[net][static]") {
  const StaticFiles files(makeTree("static-missing"));
  for (const std::string target : {"/missing.html", "/css/missing.css", "/missing/dir/", "/empty/", "/empty"}) {
    INFO("target: " << target);
    CHECK(files.resolve(target).status == StaticStatus::notFound);
  }
}

TEST_CASE("static files: the root must be a directory", "[net][static]") {
  const fs::path root = makeTree("static-root");
  CHECK_THROWS_AS(StaticFiles(root / "index.html"), std::runtime_error);
  CHECK_THROWS_AS(StaticFiles(root / "no-such-dir"), std::runtime_error);
}

TEST_CASE("static files: MIME types by extension, case-insensitive", "[net][static]") {
  CHECK(mimeTypeFor("a.html") == "text/html; charset=utf-8");
  CHECK(mimeTypeFor("a.HTM") == "text/html; charset=utf-8");
  CHECK(mimeTypeFor("a.js") == "text/javascript; charset=utf-8");
  CHECK(mimeTypeFor("a.mjs") == "text/javascript; charset=utf-8");
  CHECK(mimeTypeFor("a.css") == "text/css; charset=utf-8");
  CHECK(mimeTypeFor("a.json") == "application/json");
  CHECK(mimeTypeFor("a.js.map") == "application/json");
  CHECK(mimeTypeFor("a.png") == "image/png");
  CHECK(mimeTypeFor("a.JPG") == "image/jpeg");
  CHECK(mimeTypeFor("a.jpeg") == "image/jpeg");
  CHECK(mimeTypeFor("a.svg") == "image/svg+xml");
  CHECK(mimeTypeFor("a.wasm") == "application/wasm");
  CHECK(mimeTypeFor("favicon.ico") == "image/vnd.microsoft.icon");
  CHECK(mimeTypeFor("a.txt") == "text/plain; charset=utf-8");
  CHECK(mimeTypeFor("a.mzv") == "application/octet-stream");
  CHECK(mimeTypeFor("Makefile") == "application/octet-stream");
}
