#include "service/etcd_store.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <set>

namespace marzipan::service {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::int64_t kRangePage = 512;
// A write whose outcome is unknown (no member answered) is retried this often while the lease
// lasts: the retry is idempotent (only-if-absent, and an existing key holding our value is ours).
constexpr std::chrono::milliseconds kRetryPause{100};

std::string hex16(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

// Base64 and the JSON around one key or value in a gateway request.
std::size_t wireBytes(std::size_t raw) { return (raw + 2) / 3 * 4 + 48; }

KvCompare ownedBy(const std::string& ownerKey, std::int64_t token) {
  return KvCompare{ownerKey, KvCompare::Target::createRevision, KvCompare::Result::equal, token, {}};
}
KvCompare absent(const std::string& key) {
  return KvCompare{key, KvCompare::Target::createRevision, KvCompare::Result::equal, 0, {}};
}

std::optional<SnapshotRef> parseRef(const json& j) {
  if (!j.is_object()) return std::nullopt;
  SnapshotRef r;
  r.file = j.at("file").get<std::string>();
  r.revision = j.at("revision").get<std::uint64_t>();
  r.next = j.at("next").get<std::uint64_t>();
  r.headFrom = j.value("head_from", r.next);
  if (r.headFrom > r.next) throw std::runtime_error("snapshot pointer: head_from after next");
  // A pointer written before 2026-11-29 holds its head itself.
  for (const json& rec : j.value("head", json::array())) r.head.push_back(rec);
  return r;
}
json refJson(const SnapshotRef& r) {
  json j{{"file", r.file}, {"revision", r.revision}, {"head_from", r.headFrom}, {"next", r.next}};
  if (!r.head.empty()) j["head"] = r.head;  // only a pointer written before 2026-11-29 had one
  return j;
}

// The journal value of one part of a snapshot's head, built from its records' JSON texts.
std::string headValue(const std::vector<std::string>& records, std::int64_t token) {
  std::string v = "{\"head\":[";
  for (std::size_t k = 0; k < records.size(); ++k) {
    if (k) v += ',';
    v += records[k];
  }
  return v + "],\"token\":" + std::to_string(token) + "}";
}

}  // namespace

std::string prefixEnd(std::string prefix) {
  while (!prefix.empty()) {
    if (static_cast<unsigned char>(prefix.back()) < 0xff) {
      prefix.back() = static_cast<char>(static_cast<unsigned char>(prefix.back()) + 1);
      return prefix;
    }
    prefix.pop_back();
  }
  return std::string(1, '\0');  // etcd: every key
}

struct EtcdOwner::Pending {
  EtcdJournal* journal;
  std::uint64_t seq;
  std::string value;
  bool done = false;
  std::exception_ptr error;
};

// ---- EtcdOwner --------------------------------------------------------------------------------

EtcdOwner::EtcdOwner(KeyValue& kv, std::string address, EtcdOptions options, EtcdEvents events)
    : kv_(kv), address_(std::move(address)), options_(std::move(options)), events_(std::move(events)) {}

EtcdOwner::~EtcdOwner() { stop(); }

std::string EtcdOwner::ownerKey(const std::string& id) const { return options_.prefix + "sessions/" + id + "/owner"; }
std::string EtcdOwner::journalKey(const std::string& id, std::uint64_t seq) const {
  return options_.prefix + "sessions/" + id + "/journal/" + hex16(seq);
}
std::string EtcdOwner::pointerKey(const std::string& id) const { return options_.prefix + "sessions/" + id + "/snapshot"; }

void EtcdOwner::start(std::function<void()> lost) {
  const auto sent = Clock::now();
  const std::int64_t lease = kv_.leaseGrant(options_.leaseTtlSeconds);
  const std::lock_guard lock(mutex_);
  lease_ = lease;
  held_ = true;
  stopping_ = false;
  lastRenewed_ = sent;
  lost_ = std::move(lost);
  keeper_ = std::thread([this] { keepAlive(); });
}

void EtcdOwner::stop() {
  std::int64_t lease = 0;
  {
    const std::lock_guard lock(mutex_);
    if (stopping_ || !keeper_.joinable()) return;
    stopping_ = true;
    if (held_) lease = lease_;
    held_ = false;
  }
  wake_.notify_all();
  renewed_.notify_all();
  keeper_.join();
  if (lease == 0) return;
  try {
    kv_.leaseRevoke(lease);
  } catch (const std::exception& e) {
    // The lease then expires by itself within its TTL.
    if (events_.log) events_.log(std::string("etcd: revoking the lease failed (it expires by itself): ") + e.what());
  }
}

bool EtcdOwner::liveLease() const {
  return held_ && Clock::now() - lastRenewed_ < std::chrono::seconds(options_.leaseTtlSeconds);
}

bool EtcdOwner::leaseHeld() const {
  const std::lock_guard lock(mutex_);
  return liveLease();
}

bool EtcdOwner::leaseKept() const {
  const std::lock_guard lock(mutex_);
  return held_;
}

bool EtcdOwner::confirmLease() {
  std::unique_lock lock(mutex_);
  if (liveLease()) return true;
  if (!held_) return false;
  renewNow_ = true;
  wake_.notify_all();
  renewed_.wait_for(lock, kLeaseWait, [this] { return stopping_ || !held_ || liveLease(); });
  return !stopping_ && liveLease();
}

void EtcdOwner::keepAlive() {
  const auto ttl = std::chrono::seconds(options_.leaseTtlSeconds);
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, held_ ? ttl / 3 : kRetryPause * 5, [this] { return stopping_ || renewNow_; });
    if (stopping_) break;
    renewNow_ = false;
    const bool held = held_;
    const std::int64_t lease = lease_;
    lock.unlock();
    const auto sent = Clock::now();
    std::string lostWhy;
    std::int64_t granted = 0;
    try {
      if (held) {
        if (kv_.leaseKeepAlive(lease) <= 0) lostWhy = "the lease expired";
      } else {
        granted = kv_.leaseGrant(options_.leaseTtlSeconds);
      }
    } catch (const std::exception& e) {
      lostWhy = e.what();
    }
    lock.lock();
    if (stopping_) {
      if (granted != 0) {
        lock.unlock();
        try {
          kv_.leaseRevoke(granted);
        } catch (const std::exception&) {
        }
        lock.lock();
      }
      break;
    }
    if (granted != 0) {
      lease_ = granted;
      held_ = true;
      lastRenewed_ = sent;
      renewed_.notify_all();
      continue;
    }
    if (!held) continue;
    if (lostWhy.empty()) {
      lastRenewed_ = sent;
      renewed_.notify_all();
    } else if (lostWhy == "the lease expired" || Clock::now() - lastRenewed_ >= ttl) {
      held_ = false;
      renewed_.notify_all();  // confirmLease(): gone
      const auto lost = lost_;
      lock.unlock();
      loseLease(lostWhy);
      if (lost) lost();
      lock.lock();
      // A server that was stopped or cut off serves again as soon as etcd grants a new lease.
      renewNow_ = true;
    }
  }
}

