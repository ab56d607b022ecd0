// Journal records made and replayed (see journal_records.hpp).
#include "service/journal_records.hpp"

#include <bit>
#include <cstring>
#include <stdexcept>

#include "engine/volume_file.hpp"
#include "protocol/cpp/little_endian.hpp"
#include "protocol/cpp/ops.hpp"

namespace marzipan::service {

using nlohmann::json;

namespace {

json vec3Json(Vec3 v) { return json::array({v.x, v.y, v.z}); }

Vec3 warpPointOf(const json& j) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error("bad point in a warp stroke's record");
  return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
}

// A warp stroke's record: its settings, and once it has an anchor its state (apply_op.hpp,
// WarpStroke), which replay takes back as it is.
json warpBeginRecord(StrokeId id, const Session::StrokeParams& st) {
  const WarpStroke& w = *st.warp;
  json record{{"stroke_begin", id},
              {"tool", protocol::nameOf(protocol::kWarpToolNames, w.tool)},
              {"radius", w.radius},
              {"strength", w.strength}};
  if (w.tool == protocol::WarpTool::ElasticGrab) record["volume"] = w.volume;
  if (w.direction) record["direction"] = vec3Json(*w.direction);
  if (!st.by.id.empty() || !st.by.name.empty()) record["by"] = {{"id", st.by.id}, {"name", st.by.name}};
  if (w.anchor) {
    json state{{"anchor", vec3Json(*w.anchor)}, {"normal", vec3Json(w.normal)}, {"held", vec3Json(w.heldD)},
               {"held_amount", w.heldAmount}};
    if (w.pointer) state["pointer"] = vec3Json(*w.pointer);
    record["warp"] = std::move(state);
  }
  return record;
}

WarpStroke warpOfRecord(const json& rec, protocol::WarpTool tool) {
  WarpStroke w;
  w.tool = tool;
  w.radius = rec.at("radius").get<double>();
  w.strength = rec.at("strength").get<double>();
  w.volume = rec.value("volume", w.volume);
  if (const auto d = rec.find("direction"); d != rec.end()) w.direction = warpPointOf(*d);
  if (const auto s = rec.find("warp"); s != rec.end()) {
    w.anchor = warpPointOf(s->at("anchor"));
    w.normal = warpPointOf(s->at("normal"));
    w.heldD = warpPointOf(s->at("held"));
    w.heldAmount = s->at("held_amount").get<double>();
    if (const auto p = s->find("pointer"); p != s->end()) w.pointer = warpPointOf(*p);
  }
  return w;
}

// A paint or mask stroke's settings from its stroke_begin record.
PaintSettings paintOfRecord(const json& rec, protocol::PaintTool tool) {
  PaintSettings st;
  st.mode = enginePaintMode(tool);
  if (st.mode == PaintMode::MaskAdd && rec.value("erase", false)) st.mode = PaintMode::MaskErase;
  if (st.mode == PaintMode::Color) {
    const json& c = rec.at("color");
    if (!c.is_array() || c.size() != 3) throw std::runtime_error("bad colour in a paint stroke's record");
    st.color = Rgb8{c[0].get<std::uint8_t>(), c[1].get<std::uint8_t>(), c[2].get<std::uint8_t>()};
  }
  st.radius = rec.at("radius").get<double>();
  st.strength = rec.at("strength").get<double>();
  st.hardness = rec.at("hardness").get<double>();
  return st;
}

}  // namespace

json strokeBeginRecord(StrokeId id, const Session::StrokeParams& st) {
  if (st.warp) return warpBeginRecord(id, st);
  const std::string symmetry =
      std::string(st.symmetry.x ? "x" : "") + (st.symmetry.y ? "y" : "") + (st.symmetry.z ? "z" : "");
  json record{{"stroke_begin", id},
              {"tool", st.paint ? paintToolName(st.paint->mode) : protocol::nameOf(protocol::kBrushToolNames, st.tool)},
              {"radius", st.radius},
              {"strength", st.strength},
              {"symmetry", symmetry}};
  if (st.paint) {
    record["hardness"] = st.paint->hardness;
    if (st.paint->mode == PaintMode::Color) record["color"] = {st.paint->color.r, st.paint->color.g, st.paint->color.b};
    if (st.paint->mode == PaintMode::MaskErase) record["erase"] = true;
  }
  if (st.accumulate) record["accumulate"] = true;
  if (st.height) record["height"] = *st.height;
  if (!st.by.id.empty() || !st.by.name.empty()) record["by"] = {{"id", st.by.id}, {"name", st.by.name}};
  if (!st.memory.empty()) {
    json applied = json::array();
    for (const StrokeDab& d : st.memory) {
      json dab{d.center.x, d.center.y, d.center.z, d.weight};
      if (d.normal != Vec3{}) dab.insert(dab.end(), {d.normal.x, d.normal.y, d.normal.z});
      applied.push_back(std::move(dab));
    }
    record["applied"] = std::move(applied);
  }
  if (st.plane) record["plane"] = planeJson(*st.plane);
  return record;
}

