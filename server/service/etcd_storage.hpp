// SessionStorage on etcd (service/etcd_store.hpp) plus a shared data directory: the owner, the
// journal and the snapshot pointer live in etcd, fenced by the owner key's create revision;
// the files live on the volume every server mounts.
//
// Layout of DATA/sessions/ID/ (mode 0700: it holds the tokens):
//   session.json                 {"token", "view_token"}, written last by create()
//   snapshot-R-T-S.mzv           the volume at revision R, written by the owner with token T
//                                when its journal's next SEQ was S (never reused: T is unique
//                                per ownership and S per snapshot of one owner); current only
//                                once the pointer in etcd names it
//   step-R-T-S.bin, load-R-T-S.mzv   what an undo/redo or volume.load record names (the
//                                record's SEQ is S): a stale owner's files are never named by
//                                a record that etcd accepted
// Files no pointer or kept record can name (SEQ below the previous snapshot's) are deleted
// after each snapshot, by the pointer as the journal just wrote it (nothing is read back); a
// snapshot whose commit failed deletes its own file (unless the outcome is unknown: then it goes
// with the snapshot after next). The sync interval does not apply: an append returns once etcd
// has it. A change etcd refuses (too large, quota) or cannot take (no member answers) is refused
// with std::runtime_error and rolled back by the hub; one past what a session may hold in etcd
// (EtcdOptions::maxSessionKeys, maxSessionBytes) with StorageLimit; another owner's fence
// throws OwnershipLost. The log asks for a snapshot (wantsSnapshot) once a quarter of either
// bound has passed since the current one.
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>

#include "service/etcd_store.hpp"
#include "service/session_storage.hpp"
#include "service/session_store.hpp"

namespace marzipan::service {

class EtcdStorage final : public SessionStorage {
 public:
  // Grants this server's lease (throws KvUnavailable when etcd cannot be reached). `address`:
  // this server's name (--server-id), stored in the owner keys and told by holder().
  EtcdStorage(KeyValue& kv, std::filesystem::path dataDir, std::string address, EtcdOptions options = {},
              EtcdEvents events = {});
  ~EtcdStorage() override;  // revokes the lease: this server's sessions are free at once

  bool persistent() const override { return true; }
  std::string where() const override;

  bool acquire(const std::string& id) override;
  bool renew(const std::string& id) override;
  // The lease renewed within its TTL (by the steady clock, which runs on while the process is
  // stopped), else renewed now (EtcdOwner::confirmLease: a late lease is kept, an expired one
  // says no), and id claimed on it, its journal not fenced.
  bool holds(const std::string& id) override;
  void release(const std::string& id) override;
  std::chrono::milliseconds renewEvery() const override;
  void onLost(std::function<void(const std::string& id)> handler) override;
  std::optional<std::string> holder(const std::string& id) override;

  bool exists(const std::string& id) const override;
  std::optional<SessionSecrets> secrets(const std::string& id) const override;
  std::unique_ptr<SessionLog> create(const std::string& id, const SessionSecrets& secrets, const Volume& volume) override;
  std::unique_ptr<SessionLog> snapshot(const std::string& id, const Volume& volume,
                                       const std::vector<nlohmann::json>& head = {}) override;
  std::string saveStep(const std::string& id, std::uint64_t revision,
                       const std::vector<std::pair<Int3, BrickRef>>& bricks) override;
  std::string saveUpload(const std::string& id, std::uint64_t revision, std::span<const std::uint8_t> file) override;
  Recovered recover(const std::string& id, std::size_t historyBytes, ThreadPool& pool) override;
  void remove(const std::string& id) override;
  std::vector<std::string> removeUntouched(std::chrono::seconds maxAge,
                                           const std::function<bool(const std::string&)>& live) override;

  EtcdOwner& owner() { return owner_; }

 private:
  std::shared_ptr<EtcdJournal> journal(const std::string& id) const;  // throws OwnershipLost
  std::filesystem::path sessionDir(const std::string& id) const { return dir_ / "sessions" / id; }
  std::string fileName(const char* prefix, std::uint64_t revision, const EtcdJournal& j, const char* ext) const;
  void removeUnreferenced(const std::string& id, const SnapshotRef& current, const std::optional<SnapshotRef>& previous);

  std::filesystem::path dir_;
  SessionStore files_;  // session.json: exists() and secrets()
  EtcdEvents events_;
  EtcdOwner owner_;
  mutable std::mutex mutex_;  // guards the two below
  std::map<std::string, std::shared_ptr<EtcdJournal>> owned_;
  std::function<void(const std::string&)> lost_;
};

}  // namespace marzipan::service