void EtcdOwner::loseLease(const std::string& why) {
  if (events_.log) events_.log("etcd: this server's lease is lost (" + why + "); its sessions close");
}

void EtcdOwner::fenced(const std::string& id) {
  if (events_.fencedRejection) events_.fencedRejection(id);
}

EtcdOwner::Claim EtcdOwner::claim(const std::string& id) {
  std::int64_t lease = 0;
  {
    std::unique_lock lock(mutex_);
    if (!liveLease()) {
      renewNow_ = true;
      wake_.notify_all();
      renewed_.wait_for(lock, kLeaseWait, [this] { return stopping_ || liveLease(); });
    }
    if (stopping_ || !liveLease()) throw KvUnavailable("this server holds no live etcd lease");
    lease = lease_;
  }
  const std::string key = ownerKey(id);
  Claim out;
  for (int attempt = 0; attempt < 3; ++attempt) {
    const KvTxnResult r = kv_.txn({absent(key)}, {KvOp{KvOp::Kind::put, key, {}, address_, lease}},
                                  {KvOp{KvOp::Kind::range, key, {}, {}, 0}});
    if (r.succeeded) {
      // The put's revision is the key's createRevision: the token.
      try {
        out.state = read(id);
        for (const JournalEntry& e : out.state.journal)
          if (e.token > r.revision) throw std::runtime_error("session " + id + ": journal token above the new owner's");
      } catch (...) {
        // Not taken after all: left in place, the key named this server as the owner to its
        // own later claims until the lease ended. Deleted only if still this claim's.
        try {
          kv_.txn({ownedBy(key, r.revision)}, {KvOp{KvOp::Kind::deleteRange, key, {}, {}, 0}}, {});
        } catch (const std::exception& e) {
          if (events_.log)
            events_.log("session " + id + ": deleting the owner key of a failed claim failed (" + e.what() +
                        "); it goes with the lease");
        }
        throw;
      }
      out.journal.reset(new EtcdJournal(*this, id, r.revision, out.state));
      if (events_.ownershipChanged) events_.ownershipChanged(id, true);
      return out;
    }
    if (!r.ranges.empty() && !r.ranges[0].empty()) {
      out.owner = r.ranges[0][0].value;
      return out;
    }
    // Deleted between the compare and the range (a lease expired): try again.
  }
  throw KvUnavailable("session " + id + ": its owner key keeps changing");
}

