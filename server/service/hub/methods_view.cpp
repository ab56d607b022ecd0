// Handlers of view.set, render.frame and splats.get (service/hub/methods.hpp): what a client
// sees of the session, pushed (view.set) or asked for (a frame, the full splat buffer).
#include "engine/image_io.hpp"
#include "engine/raycast.hpp"
#include "protocol/cpp/splats.hpp"
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;
using protocol::ViewMode;

void viewSet(HubCore& hub, const Call& call) {
  const protocol::ViewSetParams p = protocol::parseViewSetParams(call.req.params, hub.limits().maxFrameSide);
  hub.onStrand(call, false, [self = hub.shared_from_this(), c = call.client, p](LiveSession& s, Reply& r) {
    c->mode = p.mode;
    if (p.camera) c->camera = *p.camera;
    c->shading = p.shading;
    c->thicknessMinVu = p.minVu;
    r.result = {{"mode", protocol::nameOf(protocol::kViewModeNames, p.mode)}, {"revision", s.session->revision()}};
    r.after = [self, &s, c] {
      if (c->mode == ViewMode::Splats) self->broadcast.sendFullSplats(s, *c, 0);
      if (c->mode == ViewMode::Frames) self->broadcast.requestFrame(s, c);
    };
  });
}

void renderFrame(HubCore& hub, const Call& call) {
  const protocol::RenderFrameParams p = protocol::parseRenderFrameParams(call.req.params, hub.limits().maxFrameSide);
  hub.offStrand(call, [self = hub.shared_from_this(), p, frameId = call.req.frameId](const Volume& vol,
                                                                                      std::uint64_t revision, Reply& r) {
    const Frame f = render(vol, p.camera, p.shading, self->pool, FrameQuality::Still, p.minVu);
    const bool png = p.format == protocol::ImageKind::Png;
    const Bytes file = png ? encodePng(f.rgb, f.width, f.height) : encodeJpeg(f.rgb, f.width, f.height, p.quality);
    r.frame = makeFrame(png ? protocol::FrameKind::FramePng : protocol::FrameKind::FrameJpeg, frameId, revision, file);
    r.result = {{"revision", revision}, {"width", f.width}, {"height", f.height}, {"format", png ? "png" : "jpeg"},
                {"bytes", file.size()}};
  }, {}, p.revision);
}

void splatsGet(HubCore& hub, const Call& call) {
  protocol::parseNoParams(call.req.params, call.req.method);
  hub.offStrand(call, [self = hub.shared_from_this(), frameId = call.req.frameId,
                       version = std::uint16_t(call.client->splats)](const Volume& vol, std::uint64_t revision, Reply& r) {
    // At most one point per voxel of a stored brick, 12 bytes each (uniform bricks yield points
    // only where a -band brick meets a +band one; max_volume_bytes bounds those).
    const std::size_t estimate = vol.presentBricks() * (kSplatBrickHeaderBytes + kSplatPaintedPointBytes * std::size_t(kBrickVoxels));
    const std::size_t max = self->limits().maxOutputBytes;
    if (estimate > max)
      throw RpcException(RpcCode::LimitExceeded,
                         "the splat buffer could reach " + std::to_string(estimate) + " bytes, over max_output_bytes " +
                             std::to_string(max),
                         {{"limit", "max_output_bytes"}, {"value", estimate}, {"max", max}});
    std::size_t bricks = 0, points = 0;
    r.frame = self->broadcast.fullSplatsFrame(vol, frameId, revision, &bricks, &points, version);
    r.result = {{"revision", revision}, {"bricks", bricks}, {"points", points},
                {"bytes", r.frame->size() - protocol::kFrameHeaderBytes}};
  }, [c = call.client](LiveSession& s, Reply& r) {
    // A splats-mode client that applies this buffer (a snapshot of now) replaces what the
    // deltas sent meanwhile brought, which may reach it first: until the buffer is queued (or
    // the call failed), every delta sends all the bricks it lists, and then the session's record
    // of what its clients hold starts afresh (HeldSplats::buffersInFlight).
    if (c->mode != ViewMode::Splats) return;
    ++s.heldSplats.buffersInFlight;
    struct Landed {
      explicit Landed(std::weak_ptr<LiveSession> s) : session(std::move(s)) {}
      Landed(const Landed&) = delete;
      Landed& operator=(const Landed&) = delete;
      std::weak_ptr<LiveSession> session;
      ~Landed() {
        const auto live = session.lock();
        if (!live) return;
        try {
          live->strand->post([live] {
            --live->heldSplats.buffersInFlight;
            live->heldSplats.clear();
          });
        } catch (...) {
          // Not posted (out of memory): the count stays up and every delta sends all it lists.
        }
      }
    };
    r.hold = std::make_shared<Landed>(s.weak_from_this());
  });
}

}  // namespace marzipan::service
