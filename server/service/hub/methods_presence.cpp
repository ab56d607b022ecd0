// Handler of presence (service/hub/methods.hpp): a client's brush and camera, forwarded to the
// session's other clients by the PresenceRelay (service/hub/presence_relay.hpp). Handled on the
// pump, never posted to the strand: a presence never waits behind edits (after an edit, the pump
// that takes it runs inside that edit's strand task, for the microseconds of its hand-over).
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"

namespace marzipan::service {

void presence(HubCore& hub, const Call& call) {
  const protocol::PresenceParams p = protocol::parsePresenceParams(call.req.params);
  hub.presence.update(call.client->session, *call.client, p);
  hub.sendResult(*call.client, call.req.id, nlohmann::json::object());
  hub.finish(call.client);
}

}  // namespace marzipan::service