std::optional<std::string> EtcdOwner::ownerOf(const std::string& id) {
  const auto found = kv_.range(ownerKey(id));
  if (found.empty()) return std::nullopt;
  return found.front().value;
}

EtcdSessionState EtcdOwner::read(const std::string& id) {
  EtcdSessionState st;
  if (const auto p = kv_.range(pointerKey(id)); !p.empty()) {
    const json j = json::parse(p.front().value);
    st.current = parseRef(j.at("current"));
    st.previous = parseRef(j.value("previous", json()));
    st.pointerBytes = p.front().key.size() + p.front().value.size();
  }
  struct Key {
    std::uint64_t seq;
    std::size_t bytes;
    json value;
  };
  std::vector<Key> keys;
  const std::string first = journalKey(id, 0);
  const std::string end = prefixEnd(options_.prefix + "sessions/" + id + "/journal/");
  std::string from = first;
  const std::size_t seqAt = first.size() - 16;
  for (;;) {
    const auto page = kv_.range(from, end, kRangePage);
    for (const KvEntry& e : page)
      keys.push_back({std::stoull(e.key.substr(seqAt), nullptr, 16), e.key.size() + e.value.size(), json::parse(e.value)});
    if (page.size() < static_cast<std::size_t>(kRangePage)) break;
    from = page.back().key + '\0';
  }
  // Keys before the oldest kept snapshot's head are deleted with the pointer's move; a gap would
  // be a change whose append never succeeded: nothing after it was acknowledged on top of it.
  const std::uint64_t start = st.previous ? st.previous->headFrom : st.current ? st.current->headFrom : 0;
  std::erase_if(keys, [start](const Key& k) { return k.seq < start; });
  for (std::size_t k = 0; k < keys.size(); ++k) {
    if (keys[k].seq != start + k) {
      if (events_.log) events_.log("session " + id + ": journal gap at " + hex16(start + k) + "; stopping there");
      keys.resize(k);
      break;
    }
  }
  st.next = !keys.empty() ? keys.back().seq + 1 : st.current ? st.current->next : 0;
  const auto headOf = [](std::optional<SnapshotRef>& ref, std::uint64_t seq) {
    return ref && seq >= ref->headFrom && seq < ref->next ? &ref->head : nullptr;
  };
  for (Key& k : keys) {
    st.keys[k.seq] = k.bytes;
    if (const auto head = k.value.find("head"); head != k.value.end()) {
      // A head no pointer names (its commit failed) is skipped: it announces again strokes that
      // the replay has open already.
      std::vector<json>* into = headOf(st.current, k.seq);
      if (!into) into = headOf(st.previous, k.seq);
      if (into)
        for (const json& rec : *head) into->push_back(rec);
      continue;
    }
    JournalEntry entry;
    entry.seq = k.seq;
    entry.token = k.value.at("token").get<std::int64_t>();
    for (const json& rec : k.value.at("records")) entry.records.push_back(rec);
    st.journal.push_back(std::move(entry));
  }
  return st;
}

void EtcdOwner::submit(EtcdJournal& j, std::uint64_t seq, std::string value) {
  auto p = std::make_shared<Pending>(Pending{&j, seq, std::move(value), false, nullptr});
  std::unique_lock lock(mutex_);
  queue_.push_back(p);
  if (committing_) {
    wake_.wait(lock, [&] { return p->done; });
  } else {
    committing_ = true;
    while (!queue_.empty()) {
      // One group: within etcd's operation and request limits.
      std::vector<std::shared_ptr<Pending>> group;
      std::set<std::string> sessions;
      std::size_t bytes = 256, compares = 0;
      while (!queue_.empty()) {
        const Pending& next = *queue_.front();
        const std::size_t more = wireBytes(next.value.size()) + 2 * wireBytes(64);
        const std::size_t moreCompares = 1 + (sessions.count(next.journal->id()) ? 0 : 1);
        if (!group.empty() && (bytes + more > options_.maxRequestBytes * 9 / 10 ||
                               compares + moreCompares > options_.maxTxnOps || group.size() + 1 > options_.maxTxnOps))
          break;
        bytes += more;
        compares += moreCompares;
        sessions.insert(next.journal->id());
        group.push_back(queue_.front());
        queue_.pop_front();
      }
      lock.unlock();
      runGroup(group);
      lock.lock();
      for (const auto& g : group) g->done = true;
      wake_.notify_all();
    }
    committing_ = false;
  }
  if (p->error) std::rethrow_exception(p->error);
}

