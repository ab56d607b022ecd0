// One sculpting session (see session.hpp).
#include "service/session.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_set>
#include <utility>

#include "engine/errors.hpp"
#include "engine/progress.hpp"
#include "engine/splats.hpp"
#include "service/apply_op.hpp"

namespace marzipan::service {
namespace {

constexpr double kMinMarchStep = 0.1;  // vu
constexpr double kBisectTolerance = 1e-9;

[[noreturn]] void rethrow(const EngineError& e, const std::string& fieldPrefix) {
  const std::string field = fieldPrefix.empty() ? e.field()
                            : e.field().empty() ? fieldPrefix
                                                : fieldPrefix + "." + e.field();
  switch (e.kind()) {
    case ErrorKind::OutOfDomain:
      throw ServiceError(protocol::RpcCode::EngineRefused, field, e.what());
    case ErrorKind::TooLarge:
      throw ServiceError(protocol::RpcCode::LimitExceeded, field, e.what());
    case ErrorKind::InvalidArgument:
    case ErrorKind::Format:
      break;
  }
  throw ServiceError(protocol::RpcCode::InvalidParams, field, e.what());
}

[[noreturn]] void invalid(const std::string& field, const std::string& what) {
  throw ServiceError(protocol::RpcCode::InvalidParams, field, field + ": " + what);
}

void requirePoint(Vec3 p, const std::string& field) {
  if (!isFinite(p)) invalid(field, "must be three finite numbers");
  for (int a = 0; a < 3; ++a)
    if (std::abs(p[a]) > protocol::kMaxCoordinate) invalid(field, "must be within +-1e6 vu on each axis");
}

void requireRay(const Ray& r, const std::string& field) {
  requirePoint(r.origin, field + ".origin");
  if (!isFinite(r.direction)) invalid(field + ".direction", "must be three finite numbers");
  if (r.direction == Vec3{0, 0, 0}) invalid(field + ".direction", "must not be zero");
}

// A direction of unit length, robust to components near the double range's ends.
Vec3 unitDirection(Vec3 d) {
  const double m = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
  return normalized(d / m);
}

}  // namespace

std::vector<StrokeDab> mirrorImages(const StrokeDab& dab, Symmetry s, Int3 dims) {
  std::vector<StrokeDab> out{dab};
  const bool on[3] = {s.x, s.y, s.z};
  for (int a = 0; a < 3; ++a) {
    if (!on[a]) continue;
    const std::size_t n = out.size();
    for (std::size_t i = 0; i < n; ++i) {
      StrokeDab q = out[i];
      q.center[a] = (dims[a] - 1) - q.center[a];
      q.normal[a] = -q.normal[a];
      out.push_back(q);
    }
  }
  // A dab on a mirror plane is its own image: apply it once.
  std::vector<StrokeDab> distinct;
  for (const StrokeDab& q : out)
    if (std::none_of(distinct.begin(), distinct.end(), [&](const StrokeDab& d) { return d.center == q.center; }))
      distinct.push_back(q);
  return distinct;
}

namespace {

// The mirrors a symmetry enables, each a set of axes (bit a: mirrored across axis a), in the
// order mirrorImages makes their images: the identity (0) first.
std::vector<int> mirrorSets(Symmetry s) {
  std::vector<int> sets{0};
  const bool on[3] = {s.x, s.y, s.z};
  for (int a = 0; a < 3; ++a) {
    if (!on[a]) continue;
    const std::size_t n = sets.size();
    for (std::size_t i = 0; i < n; ++i) sets.push_back(sets[i] | 1 << a);
  }
  return sets;
}

// A point and a direction mirrored across the axes of `set` (as mirrorImages mirrors them).
void mirror(Vec3& point, Vec3& direction, int set, Int3 dims) {
  for (int a = 0; a < 3; ++a)
    if (set & 1 << a) {
      point[a] = (dims[a] - 1) - point[a];
      direction[a] = -direction[a];
    }
}

// The images under mirror sets[k] of the dabs that are not their own image under an earlier
// mirror of the list (a dab on a mirror plane applies once, as in mirrorImages).
std::vector<StrokeDab> imagesUnder(std::span<const StrokeDab> dabs, const std::vector<int>& sets, std::size_t k,
                                   Int3 dims) {
  std::vector<StrokeDab> out;
  for (const StrokeDab& d : dabs) {
    StrokeDab image = d;
    mirror(image.center, image.normal, sets[k], dims);
    bool seen = false;
    for (std::size_t j = 0; j < k && !seen; ++j) {
      StrokeDab earlier = d;
      mirror(earlier.center, earlier.normal, sets[j], dims);
      seen = earlier.center == image.center;
    }
    if (!seen) out.push_back(image);
  }
  return out;
}

// The unit outward normal of vol's surface at a point on it, or zero where the field there has
// no slope to speak of (a point off the band).
Vec3 surfaceNormal(const Volume& vol, Vec3 p) {
  const Vec3 g = vol.gradient(p);
  const double length = std::sqrt(dot(g, g));
  return isFinite(g) && length > 0.5 ? g / length : Vec3{};
}

std::int64_t systemMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t steadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

bool samePaint(const BrickPaint* a, const BrickPaint* b) {
  if (a == b) return true;
  return a && b && std::memcmp(a->t, b->t, sizeof(a->t)) == 0;
}

// The same voxels and the same channels (two volumes of one base colour).
bool sameBrick(const BrickRef& a, const BrickRef& b) {
  if (a == b) return true;
  return a.data && b.data && std::memcmp(a.data->v, b.data->v, sizeof(a.data->v)) == 0 &&
         samePaint(a.paint.get(), b.paint.get());
}

// A dab's centre: its point, or where its ray meets `start`'s surface (none, counted in
// result.missed, when the ray misses it).
std::optional<Vec3> dabCentre(const Volume& start, const Dab& dab, ApplyResult& result) {
  if (const auto* c = std::get_if<Vec3>(&dab.at)) return *c;
  const Ray& ray = std::get<Ray>(dab.at);
  const std::optional<Vec3> hit = pickSurface(start, ray.origin, ray.direction);
  if (!hit) ++result.missed;
  return hit;
}

}  // namespace

std::optional<Vec3> pickSurface(const Volume& vol, Vec3 origin, Vec3 direction) {
  if (!isFinite(origin) || !isFinite(direction) || direction == Vec3{0, 0, 0}) return std::nullopt;
  const Vec3 dir = unitDirection(direction);
  // The domain grown by one voxel holds every zero of the interpolant (outside reads +band).
  double t0 = 0, t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    const double lo = -1, hi = vol.dims()[a];
    if (dir[a] == 0) {
      if (origin[a] < lo || origin[a] > hi) return std::nullopt;
      continue;
    }
    double ta = (lo - origin[a]) / dir[a], tb = (hi - origin[a]) / dir[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t0 <= t1)) return std::nullopt;
  const auto at = [&](double t) { return origin + dir * t; };
  double t = t0;
  double d = vol.sample(at(t));
  if (d <= 0) return at(t);
  while (t < t1) {
    const double tn = std::min(t1, t + std::max(kMinMarchStep, 0.5 * d));
    const double dn = vol.sample(at(tn));
    if (dn <= 0) {
      double lo = t, hi = tn;
      for (int i = 0; i < 64 && hi - lo > kBisectTolerance; ++i) {
        const double mid = 0.5 * (lo + hi);
        (vol.sample(at(mid)) <= 0 ? hi : lo) = mid;
      }
      return at(0.5 * (lo + hi));
    }
    t = tn;
    d = dn;
  }
  return std::nullopt;
}

