#include "service/hub/broadcast.hpp"

#include <algorithm>
#include <bit>

#include "engine/image_io.hpp"
#include "engine/raycast.hpp"
#include "engine/splats.hpp"
#include "protocol/cpp/splats.hpp"
#include "service/hub/core.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::ViewMode;

SharedBytes makeFrame(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision,
                      std::span<const std::uint8_t> payload) {
  return std::make_shared<const Bytes>(protocol::encodeFrame(kind, requestId, revision, payload));
}

SharedBytes makeFrameInPlace(protocol::FrameKind kind, std::uint32_t requestId, std::uint64_t revision, Bytes buffer) {
  return std::make_shared<const Bytes>(protocol::encodeFrameInPlace(kind, requestId, revision, std::move(buffer)));
}

std::pair<std::vector<std::uint8_t>*, bool> HeldBlocks::findOrAdd(std::uint64_t key) {
  if (2 * (size_ + 1) > entries_.size()) {
    std::vector<Entry> old = std::move(entries_);
    entries_ = std::vector<Entry>(std::max<std::size_t>(64, 2 * old.size()));
    shift_ = 64 - std::countr_zero(entries_.size());
    const std::size_t mask = entries_.size() - 1;
    for (Entry& e : old) {
      if (e.key == kNone) continue;
      std::size_t i = slotOf(e.key);
      while (entries_[i].key != kNone) i = (i + 1) & mask;
      entries_[i] = std::move(e);
    }
  }
  const std::size_t mask = entries_.size() - 1;
  std::size_t i = slotOf(key);
  while (entries_[i].key != kNone && entries_[i].key != key) i = (i + 1) & mask;
  Entry& e = entries_[i];
  if (e.key == key) return {&e.block, false};
  e.key = key;
  ++size_;
  return {&e.block, true};
}

void HeldBlocks::clear() {
  std::vector<Entry>().swap(entries_);
  shift_ = 64;
  size_ = 0;
}

void HeldSplats::clear() {
  of = nullptr;
  revision = 0;
  blocks.clear();
  bytes = 0;
}

void Broadcaster::changed(LiveSession& s, const HubClient& by, std::string_view cause, const Box& roi,
                          const std::vector<Int3>& bricks, bool full) {
  const Session& ss = *s.session;
  const std::string text = protocol::sessionChangedText(ss.revision(), by.clientId, cause, roi, digestText(ss.digest()),
                                                        ss.canUndo(), ss.canRedo());
  const auto members = s.members();
  // The other clients first: they need not wait for the splats to be extracted.
  bool splatsMode = false;
  for (const auto& c : members) {
    if (c->mode == ViewMode::Splats) {
      splatsMode = true;
      continue;
    }
    c->link->sendText(text);
    if (c->mode == ViewMode::Frames) requestFrame(s, c);
  }
  if (!splatsMode) {
    s.heldSplats.clear();  // nobody holds it now (a later delta would start afresh anyway)
    return;
  }
  if (full) s.heldSplats.clear();
  const SharedBytes splats = full ? fullSplatsFrame(ss.volume(), 0, ss.revision(), nullptr, nullptr, kSplatFormatVersion)
                                  : deltaFrame(s, bricks);
  // Clients that read version 1 get the same buffer without its colours, made once.
  SharedBytes plain;
  const auto shared = std::make_shared<const std::string>(text);
  for (const auto& c : members) {
    if (c->mode != ViewMode::Splats) continue;
    if (c->splats == kSplatFormatVersion) {
      c->link->sendTogether({{shared, nullptr}, {nullptr, splats}});
      continue;
    }
    if (!plain) plain = plainFrame(*splats);
    c->link->sendTogether({{shared, nullptr}, {nullptr, plain}});
  }
}

SharedBytes plainFrame(const Bytes& frame) {
  const protocol::DecodedFrame f = *protocol::decodeFrameHeader(frame).frame;  // a frame this server made
  return makeFrame(f.header.kind, f.header.requestId, f.header.revision, splatsAsVersion1(f.payload));
}

std::vector<std::uint8_t> HeldSplats::delta(const std::vector<BrickSplats>& fresh, const Volume& vol, std::size_t headroom) {
  std::vector<std::span<const std::uint8_t>> changed;
  changed.reserve(fresh.size());
  std::vector<std::uint8_t> block;
  for (const BrickSplats& b : fresh) {
    encodeSplatBlock(b, block);
    auto [held, added] = blocks.findOrAdd(splatBrickKey(b.brick));
    if (!added && *held == block) continue;
    // A block of its own size: a brick the surface left keeps a few bytes, not its old 4 KiB.
    std::vector<std::uint8_t> kept(block.begin(), block.end());
    bytes = bytes - held->capacity() + kept.capacity() + (added ? kEntryBytes : 0);
    *held = std::move(kept);
    changed.emplace_back(*held);
  }
  std::vector<std::uint8_t> buffer = joinSplatBlocks(changed, kSplatFormatVersion, headroom);
  if (bytes > kMaxBytes || (bytes > kCheckBytes && bytes > vol.memoryBytes() / 2)) {
    blocks.clear();
    bytes = 0;
  }
  return buffer;
}