void EtcdOwner::runGroup(std::vector<std::shared_ptr<Pending>> group) {
  const auto t0 = Clock::now();
  // Refused here only once the lease is known lost. One not renewed within its TTL may only be
  // late (an etcd election, or a loaded machine, holding the keep-alive up while etcd keeps the
  // lease): refusing then closed sessions whose lease was alive (a failover test run under load,
  // 2026-11-29). The transaction's compare of the owner key's create revision is the fence,
  // and etcd decides it whatever this server's clock says.
  if (!leaseKept()) {
    for (const auto& p : group) {
      fenced(p->journal->id());
      p->error = std::make_exception_ptr(Fenced("session " + p->journal->id() + ": this server's etcd lease is lost"));
    }
    return;
  }
  if (group.size() > 1) {
    std::vector<KvCompare> compares;
    std::vector<KvOp> puts;
    std::set<std::string> fencedOnce;
    for (const auto& p : group) {
      const std::string& id = p->journal->id();
      if (fencedOnce.insert(id).second) compares.push_back(ownedBy(ownerKey(id), p->journal->token()));
      compares.push_back(absent(journalKey(id, p->seq)));
      puts.push_back(KvOp{KvOp::Kind::put, journalKey(id, p->seq), {}, p->value, 0});
    }
    try {
      if (kv_.txn(compares, puts, {}).succeeded) {
        if (events_.appended) events_.appended(std::chrono::duration<double>(Clock::now() - t0).count(), group.size());
        return;
      }
    } catch (const KvUnavailable&) {
      // Each one again, alone: the retries below find out which (if any) went through.
    } catch (const KvRefused&) {
      // Alone, each fits (the sizes were checked): whichever does not is refused alone.
    }
  }
  // One by one: which compare failed says whether it was fenced, and a retry after an unknown
  // outcome recognises its own record.
  // Retried for half the lease's TTL at most: long enough for an etcd election (about a second),
  // short enough that the keep-alive, which gives up after a whole TTL, still holds the lease.
  const auto deadline = Clock::now() + std::chrono::milliseconds(options_.leaseTtlSeconds * 500);
  for (const auto& p : group) {
    const std::string& id = p->journal->id();
    const std::string oKey = ownerKey(id), jKey = journalKey(id, p->seq);
    for (;;) {
      try {
        const KvTxnResult r = kv_.txn({ownedBy(oKey, p->journal->token()), absent(jKey)},
                                      {KvOp{KvOp::Kind::put, jKey, {}, p->value, 0}},
                                      {KvOp{KvOp::Kind::range, oKey, {}, {}, 0}, KvOp{KvOp::Kind::range, jKey, {}, {}, 0}});
        if (r.succeeded || (r.ranges.size() == 2 && !r.ranges[1].empty() && r.ranges[1][0].value == p->value)) {
          if (events_.appended) events_.appended(std::chrono::duration<double>(Clock::now() - t0).count(), 1);
          break;
        }
        fenced(id);
        const bool owned = r.ranges.size() == 2 && !r.ranges[0].empty() && r.ranges[0][0].createRevision == p->journal->token();
        p->error = std::make_exception_ptr(
            Fenced(owned ? "session " + id + ": journal SEQ " + hex16(p->seq) + " is taken"
                         : "session " + id + ": another server owns it now (token " + std::to_string(p->journal->token()) + " is stale)"));
        break;
      } catch (const KvUnavailable&) {
        if (Clock::now() >= deadline || !leaseKept()) {
          p->error = std::current_exception();
          break;
        }
        std::this_thread::sleep_for(kRetryPause);
      } catch (...) {
        p->error = std::current_exception();
        break;
      }
    }
  }
}

// ---- EtcdJournal ------------------------------------------------------------------------------