Session::Session(Volume initial, std::size_t historyBudgetBytes)
    : volume_(std::move(initial)),
      history_(historyBudgetBytes),
      revision_(volume_.revision()),
      digestTerms_(digestTermSum(volume_)),
      clock_(systemMs),
      strokeClock_(steadyMs) {}

void Session::setClock(std::function<std::int64_t()> nowMs) { clock_ = nowMs ? std::move(nowMs) : systemMs; }

void Session::setStrokeClock(std::function<std::int64_t()> nowMs) {
  strokeClock_ = nowMs ? std::move(nowMs) : steadyMs;
}

StepInfo Session::stepInfo(const StepAuthor& by, std::string_view tool) const {
  StepInfo info;
  info.revision = info.firstRevision = revision_ + 1;
  info.author = by;
  info.tool = std::string(tool);
  info.timeMs = clock_();
  return info;
}

void Session::trackDigest(const std::vector<BrickChange>& changes, bool forward) {
  changedBricks_ += changes.size();
  const Int3 n = volume_.brickDims();
  if (cachedTerms_.empty())
    cachedTerms_.resize(std::min(std::size_t(n.x) * std::size_t(n.y) * std::size_t(n.z), kMaxCachedTerms));
  for (const BrickChange& c : changes) {
    const BrickRef& from = forward ? c.before : c.after;
    const BrickRef& to = forward ? c.after : c.before;
    const std::uint64_t key = std::uint64_t(std::uint32_t(c.brick.x)) | std::uint64_t(std::uint32_t(c.brick.y)) << 21 |
                              std::uint64_t(std::uint32_t(c.brick.z)) << 42;
    const std::size_t index =
        std::size_t(c.brick.x) + std::size_t(n.x) * (std::size_t(c.brick.y) + std::size_t(n.y) * std::size_t(c.brick.z));
    CachedTerm& slot = cachedTerms_[index % cachedTerms_.size()];
    const bool known = slot.key == key && from.data && slot.data == from.data && slot.paint == from.paint;
    digestTerms_ -= known ? slot.term : brickDigestTerm(c.brick, from);
    const std::uint64_t term = brickDigestTerm(c.brick, to);
    digestTerms_ += term;
    slot = {key, to.data, to.paint, term};
  }
}