SharedBytes Broadcaster::deltaFrame(LiveSession& s, const std::vector<Int3>& bricks) {
  const Session& ss = *s.session;
  HeldSplats& held = s.heldSplats;
  if (held.of != &ss || held.revision + 1 != ss.revision() || held.buffersInFlight > 0) held.clear();
  held.of = &ss;
  held.revision = ss.revision();
  try {
    // The delta written after room for the frame's header: ~12 KB not copied again.
    return makeFrameInPlace(protocol::FrameKind::SplatsDelta, 0, ss.revision(),
                            held.delta(extractSplats(ss.volume(), bricks), ss.volume(), protocol::kFrameHeaderBytes));
  } catch (...) {
    held.clear();  // it may record blocks that were never sent
    throw;
  }
}

json Broadcaster::clientList(const LiveSession& s) {
  json list = json::array();
  for (const auto& c : s.members())
    list.push_back({{"client", c->clientId}, {"read_only", c->readOnly}, {"name", c->name}, {"color", c->color}});
  return list;
}

void Broadcaster::clients(LiveSession& s, const HubClient* except, const json& list) {
  const std::string text = protocol::notificationText("session.clients", {{"clients", list}});
  for (const auto& other : s.members())
    if (other.get() != except) other->link->sendText(text);
}

SharedBytes Broadcaster::fullSplatsFrame(const Volume& vol, std::uint32_t requestId, std::uint64_t revision,
                                         std::size_t* bricks, std::size_t* points, std::uint16_t version) {
  const std::vector<BrickSplats> all = extractAllSplats(vol, hub_.pool);
  if (bricks) *bricks = all.size();
  if (points) {
    *points = 0;
    for (const BrickSplats& b : all) *points += b.points.size();
  }
  return makeFrame(protocol::FrameKind::SplatsFull, requestId, revision, encodeSplats(all, version));
}

void Broadcaster::sendFullSplats(LiveSession& s, HubClient& c, std::uint32_t requestId) {
  c.link->sendBinary(
      fullSplatsFrame(s.session->volume(), requestId, s.session->revision(), nullptr, nullptr, std::uint16_t(c.splats)), false);
}

void Broadcaster::requestFrame(LiveSession& s, const std::shared_ptr<HubClient>& c) {
  ++c->frameSeq;
  if (c->rendering) {
    c->renderAgain = true;
    return;
  }
  startRender(s, c, false);
}

void Broadcaster::startRender(LiveSession& s, const std::shared_ptr<HubClient>& c, bool still) {
  c->rendering = true;
  auto snapshot = std::make_shared<Volume>(s.session->snapshot());
  const std::uint64_t revision = s.session->revision(), seq = c->frameSeq;
  const Camera camera = c->camera;
  const Shading shading = c->shading;
  const double minVu = c->thicknessMinVu;
  const int quality = still ? hub_.options.stillQuality : hub_.options.interactiveQuality;
  // The client may have left s (and joined another session, whose strand owns its view state
  // then) by the time the render is done: s's strand touches c only while c is still the same
  // client of s (c->session belongs to the connection's pump, not to this strand).
  std::weak_ptr<LiveSession> weak = s.weak_from_this();
  const int clientId = c->clientId;
  hub_.workers.post([self = hub_.shared_from_this(), weak, c, clientId, snapshot, revision, seq, camera, shading, minVu,
                     quality, still] {
    try {
      const Frame f =
          render(*snapshot, camera, shading, self->pool, still ? FrameQuality::Still : FrameQuality::Preview, minVu);
      const Bytes jpeg = encodeJpeg(f.rgb, f.width, f.height, quality);
      c->link->sendBinary(makeFrame(protocol::FrameKind::FrameJpeg, 0, revision, jpeg), true);
    } catch (const std::exception& e) {
      self->log(std::string("frame render failed: ") + e.what());
    }
    const auto live = weak.lock();
    if (!live) return;
    live->strand->post([self, s = live, c, clientId, seq, still] {
      if (!s->hasClient(*c, clientId)) return;
      c->rendering = false;
      if (c->mode != ViewMode::Frames) return;
      if (c->renderAgain) {
        c->renderAgain = false;
        return self->broadcast.startRender(*s, c, false);
      }
      if (still) return;
      self->workers.postAfter(self->options.stillDelay, [self, s, c, clientId, seq] {
        s->strand->post([self, s, c, clientId, seq] {
          if (s->hasClient(*c, clientId) && c->mode == ViewMode::Frames && !c->rendering && c->frameSeq == seq)
            self->broadcast.startRender(*s, c, true);
        });
      });
    });
  });
}

}  // namespace marzipan::service
