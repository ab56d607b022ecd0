// Handlers of mesh.export, volume.save, volume.load (with its upload) and analysis.thickness
// (service/hub/methods.hpp): whole-volume files out and in, and the thickness analysis. The
// outputs are sized from the band before any work (max_output_bytes). Volume files are .mzv,
// and .vdb (OpenVDB level sets) in a build with OpenVDB, read and written in memory: the server
// writes no temporary file for a client.
#include "engine/brick.hpp"
#include "engine/decimate.hpp"
#include "engine/marching_cubes.hpp"
#include "engine/mesh_io.hpp"
#include "engine/thickness.hpp"
#include "engine/volume_file.hpp"
#ifdef MARZIPAN_HAS_OPENVDB
#include <istream>
#include <sstream>
#include <streambuf>

#include "engine/errors.hpp"
#include "engine/openvdb/vdb_io.hpp"
#endif
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"
#include "service/journal_records.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;

namespace {

// Grid edges the surface crosses (a sign change between two voxels of one brick; those across
// brick borders are left out, a few percent). Marching cubes makes one vertex per crossed edge
// and about two triangles per vertex, so this sizes a mesh before it is built.
std::size_t crossedEdges(const Volume& vol) {
  constexpr int kLast = Bricks::kSide - 1;
  constexpr int kStepY = Bricks::index(0, 1, 0), kStepZ = Bricks::index(0, 0, 1);
  std::size_t edges = 0;
  vol.forEachPresentBrick([&](Int3, const Brick& b) {
    for (int i = 0; i < Bricks::kVoxels; ++i) {
      const Int3 l = Bricks::local(i);
      const bool in = b.v[i] < 0;
      if (l.x < kLast && in != (b.v[i + 1] < 0)) ++edges;
      if (l.y < kLast && in != (b.v[i + kStepY] < 0)) ++edges;
      if (l.z < kLast && in != (b.v[i + kStepZ] < 0)) ++edges;
    }
  });
  return edges;
}

// Bytes of a mesh file per crossed edge (one vertex, two triangles): STL 2 x 50; OBJ a "v"
// line and two "f" lines, PLY a vertex with its normal and two faces (140 and 55, measured on
// the 96^3 pig 2026-11-24; tests/service/test_hub.cpp holds each within 0.8-1.3 of the file);
// GLB a position and normal (24 bytes) and two triangles of 32-bit indices (24): 48. A vertex's
// colour (marching_cubes.hpp, carriesColor) adds its bytes: OBJ " 0.8667 0.7098 0.6078" (21),
// PLY three uchar, GLB three floats.
std::size_t meshBytesPerEdge(const std::string& format, bool colored) {
  const std::size_t plain = format == "stl" ? 100 : format == "obj" ? 140 : format == "glb" ? 48 : 55;
  return plain + (!colored || format == "stl" ? 0 : format == "obj" ? 21 : format == "glb" ? 12 : 3);
}

protocol::FrameKind meshFrameKind(const std::string& format) {
  return format == "stl"   ? protocol::FrameKind::MeshStl
         : format == "obj" ? protocol::FrameKind::MeshObj
         : format == "glb" ? protocol::FrameKind::MeshGlb
                           : protocol::FrameKind::MeshPly;
}

#ifdef MARZIPAN_HAS_OPENVDB
constexpr bool kWithOpenVdb = true;
#else
constexpr bool kWithOpenVdb = false;
#endif

// A format this build cannot read or write is an invalid params value, checked before anything
// else happens (the upload is then never expected).
void requireVolumeFormat(protocol::VolumeFormat f) {
  if (f == protocol::VolumeFormat::Vdb && !kWithOpenVdb)
    throw RpcException(RpcCode::InvalidParams,
                       "\"format\" \"vdb\" is not available: this server was built without OpenVDB (its "
                       "limits.volume_formats lists what it reads and writes)",
                       {{"field", "format"}});
}

Bytes volumeFileBytes(const Volume& vol, protocol::VolumeFormat f) {
#ifdef MARZIPAN_HAS_OPENVDB
  if (f == protocol::VolumeFormat::Vdb) {
    std::ostringstream out(std::ios::binary);
    saveVdb(vol, out);
    const std::string s = std::move(out).str();
    return Bytes(s.begin(), s.end());
  }
#endif
  (void)f;
  return saveVolume(vol);
}

// The refusal of a loaded volume over max_volume_bytes; `held` is unknown when the read stopped
// once past it.
RpcException overMaxVolume(std::size_t max, std::optional<std::size_t> held) {
  json data{{"limit", "max_volume_bytes"}, {"max", max}, {"field", "file"}};
  if (held) data["value"] = *held;
  return RpcException(RpcCode::LimitExceeded,
                      "the file's volume holds " + (held ? std::to_string(*held) : "more than " + std::to_string(max)) +
                          " bytes of bricks, over max_volume_bytes " + std::to_string(max),
                      data);
}

// A .vdb upload holds distances by index: it takes the session's grid size and band, and its
// read stops once its bricks pass maxBytes (a .mzv's bricks are bounded by its own bytes).
Volume volumeFromFile(std::span<const std::uint8_t> file, protocol::VolumeFormat f, Int3 dims, float band,
                      std::size_t maxBytes) {
#ifdef MARZIPAN_HAS_OPENVDB
  if (f == protocol::VolumeFormat::Vdb) {
    try {
      return loadVdb(file, dims, band, maxBytes);
    } catch (const EngineError& e) {
      if (e.kind() == ErrorKind::TooLarge) throw overMaxVolume(maxBytes, std::nullopt);
      throw;
    }
  }
#endif
  (void)f, (void)dims, (void)band, (void)maxBytes;
  return ::marzipan::loadVolume(file);
}

// An upload's file, read where it lies in the frame that brought it (after the frame's header);
// a .vdb's is replaced by the .mzv the journal keeps.
struct UploadFile {
  Bytes bytes;
  std::size_t from = 0;
  std::span<const std::uint8_t> file() const { return std::span(bytes).subspan(from); }
};

}  // namespace

