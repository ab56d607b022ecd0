// JSON-RPC 2.0 messages of the Marzipan protocol: the request envelope, the params of every
// method, and the texts the server sends back. protocol/PROTOCOL.md ("Requests and responses",
// "Methods", "Errors") is the contract; this is its C++ side. No sockets, no sessions: the
// service decides what a valid request does.
//
// Conventions: everything here reads untrusted text. Envelope problems come back as an
// RpcError (never thrown past parseRequest); params decoders throw OpError (code -32602,
// `field` = the top-level params key) or RpcException (other codes, e.g. -32004 for a list
// over a limit) before any effect. Coordinates in vu of the session grid, as in the engine.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/geometry.hpp"
#include "protocol/cpp/values.hpp"
#include "ops.hpp"

namespace marzipan::protocol {

inline constexpr int kProtocolMajor = 1, kProtocolMinor = 7;

// Every error code of PROTOCOL.md, section Errors.
enum class RpcCode : int {
  ParseError = -32700,
  InvalidRequest = -32600,
  UnknownMethod = -32601,
  InvalidParams = -32602,
  Internal = -32000,
  NoSuchSession = -32001,
  BadToken = -32002,
  SessionFull = -32003,
  LimitExceeded = -32004,
  Busy = -32005,
  EngineRefused = -32006,
  ReadOnly = -32007,
  UnsupportedProtocol = -32008,
  NotInSession = -32009,
  AlreadyInSession = -32010,
  NoSuchStroke = -32011,
  NothingToUndo = -32012,
  UploadMissing = -32013,
  SessionExists = -32014,
  HeldElsewhere = -32015,
  Cancelled = -32016,
  UndoConflict = -32017,
};

// An error to answer with; `data` is null or an object.
class RpcException : public std::runtime_error {
 public:
  RpcException(RpcCode code, const std::string& message, nlohmann::json data = nullptr)
      : std::runtime_error(message), code_(code), data_(std::move(data)) {}
  RpcCode code() const { return code_; }
  const nlohmann::json& data() const { return data_; }

