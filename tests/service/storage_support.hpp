// Helpers of the tests that keep sessions in a data directory: a directory of a test's own, the
// session as a copy of a data directory recovers it, and the check every SessionStorage backed by
// a data directory must pass (the age limit).
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include <unistd.h>

#include "engine/solids.hpp"
#include "engine/thread_pool.hpp"
#include "service/session_storage.hpp"
#include "service/session_store.hpp"

namespace marzipan::service::testing {

// An empty directory for one test: <temp>/marzipan-<pid>-<name>. ctest runs each test case as a
// process of its own, two at a time, so the process id keeps two cases that use the same name
// out of each other's files.
inline std::filesystem::path freshDir(const std::string& name) {
  const std::filesystem::path d =
      std::filesystem::temp_directory_path() / ("marzipan-" + std::to_string(::getpid()) + "-" + name);
  std::filesystem::remove_all(d);
  return d;
}

// The session `id` as the data directory `dir` alone recovers it, read from a copy (a hub may
// still be writing dir) that is removed again. Memory limit 64 MiB, one thread.
inline std::unique_ptr<Session> recoverCopy(const std::filesystem::path& dir, const std::string& id) {
  const std::filesystem::path copy = freshDir(dir.filename().string() + "-copy");
  std::filesystem::copy(dir, copy, std::filesystem::copy_options::recursive);
  Recovered r = SessionStore(copy).recover(id, std::size_t(64) << 20, ThreadPool::serial());
  std::filesystem::remove_all(copy);
  return std::move(r.session);
}

// The age limit removes a session at rest whose every file is older than the limit, and keeps a
// younger one and a live one (loaded on this server).
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