nlohmann::json volumeFormatsJson() { return kWithOpenVdb ? json{"mzv", "vdb"} : json{"mzv"}; }

void meshExport(HubCore& hub, const Call& call) {
  const protocol::MeshExportParams p = protocol::parseMeshExportParams(call.req.params);
  hub.offStrand(call, [self = hub.shared_from_this(), p, frameId = call.req.frameId](const Volume& vol,
                                                                                      std::uint64_t revision, Reply& r) {
    const std::string& format = p.format;
    const std::size_t estimate = crossedEdges(vol) * meshBytesPerEdge(format, carriesColor(vol));
    const std::size_t max = self->limits().maxOutputBytes;
    if (estimate > max)
      throw RpcException(RpcCode::LimitExceeded,
                         "the mesh file would be about " + std::to_string(estimate) + " bytes, over max_output_bytes " +
                             std::to_string(max),
                         {{"limit", "max_output_bytes"}, {"value", estimate}, {"max", max}});
    Mesh mesh = extractMesh(vol, self->pool);
    std::optional<DecimateResult> decimated;
    if (p.maxTriangles || p.maxError) {
      decimated = decimateMesh(mesh, vol, {p.maxTriangles, p.maxError}, self->pool);
      mesh = std::move(decimated->mesh);
    }
    const Bytes file = exportMesh(mesh, *meshFormatFromName(format));
    if (file.size() > protocol::kMaxFramePayload)
      throw RpcException(RpcCode::LimitExceeded, "the mesh file is larger than one frame can carry (4 GiB)",
                         {{"limit", "frame_payload"}, {"max", protocol::kMaxFramePayload}});
    r.frame = makeFrame(meshFrameKind(format), frameId, revision, file);
    r.result = {{"revision", revision}, {"format", format}, {"vertices", mesh.vertexCount()},
                {"triangles", mesh.triangleCount()}, {"bytes", file.size()}};
    if (decimated) {
      r.result["source_triangles"] = decimated->sourceTriangles;
      r.result["max_error"] = decimated->maxError;
    }
  });
}