EtcdJournal::EtcdJournal(EtcdOwner& owner, std::string id, std::int64_t token, EtcdSessionState state)
    : owner_(owner),
      id_(std::move(id)),
      token_(token),
      ownerBytes_(owner.ownerKey(id_).size() + owner.address().size()) {
  resume(state);
}

std::uint64_t EtcdJournal::nextSeq() const {
  const std::lock_guard lock(mutex_);
  return next_;
}

std::pair<std::optional<SnapshotRef>, std::optional<SnapshotRef>> EtcdJournal::snapshots() const {
  const std::lock_guard lock(mutex_);
  return {current_, previous_};
}

bool EtcdJournal::fenced() const {
  const std::lock_guard lock(mutex_);
  return state_ == State::fenced;
}

std::pair<std::size_t, std::size_t> EtcdJournal::held() const {
  const std::lock_guard lock(mutex_);
  return heldLocked();
}

std::pair<std::size_t, std::size_t> EtcdJournal::heldLocked() const {
  return {keys_.size() + (pointerBytes_ ? 2 : 1), keyBytes_ + pointerBytes_ + ownerBytes_};
}

bool EtcdJournal::wantsSnapshot() const {
  const std::lock_guard lock(mutex_);
  std::size_t keys = 0, bytes = 0;
  for (auto it = keys_.lower_bound(current_ ? current_->next : 0); it != keys_.end(); ++it) {
    ++keys;
    bytes += it->second;
  }
  const EtcdOptions& o = owner_.options_;
  return keys >= o.maxSessionKeys / 4 || bytes >= o.maxSessionBytes / 4;
}

void EtcdJournal::checkBounds(std::size_t keys, std::size_t bytes) const {
  const EtcdOptions& o = owner_.options_;
  const auto refuse = [&](const char* limit, const char* what, std::size_t value, std::size_t max) {
    throw SessionFull("session " + id_ + " would hold " + std::to_string(value) + " " + what + " in etcd, over " + limit +
                          " " + std::to_string(max),
                      limit, value, max);
  };
  if (keys > o.maxSessionKeys) refuse("max_session_etcd_keys", "keys", keys, o.maxSessionKeys);
  if (bytes > o.maxSessionBytes) refuse("max_session_etcd_bytes", "bytes", bytes, o.maxSessionBytes);
}

void EtcdJournal::append(const std::vector<json>& records) {
  std::string value = json{{"token", token_}, {"records", records}}.dump();
  if (value.size() > owner_.options_.maxChangeBytes)
    throw KvRefused("a change of " + std::to_string(value.size()) + " bytes is beyond the " +
                    std::to_string(owner_.options_.maxChangeBytes) + " one etcd request may hold");
  const std::lock_guard lock(mutex_);
  refuseIfBroken();
  const std::size_t bytes = owner_.journalKey(id_, next_).size() + value.size();
  const auto [keys, heldBytes] = heldLocked();
  checkBounds(keys + 1, heldBytes + bytes);
  submitLocked(std::move(value), bytes);
}

void EtcdJournal::submitLocked(std::string value, std::size_t bytes) {
  try {
    owner_.submit(*this, next_, std::move(value));
  } catch (const KvUnavailable&) {
    state_ = State::unknown;
    throw;
  } catch (const Fenced&) {
    state_ = State::fenced;
    throw;
  }
  keys_[next_] = bytes;
  keyBytes_ += bytes;
  ++next_;
}

void EtcdJournal::refuseIfBroken() const {
  if (state_ == State::unknown) throw KvUnavailable("session " + id_ + ": an earlier append's outcome is unknown");
  if (state_ == State::fenced) throw Fenced("session " + id_ + ": another server owns it now");
}

void EtcdJournal::resume(const EtcdSessionState& state) {
  const std::lock_guard lock(mutex_);
  if (state_ == State::fenced) return;
  state_ = State::open;
  // A head in journal keys is not kept here; one held by an older pointer itself is, so that the
  // next pointer names it as its previous again.
  const auto withoutHead = [](std::optional<SnapshotRef> ref) {
    if (ref && ref->headFrom < ref->next) ref->head.clear();
    return ref;
  };
  current_ = withoutHead(state.current);
  previous_ = withoutHead(state.previous);
  next_ = state.next;
  keys_ = state.keys;
  keyBytes_ = 0;
  for (const auto& [seq, bytes] : keys_) keyBytes_ += bytes;
  pointerBytes_ = state.pointerBytes;
}