void Session::resetDigest() {
  digestTerms_ = digestTermSum(volume_);
  cachedTerms_.clear();
}

void Session::bump() {
  ++revision_;
  volume_.setRevision(revision_);
}

void Session::finishInto(ApplyResult& result, const Edit& message) {
  const ApplyResult done = finish(message);
  result.revision = done.revision;
  result.changed = done.changed;
  result.roi = done.roi;
  result.bricks = done.bricks;
}

ApplyResult Session::finish(const Edit& edit) {
  ApplyResult r;
  r.roi = edit.region;
  if (!edit.empty()) {
    trackDigest(edit.changes, true);
    bump();
    r.changed = true;
    r.bricks = bricksAroundChanges(volume_, edit.changes);
  }
  r.revision = revision_;
  return r;
}

ApplyResult Session::apply(const protocol::Op& op, ThreadPool& pool, const StepAuthor& by) {
  Edit edit;
  // A whole-volume op publishes pass by pass: when one fails part way (cancelled, out of
  // memory) this copy (O(tiles), bricks shared) is put back, so a throw changes nothing.
  Volume before = volume_;
  try {
    edit = applyOp(volume_, op, pool);
  } catch (const EngineError& e) {
    volume_ = std::move(before);
    rethrow(e, "");
  } catch (...) {
    volume_ = std::move(before);
    throw;
  }
  // An op that changed nothing is not a change of the session: an open stroke keeps folding.
  if (!edit.empty()) lastStroke_ = 0;
  history_.push(edit, stepInfo(by, protocol::opName(op)), [this](History::StepId st) { return growingStep(st); });
  return finish(edit);
}

std::optional<Vec3> Session::pick(const Ray& ray) const {
  requireRay(ray, "ray");
  return pickSurface(volume_, ray.origin, ray.direction);
}

StrokeId Session::beginStroke(protocol::BrushTool tool, double radius, double strength, Symmetry symmetry,
                              bool accumulate, const StepAuthor& by, std::optional<double> height) {
  const auto known = std::any_of(protocol::kBrushToolNames.begin(), protocol::kBrushToolNames.end(),
                                 [&](const auto& n) { return n.value == tool; });
  if (!known) invalid("tool", "is not a brush tool");
  if (!std::isfinite(radius) || radius < protocol::kParamRadius.minimum || radius > protocol::kParamRadius.maximum)
    invalid("radius", "must be a number of vu in " + protocol::rangeText(protocol::kParamRadius));
  if (height && accumulate) invalid("height", "is for strokes that remember what they applied, not for accumulating ones");
  // The strength and the height as the engine will check every message's dabs (one check).
  // A stroke's plane comes with its first dab: any valid one stands for it here.
  try {
    StrokeSettings settings{engineBrush(tool), radius, strength, height};
    if (brushUsesPlane(settings.tool)) settings.plane = Plane{{0, 0, 0}, {0, 0, 1}};
    checkStrokeSettings(settings);
  } catch (const EngineError& e) {
    rethrow(e, "");
  }
  checkStrokeRoom();
  const StrokeId id = nextStroke_++;
  strokes_.emplace(id, Stroke{tool, radius, strength, symmetry, accumulate, {}, 0, by, height, volume_, strokeClock_(), 0,
                              changedBricks_, std::nullopt, std::nullopt, 0});
  return id;
}

void Session::checkStrokeRoom() const {
  if (strokes_.size() >= kMaxOpenStrokes)
    throw ServiceError(protocol::RpcCode::LimitExceeded, "stroke",
                       "too many open strokes in this session (at most " + std::to_string(kMaxOpenStrokes) +
                           "); end one first");
}

const Session::Stroke& Session::openStroke(StrokeId id) const {
  const auto it = strokes_.find(id);
  if (it != strokes_.end()) return it->second;
  if (id != 0 && id < nextStroke_)
    throw ServiceError(protocol::RpcCode::NoSuchStroke, "stroke", "stroke " + std::to_string(id) + " has ended");
  throw ServiceError(protocol::RpcCode::NoSuchStroke, "stroke", "no stroke " + std::to_string(id) + " in this session");
}