void volumeSave(HubCore& hub, const Call& call) {
  const protocol::VolumeFormat format = protocol::parseVolumeSaveParams(call.req.params);
  requireVolumeFormat(format);
  hub.offStrand(call, [format, frameId = call.req.frameId](const Volume& vol, std::uint64_t revision, Reply& r) {
    const Bytes file = volumeFileBytes(vol, format);
    if (file.size() > protocol::kMaxFramePayload)
      throw RpcException(RpcCode::LimitExceeded, "the volume file is larger than one frame can carry (4 GiB)",
                         {{"limit", "frame_payload"}, {"max", protocol::kMaxFramePayload}});
    const bool vdb = format == protocol::VolumeFormat::Vdb;
    r.frame = makeFrame(vdb ? protocol::FrameKind::VolumeVdb : protocol::FrameKind::VolumeFile, frameId, revision, file);
    r.result = {{"revision", revision}, {"digest", digestHex(vol)}, {"bytes", file.size()},
                {"format", protocol::volumeFormatName(format)}};
  });
}

void analysisThickness(HubCore& hub, const Call& call) {
  const protocol::ThicknessParams p = protocol::parseThicknessParams(call.req.params);
  hub.offStrand(call, [self = hub.shared_from_this(), p](const Volume& vol, std::uint64_t revision, Reply& r) {
    const ThicknessReport t = analyzeThickness(vol, p.minVu, p.maxPlaces, 4.0, self->pool);
    json places = json::array();
    for (const ThinPlace& q : t.places)
      places.push_back(
          {{"point", protocol::vec3Json(q.point)}, {"normal", protocol::vec3Json(q.normal)}, {"thickness", q.thickness}});
    r.result = {{"revision", revision}, {"min_vu", p.minVu}, {"points", t.points}, {"below", t.below},
                {"thinnest", t.points ? json(t.thinnest) : json(nullptr)}, {"places", places}};
  });
}

// The request only announces the upload: the connection's next message must be it. The edit
// right is checked on the strand (where it lives); a view client's upload is then dropped as
// unanswered.
void volumeLoad(HubCore& hub, const Call& call) {
  const protocol::VolumeLoadParams p =
      protocol::parseVolumeLoadParams(call.req.params, hub.limits().maxBinaryBytes - protocol::kFrameHeaderBytes);
  requireVolumeFormat(p.format);
  const std::size_t maxVdb = hub.limits().maxVdbBytes;
  if (p.format == protocol::VolumeFormat::Vdb && p.bytes > maxVdb)
    throw RpcException(RpcCode::LimitExceeded,
                       "a .vdb upload of " + std::to_string(p.bytes) + " bytes is over max_vdb_bytes " +
                           std::to_string(maxVdb) + " (reading a .vdb takes many times its size)",
                       {{"limit", "max_vdb_bytes"}, {"value", p.bytes}, {"max", maxVdb}, {"field", "bytes"}});
  auto s = call.client->session;
  s->strand->post([self = hub.shared_from_this(), c = call.client, id = *call.req.id, frameId = call.req.frameId, p,
                   arrived = call.arrived, access = call.access] {
    try {
      HubCore::checkAccess(*c, access);
      c->load = HubClient::PendingLoad{id, frameId, p.bytes, arrived, p.format};
    } catch (...) {
      self->sendError(*c, id, false, failureOf(std::current_exception(), self->options.events.log));
    }
    self->finish(c);
  });
}

