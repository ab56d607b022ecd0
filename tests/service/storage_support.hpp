// A check every SessionStorage backed by a data directory must pass: the age limit removes a
// session at rest whose every file is older than the limit, and keeps a younger one and a live
// one (loaded on this server).
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <string>

#include "engine/solids.hpp"
#include "service/session_storage.hpp"

namespace marzipan::service::testing {

inline void checkRemovesUntouched(SessionStorage& storage, const std::filesystem::path& dataDir) {
  namespace fs = std::filesystem;
  const Volume volume = makeSphere({16, 16, 16}, {8, 8, 8}, 5);
  for (const std::string id : {"old", "young", "live"}) {
    REQUIRE(storage.acquire(id));
    storage.create(id, {"token-" + id, "view-" + id}, volume);
    storage.release(id);
  }
  const auto longAgo = fs::file_time_type::clock::now() - std::chrono::hours(24 * 10);
  for (const std::string id : {"old", "live"})
    for (const fs::directory_entry& file : fs::directory_iterator(dataDir / "sessions" / id))
      fs::last_write_time(file.path(), longAgo);
  const auto removed = storage.removeUntouched(std::chrono::hours(24 * 7), [](const std::string& id) { return id == "live"; });
  CHECK(removed == std::vector<std::string>{"old"});
  CHECK_FALSE(storage.exists("old"));
  CHECK_FALSE(fs::exists(dataDir / "sessions" / "old"));
  CHECK(storage.exists("young"));
  CHECK(storage.exists("live"));
  CHECK(storage.removeUntouched(std::chrono::hours(24 * 7), [](const std::string&) { return false; }) ==
        std::vector<std::string>{"live"});
  CHECK(storage.exists("young"));
}

}  // namespace marzipan::service::testing
