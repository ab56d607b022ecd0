// The methods of protocol/PROTOCOL.md, one handler each, found through one table
// (methods.cpp): method -> access rule and handler, like a tool registry.
//
// A handler runs on the connection's pump with the request's params still unread. It parses
// them (protocol/cpp/rpc.hpp; OpError becomes -32602), checks what needs no session state, and
// hands its work to HubCore::onStrand (changes, and reads of the live session) or
// HubCore::offStrand (long reads of a snapshot). Whatever it throws before that is answered by
// the dispatcher; once it has handed work over, that work answers and calls HubCore::finish, so
// a handler must either throw or hand over exactly once (or call finish itself).
//
// Adding a method: its name, params decoder and result in protocol/ (PROTOCOL.md, schema,
// rpc.hpp/.cpp, the JS and Python clients), then one handler function declared below and
// defined in the file of its area, and one row in the table in methods.cpp.
#pragma once

#include <span>

#include "protocol/cpp/rpc.hpp"
#include "service/hub/request.hpp"

namespace marzipan::service {

struct HubCore;

using Handler = void (*)(HubCore& hub, const Call& call);

struct MethodEntry {
  protocol::Method method;
  Access access;
  Handler handle;
  // The handler may take long before it hands its work over (it creates or loads a session;
  // volume.load's upload follows on the workers anyway): it runs on the workers. The others only parse their params and hand
  // over (or answer at once), on whichever thread took the message, the network's included
  // (HubCore::PumpOn).
  bool slow = false;
};

// Every method's row, in protocol::Method order.
std::span<const MethodEntry> methodTable();
// The row of m, or null when the hub does not serve it.
const MethodEntry* findMethod(protocol::Method m);

// methods_session.cpp: joining, leaving and describing sessions.
void sessionCreate(HubCore&, const Call&);
void sessionJoin(HubCore&, const Call&);
void sessionLeave(HubCore&, const Call&);
void sessionStats(HubCore&, const Call&);
void sessionFork(HubCore&, const Call&);
void opCancel(HubCore&, const Call&);

// methods_edit.cpp: changes to the volume and its history.
// The author a client's steps are recorded with (service/history.hpp): its client id in the
// session, as text. On the session's strand.
StepAuthor authorOf(const HubClient& c);
// A step as history.list and history.undo/redo give it (PROTOCOL.md).
nlohmann::json stepJson(const StepInfo& step);
void toolApply(HubCore&, const Call&);
void volumeMorph(HubCore&, const Call&);
// mask.clear, mask.invert, mask.fill: {"op":"mask","action":...} as one step (MaskOp).
void maskMethod(HubCore&, const Call&);
void strokeBegin(HubCore&, const Call&);
void strokeDabs(HubCore&, const Call&);
void strokeEnd(HubCore&, const Call&);
void historyUndo(HubCore&, const Call&);
void historyRedo(HubCore&, const Call&);
void historyList(HubCore&, const Call&);

// methods_view.cpp: what a client sees.
void viewSet(HubCore&, const Call&);
void renderFrame(HubCore&, const Call&);
void splatsGet(HubCore&, const Call&);

// methods_presence.cpp: what a client tells the others of itself (brush, camera).
void presence(HubCore&, const Call&);

// methods_files.cpp: files out (mesh, volume), files in (volume.load and its upload), analysis.
void meshExport(HubCore&, const Call&);
void volumeSave(HubCore&, const Call&);
// The volume.save / volume.load formats of this build, for limits.volume_formats: ["mzv"], or
// ["mzv", "vdb"] with OpenVDB.
nlohmann::json volumeFormatsJson();
void volumeLoad(HubCore&, const Call&);
void analysisThickness(HubCore&, const Call&);
// The kind-9 frame that follows a volume.load (c->load holds what it announced).
void volumeUpload(HubCore&, const std::shared_ptr<HubClient>& c, Bytes bytes);

}  // namespace marzipan::service
