// The service side of `marzipan serve`: every live session, every connected client, and the
// JSON-RPC methods of protocol/PROTOCOL.md carried out on them. Transport-free: the network
// layer (server/net) hands in whole WebSocket messages and gets messages to send back through
// a ClientLink, so everything here runs and is tested without sockets.
//
// Conventions:
// - Threads: text()/binary()/disconnect() may be called from any thread holding no lock of the
//   caller's. On an idle connection text() parses a small message and hands its work to the
//   session's strand right there (microseconds, HubCore::PumpOn); otherwise they only enqueue. A
//   connection's messages are handled one after the other, in arrival order;
//   everything that touches a session (its volume, its clients, their view state) runs on that
//   session's strand; renders run on the workers off the strand, from a snapshot.
// - Durability (through a SessionStorage, service/session_storage.hpp: files in a data
//   directory, or none): every change is in the session's journal before its response is
//   sent; a session lives on one server at a time (its lease), and is recovered from snapshot
//   + journal when it is joined after an unload, a restart or a crash. A lease lost closes the
//   session here (its clients reconnect to the new holder).
// - Order of what one edit sends: the requester's response, then `session.changed` to every
//   client, then each client's splat delta or frame. Binary answers precede their response.
// - Ownership runs one way: the hub owns sessions; a HubClient is owned by the network
//   connection (and by tasks in flight) and holds its session; a session knows its clients by
//   weak reference.
// - Units: sizes in bytes, durations as std::chrono types, coordinates in vu.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace marzipan::service {

// The configurable limits (PROTOCOL.md, "Versions and limits"), plus the connection bounds.
struct HubLimits {
  std::size_t maxTextBytes = std::size_t(1) << 20;
  std::size_t maxBinaryBytes = std::size_t(256) << 20;
  int maxGridSide = 512;
  std::size_t maxSessions = 64;
  std::size_t maxClientsPerSession = 16;
  std::size_t maxDabs = 256;
  int maxFrameSide = 4096;
  // Undo memory per session. Busy sessions fill it (a 1-2 s stroke on 128^3 keeps ~1 MiB), so
  // the server's worst case is max_sessions times this.
  std::size_t historyBytes = std::size_t(64) << 20;
  std::chrono::seconds idleSession{600};
  std::chrono::seconds ping{30};
  // Messages of one connection waiting to be handled; beyond it requests get -32005 (busy).
  std::size_t maxPendingMessages = 64;
  // Requests one connection may send per second (bursts of twice that); beyond: -32005.
  std::size_t maxRequestsPerSecond = 400;
  // Bytes of non-droppable data (responses, splat buffers) queued for one connection; beyond
  // it the connection is closed with 1008 "too far behind" (enforced by the network layer).
  std::size_t maxQueuedBytes = std::size_t(64) << 20;
  // TCP connections (HTTP and WebSocket) at once, in all and from one client address; beyond
  // them a new connection is closed at once (enforced by the network layer).
  std::size_t maxConnections = 1024;
  std::size_t maxConnectionsPerAddress = 32;
  // A WebSocket that is in no session this long (since it opened or left one) is closed with
  // 1008: a connection outside a session holds nothing but its slot.
  std::chrono::seconds lobby{60};
  // The memory of one session's volume (its stored bricks); a volume.load beyond it is refused
  // (-32004). Full splat buffers are at most about twice this.
  std::size_t maxVolumeBytes = std::size_t(256) << 20;
  // An open stroke without a message for this long is ended at the session's next change, as
  // stroke.end would. The old bricks open strokes keep alive (each holds the volume as it
  // began) count against max_volume_bytes besides the volume: past it, the oldest are ended.
  std::chrono::seconds strokeIdle{60};
  // The largest answer a request may build (mesh.export's file, splats.get's buffer), estimated
  // from the band before any work; beyond it -32004.
  std::size_t maxOutputBytes = std::size_t(256) << 20;
  // The largest .vdb file a volume.load may announce (-32004 beyond). OpenVDB builds a file's
  // tree before anything can check it against the session: a crafted file's topology costs
  // about 33 times its size in memory while it is read (64 bytes on disk per 2 KiB leaf), so
  // this bounds that transient memory at ~0.5 GiB; a 256^3 sphere's .vdb is 2.7 MB.
  std::size_t maxVdbBytes = std::size_t(16) << 20;
  // session.create per connection and per client address in any 60 s; beyond them -32004.
  std::size_t maxCreatesPerMinute = 10;
  std::size_t maxCreatesPerAddressPerMinute = 30;
  // With a data directory: a session at rest whose files nobody changed for this long is
  // deleted (checked at start and hourly).
  std::chrono::hours maxSessionAge{24 * 90};
  // Work one request may cost, in voxels processed (service/apply_op.hpp, estimateCost): beyond
  // it the request is refused with -32004 before anything runs. The default is several minutes
  // of work on a 2-core VM; long operations can be cancelled meanwhile (op.cancel).
  double maxOpVoxels = 4e9;
};