json planeJson(const Plane& plane) {
  return {{"point", protocol::vec3Json(plane.point)}, {"normal", protocol::vec3Json(plane.normal)}};
}

void stampRecord(json& record, const StepAuthor& by, std::int64_t timeMs) {
  if (!by.id.empty() || !by.name.empty()) record["by"] = {{"id", by.id}, {"name", by.name}};
  record["t"] = timeMs;
}

json authorMoveRecord(bool undo, std::uint64_t revision, const std::string& file, const StepInfo& step) {
  return {{"r", revision},
          {undo ? "undo_mine" : "redo_mine", file},
          {"by", {{"id", step.author.id}, {"name", step.author.name}}},
          {"step", {step.firstRevision, step.revision}}};
}

namespace {

Vec3 vec3Of(const json& a) {
  if (!a.is_array() || a.size() != 3) throw std::runtime_error("bad stroke plane");
  return {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
}

// The plane of a record that has one, set on the replayed stroke (before its dabs: the starting
// volume it was fitted on may be gone with a snapshot).
void replayPlane(Session& s, StrokeId id, const json& rec) {
  const auto it = rec.find("plane");
  if (it == rec.end()) return;
  s.setStrokePlane(id, Plane{vec3Of(it->at("point")), vec3Of(it->at("normal"))});
}

StepAuthor authorOf(const json& rec) {
  const auto it = rec.find("by");
  if (it == rec.end()) return {};
  return {it->at("id").get<std::string>(), it->at("name").get<std::string>()};
}

bool sameBricks(const std::vector<std::pair<Int3, BrickRef>>& a, const std::vector<std::pair<Int3, BrickRef>>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const BrickRef &x = a[i].second, &y = b[i].second;
    if (a[i].first != b[i].first || x.uniform() != y.uniform()) return false;
    if (x.uniform() ? x.inside != y.inside : std::memcmp(x.data->v, y.data->v, sizeof(Brick)) != 0) return false;
    if (bool(x.paint) != bool(y.paint) || (x.paint && std::memcmp(x.paint->t, y.paint->t, sizeof(x.paint->t)) != 0))
      return false;
  }
  return true;
}

// Whether the session's history holds the very step a record names (its changes made
// revisions first..last, all replayed since the snapshot) as author's next step to move.
bool historyHolds(const Session& s, const std::string& author, bool undo, std::uint64_t first, std::uint64_t last) {
  const std::vector<StepInfo> steps = s.steps();
  const StepInfo* next = nullptr;
  if (undo) {
    for (const StepInfo& st : steps)
      if (!st.undone && st.author.id == author) next = &st;
  } else {
    for (const StepInfo& st : steps)
      if (st.undone && st.author.id == author) {
        next = &st;
        break;
      }
  }
  return next && next->firstRevision == first && next->revision == last;
}

}  // namespace

std::vector<std::uint8_t> encodeStep(const std::vector<std::pair<Int3, BrickRef>>& bricks) {
  std::vector<std::uint8_t> b{'M', 'Z', 'B', 'K'};
  const auto put = [&b](std::uint32_t v) {
    const std::size_t at = b.size();
    b.resize(at + 4);
    le::put32(b.data() + at, v);
  };
  put(std::uint32_t(bricks.size()));
  for (const auto& [brick, ref] : bricks) {
    put(std::uint32_t(brick.x));
    put(std::uint32_t(brick.y));
    put(std::uint32_t(brick.z));
    b.push_back(ref.data ? (ref.paint ? 3 : 2) : ref.inside ? 1 : 0);
    if (ref.data)
      for (const float v : ref.data->v) put(std::bit_cast<std::uint32_t>(v));
    if (ref.data && ref.paint)
      for (const Texel& t : ref.paint->t) b.insert(b.end(), {t.r, t.g, t.b, t.mask});
  }
  put(crc32Ieee(b));
  return b;
}

