// What a session's clients hear without asking: session.changed and session.clients
// notifications, splat buffers (full, and deltas of the touched bricks), and the pushed frames
// of frames-mode clients.
//
// Conventions:
// - Everything here runs on the session's strand, except renders (on the workers, from a
//   snapshot). One edit builds its splat buffer first (a delta, or a full buffer, shared by
//   every splats-mode client), then gives each client the notification and its buffer as one
//   hand-over (ClientLink::sendTogether), or the notification and a frame. A delta lists the
//   bricks whose points changed (HeldSplats).
// - Pushed frames are latest-wins: a client has at most one render running; changes meanwhile
//   ask for one more (renderAgain), and a still frame follows once nothing changed for
//   HubOptions::stillDelay.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/volume.hpp"
#include "protocol/cpp/frames.hpp"
#include "service/hub/connection.hpp"

namespace marzipan::service {

struct HubCore;
struct LiveSession;
class Session;

// HeldSplats' blocks by brick (splatBrickKey): open addressing with linear probing in one array
// kept at most half full, not a map of nodes. A delta looks up some 25 bricks right after the
// engine's work has evicted such nodes from the caches: as a std::unordered_map those lookups
// were ~1% of the server's CPU under load (docs/benchmark-log.md, capacity). Entries are only
// added and replaced, and cleared all at once. A block's bytes stay where they are when the
// array grows (its vector is moved), so spans of them outlive later additions.
class HeldBlocks {
 public:
  struct Entry {
    std::uint64_t key = kNone;
    std::vector<std::uint8_t> block;
  };
  static constexpr std::uint64_t kNone = ~std::uint64_t(0);  // no splatBrickKey is this

  // key's block, added empty when it had none (added).
  std::pair<std::vector<std::uint8_t>*, bool> findOrAdd(std::uint64_t key);
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  void clear();  // the array too
  template <class F>
  void forEach(F f) const {
    for (const Entry& e : entries_)
      if (e.key != kNone) f(e.key, e.block);
  }

 private:
  std::size_t slotOf(std::uint64_t key) const { return std::size_t((key * 0x9e3779b97f4a7c15ull) >> shift_); }
  std::vector<Entry> entries_;  // a power of two of them, or none
  int shift_ = 64;              // 64 - log2(entries_.size())
  std::size_t size_ = 0;
};

// What every splats-mode client of a session holds of the bricks deltas listed: per brick, its
// block as encoded (protocol/cpp/splats.hpp). A delta leaves out a brick whose block comes out
// the same: an edit rewrites a brick's voxels far from the surface too (redistancing), and
// about half of the bricks around a stroke's changes show the same points as before.
// Valid only while every change of the session passes through Broadcaster::changed with a
// delta: it names the Session and the revision it describes, and one that does not follow on
// from them (a change that sent no delta, a full refresh, a session replaced by its journal)
// starts it afresh. A splats-mode client's splats.get buffer, from a snapshot, may arrive after
// deltas and replace what they brought: from the snapshot until the buffer is queued no delta
// leaves a brick out, and then the record starts afresh (buffersInFlight). Every
// splats-mode client holds this: it joined with a full buffer of the session as it was then,
// and got every delta since (deltas are never dropped; a client too far behind is closed).
// Strand only.
struct HeldSplats {
  const Session* of = nullptr;
  std::uint64_t revision = 0;
  HeldBlocks blocks;
  std::size_t bytes = 0;  // the blocks' capacities plus kEntryBytes each
  int buffersInFlight = 0;  // splats.get buffers of splats-mode clients not yet queued (not cleared)
  // Past half the volume's own memory, or kMaxBytes, the record starts afresh (its bricks are
  // sent again, once). A brick's block is about 0.4 KiB on a surface against its 2 KiB of
  // floats, but up to 4 KiB where every voxel is near the surface (noise a client uploaded).
  // The volume's memory is read only past kCheckBytes.
  static constexpr std::size_t kMaxBytes = std::size_t(32) << 20;
  static constexpr std::size_t kCheckBytes = std::size_t(1) << 20;
  // An entry's share of HeldBlocks' array: 32 bytes, the array between a quarter and half full.
  static constexpr std::size_t kEntryBytes = 96;
  void clear();
  // The splat buffer (protocol/cpp/splats.hpp) of the bricks of `fresh` whose blocks differ from
  // the recorded ones (or are not recorded), which it records; then the bound, for a record of
  // vol's splats. fresh: distinct bricks (bricksAroundChanges' list). The buffer follows
  // `headroom` bytes of room for a frame's header (joinSplatBlocks).
  std::vector<std::uint8_t> delta(const std::vector<BrickSplats>& fresh, const Volume& vol, std::size_t headroom = 0);
};

SharedBytes makeFrame(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                      std::span<const std::uint8_t> payload);
// The same frame made in place of `buffer` (protocol::encodeFrameInPlace: its first
// kFrameHeaderBytes are room for the header, the rest the payload).
SharedBytes makeFrameInPlace(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision, Bytes buffer);
// A frame of splats (full or delta, either version) with its payload as splat format version 1.
SharedBytes plainFrame(const Bytes& frame);

class Broadcaster {
 public:
  explicit Broadcaster(HubCore& hub) : hub_(hub) {}

  // After a change by `by`: the notification, then each client's delta (or full buffer when
  // `full`) or frame.
  void changed(LiveSession& s, const HubClient& by, std::string_view cause, const Box& roi,
               const std::vector<Int3>& bricks, bool full);
  // The clients of s, as session.create/join/stats and session.clients list them.
  static nlohmann::json clientList(const LiveSession& s);
  // session.clients with `list` to every client of s but `except`.
  void clients(LiveSession& s, const HubClient* except, const nlohmann::json& list);

  // Every splat of vol in one frame of splat format `version`; counts its bricks and points
  // when asked.
  SharedBytes fullSplatsFrame(const Volume& vol, std::uint32_t requestId, std::uint64_t revision,
                              std::size_t* bricks, std::size_t* points, std::uint16_t version);
  void sendFullSplats(LiveSession& s, HubClient& c, std::uint32_t requestId);
  // A pushed frame for a frames-mode client, latest wins.
  void requestFrame(LiveSession& s, const std::shared_ptr<HubClient>& c);

 private:
  // The delta of a change of s that touched `bricks` (engine bricksAroundChanges): the bricks
  // whose blocks differ from s's HeldSplats, which it then records.
  SharedBytes deltaFrame(LiveSession& s, const std::vector<Int3>& bricks);
  void startRender(LiveSession& s, const std::shared_ptr<HubClient>& c, bool still);
  HubCore& hub_;
};

}  // namespace marzipan::service