// What the hub reports, for /metrics and the log. Any member may be empty; called from worker
// threads and from a network thread inside text().
struct HubEvents {
  std::function<void(const std::string&)> log;          // one line, no newline
  std::function<void(std::int64_t)> sessions, clients;  // gauge deltas
  std::function<void(std::string_view)> request;        // a request's method name
  std::function<void(int)> error;                       // a JSON-RPC error code sent
  std::function<void(double)> editLatency;              // seconds from arrival to response
  std::function<void()> journalSynced;                  // a journal fsynced by the --fsync-ms timer
};

class SessionStorage;

struct HubOptions {
  HubLimits limits;
  unsigned workers = 0;               // 0: one per core
  std::filesystem::path dataDir;      // empty: sessions are never saved
  // Where sessions are kept; empty: files in dataDir (service/session_store.hpp), or nowhere.
  std::shared_ptr<SessionStorage> storage;
  HubEvents events;
  // Still frames follow the last change of a frames-mode client after this pause.
  std::chrono::milliseconds stillDelay{250};
  int interactiveQuality = 70, stillQuality = 92;  // JPEG qualities of pushed frames
  // Journal durability: 0 = fsync every change before its response; else at most this often.
  std::chrono::milliseconds fsyncInterval{0};
  // A snapshot (and a fresh journal) after this many journal records.
  std::size_t snapshotEvery = 2000;
  // This server's name in session leases ([A-Za-z0-9._:-], no spaces). A server restarted with
  // the same name takes its own leases back at once; another waits for them to expire (30 s).
  // Empty: a random name.
  std::string serverId;
};

