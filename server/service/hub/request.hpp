// A request as its handler sees it (Call), who may make it (Access), and what its work on the
// session hands back to be sent (Reply).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "protocol/cpp/rpc.hpp"
#include "service/hub/connection.hpp"

namespace marzipan::service {

// Who may call a method (service/hub/methods.cpp, the table). The dispatcher refuses a method
// needing a session with -32009 before its params are read; edit rights are checked on the
// session's strand (where a client's rights live) after the params, so that a malformed request
// says what is wrong: -32007 for a view client.
enum class Access {
  Anyone,   // also outside a session: session.create, session.join, op.cancel
  Member,   // a client of a session, read-only ones included
  Editor,   // a client of a session that joined with the edit token
};

// Valid while the handler runs: work it posts captures copies (the client's shared_ptr, the id).
struct Call {
  const std::shared_ptr<HubClient>& client;
  const protocol::Request& req;
  Clock::time_point arrived;
  Access access;
};

struct Reply {
  SharedBytes frame;  // a binary answer, sent before the result
  nlohmann::json result;
  // The result's text, when written directly (stroke.dabs): then `result` is not read.
  std::string resultJson;
  std::function<void()> after;  // on the strand, after the response went out
  // Released once the work is over, answered or failed (offStrand: on the worker, after the
  // response or the error went out).
  std::shared_ptr<void> hold;
  // The journal record(s) of a change (an object or an array of them), written before the
  // response; may write files of its own (an upload).
  std::function<nlohmann::json()> record;
  // Later messages of the same connection that this work carried out too (a stroke's queued
  // stroke.dabs, applied with this one as one application): each is answered after this one,
  // in order, and counts as an edit of its own for the latency figures.
  struct Merged {
    std::optional<nlohmann::json> id;  // absent: a notification, not answered
    std::string resultJson;  // the result's text
    Clock::time_point arrived;
  };
  std::vector<Merged> merged;
};

}  // namespace marzipan::service