std::string_view Session::toolName(const Stroke& s) {
  if (s.paint) return paintToolName(s.paint->mode);
  return s.warp ? protocol::nameOf(protocol::kWarpToolNames, s.warp->tool) : protocol::nameOf(protocol::kBrushToolNames, s.tool);
}

StrokeId Session::beginPaint(const PaintSettings& st, Symmetry symmetry, bool accumulate, const StepAuthor& by) {
  try {
    checkPaintSettings(st);
  } catch (const EngineError& e) {
    rethrow(e, "");
  }
  checkStrokeRoom();
  const StrokeId id = nextStroke_++;
  strokes_.emplace(id, Stroke{protocol::BrushTool::AddBlob, st.radius, st.strength, symmetry, accumulate, {}, 0, by,
                              std::nullopt, volume_, strokeClock_(), 0, changedBricks_, std::nullopt, std::nullopt, 0, st});
  return id;
}

ApplyResult Session::paintDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool) {
  const Stroke& stroke = strokes_.at(id);
  const PaintSettings settings = *stroke.paint;
  // Rays pick on the surface as the stroke began (a load that changed the grid since: as it is).
  const Volume& start = stroke.start.dims() == volume_.dims() ? stroke.start : volume_;
  // A voxel's foot point lies within the band of it: a dab reaches this far (engine paintStroke).
  const double reach = settings.radius + volume_.band() + 1;
  ApplyResult result;
  std::vector<StrokeDab> images;
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const std::optional<Vec3> centre = dabCentre(start, dabs[i], result);
    result.hits.push_back(centre);
    result.normals.push_back(Vec3{});
    const double pressure = dabs[i].pressure.value_or(1.0);
    if (!centre || pressure == 0) continue;
    for (const StrokeDab& image : mirrorImages(StrokeDab{*centre, pressure, Vec3{}}, stroke.symmetry, volume_.dims())) {
      if (boxAround(image.center, {reach, reach, reach}).intersect(volume_.domain()).empty())
        throw ServiceError(protocol::RpcCode::EngineRefused, "dabs[" + std::to_string(i) + "].center",
                           "dabs[" + std::to_string(i) + "].center: the tool's region lies outside the volume");
      images.push_back(image);
    }
  }
  Edit message;
  try {
    message = paintStroke(volume_, settings, images, stroke.memory, pool);
  } catch (const EngineError& e) {
    rethrow(e, "dabs");
  }
  foldMessage(id, message, images);
  finishInto(result, message);
  return result;
}

void Session::foldMessage(StrokeId id, const Edit& message, const std::vector<StrokeDab>& images) {
  Stroke& s = strokes_.at(id);
  // An application that changed nothing is not journaled, so a recovered stroke never learns
  // its dabs: remembered, they would hold back this stroke's later messages here but not there.
  if (!s.accumulate && !message.empty()) {
    s.memory.insert(s.memory.end(), images.begin(), images.end());
    if (s.memory.size() > kMaxStrokeMemory) s.memory.erase(s.memory.begin(), s.memory.end() - std::ptrdiff_t(kMaxStrokeMemory));
  }
  foldIntoStep(s, id, message);
}

void Session::foldIntoStep(Stroke& s, StrokeId id, const Edit& message) {
  if (message.empty()) return;
  const bool folded = s.by.id.empty() ? lastStroke_ == id && history_.amend(s.step, message, revision_ + 1)
                                      : history_.fold(s.step, message, volume_, revision_ + 1);
  if (!folded) {
    // The stroke's earlier step grows no more: packed like any step under a newer one.
    history_.seal(s.step);
    s.step = history_.push(message, stepInfo(s.by, toolName(s)), [this, id](History::StepId st) { return growingStep(st, id); });
  }
  lastStroke_ = id;
}

StrokeId Session::beginWarp(WarpStroke w, const StepAuthor& by) {
  const auto known = std::any_of(protocol::kWarpToolNames.begin(), protocol::kWarpToolNames.end(),
                                 [&](const auto& n) { return n.value == w.tool; });
  if (!known) invalid("tool", "is not a warp tool");
  try {
    checkWarpSettings(w);
  } catch (const EngineError& e) {
    rethrow(e, "");
  }
  for (const std::optional<Vec3>& p : {w.anchor, w.pointer})
    if (p) requirePoint(*p, "anchor");
  if (!isFinite(w.normal) || !isFinite(w.heldD) || !std::isfinite(w.heldAmount))
    invalid("anchor", "the stroke's state must be finite");
  checkStrokeRoom();
  const StrokeId id = nextStroke_++;
  strokes_.emplace(id, Stroke{protocol::BrushTool::AddBlob, w.radius, w.strength, {}, false, {}, 0, by, std::nullopt,
                              volume_, strokeClock_(), 0, changedBricks_, std::nullopt, std::move(w), revision_});
  return id;
}

