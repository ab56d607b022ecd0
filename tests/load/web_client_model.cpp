#include "web_client_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <numbers>

namespace marzipan::load {

namespace {

constexpr int kBrick = 8;
constexpr double kReachLo = -2, kReachHi = 10;
constexpr double kStep = 3.0 / 4096;

double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec normalize(const Vec& v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return {v[0] / n, v[1] / n, v[2] / n};
}
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// A point's place along the drag (vu from a) and its distance from the drag's segment, across
// the view: web_client_model.py's across().
std::pair<double, double> across(const Vec& point, const Vec& a, const Vec& d, const Vec& axis, double length) {
  Vec rel = sub(point, a);
  const double depth = dot(rel, d);
  for (int i = 0; i < 3; ++i) rel[i] -= depth * d[i];
  const double along = dot(rel, axis);
  const double clipped = std::clamp(along, 0.0, length);
  double gap2 = 0;
  for (int i = 0; i < 3; ++i) {
    const double g = rel[i] - clipped * axis[i];
    gap2 += g * g;
  }
  return {along, std::sqrt(gap2)};
}

}  // namespace

PyRandom::PyRandom(std::uint32_t seed) {
  // init_genrand(19650218) then init_by_array({seed}), as CPython's random_seed does for an int.
  mt_[0] = 19650218U;
  for (std::uint32_t i = 1; i < 624; ++i) mt_[i] = 1812433253U * (mt_[i - 1] ^ (mt_[i - 1] >> 30)) + i;
  std::uint32_t i = 1;
  for (int k = 624; k > 0; --k) {
    mt_[i] = (mt_[i] ^ ((mt_[i - 1] ^ (mt_[i - 1] >> 30)) * 1664525U)) + seed;  // key[0] + j with j = 0
    if (++i >= 624) {
      mt_[0] = mt_[623];
      i = 1;
    }
  }
  for (int k = 623; k > 0; --k) {
    mt_[i] = (mt_[i] ^ ((mt_[i - 1] ^ (mt_[i - 1] >> 30)) * 1566083941U)) - i;
    if (++i >= 624) {
      mt_[0] = mt_[623];
      i = 1;
    }
  }
  mt_[0] = 0x80000000U;
  index_ = 624;
}

std::uint32_t PyRandom::next() {
  if (index_ >= 624) {
    for (int k = 0; k < 624; ++k) {
      const std::uint32_t y = (mt_[k] & 0x80000000U) | (mt_[(k + 1) % 624] & 0x7fffffffU);
      mt_[k] = mt_[(k + 397) % 624] ^ (y >> 1) ^ ((y & 1U) ? 0x9908b0dfU : 0U);
    }
    index_ = 0;
  }
  std::uint32_t y = mt_[index_++];
  y ^= y >> 11;
  y ^= (y << 7) & 0x9d2c5680U;
  y ^= (y << 15) & 0xefc60000U;
  y ^= y >> 18;
  return y;
}

double PyRandom::random() {
  const std::uint32_t a = next() >> 5, b = next() >> 6;
  return (a * 67108864.0 + b) * (1.0 / 9007199254740992.0);
}

double pyRound(double x, int digits) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", digits, x);
  return std::strtod(text, nullptr);
}

bool SplatSurface::apply(std::span<const std::uint8_t> payload, bool full) {
  // "MZSP", u16 version, u16 flags, u32 bricks, u32 points; per brick u16 x, y, z, N and the
  // points: version 1, N u64 points; version 2 (what the browser asks for), N's low 10 bits
  // count them, and bit 15 marks a painted brick, whose points are the u64 and 4 bytes of
  // colour and mask.
  if (payload.size() < 16 || std::memcmp(payload.data(), "MZSP", 4) != 0) return false;
  std::uint16_t version;
  std::memcpy(&version, payload.data() + 4, 2);
  std::uint32_t count;
  std::memcpy(&count, payload.data() + 8, 4);
  if (full) bricks_.clear();
  std::size_t at = 16;
  for (std::uint32_t b = 0; b < count; ++b) {
    if (at + 8 > payload.size()) return false;
    std::uint16_t h[4];
    std::memcpy(h, payload.data() + at, 8);
    at += 8;
    const std::size_t n = version == 2 ? h[3] & 0x3FFu : h[3];
    const std::size_t size = version == 2 && (h[3] & 0x8000u) ? 12 : 8;
    if (at + size * n > payload.size()) return false;
    const Key key{h[0], h[1], h[2]};
    if (n == 0) {
      bricks_.erase(key);
    } else {
      auto words = std::make_shared<std::vector<std::uint64_t>>(n);
      for (std::size_t i = 0; i < n; ++i) std::memcpy(words->data() + i, payload.data() + at + size * i, 8);
      bricks_[key] = std::move(words);
    }
    at += size * n;
  }
  return true;
}

