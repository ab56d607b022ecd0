// Fuzz target: one JSON-RPC text frame (protocol/cpp/rpc.hpp): parseRequest, then the params
// decoder of the method it names, with the server's default limits (PROTOCOL.md, "Versions
// and limits"). Whatever the text, the answer is a request or an RpcError, and a request's
// params either decode or throw OpError / RpcException; every error must make a valid reply.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "fuzz.hpp"
#include "protocol/cpp/frames.hpp"
#include "protocol/cpp/rpc.hpp"

using namespace marzipan::protocol;
using marzipan::fuzz::expect;
using nlohmann::json;

namespace {

constexpr std::size_t kMaxDabs = 256;
constexpr int kMaxFrameSide = 4096;
constexpr std::uint64_t kMaxUploadBytes = (std::uint64_t(256) << 20) - kFrameHeaderBytes;

void decodeParams(const Request& r) {
  const json& p = r.params;
  switch (r.method) {
    case Method::SessionCreate: (void)parseCreateParams(p); break;
    case Method::SessionJoin: (void)parseJoinParams(p); break;
    case Method::ToolApply: (void)parseToolApplyParams(p); break;
    case Method::StrokeBegin: (void)parseStrokeBeginParams(p); break;
    case Method::StrokeDabs: {
      const StrokeDabsParams d = parseStrokeDabsParams(p, kMaxDabs);
      expect(!d.dabs.empty() && d.dabs.size() <= kMaxDabs, "a stroke.dabs holds 1 to max_dabs dabs");
      break;
    }
    case Method::StrokeEnd: (void)parseStrokeEndParams(p); break;
    case Method::VolumeMorph: (void)parseMorphParams(p); break;
    case Method::ViewSet: (void)parseViewSetParams(p, kMaxFrameSide); break;
    case Method::RenderFrame: {
      const RenderFrameParams f = parseRenderFrameParams(p, kMaxFrameSide);
      expect(f.camera.width >= 1 && f.camera.width <= kMaxFrameSide && f.camera.height >= 1 &&
                 f.camera.height <= kMaxFrameSide,
             "a frame's sides are within max_frame_side");
      break;
    }
    case Method::MeshExport: (void)parseMeshExportParams(p); break;
    case Method::AnalysisThickness: {
      const ThicknessParams t = parseThicknessParams(p);
      expect(t.minVu > 0 && t.minVu <= 1e4 && t.maxPlaces >= 1 && t.maxPlaces <= 1000, "thickness params in range");
      break;
    }
    case Method::VolumeLoad: {
      const std::uint64_t bytes = parseVolumeLoadParams(p, kMaxUploadBytes).bytes;
      expect(bytes >= 52 && bytes <= kMaxUploadBytes, "an upload size is within [52, max_binary_bytes - 24]");
      break;
    }
    case Method::HistoryUndo:
    case Method::HistoryRedo: (void)parseHistoryParams(p, r.method); break;
    case Method::HistoryList: {
      const HistoryListParams h = parseHistoryListParams(p);
      expect(h.limit >= 1 && h.limit <= kMaxHistoryListLimit, "a history.list limit is within [1, max]");
      break;
    }
    case Method::SessionFork: (void)parseForkParams(p); break;
    case Method::Presence: {
      const PresenceParams q = parsePresenceParams(p);
      // What the server forwards must be writable whatever was read.
      if (q.brush) (void)brushJson(*q.brush).dump();
      if (q.camera) (void)cameraJson(*q.camera).dump();
      break;
    }
    case Method::MaskClear:
    case Method::MaskInvert:
    case Method::MaskFill:
      (void)maskActionOf(r.method);
      parseNoParams(p, r.method);
      break;
    case Method::SessionLeave:
    case Method::SessionStats:
    case Method::SplatsGet:
    case Method::OpCancel: parseNoParams(p, r.method); break;
    case Method::VolumeSave: (void)parseVolumeSaveParams(p); break;
  }
}

// The reply the server would send must be writable whatever the error says.
void expectReply(const json& id, RpcCode code, const std::string& message, const json& data) {
  marzipan::fuzz::expectMessage(message);
  expect(data.is_null() || data.is_object(), "error data is null or an object");
  const json reply = json::parse(errorText(id, code, message, data));
  expect(reply.at("error").at("code") == int(code), "the reply carries the code");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = marzipan::fuzz::textOf(data, size);
  const ParsedRequest parsed = parseRequest(text);
  // The bounded peek the server uses to answer a refused text must agree with the full reader
  // on every request it reads: a named id is the request's, a notification is one.
  const std::optional<PeekedId> peeked = peekRequestId(text);
  expect(parsed.request.has_value() != parsed.error.has_value(), "a frame gives a request or an error, not both");
  if (parsed.error) {
    const RpcError& e = *parsed.error;
    expect(e.id.is_null() || e.id.is_string() || e.id.is_number_integer(), "an error's id is null or a valid id");
    expect(e.code != RpcCode::ParseError || e.id.is_null(), "an unreadable frame is answered with id null");
    expectReply(e.id, e.code, e.message, e.data);
    return 0;
  }
  const Request& r = *parsed.request;
  expect(r.params.is_object(), "params are an object");
  expect(peeked.has_value(), "the peek reads every request the full reader reads");
  expect(peeked->notification == !r.id, "the peek tells a notification as the full reader does");
  expect(peeked->id.is_null() || (r.id && peeked->id == *r.id), "an id the peek names is the request's");
  expect(!needsFrameId(r.method) || !r.id || r.frameId != 0, "a binary-answered request has a frame id");
  const json id = r.id.value_or(json(nullptr));
  try {
    decodeParams(r);
  } catch (const OpError& e) {
    expect(e.field().size() < 50 && marzipan::fuzz::validUtf8(e.field()), "the field is a short key");
    expectReply(id, RpcCode::InvalidParams, e.message(), json{{"field", e.field()}});
  } catch (const RpcException& e) {
    expectReply(id, e.code(), e.what(), e.data());
  }
  return 0;
}
