// Handlers of the methods that change a session's volume or history: tool.apply, volume.morph,
// stroke.begin/dabs/end, history.undo/redo, and the read-only history.list (service/hub/methods.hpp).
// Each runs on the session's strand; a change is journaled before its response (Reply::record),
// and its clients hear of it after (Broadcaster::changed). The table gives the changes
// Access::Editor: a view client's request is refused (-32007) on the strand, after its params
// were checked.
#include <algorithm>

#include "engine/thread_pool.hpp"
#include "service/apply_op.hpp"
#include "service/hub/core.hpp"
#include "service/hub/methods.hpp"
#include "service/journal_records.hpp"

namespace marzipan::service {

using nlohmann::json;
using protocol::RpcCode;
using protocol::RpcException;

namespace {

// The time of the newest step, just made or grown by the change being recorded (0: none, a
// change that cleared the history).
std::int64_t stepTime(const Session& s) {
  const std::optional<StepInfo> step = s.newestStep();
  return step ? step->timeMs : 0;
}

RpcException notOpenStroke(std::uint64_t stroke) {
  return RpcException(RpcCode::NoSuchStroke, "stroke " + std::to_string(stroke) + " is not this connection's open stroke",
                      {{"field", "stroke"}});
}

// A step's author as the wire names it: the client id (an integer), or null for a step without
// one (recorded before authors were).
json clientOf(const StepAuthor& a) {
  if (a.id.empty() || a.id.size() > 9 || a.id.find_first_not_of("0123456789") != std::string::npos) return nullptr;
  return std::stoi(a.id);
}

std::string describeAuthor(const StepAuthor& a) {
  std::string who = a.id.empty() ? std::string("an unknown client") : "client " + a.id;
  if (!a.name.empty()) who += " (" + a.name + ")";
  return who;
}

// scope "mine" refused: the step in the way, named by its author and revision.
RpcException undoConflict(const HistoryResult& h, bool undo) {
  const StepInfo& mine = *h.step;
  const StepInfo& other = *h.conflict;
  const std::string message =
      undo ? describeAuthor(other.author) + "'s step at revision " + std::to_string(other.revision) + " (" + other.tool +
                 ") changed bricks of your step at revision " + std::to_string(mine.revision) +
                 " after it: it cannot be undone alone"
           : describeAuthor(other.author) + "'s undone step at revision " + std::to_string(other.revision) + " (" +
                 other.tool + ") holds bricks of your undone step at revision " + std::to_string(mine.revision) +
                 ": it would have to be redone first";
  return RpcException(RpcCode::UndoConflict, message,
                      {{"client", clientOf(other.author)}, {"revision", other.revision}, {"step", mine.revision}});
}

void historyStep(HubCore& hub, const Call& call, bool undo) {
  const protocol::HistoryScope scope = protocol::parseHistoryParams(call.req.params, call.req.method);
  hub.onStrand(call, true, [self = hub.shared_from_this(), c = call.client, undo, scope](LiveSession& s, Reply& r) {
    const bool mine = scope == protocol::HistoryScope::Mine;
    const std::string me = authorOf(*c).id;
    const HistoryResult h = !mine ? (undo ? s.session->undo() : s.session->redo())
                                  : (undo ? s.session->undoMine(me) : s.session->redoMine(me));
    if (h.conflict) throw undoConflict(h, undo);
    if (!h.changed)
      throw RpcException(RpcCode::NothingToUndo, mine ? (undo ? "you have no step to undo" : "you have no undone step to redo")
                                                      : (undo ? "nothing to undo" : "nothing to redo"));
    r.result = {{"revision", h.revision}, {"can_undo", h.canUndo}, {"can_redo", h.canRedo}};
    if (h.step) r.result["step"] = stepJson(*h.step);
    r.record = [self, &s, undo, mine, h] {
      const std::string step = self->store->persistent() ? self->store->saveStep(s.id, h.revision, h.restored) : std::string();
      if (mine) return authorMoveRecord(undo, h.revision, step, *h.step);
      return json{{"r", h.revision}, {undo ? "undo" : "redo", step}};
    };
    r.after = [self, &s, c, h, undo] { self->broadcast.changed(s, *c, undo ? "undo" : "redo", h.roi, h.bricks, false); };
  });
}

// One stroke.dabs message taken from the connection's queue behind the one being handled.
struct DabsMessage {
  std::optional<json> id;
  protocol::StrokeDabsParams params;
  Incoming raw;  // as it was queued, to give back
};

std::vector<Dab> toDabs(const std::vector<protocol::DabParam>& params) {
  std::vector<Dab> dabs;
  dabs.reserve(params.size());
  for (const protocol::DabParam& d : params) {
    Dab dab;
    if (const auto* center = std::get_if<Vec3>(&d.at)) dab.at = *center;
    else {
      const auto& ray = std::get<protocol::RayParam>(d.at);
      dab.at = Ray{ray.origin, ray.direction};
    }
    dab.pressure = d.pressure;
    dabs.push_back(dab);
  }
  return dabs;
}

// The stroke.dabs messages of stroke first.stroke queued right behind `first` on c's connection,
// in order, taken out of its queue while all of them together stay within what one message may
// be (max_dabs dabs, max_op_voxels): the first other message, or one of another stroke, a
// malformed one or one over the bounds, stays queued and ends the run. Their order among the
// connection's messages is kept; other connections' messages waiting on the session's strand
// were not answered yet either, so they may follow, as if these had arrived before them.
std::vector<DabsMessage> takeFollowers(HubCore& hub, HubClient& c, const protocol::StrokeDabsParams& first,
                                       double voxelsPerDab) {
  std::vector<DabsMessage> out;
  if (hub.stopping()) return out;
  std::size_t dabs = first.dabs.size();
  Incoming in;
  while (c.queue.takeText(in)) {
    std::optional<DabsMessage> m;
    const protocol::ParsedRequest parsed = protocol::parseRequest(std::get<std::string>(in.message));
    if (parsed.request && parsed.request->method == protocol::Method::StrokeDabs) {
      try {
        protocol::StrokeDabsParams p = protocol::parseStrokeDabsParams(parsed.request->params, hub.limits().maxDabs);
        const std::size_t total = dabs + p.dabs.size();
        const bool fits = total <= hub.limits().maxDabs && double(total) * voxelsPerDab <= hub.limits().maxOpVoxels;
        if (p.stroke == first.stroke && fits) m = DabsMessage{parsed.request->id, std::move(p), {}};
      } catch (const RpcException&) {
        // Answered with its error in its turn.
      }
    }
    if (!m) {
      c.queue.putBack(std::move(in));
      break;
    }
    dabs += m->params.dabs.size();
    m->raw = std::move(in);
    out.push_back(std::move(*m));
  }
  return out;
}

// The answers and the journal record of one application of stroke.dabs messages (p and the
// messages merged behind it, whose dabs `params` are, in order).
void answerDabs(HubCore& hub, const std::shared_ptr<HubClient>& c, LiveSession& s, Reply& r,
                const protocol::StrokeDabsParams& p, const std::vector<DabsMessage>& merged,
                std::vector<protocol::DabParam> params, const ApplyResult& a) {
  // Every message of the application answers its revision and box; `applied` counts its own dabs.
  auto appliedIn = [&a](std::size_t from, std::size_t count) -> std::size_t {
    if (!a.changed) return 0;
    const auto begin = a.hits.begin() + std::ptrdiff_t(from);
    return std::size_t(std::count_if(begin, begin + std::ptrdiff_t(count), [](const auto& h) { return h.has_value(); }));
  };
  // Every message's result is written as one text. Flatten and contrast (and clay with a
  // height) answer the stroke's plane too, once its first dab fitted it.
  const Box box = a.changed ? a.roi : Box{};
  const json plane = a.plane ? planeJson(*a.plane) : json();
  const auto answer = [&](std::size_t from, std::size_t count) {
    return protocol::strokeDabsResultJson(a.revision, appliedIn(from, count), box, plane);
  };
  r.resultJson = answer(0, p.dabs.size());
  std::size_t from = p.dabs.size();
  for (const DabsMessage& m : merged) {
    if (hub.options.events.request) hub.options.events.request("stroke.dabs");
    r.merged.push_back({m.id, answer(from, m.params.dabs.size()), m.raw.arrived});
    from += m.params.dabs.size();
  }
  // A warp stroke's message that took its anchor is recorded though it changed nothing: the
  // stroke's later messages depend on it.
  if (a.changed || a.anchored) {
    // The stroke's author is in its stroke_begin record; the time is that of a step the dabs
    // started (a step they folded into keeps its own). One record per application: replay
    // applies its dabs as one, as here. Built only when there is a journal to take it.
    r.record = [stroke = p.stroke, hits = a.hits, normals = a.normals, plane = a.plane, params = std::move(params),
                rev = a.revision, t = stepTime(*s.session)] {
      json applied = json::array();
      for (std::size_t i = 0; i < hits.size(); ++i)
        if (hits[i]) {
          json dab{hits[i]->x, hits[i]->y, hits[i]->z, params[i].pressure};
          if (const Vec3 n = normals[i]; n != Vec3{}) dab.insert(dab.end(), {n.x, n.y, n.z});
          applied.push_back(std::move(dab));
        }
      json rec{{"r", rev}, {"stroke", stroke}, {"dabs", std::move(applied)}, {"t", t}};
      if (plane) rec["plane"] = planeJson(*plane);
      return rec;
    };
  }
  if (a.changed)
    r.after = [self = hub.shared_from_this(), &s, c, a] { self->broadcast.changed(s, *c, "stroke", a.roi, a.bricks, a.fullRefresh); };
}

// A warp stroke's stroke.dabs (Session::strokeDabs; PROTOCOL.md, warp strokes): costed before
// any work (warpStrokeCost against max_op_voxels), run on the hub's pool with progress and
// cancellation as a long tool.apply is. An anchored stroke's result depends only on its last
// dab, so the messages of the stroke waiting behind this one are applied with it as one
// application when their work together fits the budget: a slow warp then skips the pointer's
// intermediate places instead of falling behind. A snake hook's every dab is a move: it takes
// its messages one by one.
void warpMessage(HubCore& hub, const std::shared_ptr<HubClient>& c, LiveSession& s, Reply& r,
                 const protocol::StrokeDabsParams& p, const WarpStroke& w, HubCore::RunningOp& running) {
  OpCost cost = *s.session->warpCost(p.stroke, toDabs(p.dabs));
  hub.checkBudget(cost.voxels, "this warp message");
  std::vector<DabsMessage> merged;
  std::vector<protocol::DabParam> params = p.dabs;
  if (!protocol::dabsArePath(w.tool)) {
    merged = takeFollowers(hub, *c, p, 0);
    if (!merged.empty()) {
      std::vector<protocol::DabParam> all = p.dabs;
      for (const DabsMessage& m : merged) all.insert(all.end(), m.params.dabs.begin(), m.params.dabs.end());
      const OpCost together = *s.session->warpCost(p.stroke, toDabs(all));
      if (together.voxels <= hub.limits().maxOpVoxels) {
        cost = together;
        params = std::move(all);
      } else {
        for (auto m = merged.rbegin(); m != merged.rend(); ++m) c->queue.putBack(std::move(m->raw));
        merged.clear();
      }
    }
  }
  running.progress->setTotal(std::max(1.0, cost.passes));
  std::optional<Workers::LongTask> longTask;
  if (cost.voxels > kLongOpVoxels) longTask.emplace(hub.workers);
  const Progress::Scope scope(*running.progress);
  ApplyResult a;
  try {
    a = s.session->strokeDabs(p.stroke, toDabs(params), hub.pool);
  } catch (...) {
    if (merged.empty()) throw;
    // As for a brush's merged messages: each then gets the answer it would have had alone.
    for (auto m = merged.rbegin(); m != merged.rend(); ++m) c->queue.putBack(std::move(m->raw));
    merged.clear();
    params = p.dabs;
    a = s.session->strokeDabs(p.stroke, toDabs(params), hub.pool);
  }
  running.done();
  answerDabs(hub, c, s, r, p, merged, std::move(params), a);
}

}  // namespace

// The step keeps the display name the author had then: a timeline still names who left.
StepAuthor authorOf(const HubClient& c) { return {std::to_string(c.clientId), c.name}; }

json stepJson(const StepInfo& st) {
  json j{{"revision", st.revision},
         {"first_revision", st.firstRevision},
         {"client", clientOf(st.author)},
         {"tool", st.tool},
         {"time_ms", st.timeMs},
         {"region", protocol::boxJson(st.region)},
         {"undone", st.undone}};
  if (!st.author.name.empty()) j["name"] = st.author.name;
  return j;
}

void historyList(HubCore& hub, const Call& call) {
  const protocol::HistoryListParams p = protocol::parseHistoryListParams(call.req.params);
  // One page: a history of tiny steps holds 10^5 of them, whose whole list was ~100 MB of JSON.
  hub.onStrand(call, false, [p](LiveSession& s, Reply& r) {
    const History::Page page = s.session->history().page(p.before, p.limit);
    if (!page.found)
      throw RpcException(RpcCode::InvalidParams,
                         "\"before\" " + std::to_string(*p.before) +
                             " names no step of this session's history (any more): list again from the newest",
                         {{"field", "before"}});
    json steps = json::array();
    for (const StepInfo& st : page.steps) steps.push_back(stepJson(st));
    r.result = {{"revision", s.session->revision()}, {"steps", std::move(steps)}, {"more", page.more}};
  });
}

void toolApply(HubCore& hub, const Call& call) {
  const protocol::ToolApplyParams p = protocol::parseToolApplyParams(call.req.params);
  const auto running = hub.track(call.client, call.req.id);
  hub.onStrand(call, true, [self = hub.shared_from_this(), c = call.client, p, running](LiveSession& s, Reply& r) {
    const OpCost cost = estimateCost(s.session->volume(), p.op);
    self->checkBudget(cost.voxels, "this tool");
    running->progress->setTotal(cost.passes);
    protocol::Op op = p.op;
    std::optional<Vec3> hit;
    if (p.ray) {
      hit = s.session->pick(Ray{p.ray->origin, p.ray->direction});
      if (!hit) {
        r.result = {{"revision", s.session->revision()}, {"roi", nullptr}, {"hit", nullptr}};
        return;
      }
      if (auto* b = std::get_if<protocol::BrushOp>(&op)) b->params.center = *hit;
      if (auto* g = std::get_if<protocol::CsgToolOp>(&op)) g->params.center = *hit;
    }
    const bool brush = std::holds_alternative<protocol::BrushOp>(op);
    std::optional<Workers::LongTask> longTask;
    if (cost.voxels > kLongOpVoxels) longTask.emplace(self->workers);
    const Progress::Scope scope(*running->progress);
    const StepAuthor by = authorOf(*c);
    const ApplyResult a = s.session->apply(op, brush ? ThreadPool::serial() : self->pool, by);
    running->done();
    r.result = {{"revision", a.revision}, {"roi", protocol::boxJson(a.changed ? a.roi : Box{})}};
    if (p.ray) r.result["hit"] = protocol::vec3Json(*hit);
    if (a.changed) {
      r.record = [op, a, by, t = stepTime(*s.session)] {
        json rec{{"r", a.revision}, {"op", protocol::toJson(op)}};
        stampRecord(rec, by, t);
        return rec;
      };
      r.after = [self, &s, c, a] { self->broadcast.changed(s, *c, "tool", a.roi, a.bricks, a.fullRefresh); };
    }
  });
}

namespace {

// A whole-volume step (morphology, a mask operation): costed against the voxel budget before
// any work, a long task when it is large, one undo step and one journal record.
// what: the budget error's words; kind: the session.changed notification's.
void applyWholeVolume(HubCore& hub, const Call& call, const protocol::Op& op, const char* what, const char* kind) {
  const auto running = hub.track(call.client, call.req.id);
  hub.onStrand(call, true, [self = hub.shared_from_this(), c = call.client, op, running, what, kind](LiveSession& s, Reply& r) {
    const OpCost cost = estimateCost(s.session->volume(), op);
    self->checkBudget(cost.voxels, what);
    running->progress->setTotal(cost.passes);
    std::optional<Workers::LongTask> longTask;
    if (cost.voxels > kLongOpVoxels) longTask.emplace(self->workers);
    const Progress::Scope scope(*running->progress);
    const StepAuthor by = authorOf(*c);
    const ApplyResult a = s.session->apply(op, self->pool, by);
    running->done();
    r.result = {{"revision", a.revision}, {"roi", protocol::boxJson(a.changed ? a.roi : Box{})}};
    if (a.changed) {
      r.record = [op, a, by, t = stepTime(*s.session)] {
        json rec{{"r", a.revision}, {"op", protocol::toJson(op)}};
        stampRecord(rec, by, t);
        return rec;
      };
      r.after = [self, &s, c, a, kind] { self->broadcast.changed(s, *c, kind, a.roi, a.bricks, a.fullRefresh); };
    }
  });
}

}  // namespace

void volumeMorph(HubCore& hub, const Call& call) {
  const protocol::Op op = protocol::parseMorphParams(call.req.params);
  applyWholeVolume(hub, call, op, "this morphology", "morph");
}

void maskMethod(HubCore& hub, const Call& call) {
  protocol::parseNoParams(call.req.params, call.req.method);
  applyWholeVolume(hub, call, protocol::MaskOp{protocol::maskActionOf(call.req.method)}, "this mask operation", "mask");
}

void strokeBegin(HubCore& hub, const Call& call) {
  const protocol::StrokeBeginParams p = protocol::parseStrokeBeginParams(call.req.params);
  hub.onStrand(call, false, [c = call.client, p](LiveSession& s, Reply& r) {
    json records = json::array();
    if (c->stroke) {
      try {
        s.session->endStroke(c->stroke);
        records.push_back({{"stroke_end", c->stroke}});
      } catch (const ServiceError&) {
        // The session closed it already (a reload); nothing to end.
      }
      c->stroke = 0;
    }
    Session::StrokeParams params{p.tool, p.radius, p.strength, Symmetry{p.mirrorX, p.mirrorY, p.mirrorZ},
                                 p.accumulate, {}, authorOf(*c), p.height};
    if (p.warp) {
      WarpStroke w;
      w.tool = p.warp->tool;
      w.radius = p.radius;
      w.strength = p.strength;
      w.volume = p.warp->volume;
      w.direction = p.warp->direction;
      params.warp = w;
      c->stroke = s.session->beginWarp(*params.warp, params.by);
    } else if (p.paint) {
      params.paint = paintSettingsOf(p);
      c->stroke = s.session->beginPaint(*params.paint, params.symmetry, params.accumulate, params.by);
    } else {
      c->stroke = s.session->beginStroke(params.tool, params.radius, params.strength, params.symmetry, params.accumulate,
                                         params.by, params.height);
    }
    records.push_back(strokeBeginRecord(c->stroke, params));
    r.record = [records] { return records; };
    r.result = {{"stroke", c->stroke}};
  });
}

void strokeDabs(HubCore& hub, const Call& call) {
  const protocol::StrokeDabsParams p = protocol::parseStrokeDabsParams(call.req.params, hub.limits().maxDabs);
  const auto running = hub.track(call.client, call.req.id);
  hub.onStrand(call, true, [self = hub.shared_from_this(), c = call.client, p, running](LiveSession& s, Reply& r) {
    if (p.stroke != c->stroke) throw notOpenStroke(p.stroke);
    const std::optional<Session::StrokeParams> settings = s.session->strokeSettings(p.stroke);
    if (settings && settings->warp) return warpMessage(*self, c, s, r, p, *settings->warp, *running);
    double voxelsPerDab = 0;
    bool accumulate = false;
    if (const auto& st = settings) {
      const int images = (st->symmetry.x ? 2 : 1) * (st->symmetry.y ? 2 : 1) * (st->symmetry.z ? 2 : 1);
      // A height takes a sub-step per vu (engine applyStroke).
      const double substeps = st->height ? std::ceil(*st->height) : 1;
      voxelsPerDab = strokeDabVoxels(s.session->volume(), st->radius, images, substeps, s.session->strokeMemory(p.stroke));
      accumulate = st->accumulate;
    }
    self->checkBudget(double(p.dabs.size()) * voxelsPerDab, "this message's dabs");
    // A stroke that remembers what it applied moves the surface the same however its dabs are
    // grouped into messages, so the messages of this stroke waiting behind this one on the
    // connection are applied with it as one application (an accumulating stroke's result
    // depends on the grouping: never).
    std::vector<DabsMessage> merged;
    if (!accumulate) merged = takeFollowers(*self, *c, p, voxelsPerDab);
    std::vector<protocol::DabParam> params = p.dabs;
    for (const DabsMessage& m : merged) params.insert(params.end(), m.params.dabs.begin(), m.params.dabs.end());
    std::optional<Workers::LongTask> longTask;
    if (double(params.size()) * voxelsPerDab > kLongOpVoxels) longTask.emplace(self->workers);
    const Progress::Scope scope(*running->progress);
    ApplyResult a;
    try {
      a = s.session->strokeDabs(p.stroke, toDabs(params), ThreadPool::serial());
    } catch (...) {
      if (merged.empty()) throw;
      // Refused or cancelled, the application changed nothing: the messages are handled one by
      // one instead, this one now (which fails with its own error, or applies) and the others
      // in their turn, so that each gets the answer it would have had alone.
      for (auto m = merged.rbegin(); m != merged.rend(); ++m) c->queue.putBack(std::move(m->raw));
      merged.clear();
      params = p.dabs;
      a = s.session->strokeDabs(p.stroke, toDabs(params), ThreadPool::serial());
    }
    running->done();
    answerDabs(*self, c, s, r, p, merged, std::move(params), a);
  });
}

void strokeEnd(HubCore& hub, const Call& call) {
  const std::uint64_t stroke = protocol::parseStrokeEndParams(call.req.params);
  hub.onStrand(call, false, [c = call.client, stroke](LiveSession& s, Reply& r) {
    if (stroke != c->stroke) throw notOpenStroke(stroke);
    try {
      s.session->endStroke(stroke);
    } catch (const ServiceError&) {
      // Closed by a reload of the session: ending it again is what the client asked.
    }
    c->stroke = 0;
    r.record = [stroke] { return json{{"stroke_end", stroke}}; };
    r.result = {{"revision", s.session->revision()}, {"can_undo", s.session->canUndo()}, {"can_redo", s.session->canRedo()}};
  });
}

void historyUndo(HubCore& hub, const Call& call) { historyStep(hub, call, true); }
void historyRedo(HubCore& hub, const Call& call) { historyStep(hub, call, false); }

}  // namespace marzipan::service