std::vector<SplatSurface::Brick> SplatSurface::snapshot() const {
  std::vector<Brick> out;
  out.reserve(bricks_.size());
  for (const auto& [key, words] : bricks_) out.push_back({key, words});
  return out;
}

Drag::Drag(PyRandom& rng, int size) {
  const double c = (size - 1) / 2.0;
  const double azimuth = rng.uniform(0, 2 * std::numbers::pi);
  const double elevation = rng.uniform(-15, 45) * (std::numbers::pi / 180);  // math.radians
  const Vec towardsEye{std::cos(elevation) * std::cos(azimuth), std::sin(elevation),
                       std::cos(elevation) * std::sin(azimuth)};
  right_ = normalize(cross({0.0, 1.0, 0.0}, towardsEye));
  up_ = cross(towardsEye, right_);
  const double reach = 0.22 * size;
  if (rng.random() < 0.5) {
    u0_ = -reach;
    u1_ = reach;
  } else {
    u0_ = reach;
    u1_ = -reach;
  }
  v0_ = rng.uniform(-0.12, 0.15) * size;
  v1_ = rng.uniform(-0.12, 0.15) * size;
  const double distance = 1.5 * size;
  for (int i = 0; i < 3; ++i) {
    eye_[i] = c + distance * towardsEye[i];
    direction_[i] = pyRound(-towardsEye[i], 4);
  }
}

Vec Drag::origin(double t) const {
  const double u = u0_ + (u1_ - u0_) * t, v = v0_ + (v1_ - v0_) * t;
  return {eye_[0] + u * right_[0] + v * up_[0], eye_[1] + u * right_[1] + v * up_[1], eye_[2] + u * right_[2] + v * up_[2]};
}

StrokePicker::StrokePicker(const std::vector<SplatSurface::Brick>& surface, const Vec& originA, const Vec& originB,
                           const Vec& direction, double discRadius)
    : d_(direction), a_(originA), r_(discRadius) {
  Vec span = sub(originB, originA);
  const double depth = dot(span, d_);
  for (int i = 0; i < 3; ++i) span[i] -= depth * d_[i];  // origins differ only across the view
  const double length = std::sqrt(dot(span, span));
  axis_ = length > 0 ? Vec{span[0] / length, span[1] / length, span[2] / length} : Vec{0, 0, 0};
  struct Kept {
    double along;
    Disc disc;
  };
  std::vector<Kept> kept;
  for (const auto& brick : surface) {
    // A brick's points and their discs lie within 6 + disc radius of its centre per axis.
    Vec centre;
    for (int i = 0; i < 3; ++i) centre[i] = brick.key[i] * kBrick + (kReachLo + kReachHi) / 2;
    if (across(centre, a_, d_, axis_, length).second > (6 + r_) * std::sqrt(3.0)) continue;
    Vec origin;
    for (int i = 0; i < 3; ++i) origin[i] = brick.key[i] * double(kBrick) - 2;
    for (const std::uint64_t w : *brick.words) {
      Vec p;
      for (int i = 0; i < 3; ++i) p[i] = double((w >> (14 * i)) & 0x3FFF) * kStep + origin[i];
      const double u = (2.0 * double((w >> 42) & 0x7FF) - 2047) / 2047;
      const double v = (2.0 * double(w >> 53) - 2047) / 2047;
      const double z = 1 - std::fabs(u) - std::fabs(v);
      double fu = u, fv = v;
      if (z < 0) {
        fu = (1 - std::fabs(v)) * (u >= 0 ? 1.0 : -1.0);
        fv = (1 - std::fabs(u)) * (v >= 0 ? 1.0 : -1.0);
      }
      const Vec n = normalize({fu, fv, z});
      const double facing = dot(n, d_);
      if (!(facing < -1e-3)) continue;  // back faces are not drawn
      const auto [along, off] = across(p, a_, d_, axis_, length);
      if (off > r_) continue;
      kept.push_back({along, {p, n, facing, dot(p, n)}});
    }
  }
  std::stable_sort(kept.begin(), kept.end(), [](const Kept& x, const Kept& y) { return x.along < y.along; });
  along_.reserve(kept.size());
  discs_.reserve(kept.size());
  for (const auto& k : kept) {
    along_.push_back(k.along);
    discs_.push_back(k.disc);
  }
}