void EtcdJournal::commitSnapshot(const std::string& file, std::uint64_t revision, const std::vector<json>& head) {
  const EtcdOptions& o = owner_.options_;
  const std::lock_guard lock(mutex_);
  refuseIfBroken();
  // The head as few journal values as fit one change's bytes each.
  std::vector<std::string> values, part;
  std::size_t partBytes = 0;
  const std::size_t envelope = headValue({}, token_).size();
  for (const json& rec : head) {
    std::string text = rec.dump();
    if (envelope + text.size() > o.maxChangeBytes)
      throw KvRefused("session " + id_ + ": an open stroke's record of " + std::to_string(text.size()) +
                      " bytes is beyond the " + std::to_string(o.maxChangeBytes) + " one etcd request may hold");
    if (!part.empty() && envelope + partBytes + 1 + text.size() > o.maxChangeBytes) {
      values.push_back(headValue(part, token_));
      part.clear();
      partBytes = 0;
    }
    partBytes += text.size() + (part.empty() ? 0 : 1);
    part.push_back(std::move(text));
  }
  if (!part.empty()) values.push_back(headValue(part, token_));

  SnapshotRef now{file, revision, next_, next_ + values.size(), {}};
  json pointer{{"current", refJson(now)}};
  if (current_) pointer["previous"] = refJson(*current_);
  const std::string value = pointer.dump();
  const std::string pointerKey = owner_.pointerKey(id_);
  // What the session holds once the pointer has moved: the keys before the new previous's head
  // go. A snapshot without a head never holds more than before: it always goes.
  const std::uint64_t dropBelow = current_ ? current_->headFrom : 0;
  std::size_t keys = keys_.size() + values.size() + 2, bytes = keyBytes_ + ownerBytes_ + pointerKey.size() + value.size();
  for (auto it = keys_.begin(); it != keys_.end() && it->first < dropBelow; ++it) {
    --keys;
    bytes -= it->second;
  }
  for (std::size_t k = 0; k < values.size(); ++k) bytes += owner_.journalKey(id_, next_ + k).size() + values[k].size();
  if (!values.empty()) checkBounds(keys, bytes);

  for (std::string& v : values) {
    const std::size_t vBytes = owner_.journalKey(id_, next_).size() + v.size();
    submitLocked(std::move(v), vBytes);
  }
  std::vector<KvOp> ops{KvOp{KvOp::Kind::put, pointerKey, {}, value, 0}};
  // The journal before the snapshot that now becomes the previous one is covered twice over.
  if (dropBelow > 0) ops.push_back(KvOp{KvOp::Kind::deleteRange, owner_.journalKey(id_, 0), owner_.journalKey(id_, dropBelow), {}, 0});
  KvTxnResult r;
  try {
    r = owner_.kv_.txn({ownedBy(owner_.ownerKey(id_), token_)}, ops, {});
  } catch (const KvUnavailable&) {
    state_ = State::unknown;  // the pointer may have moved: read it back before going on
    throw;
  }
  if (!r.succeeded) {
    owner_.fenced(id_);
    state_ = State::fenced;
    throw Fenced("session " + id_ + ": another server owns it now; snapshot " + file + " is not current");
  }
  for (auto it = keys_.begin(); it != keys_.end() && it->first < dropBelow; it = keys_.erase(it)) keyBytes_ -= it->second;
  pointerBytes_ = pointerKey.size() + value.size();
  previous_ = current_;
  current_ = now;
}

void EtcdJournal::erase() {
  const std::lock_guard lock(mutex_);
  const std::string all = owner_.options_.prefix + "sessions/" + id_ + "/";
  const KvTxnResult r = owner_.kv_.txn({ownedBy(owner_.ownerKey(id_), token_)},
                                       {KvOp{KvOp::Kind::deleteRange, all, prefixEnd(all), {}, 0}}, {});
  if (!r.succeeded) {
    owner_.fenced(id_);
    state_ = State::fenced;
    throw Fenced("session " + id_ + ": another server owns it now; it was not deleted");
  }
  state_ = State::fenced;  // no owner key any more: nothing more is written through this journal
}

void EtcdJournal::release() {
  const std::string key = owner_.ownerKey(id_);
  owner_.kv_.txn({ownedBy(key, token_)}, {KvOp{KvOp::Kind::deleteRange, key, {}, {}, 0}}, {});
  if (owner_.events_.ownershipChanged) owner_.events_.ownershipChanged(id_, false);
}

}  // namespace marzipan::service