std::optional<OpCost> Session::warpCost(StrokeId id, const std::vector<Dab>& dabs) const {
  const auto it = strokes_.find(id);
  if (it == strokes_.end() || !it->second.warp || dabs.empty()) return std::nullopt;
  const WarpStroke& w = *it->second.warp;
  std::optional<Vec3> anchor;
  std::vector<Vec3> points;
  std::vector<double> pressures;
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const auto* c = std::get_if<Vec3>(&dabs[i].at);
    // A ray can only be the anchor; its hit is not known before the pick: the anchor's worst
    // place is the farthest from the pointer, which the engine's travel bound caps anyway.
    if (i == 0 && !w.anchor) anchor = c ? *c : Vec3{};
    else if (c) points.push_back(*c), pressures.push_back(std::clamp(dabs[i].pressure.value_or(1.0), 0.0, 1.0));
  }
  if (!w.anchor && !std::holds_alternative<Vec3>(dabs[0].at) && !points.empty()) {
    const double far = 1e9;
    anchor = points.back() + Vec3{far, far, far};
  }
  return warpStrokeCost(volume_, w, anchor, points, pressures);
}

void Session::rebaseWarps() {
  for (auto& [id, s] : strokes_)
    if (s.warp) {
      rebaseWarp(*s.warp);
      s.start = volume_;
      s.warpRevision = revision_;
    }
}

ApplyResult Session::warpDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool) {
  Stroke& stroke = strokes_.at(id);
  WarpStroke w = *stroke.warp;  // the stroke's state changes only when the whole message applied
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const std::string field = "dabs[" + std::to_string(i) + "]";
    if (const auto* c = std::get_if<Vec3>(&dabs[i].at)) requirePoint(*c, field + ".center");
    else if (i == 0 && !w.anchor) requireRay(std::get<Ray>(dabs[i].at), field + ".ray");
    else invalid(field + ".ray", "a warp stroke's dabs after its anchor are the pointer's points: give a centre");
    if (const auto& p = dabs[i].pressure; p && !(*p >= 0 && *p <= 1)) invalid(field + ".pressure", "must be in [0, 1]");
  }
  // Something else changed the session since the stroke's last message: it goes on from the
  // volume as it is (a base that lacks those changes would take them back).
  const bool rebase = stroke.warpRevision != revision_;
  std::optional<Volume> rebased;  // the volume as it is: bricks shared, untouched by the warp below
  if (rebase) {
    rebaseWarp(w);
    rebased = volume_;
  }
  const Volume& base = rebased ? *rebased : stroke.start;

  ApplyResult result;
  std::size_t first = 0;
  Vec3 anchorAt;  // the anchor this message took (a ray's hit, or the point carried to the surface), for the journal
  if (!w.anchor) {
    std::optional<Vec3> at;
    if (const auto* c = std::get_if<Vec3>(&dabs[0].at)) at = *c;
    else if (!(at = pickSurface(base, std::get<Ray>(dabs[0].at).origin, std::get<Ray>(dabs[0].at).direction)))
      ++result.missed;
    if (!at) {
      // No anchor: the message does nothing (its other dabs have nothing to move).
      result.hits.assign(dabs.size(), std::nullopt);
      result.normals.assign(dabs.size(), Vec3{});
      result.revision = revision_;
      return result;
    }
    try {
      setWarpAnchor(w, base, *at);
    } catch (const EngineError& e) {
      rethrow(e, "");
    }
    result.anchored = true;
    anchorAt = *w.anchor;
    first = 1;
  }
  std::vector<Vec3> points;
  std::vector<double> pressures;
  for (std::size_t i = first; i < dabs.size(); ++i)
    points.push_back(std::get<Vec3>(dabs[i].at)), pressures.push_back(dabs[i].pressure.value_or(1.0));

  Edit message;
  Volume before = volume_;
  try {
    message = applyWarpStroke(volume_, base, w, points, pool, pressures);
  } catch (const EngineError& e) {
    volume_ = std::move(before);
    rethrow(e, "dabs");
  } catch (...) {
    volume_ = std::move(before);
    throw;
  }
  if (rebased) stroke.start = std::move(*rebased);
  stroke.warp = w;
  if (first == 1) result.hits.push_back(anchorAt);
  for (const Vec3 p : points) result.hits.push_back(p);
  result.normals.assign(dabs.size(), Vec3{});
  foldIntoStep(stroke, id, message);
  finishInto(result, message);
  stroke.warpRevision = revision_;
  return result;
}

