// The journal file: records read back in order, a torn or corrupt tail dropped and cut off.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

#include "service/journal.hpp"

using marzipan::service::Journal;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {
fs::path freshFile(const std::string& name) {
  const fs::path p = fs::temp_directory_path() / ("marzipan-journal-" + name + ".log");
  fs::remove(p);
  return p;
}
}  // namespace

TEST_CASE("journal records come back in order and survive reopening", "[journal]") {
  const fs::path p = freshFile("order");
  {
    Journal j(p, std::chrono::milliseconds(0));
    j.append({{"r", 1}, {"undo", true}});
    j.append({{"stroke_begin", 3}, {"tool", "add_blob"}});
    CHECK(j.records() == 2);
  }
  Journal again(p, std::chrono::milliseconds(0));
  CHECK(again.records() == 2);
  again.append({{"r", 2}, {"redo", true}});
  const auto records = Journal::read(p, false, {});
  REQUIRE(records.size() == 3);
  CHECK(records[0]["undo"] == true);
  CHECK(records[1]["stroke_begin"] == 3);
  CHECK(records[2]["r"] == 2);
}

TEST_CASE("a torn last record is dropped and cut from the file", "[journal]") {
  const fs::path p = freshFile("torn");
  {
    Journal j(p, std::chrono::milliseconds(0));
    j.append({{"r", 1}, {"undo", true}});
    j.append({{"r", 2}, {"redo", true}});
  }
  const auto whole = fs::file_size(p);
  {
    std::ofstream f(p, std::ios::app | std::ios::binary);
    f << marzipan::service::journalLine({{"r", 3}, {"undo", true}}).substr(0, 20);
  }
  std::vector<std::string> warnings;
  const auto records = Journal::read(p, true, [&](const std::string& w) { warnings.push_back(w); });
  CHECK(records.size() == 2);
  CHECK(warnings.size() == 1);
  CHECK(fs::file_size(p) == whole);
}

TEST_CASE("a record whose CRC does not match ends the journal", "[journal]") {
  const fs::path p = freshFile("crc");
  {
    Journal j(p, std::chrono::milliseconds(0));
    j.append({{"r", 1}, {"undo", true}});
    j.append({{"r", 2}, {"redo", true}});
    j.append({{"r", 3}, {"undo", true}});
  }
  std::string text;
  {
    std::ifstream f(p, std::ios::binary);
    text.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  const std::size_t second = text.find('\n') + 1;
  text[second + 15] = text[second + 15] == '1' ? '2' : '1';  // a flipped digit inside record 2
  {
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f << text;
  }
  const auto records = Journal::read(p, false, {});
  CHECK(records.size() == 1);
}