// One connection as the hub sees it. Implemented by the network layer; the hub calls it from
// worker threads and from the network thread inside text() (a refusal, a presence, an answer
// given without work), never while holding a session's strand for long.
class ClientLink {
 public:
  virtual ~ClientLink() = default;
  // A JSON-RPC text message; never dropped.
  virtual void sendText(std::string text) = 0;
  // A binary frame (header + payload). latestWins: a pushed image that a newer one may replace
  // while it still waits in the queue; otherwise never dropped.
  virtual void sendBinary(std::shared_ptr<const std::vector<std::uint8_t>> frame, bool latestWins) = 0;
  // JSON-RPC texts that may be dropped (presence): one with the same `key` still waiting
  // replaces it, any other message overtakes it while it waits, and it never counts against
  // max_queue_bytes. Links without a queue of their own send it as any text.
  // Transient texts, each with its key, in order (one hand-over to the link for all of them).
  struct Transient {
    std::shared_ptr<const std::string> text;
    std::uint64_t key;
  };
  virtual void sendTransient(std::vector<Transient> texts) {
    for (Transient& t : texts) sendText(*t.text);
  }
  // Messages handed over as one, in order, none dropped: a change's notification and its splat
  // delta. A link with a socket writes them in one TCP push (one wake-up of the reader instead
  // of one per message). Each is a text (`text` set) or a binary frame.
  struct Message {
    std::shared_ptr<const std::string> text;
    std::shared_ptr<const std::vector<std::uint8_t>> binary;
  };
  virtual void sendTogether(std::vector<Message> messages) {
    for (Message& m : messages) {
      if (m.text) sendText(*m.text);
      else sendBinary(std::move(m.binary), false);
    }
  }
  // What one piece of work sent this link, handed over as one (service/hub/outbox.hpp), in
  // order: a text (`text` set), a binary frame (`binary`, latestWins as in sendBinary), or a
  // transient text (`transient`, its `key` as in sendTransient). A link with a socket writes the
  // texts and frames that are neither transient nor latestWins in one TCP push (a response,
  // then its change's notification and splat delta: one wake-up of the reader, and one
  // hand-over to the network thread instead of one per message).
  struct Item {
    std::shared_ptr<const std::string> text;
    std::shared_ptr<const std::vector<std::uint8_t>> binary;
    bool latestWins = false;
    bool transient = false;
    std::uint64_t key = 0;
  };
  virtual void sendAll(std::vector<Item> items) {
    for (Item& i : items) {
      if (i.transient) sendTransient({{std::move(i.text), i.key}});
      else if (i.text) sendText(*i.text);
      else sendBinary(std::move(i.binary), i.latestWins);
    }
  }
  // What one piece of work sent several links that share a carrier (carrier()), handed to it
  // in one call: the network's carrier takes them to the network thread in one hand-over, where
  // one per link was a wake-up of that thread each (a change goes to every client of its
  // session at once).
  struct Delivery {
    std::shared_ptr<ClientLink> link;
    std::vector<Item> items;
  };
  class Carrier {
   public:
    virtual ~Carrier() = default;
    // Each delivery's items to its link as its sendAll would take them; deliveries to
    // different links have no order between them.
    virtual void carry(std::vector<Delivery> deliveries) = 0;
  };
  // This link's carrier, shared with other links; null: its sendAll is called alone.
  virtual Carrier* carrier() { return nullptr; }
  // Close the WebSocket with this code and reason (<= 123 bytes).
  virtual void close(int code, std::string reason) = 0;
};

class HubClient;  // a connection's state, opaque to the network layer
struct HubCore;   // the pieces of the hub (service/hub/core.hpp)

class Hub {
 public:
  explicit Hub(HubOptions options);
  ~Hub();  // shutdown()
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;

  const HubLimits& limits() const;

  std::shared_ptr<HubClient> connect(std::shared_ptr<ClientLink> link, std::string peer);
  // One text message (already checked for size and UTF-8 by the transport). An op.cancel is
  // answered at once, ahead of the connection's queued messages.
  void text(const std::shared_ptr<HubClient>& client, std::string message);
  // One binary message (already checked by decodeFrameHeader, kind 9).
  void binary(const std::shared_ptr<HubClient>& client, std::vector<std::uint8_t> message);
  // Whether the client's next binary message may be an upload of up to max_binary_bytes: it
  // is an editor in a session. Without it the transport reads no message over max_text_bytes.
  bool mayUpload(const std::shared_ptr<HubClient>& client) const;
  // The connection is gone: leaves its session, drops its queued messages.
  void disconnect(const std::shared_ptr<HubClient>& client);

  // Refuses new requests (-32005), cancels running long operations (they change nothing and
  // answer -32016), lets other running edits finish, snapshots every session in the data
  // directory (when set), releases their leases and stops the workers, all within about 8 s
  // (a snapshot still running then finishes before the workers stop). Idempotent.
  void shutdown();

  std::size_t sessionCount() const;

 private:
  std::shared_ptr<HubCore> impl_;
};

}  // namespace marzipan::service