std::vector<std::pair<Int3, BrickRef>> decodeStep(std::span<const std::uint8_t> b, const std::string& name) {
  const auto fail = [&]() -> std::runtime_error { return std::runtime_error("unreadable step file " + name); };
  if (b.size() < 12 || std::memcmp(b.data(), "MZBK", 4) != 0) throw fail();
  if (crc32Ieee({b.data(), b.size() - 4}) != le::get32(b.data() + b.size() - 4)) throw fail();
  const std::uint32_t count = le::get32(b.data() + 4);
  std::vector<std::pair<Int3, BrickRef>> out;
  std::size_t at = 8;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (at + 13 > b.size() - 4) throw fail();
    const Int3 brick{std::int32_t(le::get32(b.data() + at)), std::int32_t(le::get32(b.data() + at + 4)),
                     std::int32_t(le::get32(b.data() + at + 8))};
    const std::uint8_t kind = b[at + 12];
    at += 13;
    BrickRef ref;
    if (kind > 3) throw fail();
    if (kind >= 2) {
      if (at + sizeof(Brick) > b.size() - 4) throw fail();
      auto data = std::make_shared<Brick>();
      for (int v = 0; v < kBrickVoxels; ++v) data->v[v] = le::getF32(b.data() + at + 4 * std::size_t(v));
      at += sizeof(Brick);
      ref.data = std::move(data);
    }
    if (kind == 3) {
      if (at + 4 * std::size_t(kBrickVoxels) > b.size() - 4) throw fail();
      auto paint = std::make_shared<BrickPaint>();
      for (int v = 0; v < kBrickVoxels; ++v) {
        const std::uint8_t* t = b.data() + at + 4 * std::size_t(v);
        paint->t[v] = Texel{t[0], t[1], t[2], t[3]};
        paint->masked = paint->masked || t[3] > 0;
      }
      at += 4 * std::size_t(kBrickVoxels);
      ref.paint = std::move(paint);
    }
    if (kind < 2) {
      ref.inside = kind == 1;
    }
    out.emplace_back(brick, std::move(ref));
  }
  return out;
}

