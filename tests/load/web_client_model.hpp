// The browser's strokes for the compiled load client (load_client.cpp): the same model as
// web_client_model.py and marzipan_load.py's WebClientStroke and Drag, number for number. A
// stroke draws its numbers from CPython's random.Random in the Python tool's order, so that one
// seed gives both tools the same strokes (tests/load/test_load_client.py checks that they do);
// the splats are kept and picked as web-client/math/splat-pick.js picks them, and the hits
// spaced into dabs as web-client/math/dab-spacer.js spaces them.
//
// Conventions: vu, y up, voxel (i, j, k) at (i, j, k); a brick (bx, by, bz) holds points within
// [8 b - 2, 8 b + 10) per axis, 8-byte points in protocol/cpp/splats.hpp's layout (read here
// without its checks: the buffers come from the server under test); pressure in (0, 1]; ray
// directions unit length. No Boost here: only load_client.cpp pays for Beast.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace marzipan::load {

using Vec = std::array<double, 3>;

// CPython's random.Random(seed) for a seed in [0, 2^32): MT19937 seeded by init_by_array, and
// random() / uniform() as CPython computes them.
class PyRandom {
 public:
  explicit PyRandom(std::uint32_t seed);
  double random();
  double uniform(double a, double b) { return a + (b - a) * random(); }

 private:
  std::uint32_t next();
  std::array<std::uint32_t, 624> mt_{};
  int index_ = 624;
};

// Python's round(x, digits) of a float: the exact binary value rounded to `digits` decimals,
// ties to even (glibc's printf rounds the exact value too).
double pyRound(double x, int digits);

// The web client's constants, as web_client_model.py and marzipan_load.py give them.
inline constexpr double kDabSpacing = 0.25;     // of the brush radius
inline constexpr double kMinDabSpacing = 0.25;  // vu
inline constexpr double kDiscRadius = 0.8;      // vu
inline constexpr double kFrameHz = 60;
inline constexpr double kStrokeS = 1.5;  // each stroke lasts 0.8-1.2 times this
inline constexpr double kPauseS = 0.25;  // between a stroke's end and the next one's begin
inline constexpr int kMaxInFlight = 3;
inline constexpr int kMaxDabs = 256;
inline constexpr const char* kTools[] = {"add_blob", "remove_blob", "smooth"};
inline constexpr double kGrabShare = 0.2;   // of the strokes, with dab spacing only
inline constexpr double kGrabReach = 20.0;  // vu the anchor is dragged by the stroke's end

// A session's splats by brick as a client holds them; a snapshot shares the bricks' points.
class SplatSurface {
 public:
  using Key = std::array<int, 3>;
  struct Brick {
    Key key;
    std::shared_ptr<const std::vector<std::uint64_t>> words;
  };
  // A splat buffer (MZSP); `full` replaces everything, else the listed bricks replace theirs
  // (an empty one removes its brick). Returns false for a buffer that is not one.
  bool apply(std::span<const std::uint8_t> payload, bool full);
  std::vector<Brick> snapshot() const;

 private:
  std::map<Key, std::shared_ptr<const std::vector<std::uint64_t>>> bricks_;
};

// marzipan_load.py's Drag: a straight pointer path across the model seen from a random side,
// rays of an orthographic camera.
class Drag {
 public:
  Drag(PyRandom& rng, int size);
  Vec origin(double t) const;
  const Vec& direction() const { return direction_; }

 private:
  Vec eye_{}, right_{}, up_{}, direction_{};
  double u0_ = 0, v0_ = 0, u1_ = 0, v1_ = 0;
};

// web_client_model.py's StrokePicker: the first front-facing disc each ray of one drag meets.
class StrokePicker {
 public:
  StrokePicker(const std::vector<SplatSurface::Brick>& surface, const Vec& originA, const Vec& originB, const Vec& direction,
               double discRadius = kDiscRadius);
  std::optional<Vec> pick(const Vec& origin) const;

 private:
  struct Disc {
    Vec p, n;
    double facing, pn;
  };
  Vec d_{}, a_{}, axis_{};
  double r_;
  std::vector<double> along_;
  std::vector<Disc> discs_;
};

// web_client_model.py's DabSpacer.
class DabSpacer {
 public:
  struct Dab {
    Vec point;
    double pressure, fraction;
  };
  explicit DabSpacer(double spacing) : spacing_(spacing), maxGap_(8 * spacing) {}
  std::vector<Dab> add(const std::optional<Vec>& point, double pressure);

 private:
  double spacing_, maxGap_;
  std::optional<std::pair<Vec, double>> last_;
  double travelled_ = 0;
};

// marzipan_load.py's WebClientStroke: one stroke's parameters and the dabs of its pointer events
// (a grab: the anchor first, then the anchor dragged along the drag's screen direction).
struct StrokeParams {
  std::string tool;
  double radius = 0, strength = 0;
  std::optional<double> height;  // add/remove blob
  bool accumulate = false;       // smoothing
};
struct WireDab {
  Vec at;  // a centre, or with isRay a ray's origin
  double pressure;
  bool isRay = false;
  Vec direction{};
};
class WebClientStroke {
 public:
  WebClientStroke(PyRandom& rng, const std::string& tool, int size, const std::vector<SplatSurface::Brick>& surface,
                  double dabSpacing);
  std::vector<WireDab> pointer(int k);
  bool grab = false;
  StrokeParams params;
  int frames = 1;

 private:
  std::vector<WireDab> grabPointer(int k, double pressure);
  PyRandom& rng_;
  std::optional<Drag> drag_;
  std::optional<StrokePicker> picker_;
  std::optional<DabSpacer> spacer_;
  std::optional<Vec> anchor_;
  int anchorEvent_ = 0;
};

}  // namespace marzipan::load