ApplyResult Session::strokeDabs(StrokeId id, const std::vector<Dab>& dabs, ThreadPool& pool) {
  const Stroke& stroke = openStroke(id);
  strokes_.at(id).lastMessageMs = strokeClock_();
  if (stroke.warp) return warpDabs(id, dabs, pool);
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const std::string field = "dabs[" + std::to_string(i) + "]";
    if (const auto* c = std::get_if<Vec3>(&dabs[i].at)) requirePoint(*c, field + ".center");
    else requireRay(std::get<Ray>(dabs[i].at), field + ".ray");
    if (const auto& p = dabs[i].pressure; p && !(*p >= 0 && *p <= 1)) invalid(field + ".pressure", "must be in [0, 1]");
  }
  if (stroke.paint) return paintDabs(id, dabs, pool);

  ApplyResult result;
  StrokeSettings settings{engineBrush(stroke.tool), stroke.radius, stroke.strength, stroke.height};
  // The surface as the stroke began (a load that changed the grid since: as it is now).
  const Volume& start = stroke.start.dims() == volume_.dims() ? stroke.start : volume_;
  // Flatten and contrast apply each mirror's images with the plane mirrored alike (beginStroke,
  // "The stroke's plane"): what they remember, and what applies here, are the dabs themselves.
  const bool planar = brushUsesPlane(settings.tool);
  const bool clayNormal = settings.tool == Brush::Clay && stroke.height;
  std::optional<Plane> plane = stroke.plane;
  std::vector<StrokeDab> images;
  for (std::size_t i = 0; i < dabs.size(); ++i) {
    const std::optional<Vec3> centre = dabCentre(start, dabs[i], result);
    result.hits.push_back(centre);
    const std::string field = "dabs[" + std::to_string(i) + "]";
    const double pressure = dabs[i].pressure.value_or(1.0);
    if ((planar || clayNormal) && !plane && centre && pressure > 0) {
      try {
        plane = fitBrushPlane(start, *centre, stroke.radius);
      } catch (const EngineError& e) {
        rethrow(e, field);
      }
    }
    if (planar) settings.plane = plane;
    // A stroke with a height anchors each dab along the starting surface's normal there (add
    // and remove blob), along the stroke's normal (clay), or along each point's own (inflate).
    Vec3 normal;
    if (stroke.height && centre && settings.tool != Brush::Inflate)
      normal = dabs[i].normal ? *dabs[i].normal : clayNormal && plane ? plane->normal : surfaceNormal(start, *centre);
    result.normals.push_back(normal);
    if (!centre || pressure == 0) continue;
    const StrokeDab dab{*centre, pressure, normal};
    for (const StrokeDab& image : mirrorImages(dab, stroke.symmetry, volume_.dims())) {
      try {
        checkStrokeDab(volume_, settings, image);
      } catch (const EngineError& e) {
        rethrow(e, field);
      }
      if (!planar) images.push_back(image);
    }
    if (planar) images.push_back(dab);
  }
  Edit message;
  const std::vector<int> sets = mirrorSets(stroke.symmetry);
  // Bricks shared (O(tiles)): put back when a later mirror's application fails (cancelled, out
  // of memory) after an earlier one changed the volume. One application changes nothing then.
  std::optional<Volume> before;
  if (planar && sets.size() > 1) before = volume_;
  try {
    if (!planar) {
      message = applyStroke(volume_, settings, images, stroke.memory, pool);
    } else if (plane) {
      for (std::size_t k = 0; k < sets.size(); ++k) {
        StrokeSettings mirrored = settings;
        mirror(mirrored.plane->point, mirrored.plane->normal, sets[k], volume_.dims());
        const std::vector<StrokeDab> here = imagesUnder(images, sets, k, volume_.dims());
        const std::vector<StrokeDab> remembered = imagesUnder(stroke.memory, sets, k, volume_.dims());
        const Edit part = applyStroke(volume_, mirrored, here, remembered, pool);
        if (k == 0) message = part;
        else message.append(part.changes, part.region);
      }
    }
  } catch (const EngineError& e) {
    if (before) volume_ = std::move(*before);
    rethrow(e, "dabs");
  } catch (...) {
    if (before) volume_ = std::move(*before);
    throw;
  }
  strokes_.at(id).plane = plane;
  result.plane = plane;
  foldMessage(id, message, images);
  finishInto(result, message);
  return result;
}

std::vector<std::pair<StrokeId, Session::StrokeParams>> Session::openStrokeList() const {
  std::vector<std::pair<StrokeId, StrokeParams>> out;
  for (const auto& [id, st] : strokes_) {
    out.push_back({id, *strokeSettings(id)});
    out.back().second.memory = st.memory;
  }
  return out;
}

std::optional<Session::StrokeParams> Session::strokeSettings(StrokeId id) const {
  const auto it = strokes_.find(id);
  if (it == strokes_.end()) return std::nullopt;
  const Stroke& st = it->second;
  return StrokeParams{st.tool, st.radius, st.strength, st.symmetry, st.accumulate, {}, st.by, st.height, st.plane,
                      st.warp, st.paint};
}