 private:
  RpcCode code_;
  nlohmann::json data_;
};

enum class Method {
  SessionCreate, SessionJoin, SessionLeave, SessionStats, ToolApply, StrokeBegin, StrokeDabs, StrokeEnd,
  VolumeMorph, HistoryUndo, HistoryRedo, ViewSet, RenderFrame, SplatsGet, MeshExport, VolumeSave, VolumeLoad,
  AnalysisThickness,
  OpCancel,
  HistoryList, SessionFork, Presence,
  MaskClear, MaskInvert, MaskFill,
};
inline constexpr std::array<NameOf<Method>, 25> kMethodNames{{
    {Method::SessionCreate, "session.create"}, {Method::SessionJoin, "session.join"},
    {Method::SessionLeave, "session.leave"},   {Method::SessionStats, "session.stats"},
    {Method::ToolApply, "tool.apply"},         {Method::StrokeBegin, "stroke.begin"},
    {Method::StrokeDabs, "stroke.dabs"},       {Method::StrokeEnd, "stroke.end"},
    {Method::VolumeMorph, "volume.morph"},     {Method::HistoryUndo, "history.undo"},
    {Method::HistoryRedo, "history.redo"},     {Method::ViewSet, "view.set"},
    {Method::RenderFrame, "render.frame"},     {Method::SplatsGet, "splats.get"},
    {Method::MeshExport, "mesh.export"},       {Method::VolumeSave, "volume.save"},
    {Method::VolumeLoad, "volume.load"},       {Method::AnalysisThickness, "analysis.thickness"},
    {Method::OpCancel, "op.cancel"},
    {Method::HistoryList, "history.list"},     {Method::SessionFork, "session.fork"},
    {Method::Presence, "presence"},
    {Method::MaskClear, "mask.clear"},         {Method::MaskInvert, "mask.invert"},
    {Method::MaskFill, "mask.fill"},
}};
// The mask action of mask.clear / mask.invert / mask.fill (a method without params).
MaskAction maskActionOf(Method m);
// Methods whose id travels in a binary header (answered by a frame, or naming an upload).
bool needsFrameId(Method m);
// Methods that change the volume or the history: refused for view tokens.
bool isEdit(Method m);

struct Request {
  // The id as sent (an integer within +-(2^53-1) or a string); absent for a notification.
  std::optional<nlohmann::json> id;
  Method method = Method::SessionStats;
  nlohmann::json params = nlohmann::json::object();  // always an object
  // The id as a binary frame's request id, for methods that need one (else 0).
  std::uint32_t frameId = 0;
};

struct RpcError {
  RpcCode code;
  std::string message;
  nlohmann::json data;  // null or an object
  nlohmann::json id;    // the request's id when it could be read, else null
  bool notification = false;  // the request had no id: nothing may be sent back
};

struct ParsedRequest {
  std::optional<Request> request;
  std::optional<RpcError> error;
};

// One text frame. Checks in the order of PROTOCOL.md: one JSON value without repeated keys
// (-32700), a single object, not a batch (-32600), "jsonrpc" exactly "2.0", only the four
// envelope keys, a valid id, "method" a string (-32600), a known method (-32601), params an
// object when present (-32602, field "params"), an integer id in [1, 2^32-1] for methods that
// need one (-32600).
ParsedRequest parseRequest(std::string_view text);

// The id an answer to `text` carries, found without parsing the whole text: for refusing a
// request cheaply (Busy) on a network thread, where parseRequest of a 1 MiB text would take
// tens of milliseconds. Walks the top-level object in one pass, skipping every other value
// without building it (strings with their escapes, numbers, literals, nested arrays and
// objects up to parseRequest's 64 levels), and parses only the "id" member's own text.
// - A valid request: the same id and notification flag as parseRequest.
// - An "id" that is not a valid id (a fraction, null, an object...), or longer than
//   kMaxPeekedIdBytes: id null, not a notification (it has an id, which cannot be echoed).
// - Not a JSON object, malformed at the top level or in the structure of a nested value, or
//   "id" twice at the top level (parseRequest refuses repeated keys): nullopt; answer with id
//   null. Repeated keys below the top level, invalid UTF-8 and other keys are not checked:
//   such a text gets the id it names, where parseRequest would answer with null.
struct PeekedId {
  nlohmann::json id;  // null or a valid id
  bool notification = false;
};
inline constexpr std::size_t kMaxPeekedIdBytes = 256;
std::optional<PeekedId> peekRequestId(std::string_view text);

// --- params of each method ------------------------------------------------------------------
enum class ViewMode { Splats, Frames, None };
inline constexpr std::array<NameOf<ViewMode>, 3> kViewModeNames{
    {{ViewMode::Splats, "splats"}, {ViewMode::Frames, "frames"}, {ViewMode::None, "none"}}};

struct RayParam {
  Vec3 origin, direction;  // direction finite, not zero, any length
};

// The splat buffer versions a client may ask for (`splats`, since 1.7; PROTOCOL.md, splat
// buffers): 1 drops the colour, 2 carries it.
inline constexpr int kSplatsVersionDefault = 1, kSplatsVersionNewest = 2;

struct CreateParams {
  Int3 size;
  SolidKind solid = SolidKind::Sphere;
  std::optional<std::string> session;  // the id the client proposes
  std::optional<int> protocol;
  ViewMode view = ViewMode::Splats;
  std::optional<std::string> name;  // the display name, trimmed (since 1.2)
  std::optional<SrgbColor> baseColor;  // the colour of unpainted clay (since 1.7; absent: the clay colour)
  int splats = kSplatsVersionDefault;  // the splat buffer version this client reads (since 1.7)
};
struct JoinParams {
  std::string session, token;
  std::optional<int> protocol;
  ViewMode view = ViewMode::Splats;
  std::optional<std::string> name;
  int splats = kSplatsVersionDefault;
};
struct ToolApplyParams {
  Op op;                       // a tool op; its centre is a placeholder when `ray` is set
  std::optional<RayParam> ray;
};
// The parameters of a warp stroke (PROTOCOL.md, warp strokes): volume for elastic_grab,
// direction (any length, not zero) for twist, scale and pinch.
struct WarpBeginParams {
  WarpTool tool = WarpTool::Grab;
  double volume = *kParamVolume.defaultValue;
  std::optional<Vec3> direction;
};
// The parameters of a paint or mask stroke (since 1.7; PROTOCOL.md, paint and mask strokes):
// the colour for paint, erase for mask, hardness for both.
struct PaintBeginParams {
  PaintTool tool = PaintTool::Color;
  SrgbColor color;
  double hardness = *kParamHardness.defaultValue;
  bool erase = false;
};
struct StrokeBeginParams {
  BrushTool tool = BrushTool::AddBlob;  // unless warp or paint is set
  std::optional<WarpBeginParams> warp;  // a warp tool: tool is then unused; no symmetry, no accumulate
  std::optional<PaintBeginParams> paint;  // a paint tool: tool is then unused
  double radius = *kParamRadius.defaultValue, strength = *kParamStrength.defaultValue;
  bool mirrorX = false, mirrorY = false, mirrorZ = false;
  bool accumulate = false;  // every stroke.dabs adds (build-up), see PROTOCOL.md
  // vu (since 1.4): the stroke moves the surface by this at most, however often it passes;
  // kParamHeight, for the tools that take it (kTools), not with accumulate
  std::optional<double> height;
};
struct DabParam {
  std::variant<Vec3, RayParam> at;
  double pressure = 1;  // (0, 1]
};
struct StrokeDabsParams {
  std::uint64_t stroke = 0;
  std::vector<DabParam> dabs;
};
struct ViewSetParams {
  ViewMode mode = ViewMode::Splats;
  std::optional<Camera> camera;  // with width and height set; present exactly for frames
  Shading shading = Shading::Lit;  // of pushed frames
  double minVu = 1;                // thickness shading: red below this many vu
};
enum class ImageKind { Jpeg, Png };
// mesh.export: the file format and the optional decimation (server/engine/decimate.hpp).
struct MeshExportParams {
  std::string format;                       // "stl", "obj", "ply" or "glb"
  std::optional<std::uint32_t> maxTriangles;  // >= 1
  std::optional<double> maxError;             // vu, > 0 and at most 1e6
};

struct RenderFrameParams {
  Camera camera;  // with width and height
  ImageKind format = ImageKind::Jpeg;
  int quality = 90;
  Shading shading = Shading::Lit;
  double minVu = 1;  // thickness shading: red below this many vu
  std::optional<std::uint64_t> revision;  // an earlier revision still in history (since 1.2)
};

// --- presence (since 1.2; PROTOCOL.md, "Presence") -----------------------------------------------
// What a client reports of itself: its brush under the pointer and its camera. Each presence
// replaces the sender's whole previous one (a part left out is none).
struct BrushPresence {
  std::string tool;  // a tool name (kTools)
  double radius = *kParamRadius.defaultValue;  // kParamRadius's range, vu
  Vec3 point;   // within +-kMaxCoordinate vu
  Vec3 normal;  // unit length (the decoder normalizes any finite, non-zero vector)
  bool active = false;  // sculpting now (a stroke is open)
  std::optional<SrgbColor> color;  // the paint colour (since 1.7): others draw the ring in it
};
struct PresenceParams {
  std::optional<BrushPresence> brush;
  std::optional<Camera> camera;  // eye, target, up, fov as in view.set (width, height unused)
};
inline constexpr std::size_t kMaxNameChars = 64;  // code points of a display name

// The display name of session.create/join: trimmed of white space at both ends, 1 to
// kMaxNameChars code points with at least one visible character, no control characters (C0,
// DEL, C1), line or paragraph separators, bidirectional embedding/override/isolate controls, or
// invisible characters (zero-width, direction marks, Hangul fillers; rpc.cpp, isInvisible).
// OpError field "name".
std::string nameValue(const nlohmann::json& v);
PresenceParams parsePresenceParams(const nlohmann::json& params);
// The canonical JSON of a presence's parts, as the server forwards them.
nlohmann::json brushJson(const BrushPresence& b);
nlohmann::json cameraJson(const Camera& c);

// Session ids and tokens as PROTOCOL.md spells them.
bool isSessionId(std::string_view s);  // [A-Za-z0-9_-]{1,64}
bool isToken(std::string_view s);      // [A-Za-z0-9_-]{1,128}

// Each throws OpError (-32602) naming the params key. Limits that are the server's are
// checked by the caller, except maxDabs, which is checked before the dabs are read (-32004).
CreateParams parseCreateParams(const nlohmann::json& params);
JoinParams parseJoinParams(const nlohmann::json& params);
ToolApplyParams parseToolApplyParams(const nlohmann::json& params);
StrokeBeginParams parseStrokeBeginParams(const nlohmann::json& params);
StrokeDabsParams parseStrokeDabsParams(const nlohmann::json& params, std::size_t maxDabs);
std::uint64_t parseStrokeEndParams(const nlohmann::json& params);
MorphOp parseMorphParams(const nlohmann::json& params);
// maxSide: the server's max_frame_side (-32004 above it).
ViewSetParams parseViewSetParams(const nlohmann::json& params, int maxSide);
RenderFrameParams parseRenderFrameParams(const nlohmann::json& params, int maxSide);
MeshExportParams parseMeshExportParams(const nlohmann::json& params);
// analysis.thickness: min_vu (> 0, at most 1e4) and max_places (1..1000, default 64).
struct ThicknessParams {
  double minVu = 0;
  std::uint32_t maxPlaces = 64;
};
ThicknessParams parseThicknessParams(const nlohmann::json& params);
// volume.save / volume.load: the file's format (since 1.3; absent: mzv). Whether this server
// reads and writes "vdb" is the server's to check (limits.volume_formats).
enum class VolumeFormat { Mzv, Vdb };
std::string_view volumeFormatName(VolumeFormat f);
VolumeFormat parseVolumeSaveParams(const nlohmann::json& params);
struct VolumeLoadParams {
  std::uint64_t bytes = 0;  // the upload's payload length, 52 .. maxBytes
  VolumeFormat format = VolumeFormat::Mzv;
};
VolumeLoadParams parseVolumeLoadParams(const nlohmann::json& params, std::uint64_t maxBytes);
// history.undo / history.redo: whose step moves (since 1.2).
enum class HistoryScope { Session, Mine };
HistoryScope parseHistoryParams(const nlohmann::json& params, Method m);
// session.fork: the revision to start from (absent: the current one).
std::optional<std::uint64_t> parseForkParams(const nlohmann::json& params);
// history.list (paged since 2026-11-29): the steps listed after the step named `before` (absent: from
// the newest), at most `limit` of them (1..kMaxHistoryListLimit, default kHistoryListLimit).
inline constexpr std::size_t kHistoryListLimit = 100, kMaxHistoryListLimit = 1000;
struct HistoryListParams {
  std::optional<std::uint64_t> before;
  std::size_t limit = kHistoryListLimit;
};
HistoryListParams parseHistoryListParams(const nlohmann::json& params);
// Methods without params: refuses any key.
void parseNoParams(const nlohmann::json& params, Method m);

// --- what the server sends -------------------------------------------------------------------
std::string resultText(const nlohmann::json& id, const nlohmann::json& result);
// The same response around a result's text (JSON of an object, as its dump writes it).
std::string resultTextOfJson(const nlohmann::json& id, std::string_view result);
// A stroke.dabs result ({"applied", "revision", "roi"} and, for a stroke with a plane, "plane":
// PROTOCOL.md) as the dump of its object: the text every stroke message is answered with,
// written directly. plane: its object (service planeJson), null for none.
std::string strokeDabsResultJson(std::uint64_t revision, std::uint64_t applied, const Box& roi,
                                 const nlohmann::json& plane);
std::string errorText(const nlohmann::json& id, RpcCode code, const std::string& message,
                      const nlohmann::json& data = nullptr);
std::string notificationText(std::string_view method, const nlohmann::json& params);
// The session.changed notification (PROTOCOL.md) that every edit sends each client of its
// session: the bytes of notificationText of its params object, written directly. roi: null
// when empty, as boxJson.
std::string sessionChangedText(std::uint64_t revision, int by, std::string_view cause, const Box& roi,
                               std::string_view digest, bool canUndo, bool canRedo);

// {"lo":[x,y,z],"hi":[x,y,z]}, or null for an empty box. strokeDabsResultJson and
// sessionChangedText write the same shape directly; the [rpc] tests hold them to it.
nlohmann::json boxJson(const Box& b);
nlohmann::json vec3Json(Vec3 v);
// [r, g, b], as the wire writes a colour.
nlohmann::json colorJson(SrgbColor c);

}  // namespace marzipan::protocol