void volumeUpload(HubCore& hub, const std::shared_ptr<HubClient>& c, Bytes bytes) {
  const HubLimits& l = hub.limits();
  const auto decoded = protocol::decodeFrameHeader(bytes, l.maxBinaryBytes);
  if (!c->load || !decoded || decoded.frame->header.kind != protocol::FrameKind::VolumeUpload ||
      decoded.frame->header.requestId != c->load->frameId) {
    // An upload that answers no pending volume.load is dropped; a pending load whose next
    // message is another frame fails.
    if (c->load) {
      hub.sendError(*c, c->load->id, false, {RpcCode::UploadMissing, "volume.load was not followed by its upload", nullptr});
      c->load.reset();
    }
    return hub.finish(c);
  }
  const HubClient::PendingLoad load = *c->load;
  c->load.reset();
  const std::uint64_t got = decoded.frame->header.payloadLength;
  if (got != load.bytes) {
    hub.sendError(*c, load.id, false,
                  {RpcCode::UploadMissing,
                   "the upload holds " + std::to_string(got) + " bytes, volume.load announced " + std::to_string(load.bytes),
                   nullptr});
    return hub.finish(c);
  }
  auto upload = std::make_shared<UploadFile>(UploadFile{std::move(bytes), protocol::kFrameHeaderBytes});
  // The edit right was checked when the volume.load was accepted.
  hub.onStrand(c, c->session, load.id, load.arrived, true, Access::Member, [self = hub.shared_from_this(), c, upload,
                                                                               format = load.format](LiveSession& s,
                                                                                                     Reply& r) {
    const std::size_t maxVolume = self->limits().maxVolumeBytes;
    Volume vol =
        volumeFromFile(upload->file(), format, s.session->volume().dims(), s.session->volume().band(), maxVolume);
    if (vol.memoryBytes() > maxVolume) throw overMaxVolume(maxVolume, vol.memoryBytes());
    const Int3 d = s.session->volume().dims();
    if (vol.dims() != d)
      throw RpcException(RpcCode::EngineRefused,
                         "the file's grid is " + std::to_string(vol.dims().x) + "x" + std::to_string(vol.dims().y) + "x" +
                             std::to_string(vol.dims().z) + ", the session's " + std::to_string(d.x) + "x" +
                             std::to_string(d.y) + "x" + std::to_string(d.z),
                         {{"field", "file"}});
    // Another band width would be another grid: the load could not be one undoable step.
    if (vol.band() != s.session->volume().band())
      throw RpcException(RpcCode::EngineRefused,
                         "the file's band half-width is " + std::to_string(vol.band()) + " vu, the session's " +
                             std::to_string(s.session->volume().band()) + " vu; save it with the session's band",
                         {{"field", "file"}});
    // The journal keeps every load as a .mzv (a server without OpenVDB replays it too).
    if (format == protocol::VolumeFormat::Vdb) *upload = UploadFile{saveVolume(vol), 0};
    const StepAuthor by = authorOf(*c);
    ApplyResult a = s.session->load(std::move(vol), by);
    a.fullRefresh = true;
    const std::optional<StepInfo> step = s.session->newestStep();
    r.record = [self, &s, upload, rev = a.revision, by, t = step ? step->timeMs : 0] {
      json rec{{"r", rev}, {"load", self->store->persistent() ? self->store->saveUpload(s.id, rev, upload->file()) : std::string()}};
      stampRecord(rec, by, t);
      return rec;
    };
    r.result = {{"revision", a.revision}, {"digest", digestText(s.session->digest())}, {"roi", protocol::boxJson(a.roi)},
                {"can_undo", s.session->canUndo()}, {"can_redo", s.session->canRedo()}};
    r.after = [self, &s, c, a] {
      // A snapshot now lets the next rotation remove this upload's file: without it every
      // load-R.mzv (up to max_binary_bytes each) stayed until snapshot_every records passed.
      if (s.journal) {
        try {
          self->durability.rotate(s);
        } catch (const std::exception& e) {
          self->log("session " + s.id + ": snapshot after a load failed (" + e.what() + "); the journal goes on");
        }
      }
      self->broadcast.changed(s, *c, "load", a.roi, a.bricks, true);
    };
  });
}

}  // namespace marzipan::service