std::span<const StrokeDab> Session::strokeMemory(StrokeId id) const {
  const auto it = strokes_.find(id);
  if (it == strokes_.end()) return {};
  return it->second.memory;
}

void Session::setStrokeMemory(StrokeId id, std::vector<StrokeDab> applied) {
  openStroke(id);
  Stroke& s = strokes_.at(id);
  if (s.accumulate) return;
  if (applied.size() > kMaxStrokeMemory) applied.erase(applied.begin(), applied.end() - std::ptrdiff_t(kMaxStrokeMemory));
  s.memory = std::move(applied);
}

void Session::setStrokePlane(StrokeId id, const Plane& plane) {
  openStroke(id);
  Stroke& s = strokes_.at(id);
  if (!brushUsesPlane(engineBrush(s.tool)) && !(engineBrush(s.tool) == Brush::Clay && s.height))
    invalid("plane", "is only for flatten, contrast and clay with a height");
  if (!isFinite(plane.point) || !isFinite(plane.normal) || !(std::abs(dot(plane.normal, plane.normal) - 1) <= 1e-6))
    invalid("plane", "must be a finite point and a unit normal");
  s.plane = plane;
}

bool Session::growingStep(History::StepId step, StrokeId except) const {
  return std::any_of(strokes_.begin(), strokes_.end(),
                     [&](const auto& s) { return s.first != except && s.second.step == step; });
}

void Session::endStroke(StrokeId id) {
  openStroke(id);
  history_.seal(strokes_.at(id).step);
  strokes_.erase(id);
  if (lastStroke_ == id) lastStroke_ = 0;
}

namespace {

// Calls f(buffer) for each data brick of start that vol no longer holds (none when a load
// changed the grid since: start is then unused).
template <class F>
void forHeldBricks(const Volume& start, const Volume& vol, F&& f) {
  if (start.dims() != vol.dims()) return;
  const Int3 bd = vol.brickDims();
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) {
        const BrickRef b = start.brick({x, y, z});
        if (b.data && b.data != vol.brick({x, y, z}).data) f(b.data.get());
      }
}

}  // namespace

std::size_t Session::strokeHeldBytes() const {
  std::unordered_set<const Brick*> held;
  for (const auto& [id, st] : strokes_) forHeldBricks(st.start, volume_, [&](const Brick* b) { held.insert(b); });
  return held.size() * sizeof(Brick);
}

std::vector<StrokeId> Session::endStaleStrokes(std::size_t maxBytes, std::int64_t idleMs) {
  std::vector<StrokeId> ended;
  const std::int64_t now = strokeClock_();
  for (const auto& [id, st] : strokes_)
    if (now - st.lastMessageMs > idleMs) ended.push_back(id);
  for (const StrokeId id : ended) endStroke(id);
  std::size_t bound = 0;
  for (const auto& [id, st] : strokes_) bound += (st.heldBricks + (changedBricks_ - st.changedAtCount)) * sizeof(Brick);
  if (bound <= maxBytes) return ended;
  // Oldest first (ids grow with time): its start lies furthest back.
  while (!strokes_.empty() && strokeHeldBytes() > maxBytes) {
    ended.push_back(strokes_.begin()->first);
    endStroke(strokes_.begin()->first);
  }
  // Not a structured binding: clang 14 (the sanitizer builds') cannot capture one.
  for (auto& entry : strokes_) {
    Stroke& st = entry.second;
    st.heldBricks = 0;
    st.changedAtCount = changedBricks_;
    forHeldBricks(st.start, volume_, [&](const Brick*) { ++st.heldBricks; });
  }
  return ended;
}

HistoryResult Session::undo() {
  const Edit* e = history_.undo(volume_);
  if (e) trackDigest(e->changes, false);
  return historyMoved(e);
}

HistoryResult Session::redo() {
  const Edit* e = history_.redo(volume_);
  if (e) trackDigest(e->changes, true);
  return historyMoved(e);
}

HistoryResult Session::undoMine(const std::string& author) { return authorMoved(history_.undoOf(volume_, author), false); }

HistoryResult Session::redoMine(const std::string& author) { return authorMoved(history_.redoOf(volume_, author), true); }

HistoryResult Session::authorMoved(const History::AuthorMove& m, bool forward) {
  if (m.edit) trackDigest(m.edit->changes, forward);
  HistoryResult r = historyMoved(m.edit);
  if (m.outcome == History::AuthorMove::Conflict) {
    r.step = m.step;
    r.conflict = m.conflict;
  }
  return r;
}