std::optional<Vec> StrokePicker::pick(const Vec& o) const {
  const double at = dot(sub(o, a_), axis_);
  const auto first = std::lower_bound(along_.begin(), along_.end(), at - r_) - along_.begin();
  const auto last = std::upper_bound(along_.begin(), along_.end(), at + r_) - along_.begin();
  double best = INFINITY;
  const double r2 = r_ * r_;
  for (auto k = first; k < last; ++k) {
    const Disc& c = discs_[std::size_t(k)];
    const double t = (c.pn - dot(c.n, o)) / c.facing;
    if (t < 0 || t >= best) continue;
    const double ex = o[0] + t * d_[0] - c.p[0], ey = o[1] + t * d_[1] - c.p[1], ez = o[2] + t * d_[2] - c.p[2];
    if (ex * ex + ey * ey + ez * ez <= r2) best = t;
  }
  if (best == INFINITY) return std::nullopt;
  return Vec{o[0] + best * d_[0], o[1] + best * d_[1], o[2] + best * d_[2]};
}

std::vector<DabSpacer::Dab> DabSpacer::add(const std::optional<Vec>& point, double pressure) {
  if (!point) {
    last_.reset();
    return {};
  }
  const auto prev = last_;
  last_ = std::pair{*point, pressure};
  if (!prev) {
    travelled_ = 0;
    return {{*point, pressure, 1.0}};
  }
  const Vec step3 = sub(*point, prev->first);
  const double step = std::sqrt(dot(step3, step3));
  if (step > maxGap_) {
    travelled_ = 0;
    return {{*point, pressure, 1.0}};
  }
  std::vector<Dab> dabs;
  double along = spacing_ - travelled_;
  while (along <= step) {
    const double f = along / step;
    Vec p;
    for (int i = 0; i < 3; ++i) p[i] = prev->first[i] + ((*point)[i] - prev->first[i]) * f;
    dabs.push_back({p, prev->second + (pressure - prev->second) * f, f});
    along += spacing_;
  }
  travelled_ = step - (along - spacing_);
  return dabs;
}

namespace {
StrokeParams drawParams(PyRandom& rng, const std::string& tool) {
  StrokeParams p;
  p.tool = tool;
  p.radius = pyRound(rng.uniform(4, 10), 2);
  p.strength = pyRound(rng.uniform(0.3, 0.8), 2);
  if (tool == "add_blob" || tool == "remove_blob") {
    // web-client/net/stroke-sender.js: strength x half the radius, at most 16 vu.
    const double height = p.strength * std::min(0.5 * p.radius, 16.0);
    p.height = std::max(0.001, std::floor(1000 * height) / 1000);
  } else {
    p.accumulate = true;
  }
  return p;
}
}  // namespace

WebClientStroke::WebClientStroke(PyRandom& rng, const std::string& tool, int size,
                                 const std::vector<SplatSurface::Brick>& surface, double dabSpacing)
    : rng_(rng) {
  grab = rng.random() < kGrabShare && dabSpacing > 0;
  params = drawParams(rng, tool);
  if (grab) params = {"grab", params.radius, 1.0, std::nullopt, false};  // the warps' strength
  drag_.emplace(rng, size);
  if (dabSpacing > 0) {
    picker_.emplace(surface, drag_->origin(0), drag_->origin(1), drag_->direction());
    spacer_.emplace(std::max(kMinDabSpacing, dabSpacing * params.radius));
  }
  frames = std::max(1, int(std::nearbyint(rng.uniform(0.8, 1.2) * kStrokeS * kFrameHz)));
}

std::vector<WireDab> WebClientStroke::pointer(int k) {
  const double pressure = pyRound(rng_.uniform(0.5, 1.0), 2);
  if (grab) return grabPointer(k, pressure);
  if (!spacer_) {
    Vec o = drag_->origin((k + 1) / double(frames));
    for (double& c : o) c = pyRound(c, 2);
    return {{o, pressure, true, drag_->direction()}};
  }
  std::vector<WireDab> dabs;
  for (const auto& dab : spacer_->add(picker_->pick(drag_->origin((k + 1) / double(frames))), pressure)) {
    Vec point = dab.point;
    if (dab.fraction < 1)  // between two samples: on the surface under its own ray
      if (const auto hit = picker_->pick(drag_->origin((k + dab.fraction) / frames))) point = *hit;
    for (double& c : point) c = pyRound(c, 4);
    dabs.push_back({point, pyRound(dab.pressure, 4)});
  }
  return dabs;
}

std::vector<WireDab> WebClientStroke::grabPointer(int k, double pressure) {
  Vec point;
  if (!anchor_) {
    anchor_ = picker_->pick(drag_->origin((k + 1) / double(frames)));
    if (!anchor_) return {};
    anchorEvent_ = k;
    point = *anchor_;
  } else {
    const Vec a = drag_->origin(0), b = drag_->origin(1), ab = sub(b, a);
    const double along = std::sqrt(dot(ab, ab));
    const double reach = kGrabReach * (k - anchorEvent_) / std::max(1, frames - 1 - anchorEvent_);
    for (int i = 0; i < 3; ++i) point[i] = (*anchor_)[i] + reach * ab[i] / along;
  }
  for (double& c : point) c = pyRound(c, 4);
  return {{point, pressure}};
}

}  // namespace marzipan::load
