// Sessions at rest in the data directory, so that an idle session can be unloaded and loaded
// again on join, and a session saved by one server can be loaded by another that shares the
// directory.
//
// Layout: DATA/sessions/ID/session.json ({"token", "view_token"}) and DATA/sessions/ID/volume.mzv
// (the native file, engine/volume_file.hpp, which keeps the revision). Both are written to a
// temporary name, flushed to disk and renamed, so a crash leaves the old or the new version,
// never a torn one. The directory holds secrets: it is created with mode 0700.
// Errors: std::runtime_error naming the path (I/O), EngineError from the volume loader.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "engine/volume.hpp"

namespace marzipan::service {

struct SessionSecrets {
  std::string token, viewToken;
};

class SessionStore {
 public:
  explicit SessionStore(std::filesystem::path dataDir);

  bool enabled() const { return !dir_.empty(); }
  // Whether a session of this id exists at rest (always false when disabled).
  bool exists(const std::string& id) const;
  std::optional<SessionSecrets> secrets(const std::string& id) const;
  Volume load(const std::string& id) const;
  void save(const std::string& id, const SessionSecrets& secrets, const Volume& volume) const;

 private:
  std::filesystem::path sessionDir(const std::string& id) const;
  std::filesystem::path dir_;
};

// Writes bytes to path through path + ".tmp", fsync and rename.
void writeFileAtomically(const std::filesystem::path& path, const void* data, std::size_t size);

}  // namespace marzipan::service