std::optional<Volume> Session::volumeAt(std::uint64_t revision) const {
  if (revision == revision_) return volume_;
  return history_.volumeAt(volume_, revision);
}

namespace {

ServiceError noSuchRevision(std::uint64_t revision, std::uint64_t current) {
  return ServiceError(protocol::RpcCode::InvalidParams, "revision",
                      "revision " + std::to_string(revision) + " is neither the current one (" + std::to_string(current) +
                          ") nor a step still in this session's history");
}

}  // namespace

Volume Session::forkVolume(std::optional<std::uint64_t> revision) const {
  if (!revision) return volume_;
  std::optional<Volume> v = volumeAt(*revision);
  if (!v) throw noSuchRevision(*revision, revision_);
  return std::move(*v);
}

std::variant<Volume, Rebuild> Session::versionAt(std::uint64_t revision) const {
  if (revision == revision_) return volume_;
  if (std::optional<Volume> kept = history_.keptAt(revision)) return std::move(*kept);
  std::optional<Rebuild> r = history_.rebuildAt(volume_, revision);
  if (!r) throw noSuchRevision(revision, revision_);
  return std::move(*r);
}

HistoryResult Session::historyMoved(const Edit* e) {
  HistoryResult r;
  if (e) {
    r.step = history_.moved();
    lastStroke_ = 0;
    bump();
    r.changed = true;
    r.roi = e->region;
    r.bricks = bricksAroundChanges(volume_, e->changes);
    for (const BrickChange& c : e->changes) r.restored.emplace_back(c.brick, volume_.brick(c.brick));
  }
  r.revision = revision_;
  r.canUndo = history_.canUndo();
  r.canRedo = history_.canRedo();
  return r;
}

HistoryResult Session::restore(const std::vector<std::pair<Int3, BrickRef>>& bricks) {
  const Int3 bd = volume_.brickDims();
  std::vector<BrickChange> changes;
  for (const auto& [b, ref] : bricks) {
    if (b.x < 0 || b.y < 0 || b.z < 0 || b.x >= bd.x || b.y >= bd.y || b.z >= bd.z)
      invalid("bricks", "a brick lies outside the grid");
    changes.push_back({b, volume_.brick(b), ref});
  }
  volume_.publish(changes, true);
  trackDigest(changes, true);
  history_.clear();
  lastStroke_ = 0;
  bump();
  HistoryResult r;
  r.changed = true;
  r.revision = revision_;
  r.roi = volume_.domain();
  r.bricks = bricksAroundChanges(volume_, changes);
  return r;
}

ApplyResult Session::load(Volume vol, const StepAuthor& by) {
  lastStroke_ = 0;
  // Another base colour changes what every unpainted voxel means: no step of bricks can say it.
  if (vol.dims() != volume_.dims() || vol.band() != volume_.band() || vol.baseColor() != volume_.baseColor()) {
    volume_ = std::move(vol);
    resetDigest();
    history_.clear();
    for (auto& [id, stroke] : strokes_) {
      stroke.start = volume_;
      stroke.plane.reset();
    }
    bump();
    ApplyResult r;
    r.revision = revision_;
    r.changed = true;
    r.fullRefresh = true;
    r.roi = volume_.domain();
    return r;
  }
  Edit edit;
  edit.region = volume_.domain();
  const Int3 bd = volume_.brickDims();
  for (int z = 0; z < bd.z; ++z)
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) {
        const Int3 b{x, y, z};
        BrickRef before = volume_.brick(b), after = vol.brick(b);
        if (!sameBrick(before, after)) edit.changes.push_back({b, std::move(before), std::move(after)});
      }
  volume_.publish(edit.changes, true);
  for (auto& [id, stroke] : strokes_) {
    stroke.start = volume_;
    stroke.plane.reset();
  }
  history_.push(edit, stepInfo(by, "volume.load"), [this](History::StepId st) { return growingStep(st); });
  ApplyResult r = finish(edit);
  if (!r.changed) {
    bump();
    r.revision = revision_;
    r.changed = true;
  }
  return r;
}

SessionStats Session::stats() const {
  SessionStats s = counters();
  s.measures = measure(volume_);
  std::from_chars(s.measures.digest.data(), s.measures.digest.data() + s.measures.digest.size(), s.digest, 16);
  return s;
}

SessionStats Session::counters() const {
  SessionStats s;
  s.revision = revision_;
  s.canUndo = history_.canUndo();
  s.canRedo = history_.canRedo();
  s.undoSteps = history_.undoSteps();
  s.redoSteps = history_.redoSteps();
  s.historyBytes = history_.bytes();
  s.openStrokes = strokes_.size();
  s.memoryBytes = volume_.memoryBytes();
  return s;
}

}  // namespace marzipan::service