void Replay::apply(const json& rec) {
  Session& s = session_;
  // The step's original time, if the record has it; the system clock again after.
  struct SystemClockAfter {
    Session& s;
    ~SystemClockAfter() { s.setClock(nullptr); }
  } systemClockAfter{s};
  if (const auto t = rec.find("t"); t != rec.end()) {
    const std::int64_t ms = t->get<std::int64_t>();
    s.setClock([ms] { return ms; });
  }
  if (rec.contains("op")) {
    s.apply(protocol::parseOp(rec["op"]), pool_, authorOf(rec));
  } else if (rec.contains("stroke_begin")) {
    // A stroke announced again at the head of a journal after a snapshot replaces its entry.
    if (const auto it = strokes_.find(rec["stroke_begin"].get<std::uint64_t>()); it != strokes_.end()) {
      s.endStroke(it->second);
      strokes_.erase(it);
    }
    const std::string toolName = rec.at("tool").get<std::string>();
    if (const auto warp = fromWireName(protocol::kWarpToolNames, toolName)) {
      strokes_[rec["stroke_begin"].get<std::uint64_t>()] = s.beginWarp(warpOfRecord(rec, *warp), authorOf(rec));
      return;
    }
    const auto tool = fromWireName(protocol::kBrushToolNames, toolName);
    const auto paint = fromWireName(protocol::kPaintToolNames, toolName);
    if (!tool && !paint) throw std::runtime_error("unknown stroke tool");
    const std::string sym = rec.value("symmetry", "");
    const Symmetry symmetry{sym.find('x') != std::string::npos, sym.find('y') != std::string::npos,
                            sym.find('z') != std::string::npos};
    std::optional<double> height;
    if (const auto h = rec.find("height"); h != rec.end()) height = h->get<double>();
    const StrokeId id =
        paint ? s.beginPaint(paintOfRecord(rec, *paint), symmetry, rec.value("accumulate", false), authorOf(rec))
              : s.beginStroke(*tool, rec.at("radius").get<double>(), rec.at("strength").get<double>(), symmetry,
                              rec.value("accumulate", false), authorOf(rec), height);
    strokes_[rec["stroke_begin"].get<std::uint64_t>()] = id;
    if (const auto it = rec.find("applied"); it != rec.end()) {
      // What the stroke had applied before the snapshot: its next dabs add only the excess.
      std::vector<StrokeDab> applied;
      for (const json& d : *it) {
        const Vec3 normal = d.size() == 7 ? Vec3{d[4].get<double>(), d[5].get<double>(), d[6].get<double>()} : Vec3{};
        const StrokeDab dab{Vec3{d.at(0).get<double>(), d.at(1).get<double>(), d.at(2).get<double>()}, d.at(3).get<double>(),
                            normal};
        if (!isFinite(dab.center) || !isFinite(dab.normal) || !(dab.weight > 0 && dab.weight <= 1))
          throw std::runtime_error("bad stroke memory");
        applied.push_back(dab);
      }
      s.setStrokeMemory(id, std::move(applied));
    }
    replayPlane(s, id, rec);
  } else if (rec.contains("stroke_end")) {
    const auto it = strokes_.find(rec["stroke_end"].get<std::uint64_t>());
    if (it != strokes_.end()) {
      s.endStroke(it->second);
      strokes_.erase(it);
    }
  } else if (rec.contains("stroke")) {
    std::vector<Dab> dabs;
    for (const json& d : rec.at("dabs")) {
      Dab dab{Vec3{d[0], d[1], d[2]}, d[3].get<double>(), std::nullopt};
      if (d.size() == 7) dab.normal = Vec3{d[4], d[5], d[6]};
      dabs.push_back(std::move(dab));
    }
    const StrokeId id = strokes_.at(rec["stroke"].get<std::uint64_t>());
    replayPlane(s, id, rec);
    s.strokeDabs(id, dabs, pool_);
  } else if (rec.contains("undo") || rec.contains("redo")) {
    // From the bricks it put in place, not from the replayed history: that history starts at
    // the snapshot and may hold only part of a stroke that began before it.
    const std::string name = rec[rec.contains("undo") ? "undo" : "redo"].get<std::string>();
    s.restore(decodeStep(readFile_(name), name));
  } else if (rec.contains("undo_mine") || rec.contains("redo_mine")) {
    // Through the history when it holds the very step (made wholly after the snapshot), so the
    // other steps stay undoable; its bricks must then be the file's. Otherwise (the step began
    // before the snapshot, or a plain undo's replay cleared the history) from the file, as undo.
    const bool undo = rec.contains("undo_mine");
    const std::string name = rec[undo ? "undo_mine" : "redo_mine"].get<std::string>();
    const std::vector<std::pair<Int3, BrickRef>> bricks = decodeStep(readFile_(name), name);
    const StepAuthor by = authorOf(rec);
    const json& step = rec.at("step");
    if (historyHolds(s, by.id, undo, step.at(0).get<std::uint64_t>(), step.at(1).get<std::uint64_t>())) {
      const HistoryResult h = undo ? s.undoMine(by.id) : s.redoMine(by.id);
      if (!h.changed || !sameBricks(h.restored, bricks))
        throw std::runtime_error("replayed " + std::string(undo ? "undo_mine" : "redo_mine") + " " + name +
                                 " does not put the bricks of its file in place");
    } else {
      s.restore(bricks);
    }
  } else if (rec.contains("load")) {
    s.load(loadVolume(readFile_(rec["load"].get<std::string>())), authorOf(rec));
  } else {
    throw std::runtime_error("unknown journal record");
  }
  if (rec.contains("r") && rec["r"].get<std::uint64_t>() != s.revision())
    throw std::runtime_error("replay reached revision " + std::to_string(s.revision()) + " where the journal says " +
                             rec["r"].dump());
}

void Replay::finish() {
  for (const auto& [journalStroke, stroke] : strokes_) session_.endStroke(stroke);
  strokes_.clear();
}

}  // namespace marzipan::service
