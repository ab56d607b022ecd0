// The warp resampler and its velocity fields (../level_set.hpp, warps; docs/method.md §3,
// Warps). One file, over the engine's ~800 lines: the fields are evaluated inline in the
// per-voxel integration (and along the mask's paths), where a call into another file per
// evaluation would cost more than the evaluation.
#include "engine/level_set.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include "engine/dense_grid.hpp"
#include "engine/errors.hpp"
#include "engine/progress.hpp"
#include "engine/redistance.hpp"

namespace marzipan {

namespace {

// The plateau (Velocity::falloff) of snake hook and of the affine warps.
constexpr double kPlateau = 0.5;

// The falloffs W(u) of the fields (Velocity::falloff), u going from 0 (full speed, the edge of
// the plateau) to 1 (the support's edge), and the largest |W'| of each, which the bounds of
// |grad v| scale:
// - quartic, (1 - u^2)^2: max |W'| 8 / (3 sqrt 3) = 1.54 at u = 1 / sqrt 3; its line integral
//   through the centre, 16/15 radius, is a path pinch's pass (kPathPinchPass, whose kernel is
//   this falloff in closed form). The fields with a plateau: snake hook, elastic grab, twist,
//   local scale, pinch.
// - quintic, 1 - (6u^5 - 15u^4 + 10u^3): max |W'| 15/8 at u = 1/2 (22% more sub-steps for
//   the same travel), line integral 1 radius. The field without one: grab. With W' and W''
//   zero at both ends it neither draws a tip at the centre nor a fold at the rim: the
//   quartic's W''(0) = -4 and W''(1) = 8 pulled a 3-radius grab's cap into a tip whose radius of curvature was about a
//   voxel, where even the exact field's gradient error read 0.236 (0.098 with the quintic;
//   tests/engine/level_set/test_warp.cpp). Not for the snake hook: its tentacle's foot and tip
//   came out sharper (the exact field of the first 8 moves 0.126 -> 0.148; docs/method.md).
enum class Falloff { Quartic, Quintic };
constexpr double kQuarticMaxSlope = 8 / (3 * std::numbers::sqrt3), kQuinticMaxSlope = 15.0 / 8;
constexpr Falloff falloffOf(double plateau) { return plateau == 0 ? Falloff::Quintic : Falloff::Quartic; }
constexpr double maxFalloffSlope(Falloff f) { return f == Falloff::Quintic ? kQuinticMaxSlope : kQuarticMaxSlope; }
constexpr double kPathPinchPass = 16.0 / 15;

// The bounds of |grad v| (../level_set.hpp, grabSlopeBound and the others) in the fields' own
// terms. A capsule (grab, snake hook) moving `travel` vu whose falloff has the plateau
// `plateau`: |W'| over the falloff's outer part, (1 - plateau) radius wide.
double capsuleSlope(double travel, double radius, double plateau) {
  return travel * maxFalloffSlope(falloffOf(plateau)) / ((1 - plateau) * radius);
}
// An elastic grab's load per vu of travel: at the centre the bi-scale Kelvinlet is
// (3/2 - b) (1 / eps - 1 / (2 eps)) load, b = 1 / (4 (1 - nu)), so that this load moves it by d.
double elasticLoadPerTravel(double eps, double nu) { return 2 * eps / (1.5 - 1 / (4 * (1 - nu))); }
// An elastic grab under a load of length `load`: the Kelvinlets' own slope is below
// |load| / eps^2 (their peak is about |load| / eps, reached over eps), plus the cut-off's (at
// kElasticCutoff eps, plateau kPlateau).
double elasticSlope(double load, double eps) {
  return load / (eps * eps) + load / eps * kQuarticMaxSlope / ((1 - kPlateau) * (kElasticCutoff * eps));
}
// An affine warp whose A has the Frobenius norm `norm`: |grad (P A r)| <= |A| (P + |P'| |r|).
double affineSlope(double norm) { return norm * (1 + kQuarticMaxSlope / (1 - kPlateau)); }

// Shares of a call's progress unit.
constexpr double kGatherShare = 0.1, kLatticeShare = 0.2, kResampleShare = 0.3, kRedistanceShare = 0.3;

// A stationary velocity field with bounded support.
struct Velocity {
  enum class Kind { Capsule, Affine, Elastic, PathPinch };
  Kind kind = Kind::Capsule;
  Vec3 anchor;
  double radius = 1;
  // Capsule: the segment anchor + [0, 1] * seg, velocity scale * seg * W(rho / radius).
  Vec3 seg;
  double segLength2 = 0;
  // Capsule: |seg| and seg / |seg| (set with seg, not per point: their root and divisions were
  // a tenth of the latency of a flow's integration).
  double segLength = 0;
  Vec3 segAxis;
  double scale = 1;
  // Capsule: the plateau's radius (vu) as the caller gave it; plateau * radius may round below
  // it (a snake hook's young move: ball / support * support), and the tip's foot points
  // (applyWarp, kTipFeetBall) are decided on it.
  double plateauBall = 0;
  // Affine: A (row-major), inner part of the radius where P = 1.
  double A[3][3] = {};
  // Elastic: a bi-scale regularized Kelvinlet (de Goes & James 2017) centred on anchor under
  // the load `load` (scaled by `scale`), with epsilons eps and 2 eps and Poisson ratio nu,
  // cut off smoothly by the falloff at `radius` = kElasticCutoff * eps.
  Vec3 load;
  double eps = 1, nu = 0.5;
  // PathPinch: -scale * I(y) * (across . (y - anchor)) * across, across a unit vector normal to
  // seg and I(y) the falloff integrated along the segment (pathIntegral()); scale is the call's
  // amount / (kPathPinchPass radius).
  Vec3 across;
  double amount = 0;
  // Affine: the bound of |grad v| of the call that made it (twistSlopeBound and the others).
  double affineBound = 0;

  // Whether the support is the capsule of `radius` around the segment anchor + [0, 1] * seg
  // (else the ball of `radius` around anchor).
  bool alongSegment() const { return kind == Kind::Capsule || kind == Kind::PathPinch; }

  // I(y) = integral of (1 - |y - p|^2 / radius^2)^2 over the points p of the segment where it
  // is positive (vu), and its gradient. With a the coordinate of y along the segment, h its
  // distance to the segment's line and c = 1 - h^2 / radius^2, the integrand over u = p - a is
  // K(u) = (c - u^2 / radius^2)^2 on |u| < radius sqrt(c): I = F(u1) - F(u0), F its
  // antiderivative, u0 and u1 the ends of the segment clamped to that chord. K vanishes at the
  // chord's ends, so the clamps add nothing to the derivatives: dI/da = K(u0) - K(u1),
  // dI/dc = G(u1) - G(u0) with G = dF/dc.
  double pathIntegral(Vec3 y, Vec3* grad) const {
    if (grad) *grad = {};
    if (!(segLength2 > 0)) return 0;
    const double length = std::sqrt(segLength2);
    const Vec3 axis = seg / length, r = y - anchor;
    const double a = dot(r, axis);
    const Vec3 off = r - axis * a;
    double da = 0, dh2 = 0;
    const double I = pathIntegralAt(a, dot(off, off), length, grad ? &da : nullptr, &dh2);
    if (grad) *grad = axis * da + off * (2 * dh2);
    return I;
  }

  // I at the coordinate a along the segment (of length `length`) and the squared distance h2 to
  // its line, and (when da is given) its partial derivatives in a and h2.
  double pathIntegralAt(double a, double h2, double length, double* da, double* dh2) const {
    if (da) *da = 0, *dh2 = 0;
    const double R2 = radius * radius, c = 1 - h2 / R2;
    if (!(c > 0)) return 0;
    const double chord = radius * std::sqrt(c);
    const double u0 = std::max(-a, -chord), u1 = std::min(length - a, chord);
    if (!(u1 > u0)) return 0;
    const auto F = [&](double u) { return u * (c * c - u * u * (2 * c / (3 * R2) - u * u / (5 * R2 * R2))); };
    if (da) {
      const auto K = [&](double u) { return (c - u * u / R2) * (c - u * u / R2); };
      const auto G = [&](double u) { return u * (2 * c - 2 * u * u / (3 * R2)); };
      *da = K(u0) - K(u1);
      *dh2 = -(G(u1) - G(u0)) / R2;
    }
    return F(u1) - F(u0);
  }

  // A path pinch's flow and inverse with its Jacobian (flow(), inverseWithJacobian()). Its
  // velocity is along `across` everywhere, so a point moves on the line through it along
  // `across`: its coordinate a along the segment and Q, its squared distance to the plane of
  // the segment and `across`, stay put, and the midpoint rule (and the variational equation)
  // runs on the one coordinate s = across . (y - anchor), with ds/dt = f(s) = -scale I(a, s^2 + Q) s.
  struct PinchCoordinates {
    double a = 0, s = 0, Q = 0, length = 0;
    Vec3 axis, q;  // q: y - anchor less its parts along axis and across (|q|^2 = Q)
  };
  PinchCoordinates pinchCoordinates(Vec3 y) const {
    PinchCoordinates p;
    p.length = std::sqrt(segLength2);
    p.axis = seg / p.length;
    const Vec3 r = y - anchor;
    p.a = dot(r, p.axis);
    p.s = dot(r, across);
    p.q = r - p.axis * p.a - across * p.s;
    p.Q = dot(p.q, p.q);
    return p;
  }

  Vec3 pinchFlow(Vec3 y, int n, double direction) const {
    if (!(segLength2 > 0)) return y;
    const PinchCoordinates p = pinchCoordinates(y);
    const auto f = [&](double s) { return -scale * pathIntegralAt(p.a, s * s + p.Q, p.length, nullptr, nullptr) * s; };
    const double dt = direction / n;
    double s = p.s;
    for (int i = 0; i < n; ++i) {
      const double mid = s + 0.5 * dt * f(s);
      s += dt * f(mid);
    }
    return y + across * (s - p.s);
  }

  // Backwards, with m = ds/ds0, wa = ds/da and wq = ds/dQ by the same midpoint rule (the
  // general one restricted to this flow): X(y) = y + across (s - s0),
  // DX = I + across (grad s - across)^T, grad s = m across + wa axis + 2 wq q.
  Vec3 pinchInverseWithJacobian(Vec3 y, int n, double X[3][3]) const {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) X[i][j] = i == j ? 1 : 0;
    if (!(segLength2 > 0)) return y;
    const PinchCoordinates p = pinchCoordinates(y);
    // f and its partial derivatives in s, a and Q at s.
    struct Speed {
      double f = 0, fs = 0, fa = 0, fq = 0;
    };
    const auto speedAt = [&](double s) {
      double da = 0, dh2 = 0;
      const double I = pathIntegralAt(p.a, s * s + p.Q, p.length, &da, &dh2);
      return Speed{-scale * I * s, -scale * (I + 2 * s * s * dh2), -scale * s * da, -scale * s * dh2};
    };
    const double dt = 1.0 / n;
    double s = p.s, m = 1, wa = 0, wq = 0;
    for (int i = 0; i < n; ++i) {
      const Speed v0 = speedAt(s);
      const double mid = s - 0.5 * dt * v0.f;
      const double mMid = m - 0.5 * dt * v0.fs * m;
      const double waMid = wa - 0.5 * dt * (v0.fs * wa + v0.fa), wqMid = wq - 0.5 * dt * (v0.fs * wq + v0.fq);
      const Speed v1 = speedAt(mid);
      s -= dt * v1.f;
      m -= dt * v1.fs * mMid;
      wa -= dt * (v1.fs * waMid + v1.fa);
      wq -= dt * (v1.fs * wqMid + v1.fq);
    }
    const Vec3 g = across * (m - 1) + p.axis * wa + p.q * (2 * wq);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) X[i][j] += across[i] * g[j];
    return y + across * (s - p.s);
  }

  // K_e(r) f = ((a - b) / re) f + (b / re^3) r (r . f) + (a e^2 / (2 re^3)) f, re = sqrt(r^2 + e^2),
  // with a = 1 (the brush is normalised, so the shear modulus drops out), b = 1 / (4 (1 - nu)).
  static Vec3 kelvinlet(Vec3 r, Vec3 f, double e, double nu) {
    const double a = 1, b = 1 / (4 * (1 - nu));
    const double re = std::sqrt(dot(r, r) + e * e), re3 = re * re * re;
    return f * ((a - b) / re + a * e * e / (2 * re3)) + r * (b * dot(r, f) / re3);
  }
  Vec3 elastic(Vec3 r) const {
    return (kelvinlet(r, load, eps, nu) - kelvinlet(r, load, 2 * eps, nu)) * scale;
  }
  // The falloff P(t) = 1 for t <= plateau, W(u) (Falloff: without a plateau the quintic, else
  // the quartic) from there to t = 1, u going from 0 to 1.
  // Inside the plateau the field moves as a whole: an affine warp is exact there, and a snake
  // hook's tip keeps its thickness (with no plateau every move thinned it until the tentacle
  // was a needle thinner than a voxel and the tip was lost). A grab has none: a plateau
  // turned a long grab into a thinner tentacle (gradient error 0.56 at 3 radii, 0.33 without).
  // plateau is 0, kPlateau, or a snake hook's ball fitted to a narrower tip
  // (snakeHookVelocity()): u is (t - plateau) times outerScale = 1 / (1 - plateau), and
  // d falloff / d t2 = W'(u) outerScale / (2 t), set once instead of divided per point
  // (a snake hook move integrates the flow at a thousand points, four sub-steps of two
  // falloffs each); for kPlateau it is 2, the same bits as the division.
  // plateau and what follows from it, set together by setPlateau(): its square, outerScale, and
  // falloffOf(plateau) (a test of the plateau here, before the plateau's own, cost a snake hook
  // move 1.7% more instructions). A path pinch's kernel is the falloff in closed form: it sets
  // none of them.
  double plateau = 0, plateau2 = 0;
  double outerScale = 1 / (1 - kPlateau);
  Falloff falloffShape = Falloff::Quartic;
  void setPlateau(double p) {
    plateau = p, plateau2 = p * p;
    outerScale = 1 / (1 - p);
    falloffShape = falloffOf(p);
  }
  double falloff(double t2) const {
    return falloffShape == Falloff::Quintic ? shapeFalloff<Falloff::Quintic>(t2) : shapeFalloff<Falloff::Quartic>(t2);
  }
  // falloff() of the shape kShape (falloffShape). The quintic has no plateau (falloffOf()):
  // u = (t - 0) 1 = t, and its value at t2 = 0 is 1 without the plateau's test (a grab's flow
  // takes two falloffs a sub-step: with capsuleFlow()'s truncation, 1.6% of a 20 vu grab's
  // instructions left out).
  template <Falloff kShape>
  [[gnu::always_inline]] double shapeFalloff(double t2) const {
    if constexpr (kShape == Falloff::Quintic) {
      const double u = std::sqrt(t2);
      return 1 - u * u * u * (10 - u * (15 - 6 * u));
    } else {
      if (t2 <= plateau2) return 1;
      const double u = (std::sqrt(t2) - plateau) * outerScale;
      return (1 - u * u) * (1 - u * u);
    }
  }
  // d falloff / d t2.
  double falloffSlope(double t2) const { return falloffWithSlope(t2).second; }

  // falloff(t2) and falloffSlope(t2), sharing the root.
  std::pair<double, double> falloffWithSlope(double t2) const {
    return falloffShape == Falloff::Quintic ? shapeFalloffWithSlope<Falloff::Quintic>(t2)
                                            : shapeFalloffWithSlope<Falloff::Quartic>(t2);
  }
  // falloffWithSlope() of the shape kShape (falloffShape), as shapeFalloff(): the quintic's
  // plateau is 0 and its outerScale 1, and its test is that of t = 0, where the slope would
  // divide by t.
  template <Falloff kShape>
  [[gnu::always_inline]] std::pair<double, double> shapeFalloffWithSlope(double t2) const {
    if constexpr (kShape == Falloff::Quintic) {
      if (t2 <= 0) return {1, 0};
      const double u = std::sqrt(t2);
      const double w = u * (1 - u);
      return {1 - u * u * u * (10 - u * (15 - 6 * u)), -15 * w * w / u};
    } else {
      if (t2 <= plateau2) return {1, 0};
      const double t = std::sqrt(t2);
      const double u = (t - plateau) * outerScale;
      return {(1 - u * u) * (1 - u * u), -2 * outerScale * u * (1 - u * u) / t};
    }
  }

  // v(y) and its Jacobian J (J[i][j] = d v_i / d y_j).
  Vec3 at(Vec3 y, double J[3][3]) const {
    const Vec3 r = y - anchor;
    const double R2 = radius * radius;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) J[i][j] = 0;
    if (kind == Kind::Elastic) {
      // Central differences: this runs only along the flows of the voxels next to the zero set.
      if (dot(r, r) >= R2) return {};
      const double h = 1e-4 * eps;
      for (int j = 0; j < 3; ++j) {
        Vec3 lo = y, hi = y;
        lo[j] -= h;
        hi[j] += h;
        const Vec3 dv = (at(hi) - at(lo)) / (2 * h);
        for (int i = 0; i < 3; ++i) J[i][j] = dv[i];
      }
      return at(y);
    }
    if (kind == Kind::PathPinch) {
      // v = -scale I s across, s = across . (y - anchor): J = -scale across (I across + s grad I)^T.
      Vec3 gi;
      const double I = pathIntegral(y, &gi), s = dot(r, across);
      const Vec3 g = (across * I + gi * s) * -scale;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) J[i][j] = across[i] * g[j];
      return across * (-scale * I * s);
    }
    if (kind == Kind::Capsule) {
      const double t = segLength2 > 0 ? std::clamp(dot(r, seg) / segLength2, 0.0, 1.0) : 0.0;
      const Vec3 off = r - seg * t;
      const double rho2 = dot(off, off);
      if (rho2 >= R2) return {};
      // grad rho^2 = 2 off whether t is clamped or not (off is normal to seg when it is not).
      const Vec3 g = off * (2 * scale * falloffSlope(rho2 / R2) / R2);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) J[i][j] = seg[i] * g[j];
      return seg * (scale * falloff(rho2 / R2));
    }
    const double r2 = dot(r, r);
    if (r2 >= R2) return {};
    const double p = falloff(r2 / R2);
    const Vec3 ar{A[0][0] * r.x + A[0][1] * r.y + A[0][2] * r.z, A[1][0] * r.x + A[1][1] * r.y + A[1][2] * r.z,
                  A[2][0] * r.x + A[2][1] * r.y + A[2][2] * r.z};
    const Vec3 g = r * (2 * falloffSlope(r2 / R2) / R2);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) J[i][j] = p * A[i][j] + ar[i] * g[j];
    return ar * p;
  }

  Vec3 at(Vec3 y) const {
    const Vec3 r = y - anchor;
    const double R2 = radius * radius;
    if (kind == Kind::PathPinch) return across * (-scale * pathIntegral(y, nullptr) * dot(r, across));
    if (kind == Kind::Capsule) {
      const double t = segLength2 > 0 ? std::clamp(dot(r, seg) / segLength2, 0.0, 1.0) : 0.0;
      const Vec3 off = r - seg * t;
      const double rho2 = dot(off, off);
      if (rho2 >= R2) return {};
      return seg * (scale * falloff(rho2 / R2));
    }
    const double r2 = dot(r, r);
    if (r2 >= R2) return {};
    const double p = falloff(r2 / R2);
    if (kind == Kind::Elastic) return elastic(r) * p;
    return Vec3{A[0][0] * r.x + A[0][1] * r.y + A[0][2] * r.z, A[1][0] * r.x + A[1][1] * r.y + A[1][2] * r.z,
                A[2][0] * r.x + A[2][1] * r.y + A[2][2] * r.z} *
           p;
  }

  // Whether y lies in the support's interior (elsewhere v = 0 and the flow leaves y alone).
  bool moves(Vec3 y) const {
    const Vec3 r = y - anchor;
    if (alongSegment()) {
      const double t = segLength2 > 0 ? std::clamp(dot(r, seg) / segLength2, 0.0, 1.0) : 0.0;
      const Vec3 off = r - seg * t;
      return dot(off, off) < radius * radius;
    }
    return dot(r, r) < radius * radius;
  }

  // A range [x0, x1) of the row (y, z) of `box` holding every voxel where moves() holds (a
  // superset: the support grown by a voxel, whose rows are intervals, as it is convex), so
  // that the loops over a box need not test each voxel of its rows outside the support.
  std::pair<int, int> row(int y, int z, const Box& box) const {
    const double R = radius + 1, R2 = R * R;
    double lo = 1e300, hi = -1e300;
    const auto ball = [&](Vec3 c) {
      const double rest = R2 - (y - c.y) * (y - c.y) - (z - c.z) * (z - c.z);
      if (rest <= 0) return;
      lo = std::min(lo, c.x - std::sqrt(rest));
      hi = std::max(hi, c.x + std::sqrt(rest));
    };
    ball(anchor);
    if (alongSegment() && segLength2 > 0) {
      ball(anchor + seg);
      // The cylinder between the end planes: for x = anchor.x + s, a(s) = a0 + s ax along the
      // axis and the squared distance to its line qa s^2 + qb s + qc + R^2.
      const double length = std::sqrt(segLength2);
      const Vec3 axis = seg / length, r0{0, y - anchor.y, z - anchor.z};
      const double ax = axis.x, a0 = dot(r0, axis);
      const double qa = 1 - ax * ax, qb = -2 * a0 * ax, qc = dot(r0, r0) - a0 * a0 - R2;
      double s0 = -1e300, s1 = 1e300;
      if (qa > 1e-9) {
        const double disc = qb * qb - 4 * qa * qc;
        if (disc <= 0) s0 = 1e300;
        else s0 = (-qb - std::sqrt(disc)) / (2 * qa), s1 = (-qb + std::sqrt(disc)) / (2 * qa);
      }
      if (std::fabs(ax) > 1e-9) {
        const double e0 = -a0 / ax, e1 = (length - a0) / ax;
        s0 = std::max(s0, std::min(e0, e1)), s1 = std::min(s1, std::max(e0, e1));
      } else if (a0 < -1 || a0 > length + 1) {
        s0 = 1e300;
      }
      if (s0 < s1) lo = std::min(lo, anchor.x + s0), hi = std::max(hi, anchor.x + s1);
    }
    if (!(lo <= hi)) return {box.lo.x, box.lo.x};
    const int x0 = int(std::max(double(box.lo.x), std::floor(lo) - 1));
    const int x1 = int(std::min(double(box.hi.x), std::ceil(hi) + 2));
    return {x0, std::max(x0, x1)};
  }

  // An upper bound of |grad v|: the bound of the call that made the field
  // (../level_set.hpp, grabSlopeBound and the others) at its scale.
  double lipschitz() const {
    switch (kind) {
      case Kind::Capsule: return capsuleSlope(scale * std::sqrt(segLength2), radius, plateau);
      case Kind::PathPinch: return pinchAlongSlopeBound(std::sqrt(segLength2), amount, radius);
      case Kind::Elastic: return elasticSlope(scale * length(load), eps);
      case Kind::Affine: break;
    }
    return affineBound;
  }

  int substeps() const { return std::max(1, int(std::ceil(lipschitz() / kWarpStretchPerStep))); }

  // The support's bounding box.
  Box support() const {
    if (alongSegment()) {
      Box b = boxAround(anchor, {radius, radius, radius});
      const Box e = boxAround(anchor + seg, {radius, radius, radius});
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min(b.lo[a], e.lo[a]);
        b.hi[a] = std::max(b.hi[a], e.hi[a]);
      }
      return b;
    }
    return boxAround(anchor, {radius, radius, radius});
  }

  // The flow for unit time from y, forward (+v) or backward (-v), in n midpoint sub-steps.
  Vec3 flow(Vec3 y, int n, double direction) const {
    if (kind == Kind::Capsule)
      return falloffShape == Falloff::Quintic ? capsuleFlow<Falloff::Quintic>(y, n, direction)
                                              : capsuleFlow<Falloff::Quartic>(y, n, direction);
    if (kind == Kind::PathPinch) return pinchFlow(y, n, direction);
    const double dt = direction / n;
    for (int i = 0; i < n; ++i) {
      const Vec3 mid = y + at(y) * (0.5 * dt);
      y = y + at(mid) * dt;
    }
    return y;
  }

  // Calls visit(point) at points along the backward flow from y (the path of the clay that
  // arrives at y), no two of them more than kPathSpacing vu apart, X(y) last: a capsule's
  // paths are straight (capsuleFlow()), and so are a path pinch's (its velocity is along
  // `across` everywhere); the others' are followed sub-step by sub-step.
  static constexpr double kPathSpacing = 0.5;
  template <class Visit>
  void visitPath(Vec3 y, int n, Vec3 x, Visit visit) const {
    if (alongSegment()) {
      const int k = std::max(1, int(std::ceil(length(x - y) / kPathSpacing)));
      for (int i = 0; i <= k; ++i) visit(y + (x - y) * (double(i) / k));
      return;
    }
    // |v| <= lipschitz() * 2 radius (v vanishes on the support's boundary): sub-steps that
    // short move at most kPathSpacing.
    const int m = std::max(n, int(std::ceil(2 * lipschitz() * radius / kPathSpacing)));
    const double dt = -1.0 / m;
    visit(y);
    for (int i = 0; i < m; ++i) {
      const Vec3 mid = y + at(y) * (0.5 * dt);
      y = y + at(mid) * dt;
      visit(y);
    }
  }

  // flow() of a capsule. Its velocity is parallel to seg everywhere, so a point moves along
  // the line through it parallel to seg and its distance to the segment's line stays put: the
  // midpoint rule runs on the one coordinate a along seg. Between the segment's end planes the
  // velocity does not depend on a, and there a run of sub-steps is one move (what the midpoint
  // rule gives step by step, up to rounding): a point pays sub-steps only in the end caps.
  // Inlined: once flow() also dispatched the path pinch, the compiler called it instead, 1.4%
  // more instructions a snake hook move. The falloff's shape is a parameter, which flow()
  // tests once a call (shapeFalloff()).
  template <Falloff kShape>
  [[gnu::always_inline]] Vec3 capsuleFlow(Vec3 y, int n, double direction) const {
    if (!(segLength2 > 0)) return y;
    const double length = segLength, R2 = radius * radius;
    const Vec3 axis = segAxis;
    const Vec3 r = y - anchor;
    const double a0 = dot(r, axis);
    const Vec3 off = r - axis * a0;
    const double perp2 = dot(off, off);
    if (perp2 >= R2) return y;
    const double speed = scale * length;
    const auto velocity = [&](double a) {
      const double e = a < 0 ? -a : a > length ? a - length : 0;
      const double rho2 = perp2 + e * e;
      return rho2 < R2 ? speed * shapeFalloff<kShape>(rho2 / R2) : 0.0;
    };
    // Where the speed is zero (beyond the end caps) every sub-step stays put.
    if (velocity(a0) == 0) return y;
    const double dt = direction / n, step = dt * speed * shapeFalloff<kShape>(perp2 / R2);
    double a = a0;
    for (int i = 0; i < n;) {
      if (a >= 0 && a <= length && step != 0) {
        // Sub-steps that start and end between the end planes.
        // room >= 0: truncation is its floor (std::floor a sequence of instructions without
        // SSE4.1), and it may be too large for an int.
        const double room = step < 0 ? a / -step : (length - a) / step;
        const int k = room < n - i ? int(room) : n - i;
        if (k > 0) {
          a += k * step;
          i += k;
          continue;
        }
      }
      const double mid = a + 0.5 * dt * velocity(a);
      a += dt * velocity(mid);
      ++i;
    }
    return y + axis * (a - a0);
  }

  // inverseWithJacobian() of a capsule, on the coordinates of capsuleFlow(): a along seg and
  // q, the squared distance to its line, which the flow keeps. With f(a, q) the speed, the
  // backward flow is a' = -f, and the variational equation follows m = da/da0 and
  // w = da/dq by the same midpoint rule (the general one restricted to this flow):
  // X(y) = y + axis (a - a0), DX = I + axis (m axis + 2 w off - axis)^T. The falloff's shape is
  // a parameter, as capsuleFlow()'s.
  template <Falloff kShape>
  Vec3 capsuleInverseWithJacobian(Vec3 y, int n, double X[3][3]) const {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) X[i][j] = i == j ? 1 : 0;
    if (!(segLength2 > 0)) return y;
    const double length = segLength, R2 = radius * radius;
    const Vec3 axis = segAxis;
    const Vec3 r = y - anchor;
    const double a0 = dot(r, axis);
    const Vec3 off = r - axis * a0;
    const double q = dot(off, off);
    if (q >= R2) return y;
    const double speed = scale * length;
    // f, df/da and df/dq at a.
    struct Speed {
      double f = 0, fa = 0, fq = 0;
    };
    const auto speedAt = [&](double a) {
      const double e = a < 0 ? -a : a > length ? a - length : 0;
      const double rho2 = q + e * e;
      Speed out;
      if (rho2 >= R2) return out;
      const auto [fall, fallSlope] = shapeFalloffWithSlope<kShape>(rho2 / R2);
      const double slope = speed * fallSlope / R2;
      out.f = speed * fall;
      out.fa = slope * 2 * (a < 0 ? a : e);
      out.fq = slope;
      return out;
    };
    const double dt = 1.0 / n;
    const Speed inside = speedAt(0);  // between the end planes
    double a = a0, m = 1, w = 0;
    for (int i = 0; i < n;) {
      if (a >= 0 && a <= length && inside.f > 0) {
        // Sub-steps that start and end between the end planes: f_a = 0 there. room >= 0:
        // truncation is its floor (as in capsuleFlow()).
        const double room = a / (dt * inside.f);
        const int k = room < n - i ? int(room) : n - i;
        if (k > 0) {
          a -= k * (dt * inside.f);
          w -= k * (dt * inside.fq);
          i += k;
          continue;
        }
      }
      const Speed s0 = speedAt(a);
      const double mid = a - 0.5 * dt * s0.f;
      const double mMid = m - 0.5 * dt * s0.fa * m, wMid = w - 0.5 * dt * (s0.fa * w + s0.fq);
      const Speed s1 = speedAt(mid);
      a -= dt * s1.f;
      m -= dt * s1.fa * mMid;
      w -= dt * (s1.fa * wMid + s1.fq);
      ++i;
    }
    const Vec3 g = axis * (m - 1) + off * (2 * w);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) X[i][j] += axis[i] * g[j];
    return y + axis * (a - a0);
  }

  // The same backwards, with the Jacobian of the map y -> X(y) (the variational equation
  // dJ/dt = -grad v J, by the same midpoint rule).
  Vec3 inverseWithJacobian(Vec3 y, int n, double X[3][3]) const {
    if (kind == Kind::Capsule)
      return falloffShape == Falloff::Quintic ? capsuleInverseWithJacobian<Falloff::Quintic>(y, n, X)
                                              : capsuleInverseWithJacobian<Falloff::Quartic>(y, n, X);
    if (kind == Kind::PathPinch) return pinchInverseWithJacobian(y, n, X);
    const double dt = 1.0 / n;
    double J[3][3], Jm[3][3], M[3][3], G[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) M[i][j] = i == j ? 1 : 0;
    for (int s = 0; s < n; ++s) {
      const Vec3 v0 = at(y, G);
      const Vec3 mid = y - v0 * (0.5 * dt);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Jm[i][j] = M[i][j] - 0.5 * dt * (G[i][0] * M[0][j] + G[i][1] * M[1][j] + G[i][2] * M[2][j]);
      const Vec3 v1 = at(mid, J);
      y = y - v1 * dt;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) M[i][j] -= dt * (J[i][0] * Jm[0][j] + J[i][1] * Jm[1][j] + J[i][2] * Jm[2][j]);
    }
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) X[i][j] = M[i][j];
    return y;
  }
};

// A grid as its reads see it: the origin converted to double once (each read converted it), the
// data and strides at hand.
struct GridReads {
  const float* v;
  Int3 size;
  std::size_t sx, sxy;
  Vec3 lo;
  explicit GridReads(const DenseGrid& g)
      : v(g.v.data()), size(g.size), sx(g.sx), sxy(g.sxy), lo{double(g.box.lo.x), double(g.box.lo.y), double(g.box.lo.z)} {}
};

// Trilinear interpolation of g at p; +band off the grid (the grid reaches past the support, and
// off the domain the field is air). Inlined: a call per read cost a fifth of the read.
// kInGrid: the caller knows p lies in the grid, at least a voxel below its upper faces (a read
// of the resample's: see applyWarp's inGrid), and the tests are left out (a tenth of a snake
// hook move's instructions went to them).
// One axis of a trilinear read at the coordinate p, the grid's origin lo along it: the cell and
// the fraction in it, or off the grid. Truncation is the floor from 0 up, and cheaper (std::floor
// is a sequence of instructions without SSE4.1): below 0 (or NaN) the point is off the grid
// anyway.
struct ReadAxis {
  long cell;
  double t;
  bool in;
};
template <bool kInGrid>
[[gnu::always_inline]] inline ReadAxis readAxis(double p, double lo, int size) {
  const double q = p - lo;
  if (!kInGrid && !(q >= 0)) return {0, 0, false};
  const long i = long(q);
  if (!kInGrid && i + 1 >= size) return {0, 0, false};
  return {i, q - double(i), true};
}
template <bool kInGrid>
[[gnu::always_inline]] inline double trilinearAt(const GridReads& g, const ReadAxis& x, const ReadAxis& y, const ReadAxis& z,
                                                  float band) {
  if (!kInGrid && !(x.in && y.in && z.in)) return band;
  const float* c = g.v + std::size_t(x.cell) + g.sx * std::size_t(y.cell) + g.sxy * std::size_t(z.cell);
  const auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
  const double c00 = lerp(c[0], c[1], x.t), c10 = lerp(c[g.sx], c[g.sx + 1], x.t);
  const double c01 = lerp(c[g.sxy], c[g.sxy + 1], x.t), c11 = lerp(c[g.sxy + g.sx], c[g.sxy + g.sx + 1], x.t);
  return lerp(lerp(c00, c10, y.t), lerp(c01, c11, y.t), z.t);
}
template <bool kInGrid = false>
[[gnu::always_inline]] inline double trilinear(const GridReads& g, Vec3 p, float band) {
  return trilinearAt<kInGrid>(g, readAxis<kInGrid>(p.x, g.lo.x, g.size.x), readAxis<kInGrid>(p.y, g.lo.y, g.size.y),
                              readAxis<kInGrid>(p.z, g.lo.z, g.size.z), band);
}

// The central differences of trilinear() over +-h along each axis at p, (read(p + h e_a) -
// read(p - h e_a)) / (2 h), each axis's cells found once for the six reads (the same bits).
template <bool kInGrid>
[[gnu::always_inline]] inline Vec3 centralDifferences(const GridReads& g, Vec3 p, double h, float band) {
  ReadAxis at[3], below[3], above[3];
  for (int a = 0; a < 3; ++a) {
    at[a] = readAxis<kInGrid>(p[a], g.lo[a], g.size[a]);
    below[a] = readAxis<kInGrid>(p[a] - h, g.lo[a], g.size[a]);
    above[a] = readAxis<kInGrid>(p[a] + h, g.lo[a], g.size[a]);
  }
  return {(trilinearAt<kInGrid>(g, above[0], at[1], at[2], band) - trilinearAt<kInGrid>(g, below[0], at[1], at[2], band)) / (2 * h),
          (trilinearAt<kInGrid>(g, at[0], above[1], at[2], band) - trilinearAt<kInGrid>(g, at[0], below[1], at[2], band)) / (2 * h),
          (trilinearAt<kInGrid>(g, at[0], at[1], above[2], band) - trilinearAt<kInGrid>(g, at[0], at[1], below[2], band)) / (2 * h)};
}

// Catmull-Rom (cubic convolution) interpolation of g at p over the 4x4x4 voxels around it, into
// `out`; false, `out` untouched, where a tap lies off the grid. It reproduces quadratics: the
// trilinear interpolant of a distance lies t(1 - t)/2 d2phi/dx2 above it along each axis,
// h^2 kappa / 8 on a convex surface, the zero set that far inside the true one, and a snake hook
// resamples its tip at every move. Taps that read the band's clamp are used as they are: for a
// point on the surface only taps outside its cell along two axes or more lie farther than the
// band (sqrt(6) vu at most for the others), with weights of 0.074^2 at most. Falling back to the
// trilinear read where any tap read the clamp lost thin tips again (measured 2026-11-30, 70 vu
// from a sphere: at radius 5 a helix path 1.03 vu outside the clay against 0.27 vu; at radius
// 4 the tip of a slant 0.2 vu off against 0.01).
// kGradient: also the interpolant's own gradient into `grad` (the derivatives of the weights
// along one axis each, over the same taps), `out` the same bits as without it.
template <bool kGradient = false>
[[gnu::always_inline]] inline bool tricubic(const GridReads& g, Vec3 p, double& out, Vec3* grad = nullptr) {
  const Vec3 q{p.x - g.lo.x, p.y - g.lo.y, p.z - g.lo.z};
  // As in trilinear(): truncation is the floor from 1 up, and below 1 a tap is off the grid.
  if (!(q.x >= 1 && q.y >= 1 && q.z >= 1)) return false;
  const long ix = long(q.x), iy = long(q.y), iz = long(q.z);
  if (ix + 2 >= g.size.x || iy + 2 >= g.size.y || iz + 2 >= g.size.z) return false;
  // The taps are summed in float, a row of four at a time along x, as the voxels are stored:
  // the weights are at most 1.5 and the values at most the band.
  float w[3][4], dw[3][4];
  const double f[3] = {q.x - double(ix), q.y - double(iy), q.z - double(iz)};
  for (int a = 0; a < 3; ++a) {
    const double t = f[a], t2 = t * t, t3 = t2 * t;
    w[a][0] = float(0.5 * (-t3 + 2 * t2 - t));
    w[a][1] = float(0.5 * (3 * t3 - 5 * t2 + 2));
    w[a][2] = float(0.5 * (-3 * t3 + 4 * t2 + t));
    w[a][3] = float(0.5 * (t3 - t2));
    if constexpr (kGradient) {
      dw[a][0] = float(0.5 * (-3 * t2 + 4 * t - 1));
      dw[a][1] = float(0.5 * (9 * t2 - 10 * t));
      dw[a][2] = float(0.5 * (-9 * t2 + 8 * t + 1));
      dw[a][3] = float(0.5 * (3 * t2 - 2 * t));
    }
  }
  const float* c = g.v + std::size_t(ix - 1) + g.sx * std::size_t(iy - 1) + g.sxy * std::size_t(iz - 1);
  // A slice's four row weights w[1][j] w[2][k] in one product, each row's four taps in one:
  // the same floats as one by one, and 3.4% fewer instructions a snake hook move than the
  // loops over plain arrays the compiler was left to vectorize.
  using Four = float __attribute__((vector_size(16)));
  Four wy, dwy, column = {0, 0, 0, 0}, columnDy = column, columnDz = column;
  std::memcpy(&wy, w[1], sizeof wy);
  if constexpr (kGradient) std::memcpy(&dwy, dw[1], sizeof dwy);
  for (int k = 0; k < 4; ++k) {
    const Four wjk = wy * w[2][k];
    Four dyjk, dzjk;
    if constexpr (kGradient) dyjk = dwy * w[2][k], dzjk = wy * dw[2][k];
    for (int j = 0; j < 4; ++j) {
      Four r;
      std::memcpy(&r, c + g.sx * std::size_t(j) + g.sxy * std::size_t(k), sizeof r);
      column += Four{wjk[j], wjk[j], wjk[j], wjk[j]} * r;
      if constexpr (kGradient) {
        columnDy += Four{dyjk[j], dyjk[j], dyjk[j], dyjk[j]} * r;
        columnDz += Four{dzjk[j], dzjk[j], dzjk[j], dzjk[j]} * r;
      }
    }
  }
  const auto across = [](const float* wx, Four col) {
    return double(wx[0] * col[0] + wx[1] * col[1]) + double(wx[2] * col[2] + wx[3] * col[3]);
  };
  out = across(w[0], column);
  if constexpr (kGradient) *grad = {across(dw[0], column), across(w[0], columnDy), across(w[0], columnDz)};
  return true;
}

Box unite(const Box& a, const Box& b);

// The box of the bricks where vol and base differ (empty when none): what earlier calls of the
// stroke changed. Only the bricks of the tiles vol does not share with base are looked at (the
// others are base's: vol was a copy of it), a layer of bricks per task: on a grab message's
// critical path this scan was the longest serial part.
Box changedSinceBase(const Volume& vol, const Volume& base, ThreadPool& pool) {
  const Int3 n = vol.brickDims();
  constexpr int T = Volume::kTileSide;
  std::vector<Box> layers(std::size_t(n.z));
  pool.parallelFor(std::size_t(n.z), [&](std::size_t z) {
    Box out{};
    for (int y = 0; y < n.y; ++y)
      for (int x = 0; x < n.x; ++x) {
        if (x % T == 0 && vol.sharesTile(base, {x, y, int(z)})) {
          x += T - 1;
          continue;
        }
        float uv = 0, ub = 0;
        const Int3 b{x, y, int(z)};
        const float* dv = vol.brickData(b, &uv);
        const float* db = base.brickData(b, &ub);
        if (dv == db && (dv || uv == ub) && vol.brickPaint(b) == base.brickPaint(b)) continue;
        out = unite(out, Bricks::box(b));
      }
    layers[z] = out;
  });
  Box out{};
  for (const Box& b : layers) out = unite(out, b);
  return out.intersect(vol.domain());
}

Box unite(const Box& a, const Box& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  Box u;
  for (int i = 0; i < 3; ++i) {
    u.lo[i] = std::min(a.lo[i], b.lo[i]);
    u.hi[i] = std::max(a.hi[i], b.hi[i]);
  }
  return u;
}

// The inverse map is integrated at the nodes of a lattice kLatticeStep vu apart and
// interpolated trilinearly between them: the flow was 90% of a grab's time when integrated at
// every voxel (and six more times at the voxels next to the zero set). X is smooth at the scale
// of the radius, and only decides the far voxels, whose values the redistance replaces anyway.
constexpr int kLatticeStep = 2;
// Voxels that read less than this through the lattice are read again through the flow
// integrated at the voxel: they hold the zero set (and the lattice's error, measured up to
// 0.76 vu at the peak of a 3-radius grab, stays below the margin).
constexpr float kExactNear = 2.0f;
static_assert(kLatticeStep == 2, "InverseLattice::inverse: a voxel's weights are 0 or 1/2");
// The redistance's moved boxes are the boxes of the changed voxels of slabs of this many
// slices. With one box of them all, grown by a voxel (before 2026-11-29), a snake hook move of
// 2 vu at radius 8 took 5.07M instructions; with slabs of 1, 2, 4 or 8 slices 4.83M, 4.76M,
// 4.74M, 4.75M, with one box not grown 4.76M (its march and classification the smaller).
constexpr int kMovedSlab = 4;
// The side of the blocks InverseLattice::findBlocks looks at the base in: a brick holds whole
// ones.
constexpr int kUniformBlock = std::min(4, Bricks::kSide);
static_assert(Bricks::kSide % kUniformBlock == 0);
// The blocks findBlocks looks at cover the support's box grown by this: the lattice's cells
// read within it (their corners' preimages lie in the support or are nodes at most a voxel past
// it, and trilinear() reads the next voxel up); a cell that would read past it is read voxel
// by voxel (cellValue() says NaN).
constexpr int kBlockReach = 2;

struct InverseLattice {
  Int3 origin, nodes;
  std::vector<Vec3> offset;  // X(node) - node, x fastest
  // X(node) as flow() gave it, for the nodes the flow moves (moves()): a voxel on a node that
  // wants the exact flow (the resample, kExactNear) takes it from here, the same bits.
  std::vector<Vec3> image;

  // withBlocks: findBlocks() was called, and each node's blocks are noted (nodeBlocks).
  void build(const Velocity& v, const Box& work, bool withBlocks, ThreadPool& pool, const ProgressShare& progress) {
    origin = work.lo;
    for (int a = 0; a < 3; ++a) nodes[a] = (work.size()[a] + kLatticeStep - 1) / kLatticeStep + 1;
    offset.assign(std::size_t(nodes.x) * nodes.y * nodes.z, Vec3{});
    image.resize(offset.size());
    if (withBlocks) {
      nodeBlocks.resize(offset.size());
      for (int a = 0; a < 3; ++a) {
        nodeAxisBlocks[std::size_t(a)].resize(std::size_t(nodes[a]));
        for (int i = 0; i < nodes[a]; ++i) nodeAxisBlocks[std::size_t(a)][std::size_t(i)] = axisBlocks(a, double(origin[a] + kLatticeStep * i));
      }
    }
    const int steps = v.substeps();
    pool.parallelFor(std::size_t(nodes.z), [&](std::size_t k) {
      progress.check();
      for (int j = 0; j < nodes.y; ++j)
        for (int i = 0; i < nodes.x; ++i) {
          const Vec3 p = node(i, j, int(k));
          const std::size_t n = index(i, j, int(k));
          const bool moves = v.moves(p);
          if (moves) {
            image[n] = v.flow(p, steps, -1);
            offset[n] = image[n] - p;
          }
          if (withBlocks)
            nodeBlocks[n] = moves ? blocksOf(p + offset[n])
                                  : nodeAxisBlocks[0][std::size_t(i)] | nodeAxisBlocks[1][std::size_t(j)] | nodeAxisBlocks[2][k];
        }
      progress.advance(1.0 / nodes.z);
    });
  }

  Vec3 node(int i, int j, int k) const {
    return {double(origin.x + kLatticeStep * i), double(origin.y + kLatticeStep * j), double(origin.z + kLatticeStep * k)};
  }
  std::size_t index(int i, int j, int k) const {
    return std::size_t(i) + std::size_t(nodes.x) * (std::size_t(j) + std::size_t(nodes.y) * std::size_t(k));
  }

  // Where the lattice's cells read one value. A cell's voxels read the base inside the box of
  // its corners' preimages (inverse() interpolates between them); where the base is one value
  // there, at least kExactNear from 0, each of those reads is that value bit for bit and the
  // exact flow is not wanted: deep inside and far outside the solid (most of a grab's support)
  // the resample is then a comparison. findBlocks() notes the base's blocks of one value,
  // cellValue() looks up a cell's.
  std::vector<float> blockValue;
  Int3 blockOrigin, blockCount;
  // Per node, the blocks (from blockOrigin) that trilinear() reads for points within rounding
  // of its preimage: the first's three coordinates and the last's negated, kOffBlocks where
  // that is off the grid or the blocks noted; a cell's blocks are then the lanewise least of
  // its eight corners' (the box of the preimages' blocks is the blocks of the preimages' box:
  // the block of a coordinate is monotonic in it), 8 loads and 7 minima. Per cell, the
  // preimages' box had taken ~450 instructions with the loop over its blocks (a grab at 20 vu
  // looks up ~8,000 cells).
  using NodeBlocks = std::int16_t __attribute__((vector_size(16)));
  static constexpr std::int16_t kOffBlocks = std::numeric_limits<std::int16_t>::min();
  // A grid's blocks along an axis (the support within the domain, grown by a few voxels) fit
  // the lanes.
  static_assert(kMaxDomainSide / kUniformBlock + 16 < std::numeric_limits<std::int16_t>::max());
  std::vector<NodeBlocks> nodeBlocks;
  // The blocks of value +band and of value -band in [0, i) x [0, j) x [0, k) of the blocks
  // noted, packed as plus + 2^32 minus (mod 2^64 the box sums of the inclusion-exclusion are
  // exact): whether a cell's blocks are all one such value is 8 loads.
  std::vector<std::uint64_t> bandCounts;
  float bandValue = 0;
  Box gridBox;

  void findBlocks(const Volume& vol, const DenseGrid& base, const Box& within, float band, ThreadPool& pool) {
    // vol's value per block of kUniformBlock^3 voxels (in volume coordinates, within bricks)
    // over base's box, NaN where it varies, lies within kExactNear of 0 or leaves the domain:
    // a brick stored uniform gives its blocks at once, the others are scanned.
    constexpr int B = kUniformBlock, perBrick = Bricks::kSide / B;
    const Box box = within.intersect(base.box);
    const Int3 b0{blockOf(box.lo.x), blockOf(box.lo.y), blockOf(box.lo.z)};
    const Int3 nb{blockOf(box.hi.x - 1) - b0.x + 1, blockOf(box.hi.y - 1) - b0.y + 1, blockOf(box.hi.z - 1) - b0.z + 1};
    blockOrigin = b0, blockCount = nb, bandValue = band;
    blockValue.assign(std::size_t(nb.x) * std::size_t(nb.y) * std::size_t(nb.z), std::numeric_limits<float>::quiet_NaN());
    const Int3 dims = vol.dims();
    pool.parallelFor(std::size_t(nb.z), [&](std::size_t kz) {
      const int bz = b0.z + int(kz);
      if (bz < 0 || (bz + 1) * B > dims.z) return;
      for (int ky = 0; ky < nb.y; ++ky) {
        const int by = b0.y + ky;
        if (by < 0 || (by + 1) * B > dims.y) continue;
        float* out = blockValue.data() + std::size_t(nb.x) * (std::size_t(ky) + std::size_t(nb.y) * kz);
        for (int kx = 0; kx < nb.x; ++kx) {
          const int bx = b0.x + kx;
          if (bx < 0 || (bx + 1) * B > dims.x) continue;
          const Int3 l{(bx % perBrick) * B, (by % perBrick) * B, (bz % perBrick) * B};
          float u = 0;
          const float* data = vol.brickData({bx / perBrick, by / perBrick, bz / perBrick}, &u);
          bool same = true;
          if (data) {
            u = data[Bricks::index(l)];
            for (int z = 0; z < B; ++z)
              for (int y = 0; y < B; ++y) {
                const float* row = data + Bricks::index(l.x, l.y + y, l.z + z);
                for (int x = 0; x < B; ++x) same &= row[x] == u;
              }
          }
          if (same && std::fabs(u) >= kExactNear) out[kx] = u;
        }
      }
    });
    // The counts, one pass over the blocks (a few thousand).
    const std::size_t cx = std::size_t(nb.x) + 1, cxy = cx * (std::size_t(nb.y) + 1);
    bandCounts.assign(cxy * (std::size_t(nb.z) + 1), 0);
    for (int k = 0; k < nb.z; ++k)
      for (int j = 0; j < nb.y; ++j)
        for (int i = 0; i < nb.x; ++i) {
          const float u = blockAt(b0.x + i, b0.y + j, b0.z + k);
          const std::uint64_t own = u == band ? 1 : u == -band ? std::uint64_t(1) << 32 : 0;
          std::uint64_t* c = bandCounts.data() + std::size_t(i + 1) + cx * std::size_t(j + 1) + cxy * std::size_t(k + 1);
          *c = own + c[-1] + c[-std::ptrdiff_t(cx)] + c[-std::ptrdiff_t(cxy)] - c[-std::ptrdiff_t(cx) - 1] -
               c[-std::ptrdiff_t(cxy) - 1] - c[-std::ptrdiff_t(cxy + cx)] + c[-std::ptrdiff_t(cxy + cx) - 1];
        }
    gridBox = base.box;
  }

  // The blocks of the voxels trilinear() reads for points within 1e-6 of the preimage q, all
  // within the grid (off it trilinear() reads +band), as NodeBlocks: a cell's voxels' reads are
  // convex combinations of its corners' preimages up to a few ulps. One vector per axis, which
  // sets its two lanes. From the grid's corner up truncation is the floor (and std::floor a
  // sequence of instructions without SSE4.1), and an arithmetic shift the floor of a division
  // by the block's side: blockOf(c) - blockOrigin for c = int(from) + gridBox.lo.
  NodeBlocks axisBlocks(int a, double q) const {
    static_assert(kUniformBlock == 4);
    const double from = q - 1e-6 - gridBox.lo[a], to = q + 1e-6 - gridBox.lo[a];
    const int shift = gridBox.lo[a] - kUniformBlock * blockOrigin[a];
    const int first = from >= 0 ? (int(from) + shift) >> 2 : -1;
    const int last = to < gridBox.hi[a] - gridBox.lo[a] - 1 ? (int(to) + 1 + shift) >> 2 : blockCount[a];
    NodeBlocks out{};
    out[a] = first >= 0 ? std::int16_t(first) : kOffBlocks;
    out[a + 3] = last < blockCount[a] ? std::int16_t(-last) : kOffBlocks;
    return out;
  }
  NodeBlocks blocksOf(Vec3 q) const { return axisBlocks(0, q.x) | axisBlocks(1, q.y) | axisBlocks(2, q.z); }
  // axisBlocks() of the nodes' own coordinates (the preimages of the nodes the flow leaves
  // alone, most of them), per axis.
  std::array<std::vector<NodeBlocks>, 3> nodeAxisBlocks;

  // The value every voxel of cell (i, j, k) reads from the base, when findBlocks() found one
  // block value over all it can read, else NaN.
  float cellValue(int i, int j, int k) const {
    const std::size_t sx = std::size_t(nodes.x), sxy = sx * std::size_t(nodes.y);
    const NodeBlocks* o = nodeBlocks.data() + index(i, j, k);
    const auto least = [](NodeBlocks a, NodeBlocks b) { return a < b ? a : b; };
    const NodeBlocks m = least(least(least(o[0], o[1]), least(o[sx], o[sx + 1])),
                               least(least(o[sxy], o[sxy + 1]), least(o[sxy + sx], o[sxy + sx + 1])));
    if (m[0] < 0 || m[1] < 0 || m[2] < 0 || m[3] == kOffBlocks || m[4] == kOffBlocks || m[5] == kOffBlocks)
      return std::numeric_limits<float>::quiet_NaN();
    const int x0 = m[0], y0 = m[1], z0 = m[2], x1 = -m[3], y1 = -m[4], z1 = -m[5];
    const float value = blockValue[std::size_t(x0) + std::size_t(blockCount.x) * (std::size_t(y0) + std::size_t(blockCount.y) * std::size_t(z0))];
    if (value == bandValue || value == -bandValue) {
      const std::size_t cx = std::size_t(blockCount.x) + 1, cxy = cx * (std::size_t(blockCount.y) + 1);
      const auto at = [&](int x, int y, int z) { return bandCounts[std::size_t(x) + cx * std::size_t(y) + cxy * std::size_t(z)]; };
      const std::uint64_t inBox = at(x1 + 1, y1 + 1, z1 + 1) - at(x0, y1 + 1, z1 + 1) - at(x1 + 1, y0, z1 + 1) - at(x1 + 1, y1 + 1, z0) +
                                  at(x0, y0, z1 + 1) + at(x0, y1 + 1, z0) + at(x1 + 1, y0, z0) - at(x0, y0, z0);
      const std::uint64_t all = std::uint64_t(x1 - x0 + 1) * std::uint64_t(y1 - y0 + 1) * std::uint64_t(z1 - z0 + 1);
      return inBox == (value == bandValue ? all : all << 32) ? value : std::numeric_limits<float>::quiet_NaN();
    }
    if (!(value == value)) return value;
    for (int bz = z0; bz <= z1; ++bz)
      for (int by = y0; by <= y1; ++by)
        for (int bx = x0; bx <= x1; ++bx)
          if (!(blockAt(blockOrigin.x + bx, blockOrigin.y + by, blockOrigin.z + bz) == value)) return std::numeric_limits<float>::quiet_NaN();
    return value;
  }

  // The block of a voxel coordinate (rounding down, also below 0: the grid reaches past the
  // domain by a few voxels).
  static int blockOf(int c) {
    constexpr int kBias = 1 << 12;
    static_assert(kBias % kUniformBlock == 0);
    return (c + kBias) / kUniformBlock - kBias / kUniformBlock;
  }

  float blockAt(int bx, int by, int bz) const {
    return blockValue[std::size_t(bx - blockOrigin.x) +
                      std::size_t(blockCount.x) * (std::size_t(by - blockOrigin.y) + std::size_t(blockCount.y) * std::size_t(bz - blockOrigin.z))];
  }

  // X(p) at the voxel p = (x, y, z) of `work`, the offsets interpolated trilinearly between
  // the nodes of its cell, along row(y, z). The nodes are kLatticeStep = 2 apart, so a voxel's
  // weight along each axis is 0 (on a node's plane) or 1/2: a weight of 0 takes the first of
  // each pair, as a + (b - a) 0 does up to the sign of a zero (which p + offset does not
  // see), and the interpolation runs only across the axes of weight 1/2, half its 4 + 2 + 1
  // steps on average.
  struct Row {
    const Vec3* o;  // the offsets of row (y, z)'s first cell
    bool ty, tz;    // whether its weights along y and z are 1/2
  };
  Row row(int y, int z) const {
    const unsigned dy = unsigned(y - origin.y), dz = unsigned(z - origin.z);
    return {offset.data() + index(0, int(dy / kLatticeStep), int(dz / kLatticeStep)), dy % kLatticeStep != 0, dz % kLatticeStep != 0};
  }
  // X(p) exactly (image) when the voxel p = (x, y, z) of row(y, z) lies on a node, else null.
  // Only for a voxel the flow moves: image holds only the moving nodes' (the others keep a
  // previous call's), and the resample asks only within each row's run of moving voxels.
  const Vec3* imageAt(const Row& r, int x) const {
    const unsigned dx = unsigned(x - origin.x);
    if (r.ty || r.tz || dx % kLatticeStep != 0) return nullptr;
    return image.data() + (r.o - offset.data()) + dx / kLatticeStep;
  }
  Vec3 inverse(const Row& r, Vec3 p, int x) const {
    const unsigned dx = unsigned(x - origin.x);
    const std::size_t sx = std::size_t(nodes.x), sxy = sx * std::size_t(nodes.y);
    const Vec3* o = r.o + dx / kLatticeStep;
    const bool tx = dx % kLatticeStep != 0;
    const auto half = [](Vec3 a, Vec3 b) { return a + (b - a) * 0.5; };
    const auto alongX = [&](std::size_t at) { return tx ? half(o[at], o[at + 1]) : o[at]; };
    Vec3 c = alongX(0);
    if (r.ty) c = half(c, alongX(sx));
    if (r.tz) {
      Vec3 above = alongX(sxy);
      if (r.ty) above = half(above, alongX(sxy + sx));
      c = half(c, above);
    }
    return p + c;
  }
};

struct WarpScratch {
  DenseGrid base, warped;
  InverseLattice lattice;
  // The channels of base over the grids' box, and the warped ones (painted volumes only).
  std::vector<Texel> texels, warpedTexels;
};

WarpScratch& warpScratch() {
  thread_local WarpScratch s;
  return s;
}

// The changes that take vol to base with `warped`'s distances over `region` and `texels`'s
// channels over their grid's box, within `all` (which holds both and every brick where vol
// differs from base), published. The distances are compared with base's (Volume::diff, whose
// mask holds them against base's, as one call of the stroke from base would), and each
// brick's `before` is vol's.
std::vector<BrickChange> writeBack(Volume& vol, const Volume& base, const Box& all, const Box& region,
                                   const DenseGrid& warped, const std::vector<Texel>& texels, ThreadPool& pool) {
  if (all.empty()) return {};
  DenseGrid out;
  out.gatherFrom(base, all, {}, pool);
  for (int z = region.lo.z; z < region.hi.z; ++z)
    for (int y = region.lo.y; y < region.hi.y; ++y)
      std::copy_n(&warped.v[warped.index({region.lo.x, y, z})], region.size().x, &out.v[out.index({region.lo.x, y, z})]);
  std::vector<BrickChange> found = base.diff(all, out.v.data(), out.box, pool);
  const Box bricks = Bricks::bricksOf(all);
  const Int3 nb = bricks.size();
  std::vector<std::vector<BrickChange>> layers(std::size_t(nb.z));
  std::size_t next = 0;  // found is in z, y, x order of the bricks
  std::vector<std::pair<std::size_t, std::size_t>> ranges(std::size_t(nb.z));
  for (int bz = 0; bz < nb.z; ++bz) {
    const std::size_t first = next;
    while (next < found.size() && found[next].brick.z == bricks.lo.z + bz) ++next;
    ranges[std::size_t(bz)] = {first, next};
  }
  const Texel plain = texelOf(base.baseColor());
  pool.parallelFor(std::size_t(nb.z), [&](std::size_t k) {
    const int bz = bricks.lo.z + int(k);
    std::size_t f = ranges[k].first;
    for (int by = bricks.lo.y; by < bricks.hi.y; ++by)
      for (int bx = bricks.lo.x; bx < bricks.hi.x; ++bx) {
        const Int3 b{bx, by, bz};
        BrickRef after;
        if (f < ranges[k].second && found[f].brick == b) {
          after = std::move(found[f++].after);
        } else {
          after = base.brick(b);
        }
        BrickRef before = vol.brick(b);
        if (after.data) {
          // The brick's channels: base's, with the warped ones where their grid reaches.
          const Box here = Bricks::box(b).intersect(warped.box);
          const BrickPaint* had = base.brickPaint(b);
          auto paint = std::make_shared<BrickPaint>();
          if (had) {
            *paint = *had;
          } else {
            std::fill(std::begin(paint->t), std::end(paint->t), plain);
          }
          const Int3 o = Bricks::origin(b);
          for (int z = here.lo.z; z < here.hi.z; ++z)
            for (int y = here.lo.y; y < here.hi.y; ++y)
              for (int x = here.lo.x; x < here.hi.x; ++x)
                paint->t[Bricks::index(x - o.x, y - o.y, z - o.z)] = texels[warped.index({x, y, z})];
          std::shared_ptr<const BrickPaint> now = vol.canonicalPaint(std::move(paint));
          // Equal channels keep the very BrickPaint they equal (no change where nothing moved).
          const auto same = [](const BrickPaint* a, const BrickPaint* c) {
            return a && c && std::equal(std::begin(a->t), std::end(a->t), std::begin(c->t));
          };
          if (now && same(now.get(), had)) now = base.brick(b).paint;
          if (now && same(now.get(), before.paint.get())) now = before.paint;
          after.paint = std::move(now);
        } else {
          after.paint = nullptr;
        }
        if (!(before == after)) layers[k].push_back({b, std::move(before), std::move(after)});
      }
  });
  std::vector<BrickChange> changes;
  for (auto& l : layers) std::move(l.begin(), l.end(), std::back_inserter(changes));
  vol.publish(changes, true);
  return changes;
}

// vol becomes base warped by the flow of v (../level_set.hpp, warps).
Edit applyWarp(Volume& vol, const Volume& base, const Velocity& v, ThreadPool& pool) {
  const float band = base.band();
  // As in applyStroke: a voxel band + 1 or more from every changed one keeps its distance; one
  // more voxel for the kept-voxel test at the region's edge and the stencils.
  const int reach = int(std::ceil(band + 1)) - 1;
  const int margin = reach + 2;
  const Box work = v.support().intersect(vol.domain());

  const ProgressShare share{Progress::current(), 1};
  WarpScratch& s = warpScratch();
  const Box gridBox = work.grown(margin);
  s.base.gatherFrom(base, gridBox, share.part(kGatherShare), pool);
  s.warped.box = s.base.box;
  s.warped.size = s.base.size;
  s.warped.sx = s.base.sx;
  s.warped.sxy = s.base.sxy;
  s.warped.v.assign(s.base.v.begin(), s.base.v.end());
  // Only the distances of an unpainted volume can be read a cell at a time (the channels want
  // each voxel's preimage).
  const bool painted = base.paintedBricks() != 0 || vol.paintedBricks() != 0;
  if (!painted) s.lattice.findBlocks(base, s.base, work.grown(kBlockReach), band, pool);
  s.lattice.build(v, work, !painted, pool, share.part(kLatticeShare));

  // Channels (../../channels.hpp), for a painted volume only: the colour is read back through
  // the same inverse map as the distance (the texel of the voxel nearest X(x)), so it moves
  // with the clay; the mask weight stays with its voxel. A voxel x of weight w moves by
  // (1 - w / 255) of what it would: its colour here, its distance where the result is written
  // (Volume::diff, against base). And clay does not pass through frozen clay: x keeps base's
  // distance and colour when a voxel of weight 255 lies on the clay's way from X(x) to x (x's
  // own left out), as a level-set tool stops the voxels of weight 255 (listing.cpp): a grab's
  // deep inside, which no mask reaches, is not carried through a frozen band into the air.
  bool masked = false;
  if (painted) {
    s.texels.resize(std::size_t(gridBox.voxels()));
    base.gatherTexels(gridBox, s.texels.data());
    s.warpedTexels = s.texels;
    for (const Texel& t : s.texels) masked = masked || t.mask != 0;
  }
  const auto texelIndex = [&](Vec3 q) -> std::ptrdiff_t {
    Int3 c;
    for (int a = 0; a < 3; ++a) c[a] = int(std::floor(q[a] + 0.5));
    return s.base.box.contains(c) ? std::ptrdiff_t(s.base.index(c)) : -1;
  };

  // Each pair of slices z of `work` (a layer of the lattice's cells) resamples its voxels and
  // notes, per slice, the box of those that changed, and of those whose channels changed.
  const int steps = v.substeps();
  const int slices = work.size().z, layers = (slices + kLatticeStep - 1) / kLatticeStep;
  std::vector<Box> changed(std::size_t(std::max(0, slices))), recoloured(changed.size());
  // Each row's run of voxels that the flow moves, (y, z) of work, for the pass after this one.
  const Int3 workSize = work.size();
  std::vector<std::pair<int, int>> runs(std::size_t(std::max(0, workSize.y)) * std::size_t(std::max(0, slices)));
  const auto runOf = [&](int y, int z) -> std::pair<int, int>& {
    return runs[std::size_t(y - work.lo.y) + std::size_t(workSize.y) * std::size_t(z - work.lo.z)];
  };
  const ProgressShare resample = share.part(kResampleShare);
  // The resample's reads, and the kept voxels' below (but the foot points'), lie within the
  // support grown by two voxels: its points' preimages stay in it (v vanishes on its boundary),
  // the lattice's nodes reach a voxel past it, and the slopes read half a voxel to each side.
  // When the grid holds that with a voxel to spare (a support within the domain: the margin is
  // wider), they are read without trilinear()'s tests.
  const Box readBox = v.support().grown(3);
  const bool inGrid = readBox.intersect(s.base.box) == readBox;
  const GridReads reads(s.base);
  const auto read = [&](Vec3 at) __attribute__((always_inline)) {
    return inGrid ? trilinear<true>(reads, at, band) : trilinear(reads, at, band);
  };
  // Next to the zero set, where the surface's place is read, the cubic interpolant (tricubic()):
  // the value trilinear() gives there lies h^2 kappa / 8 above a convex distance.
  const auto readNear = [&](Vec3 at) {
    double out;
    return tricubic(reads, at, out) ? out : read(at);
  };
  // The same where the point may lie anywhere (the foot points below).
  const auto readNearAnywhere = [&](Vec3 at) {
    double out;
    return tricubic(reads, at, out) ? out : trilinear(reads, at, band);
  };
  pool.parallelFor(std::size_t(std::max(0, layers)), [&](std::size_t layer) {
    resample.check();
    // The layer's cells' values (cellValue()), found as its voxels first need them: unknown
    // (infinity) until then.
    const int cellsX = s.lattice.nodes.x - 1;
    std::vector<float> cells;
    for (int i = int(layer) * kLatticeStep; i < std::min(slices, int(layer + 1) * kLatticeStep); ++i) {
      const int z = work.lo.z + i;
      Box c{{0, 0, 0}, {0, 0, 0}};
      bool any = false;
      const auto note = [&](int x, int y) {
        if (!any) c = {{x, y, z}, {x + 1, y + 1, z + 1}};
        c.lo.x = std::min(c.lo.x, x), c.lo.y = std::min(c.lo.y, y);
        c.hi.x = std::max(c.hi.x, x + 1), c.hi.y = std::max(c.hi.y, y + 1);
        any = true;
      };
      Box tc{};
      for (int y = work.lo.y; y < work.hi.y; ++y) {
        // The row's voxels that the flow moves, one run (the support is convex): only they
        // are resampled, and the others never ask for their cells' values.
        auto [x0, x1] = v.row(y, z, work);
        while (x0 < x1 && !v.moves({double(x0), double(y), double(z)})) ++x0;
        while (x1 > x0 && !v.moves({double(x1 - 1), double(y), double(z)})) --x1;
        runOf(y, z) = {x0, x1};
        const int cy = (y - work.lo.y) / kLatticeStep;
        const InverseLattice::Row latticeRow = s.lattice.row(y, z);
        float* cellRow = nullptr;
        if (!painted && x1 > x0) {
          if (cells.empty()) cells.assign(std::size_t(cellsX) * std::size_t(s.lattice.nodes.y - 1), std::numeric_limits<float>::infinity());
          cellRow = cells.data() + std::size_t(cellsX) * std::size_t(cy);
        }
        for (int x = x0; x < x1; ++x) {
          const std::size_t k = s.warped.index({x, y, z});
          if (cellRow) {
            // x >= work.lo.x: unsigned, the division is a shift (a signed one rounds towards 0).
            const int ci = int(unsigned(x - work.lo.x) / kLatticeStep);
            float& u = cellRow[ci];
            if (u == std::numeric_limits<float>::infinity()) u = s.lattice.cellValue(ci, cy, int(layer));
            // A voxel that reads its own value stays, whether the flow moves it or not.
            if (u == s.base.v[k]) continue;
            if (u == u) {
              s.warped.v[k] = u, note(x, y);
              continue;
            }
          }
          const Vec3 p{double(x), double(y), double(z)};
          Vec3 q = s.lattice.inverse(latticeRow, p, x);
          float value = float(read(q));
          // Near the zero set the surface's place is read: there X is integrated at the voxel.
          if (std::fabs(value) < kExactNear) {
            const Vec3* onNode = s.lattice.imageAt(latticeRow, x);
            q = onNode ? *onNode : v.flow(p, steps, -1);
            value = float(readNear(q));
          }
          if (painted) {
            bool stopped = false;
            if (masked)
              v.visitPath(p, steps, q, [&](Vec3 on) {
                const std::ptrdiff_t j = texelIndex(on);
                stopped = stopped || (j >= 0 && std::size_t(j) != k && s.texels[std::size_t(j)].mask == 255);
              });
            if (stopped) value = s.base.v[k];
            const std::ptrdiff_t from = texelIndex(q);
            const Texel own = s.texels[k];
            const Texel src = from >= 0 ? s.texels[std::size_t(from)] : texelOf(base.baseColor());
            // The colour's share that moves: none when the path is stopped, else (1 - w / 255) of
            // it (the write-back holds only distances).
            const float move = stopped ? 0.0f : 1.0f - float(own.mask) / 255.0f;
            const auto mix = [&](std::uint8_t a, std::uint8_t b) {
              return move == 1.0f ? b : std::uint8_t(std::lround(float(a) + move * (float(b) - float(a))));
            };
            const Texel now{mix(own.r, src.r), mix(own.g, src.g), mix(own.b, src.b), own.mask};
            if (!(now == own)) {
              s.warpedTexels[k] = now;
              tc = unite(tc, Box{{x, y, z}, {x + 1, y + 1, z + 1}});
            }
          }
          if (value == s.base.v[k]) continue;
          s.warped.v[k] = value;
          note(x, y);
        }
      }
      changed[std::size_t(i)] = any ? c : Box{};
      recoloured[std::size_t(i)] = tc;
      resample.advance(1.0 / slices);
    }
  });
  Box moved{}, texelsMoved{};
  for (const Box& c : changed) moved = unite(moved, c);
  for (const Box& c : recoloured) texelsMoved = unite(texelsMoved, c);

  // The changed voxels next to the zero set are the sources of the redistance. phi0(X(x)) is
  // not a distance where the map stretches or squeezes, and central differences of the voxels
  // cannot say by how much where it squeezes the band to a voxel or two: the gradient comes
  // from the chain rule through the map instead, and the value is phi1 / |grad phi1|, bounded by
  // the crossings on the voxel's edges as the redistance bounds its own normalisation.
  //
  // A grab (no plateau) shears its cone's sides: phi1 = phi0 o X is far from linear across a
  // voxel there, and where the map squeezes the band the voxel reads +-band, flat. There each
  // such voxel takes its distance to the zero set of phi1 itself, the continuous warped surface
  // (X integrated at each point, phi0 trilinear): Newton steps along grad phi1 from the voxel
  // find the foot point (phi1 / |grad phi1| is the first step's length); where phi1 is flat,
  // the surface is found on the edge to the neighbour across it by bisection, and the foot point
  // by Newton steps from the voxel's projection on the tangent plane there. On the tests'
  // 3-radius grab the voxels next to the zero set were 0.1-0.3 vu off on those sides (exact
  // 0.6-0.8): whole-volume gradient error 0.293 / 0.0116 against the exact field's 0.237 /
  // 0.00175, 0.234 / 0.00223 with foot points (tests/engine/level_set/test_warp.cpp). Not for
  // the path pinch, whose surface moved 0.24 vu.
  //
  // A snake hook's kept voxels take foot points around its tip only: within kTipFeetReach of
  // the plateau's capsule (the ball, sunk into the tip, swept along the move), and only when
  // the ball, the tip's radius, is at least kTipFeetBall. There phi1 / |grad phi1| left the
  // tip sharper than the exact field's (the 200 vu tentacle's gradient error 0.187 above its
  // foot, the exact tip's 0.036-0.050) and foot points hold it (0.077). Elsewhere they cost the
  // path: on a thin tip (the ball 2.5 vu at radius 5) the tentacle cut inside a helix's curve
  // 0.75 vu outside the path with foot points on the plateau alone (0.27 without), 1.28 vu
  // with them on every kept voxel; and in the falloff's outer part (2 vu past the plateau, or
  // everywhere) the radius 8 helix in moves of 2 vu left its path 0.31-0.32 vu (0.01 without).
  // With the trilinear read (before 2026-11-30) exact distances at the tip moved its zero set
  // inwards move after move (the 200 vu tentacle's path read 0.44 vu outside its surface).
  // The reach is 1.4 vu (1 before 2026-11-30): on a straight tentacle (radius 8, ball 4) the
  // tip's rim, 4 vu ahead of the anchor, was cut by the reach's edge: inside voxels with foot
  // points next to outside ones 5.3-5.5 vu from the plateau's segment with phi1 / |grad phi1|,
  // gradient error 0.147 there after 200 vu in moves of 2 vu (0.059 at 1.4; 0.12-0.16 at
  // 1.25-1.35). And on the sides just behind the tip, which every move resamples while its
  // support reaches them, phi1 / |grad phi1| moved the zero set out by about 0.002 vu a move
  // (|grad phi1| read above 1 outside the convex side, below 1 inside, its central differences
  // reaching the marched layer behind), and the redistance keeps those voxels: the sides' mean
  // 0.009 in moves of 1 vu (the exact cylinder's 0.005-0.006). That same outward drift holds the
  // helix's path (above) inside the clay: at 1.4 it read 0.13 vu outside, at 1.5 0.23 (with
  // the young tentacle's wider support, snakeHookVelocity(), 0.010 vu inside at 1.4).
  constexpr double kTipFeetReach = 1.4, kTipFeetBall = 3;
  constexpr double kSlopeStep = 0.5;
  // Newton steps to a foot point (at most: they stop once the next would be shorter than
  // kFootConverged vu; a 3-radius grab's figures moved by under 1% with 5 or 8), the residual
  // they must reach, and the bisections of a crossing (1/4096 of an edge).
  // The second step's phi1 is not read when the steps' quadratic convergence puts the third
  // below kFootSure of kFootConverged: a step of l after one of l0 predicts l^3 / l0^2 for the
  // next (Newton's l_next ~ K l^2, K from the pair). The read was there to stop the steps, and in
  // the benches' grabs and tentacles every such read did (40% of a grab's foot points, 75% of
  // a tentacle tip's took the second step): a slope fewer. It is a prediction, not a proof: of
  // the 20,206 skips in [warp]'s tests one would have taken a third step, of 1.3e-3 vu (predicted
  // 2e-6), and its foot point lies that far from where it would (2026-11-30 review; the
  // steps' own tolerance is kFootConverged). At 0.1 some tentacles' tips (radius 8, moves of 1
  // and 2 vu from a sphere of 25) took other bits in the benches. Not where the caller wants the
  // slope at the foot point (grabTipFeet): the cubic read gives it with phi1, so the skip would
  // save nothing there.
  constexpr int kFootSteps = 3;
  constexpr double kFootResidual = 0.05, kFootConverged = 1e-3, kFootSure = 0.01;
  constexpr int kCrossingBisections = 12;
  const bool footPoints = v.kind == Velocity::Kind::Capsule && v.plateau == 0;
  const double tipBall = v.kind == Velocity::Kind::Capsule ? v.plateauBall : 0;
  const bool tipFeet = tipBall >= kTipFeetBall;
  // Whether the kept voxel at p takes its foot point.
  const auto feetAt = [&](Vec3 p) {
    if (footPoints) return true;
    if (!tipFeet) return false;
    const Vec3 r = p - v.anchor;
    const double t = v.segLength2 > 0 ? std::clamp(dot(r, v.seg) / v.segLength2, 0.0, 1.0) : 0.0;
    const Vec3 off = r - v.seg * t;
    return dot(off, off) <= (tipBall + kTipFeetReach) * (tipBall + kTipFeetReach);
  };
  // The gradient of phi1 at `at`, DX^T grad phi0(X), grad phi0 by central differences of the
  // trilinear interpolant over +-kSlopeStep; and phi1 there when `phi` is given. `anywhere`: at
  // is not known to lie within the support grown by two voxels (a foot point). A grab's foot
  // points (cubicSlope) take instead the gradient of the cubic interpolant that phi1 reads next
  // to the zero set, from its own taps (Newton steps on phi1 with its own gradient), and fall
  // back to those central differences where it reads trilinearly: a fifth of the instructions
  // of a slope went to the central differences' six reads. Not a snake hook's tip: the cubic's
  // taps reach a voxel farther, into the clamped band across a thin tip, and a straight
  // tentacle's tip read gradient error 0.199 after 200 vu (0.075 with the central differences).
  const bool cubicSlope = footPoints;
  // Whether the central differences at q read within the grid (the tests of
  // centralDifferences<false>, which then all pass, left out): a foot point's mostly do.
  const auto stencilInGrid = [&](Vec3 q) {
    for (int a = 0; a < 3; ++a)
      if (!(q[a] - kSlopeStep - reads.lo[a] >= 0 && q[a] + kSlopeStep - reads.lo[a] < reads.size[a] - 1)) return false;
    return true;
  };
  const auto slopeOfWarped = [&](Vec3 at, double* phi, bool anywhere) {
    double DX[3][3];
    const Vec3 q = v.inverseWithJacobian(at, steps, DX);
    Vec3 g0;
    double value;
    if (!(cubicSlope && anywhere)) {
      if (phi) *phi = readNearAnywhere(q);
      g0 = inGrid && (!anywhere || stencilInGrid(q)) ? centralDifferences<true>(reads, q, kSlopeStep, band)
                                                     : centralDifferences<false>(reads, q, kSlopeStep, band);
    } else if (tricubic<true>(reads, q, value, &g0)) {
      if (phi) *phi = value;
    } else {
      if (phi) *phi = trilinear(reads, q, band);
      g0 = centralDifferences<false>(reads, q, kSlopeStep, band);
    }
    Vec3 g;
    for (int a = 0; a < 3; ++a) g[a] = DX[0][a] * g0.x + DX[1][a] * g0.y + DX[2][a] * g0.z;
    return g;
  };
  // Newton steps from `at` onto the zero set of phi1; false where phi1 is flat or they do not
  // converge. `slopeThere`, when given, gets the gradient of phi1 at the foot point found (the
  // last step's, nearerFoot()'s normal there).
  const auto project = [&](Vec3& at, Vec3* slopeThere = nullptr) {
    double phi = 0;
    Vec3 g = slopeOfWarped(at, &phi, true);
    double first = 0;  // the first step's length
    for (int step = 0; step < kFootSteps; ++step) {
      const double g2 = dot(g, g);
      if (!(g2 > 1e-12)) return false;
      if (step > 0 && phi * phi < kFootConverged * kFootConverged * g2) break;
      at = at - g * (phi / g2);
      const double taken = std::fabs(phi) / std::sqrt(g2);
      if (step == 0) first = taken;
      if (!slopeThere && step == 1 && taken * taken * taken < kFootSure * kFootConverged * first * first) return true;
      g = slopeOfWarped(at, &phi, true);
    }
    if (slopeThere) *slopeThere = g;
    return std::fabs(phi) < kFootResidual;
  };
  // The nearer to p of `onSurface`, a point of the zero set, and the foot point Newton steps
  // find from p's projection on the tangent plane there: the point alone lies off p's normal
  // where the surface curves. `slope`: the gradient of phi1 at onSurface, when known.
  const auto nearerFoot = [&](Vec3 p, Vec3 onSurface, const Vec3* slope = nullptr) {
    const Vec3 g = slope ? *slope : slopeOfWarped(onSurface, nullptr, true);
    if (dot(g, g) > 1e-12) {
      const Vec3 n = normalized(g);
      Vec3 onPlane = p - n * dot(p - onSurface, n);
      if (project(onPlane) && length(onPlane - p) <= length(onSurface - p)) return onPlane;
    }
    return onSurface;
  };
  // A voxel squeezed next to the zero set may read +-band, its old value, and still be one of
  // them: every voxel the flow moves within a voxel of the changed ones is looked at.
  if (!moved.empty()) moved = moved.grown(1).intersect(work);
  const int movedSlices = moved.size().z;
  std::vector<std::vector<std::pair<std::size_t, float>>> kept(std::size_t(std::max(0, moved.size().z)));
  pool.parallelFor(std::size_t(std::max(0, movedSlices)), [&](std::size_t i) {
    resample.check();
    const int z = moved.lo.z + int(i);
    auto& out = kept[i];
    // Most voxels have no neighbour across the zero set: a row's are tested at once first (a
    // loop the compiler vectorizes), the few others looked at one by one.
    std::vector<int> across;
    const std::ptrdiff_t sx = std::ptrdiff_t(s.warped.sx), sxy = std::ptrdiff_t(s.warped.sxy);
    for (int y = moved.lo.y; y < moved.hi.y; ++y) {
      const auto [r0, r1] = runOf(y, z);
      const int x0 = std::max(r0, moved.lo.x), x1 = std::min(r1, moved.hi.x);
      if (x1 <= x0) continue;
      const float* w = s.warped.v.data() + s.warped.index({x0, y, z});
      across.resize(std::size_t(x1 - x0));
      for (std::ptrdiff_t x = 0; x < x1 - x0; ++x) {
        const bool neg = w[x] < 0;
        across[std::size_t(x)] = (w[x] == 0) | ((w[x - 1] < 0) != neg) | ((w[x + 1] < 0) != neg) | ((w[x - sx] < 0) != neg) |
                                 ((w[x + sx] < 0) != neg) | ((w[x - sxy] < 0) != neg) | ((w[x + sxy] < 0) != neg);
      }
      for (int x = x0; x < x1; ++x) {
        if (!across[std::size_t(x - x0)]) continue;
        const std::size_t k = s.warped.index({x, y, z});
        const float value = s.warped.v[k];
        const bool neg = value < 0;
        const Vec3 p{double(x), double(y), double(z)};
        double bound = 1;
        for (int a = 0; a < 3; ++a)
          for (const std::size_t j : {k - s.warped.stride(a), k + s.warped.stride(a)}) {
            const float nb = s.warped.v[j];
            if ((nb < 0) != neg) bound = std::min(bound, double(value) / (double(value) - nb));
          }
        if (bound == 1 && value != 0) continue;  // not next to the zero set
        const bool feet = feetAt(p);
        double mag;
        if (!feet) {
          const double len = length(slopeOfWarped(p, nullptr, false));
          mag = len > 1e-6 ? std::min(std::fabs(double(value)) / len, bound) : bound;
        } else {
          // The surface crosses an edge of the voxel: its foot point lies within a voxel (one
          // farther is another part of the surface, reached along a curving gradient).
          Vec3 foot = p;
          if (!(std::fabs(value) < band && project(foot) && length(foot - p) <= 1)) {
            // The neighbour across whose edge the linear crossing is nearest (at `bound`).
            Vec3 other = p;
            for (int a = 0; a < 3; ++a)
              for (const int side : {-1, 1}) {
                const float nb = s.warped.v[std::size_t(std::ptrdiff_t(k) + side * std::ptrdiff_t(s.warped.stride(a)))];
                if ((nb < 0) != neg && double(value) / (double(value) - nb) == bound) other = p, other[a] += side;
              }
            double lo = 0, hi = 1;
            for (int halving = 0; halving < kCrossingBisections; ++halving) {
              const double mid = 0.5 * (lo + hi);
              ((readNearAnywhere(v.flow(p + (other - p) * mid, steps, -1)) < 0) == neg ? lo : hi) = mid;
            }
            foot = nearerFoot(p, p + (other - p) * (0.5 * (lo + hi)));
          }
          mag = length(foot - p);
        }
        out.emplace_back(k, float(std::copysign(mag, double(value))));
      }
    }
  });
  // The kept voxels' values, and the boxes of the voxels that changed, per slab of kMovedSlab
  // slices: the redistance's moved boxes (the surface moved only through the cells touching
  // them), its region those grown by the reach.
  for (std::size_t i = 0; i < kept.size(); ++i) {
    const int z = moved.lo.z + int(i);
    for (const auto& [k, value] : kept[i]) {
      s.warped.v[k] = value;
      if (value == s.base.v[k]) continue;
      const std::size_t rest = k - std::size_t(z - s.warped.box.lo.z) * s.warped.sxy;
      const int y = s.warped.box.lo.y + int(rest / s.warped.sx), x = s.warped.box.lo.x + int(rest % s.warped.sx);
      Box& c = changed[std::size_t(z - work.lo.z)];
      if (c.empty()) c = {{x, y, z}, {x + 1, y + 1, z + 1}};
      c.lo.x = std::min(c.lo.x, x), c.lo.y = std::min(c.lo.y, y);
      c.hi.x = std::max(c.hi.x, x + 1), c.hi.y = std::max(c.hi.y, y + 1);
    }
  }
  std::vector<Box> movedBoxes;
  Box changedBox{};
  for (int i = 0; i < slices; i += kMovedSlab) {
    Box b{};
    for (int j = i; j < std::min(slices, i + kMovedSlab); ++j) b = unite(b, changed[std::size_t(j)]);
    if (!b.empty()) movedBoxes.push_back(b), changedBox = unite(changedBox, b);
  }

  // A grab's tip, where the anchor lands (anchor + d), is the warped surface's most curved
  // part, and the march from the kept voxels leaves the voxels a layer in from them short of
  // their distance there: on the 3-radius grab's tip up to 0.1 vu above the exact inside, on the
  // ridge between its sides, and the gradient error of the kept voxels next to them 0.122
  // (the exact field's 0.098; tests/engine/level_set/test_warp.cpp). Within kGrabTipReach of it
  // each voxel with a neighbour next to the zero set (but not itself one) takes, after the
  // march, the distance to the nearest of the foot points that Newton steps find from each such
  // neighbour, each moved to the voxel's projection on the tangent plane there when that foot
  // point is nearer (0.087). Newton steps from the voxel itself may reach another side of the
  // tip: a voxel there read 0.2 vu past its distance (0.097).
  constexpr double kGrabTipReach = 3, kGrabTipFoot = 2.5;
  const auto grabTipFeet = [&](const Box& within) {
    const Vec3 tip = v.anchor + v.seg;
    Box b;
    for (int a = 0; a < 3; ++a) b.lo[a] = int(std::floor(tip[a] - kGrabTipReach)), b.hi[a] = int(std::ceil(tip[a] + kGrabTipReach)) + 1;
    b = b.intersect(within).intersect(s.warped.box.grown(-2));
    const auto nextToZero = [&](std::size_t k) {
      const bool neg = s.warped.v[k] < 0;
      bool across = s.warped.v[k] == 0;
      for (int a = 0; a < 3; ++a)
        for (const std::size_t j : {k - s.warped.stride(a), k + s.warped.stride(a)}) across = across || ((s.warped.v[j] < 0) != neg);
      return across;
    };
    // The foot point Newton steps find from a neighbour and the slope there, found once for
    // the up to six voxels that ask for it: per voxel of b grown by one, unknown until asked.
    struct NeighbourFoot {
      enum class State : std::uint8_t { Unknown, None, Found } state = State::Unknown;
      Vec3 foot, slope;
    };
    const Box around = b.grown(1);
    const Int3 aroundSize = around.size();
    std::vector<NeighbourFoot> neighbourFeet(around.empty() ? 0 : std::size_t(around.voxels()));
    const auto neighbourFoot = [&](Int3 c) -> const NeighbourFoot& {
      NeighbourFoot& f = neighbourFeet[std::size_t(c.x - around.lo.x) +
                                       std::size_t(aroundSize.x) * (std::size_t(c.y - around.lo.y) + std::size_t(aroundSize.y) * std::size_t(c.z - around.lo.z))];
      if (f.state == NeighbourFoot::State::Unknown) {
        f.foot = {double(c.x), double(c.y), double(c.z)};
        f.state = project(f.foot, &f.slope) ? NeighbourFoot::State::Found : NeighbourFoot::State::None;
      }
      return f;
    };
    std::vector<std::pair<std::size_t, float>> feet;
    for (int z = b.lo.z; z < b.hi.z; ++z)
      for (int y = b.lo.y; y < b.hi.y; ++y)
        for (int x = b.lo.x; x < b.hi.x; ++x) {
          const Vec3 p{double(x), double(y), double(z)};
          if (length(p - tip) > kGrabTipReach) continue;
          const std::size_t k = s.warped.index({x, y, z});
          if (nextToZero(k)) continue;
          double nearest = kGrabTipFoot;
          bool found = false;
          for (int a = 0; a < 3; ++a)
            for (const int side : {-1, 1}) {
              const std::size_t j = std::size_t(std::ptrdiff_t(k) + side * std::ptrdiff_t(s.warped.stride(a)));
              if (!nextToZero(j)) continue;
              Int3 c{x, y, z};
              c[a] += side;
              const NeighbourFoot& onSurface = neighbourFoot(c);
              if (onSurface.state != NeighbourFoot::State::Found) continue;
              const Vec3 foot = nearerFoot(p, onSurface.foot, &onSurface.slope);
              if (length(foot - p) < nearest) nearest = length(foot - p), found = true;
            }
          if (found) feet.emplace_back(k, float(std::copysign(nearest, double(s.warped.v[k]))));
        }
    for (const auto& [k, value] : feet) s.warped.v[k] = value;
  };
  Box region{};
  if (!changedBox.empty()) {
    region = changedBox.grown(reach).intersect(vol.domain());
    const Box resetBoxes[] = {region};
    RedistanceOptions options;
    options.resetBoxes = resetBoxes;
    options.movedBoxes = movedBoxes;
    options.normalizeKept = false;
    options.progress = share.part(kRedistanceShare);
    redistanceRegion(s.warped, region, band, Outside::Source, options, pool);
    if (footPoints) grabTipFeet(region);
  }
  share.check();  // the last check: nothing below stops part way

  // Earlier calls of the stroke may have changed bricks beyond this region: base's values go
  // back there. When base is vol itself (a snake hook's move) there are none, and the scan of
  // every brick of the volume is spared.
  const Box earlier = &vol == &base ? Box{} : changedSinceBase(vol, base, pool);
  Edit edit;
  if (painted) {
    const Box all = unite(unite(region, texelsMoved), earlier);
    edit.append(writeBack(vol, base, all, region, s.warped, s.warpedTexels, pool), all);
  } else if (earlier.empty() || unite(region, earlier) == region) {
    if (!region.empty()) edit.append(vol.scatter(region, s.warped.v.data(), s.warped.box, pool), region);
  } else {
    const Box all = unite(region, earlier);
    DenseGrid out;
    out.gatherFrom(base, all, {}, pool);
    for (int z = region.lo.z; z < region.hi.z; ++z)
      for (int y = region.lo.y; y < region.hi.y; ++y)
        std::copy_n(&s.warped.v[s.warped.index({region.lo.x, y, z})], region.size().x, &out.v[out.index({region.lo.x, y, z})]);
    edit.append(vol.scatter(all, out.v.data(), out.box, pool), all);
  }
  share.advance(1 - kGatherShare - kLatticeShare - kResampleShare - kRedistanceShare);
  return edit;
}

void checkBase(const Volume& vol, const Volume& base) {
  if (!(vol.dims() == base.dims()) || vol.band() != base.band())
    throw EngineError(ErrorKind::InvalidArgument, "base", "must have the volume's dimensions and band");
}

void checkAnchor(const Volume& vol, Vec3 anchor) {
  if (!isFinite(anchor)) throw EngineError(ErrorKind::InvalidArgument, "anchor", "must be three finite numbers");
  const Int3 n = vol.dims();
  for (int a = 0; a < 3; ++a)
    if (!(anchor[a] >= 0 && anchor[a] <= n[a] - 1))
      throw EngineError(ErrorKind::OutOfDomain, "anchor", "must lie in the volume");
}

void checkRadius(double radius) { requireRange(radius, kMinWarpRadius, kMaxWarpRadius, "radius"); }

Vec3 unitAxis(Vec3 axis) {
  if (!isFinite(axis) || !(length(axis) > 1e-9))
    throw EngineError(ErrorKind::InvalidArgument, "axis", "must be a finite non-zero vector");
  return normalized(axis);
}

Velocity affine(Vec3 anchor, double radius) {
  Velocity v;
  v.kind = Velocity::Kind::Affine;
  v.anchor = anchor;
  v.radius = radius;
  v.setPlateau(kPlateau);
  return v;
}

// Sets v.scale so that the flow carries the anchor to anchor + d within kWarpAnchorTolerance
// (a secant search from scale 1), or throws EngineError (field "d").
void landAnchor(Velocity& v, Vec3 anchor, Vec3 d) {
  if (!(length(d) > 0)) return;
  const Vec3 target = anchor + d;
  const auto miss = [&](double scale) {
    Velocity w = v;
    w.scale = scale;
    return dot(w.flow(anchor, w.substeps(), 1) - target, normalized(d));
  };
  double s0 = 1, m0 = miss(s0);
  double s1 = 1.1, m1 = miss(s1);
  for (int i = 0; i < 24 && std::fabs(m0) > 0.01 * kWarpAnchorTolerance && m1 != m0; ++i) {
    const double s2 = std::max(0.0, s1 - m1 * (s1 - s0) / (m1 - m0));
    s0 = s1, m0 = m1, s1 = s2, m1 = miss(s2);
    if (std::fabs(m1) < std::fabs(m0)) std::swap(s0, s1), std::swap(m0, m1);
  }
  v.scale = s0;
  if (!(length(v.flow(anchor, v.substeps(), 1) - target) <= kWarpAnchorTolerance))
    throw EngineError(ErrorKind::InvalidArgument, "d", "the anchor cannot be carried to its target");
}

// A grab's velocity (its parameters checked but the anchor's place, which the caller checks
// against its volume): d at most kMaxWarpTravelPerRadius times `radius`, the brush's, and the
// support `support` vu (the brush's radius but for a snake hook's young tentacle,
// snakeHookVelocity()) and the plateau's radius `ball` vu (0 for a grab).
Velocity grabVelocity(Vec3 anchor, Vec3 d, double radius, double ball, double support) {
  if (!isFinite(anchor)) throw EngineError(ErrorKind::InvalidArgument, "anchor", "must be three finite numbers");
  checkRadius(radius);
  if (!isFinite(d)) throw EngineError(ErrorKind::InvalidArgument, "d", "must be three finite numbers");
  if (!(length(d) <= kMaxWarpTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "d", "must be at most 8 radii long");
  Velocity v;
  v.anchor = anchor;
  v.radius = support;
  v.seg = d;
  v.segLength2 = dot(d, d);
  v.segLength = std::sqrt(v.segLength2);
  if (v.segLength > 0) v.segAxis = d / v.segLength;
  v.plateauBall = ball;
  v.setPlateau(ball / support);
  // Along the segment v = scale * d: scale 1 lands the anchor on anchor + d up to rounding.
  landAnchor(v, anchor, d);
  return v;
}

// How far a snake hook's plateau ball sinks into the tip (snakeHookVelocity()), as a share of
// its radius: with the ball sunk whole, its centre at `centre`, the clay's least distance at
// eight points a radius from the centre across the move (`along`, a unit vector), over
// kSinkClearance radii (at most the band, where distances stop), clamped to [0, 1]. The tip of
// a tentacle thinner than the support's radius sinks the ball whole; a body wider than that
// (the sphere a tentacle starts from, the tentacle's own side at a turn) keeps it at the surface.
constexpr double kSinkClearance = 0.25;
// The sunk ball's radius is the tip's (tipRadius()), at most the plateau's and at least this
// share of it (a tentacle pinched thin elsewhere keeps the ball from shrinking with it).
constexpr double kLeastBall = 0.5;
// The support of a move whose ball sinks only in part, by the share `share` (0 < share < 1):
// 1 + kYoungWidening (1 - share) radii, at most kMaxWarpRadius.
constexpr double kYoungWidening = 0.5;
// The eight unit directions across a move (`along`, a unit vector), 45 degrees apart: where the
// tip's section is sampled.
std::array<Vec3, 8> raysAcross(Vec3 along) {
  const Vec3 e1 = normalized(cross(along, std::fabs(along.x) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
  const Vec3 e2 = cross(along, e1);
  std::array<Vec3, 8> rays;
  for (int k = 0; k < 8; ++k) {
    const double angle = k * std::numbers::pi / 4;
    rays[std::size_t(k)] = e1 * std::cos(angle) + e2 * std::sin(angle);
  }
  return rays;
}

double sinkShare(const Volume& vol, Vec3 centre, Vec3 along, double radius) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const Vec3& ray : raysAcross(along)) nearest = std::min(nearest, vol.sample(centre + ray * radius));
  return std::clamp(nearest / std::min(kSinkClearance * radius, double(vol.band())), 0.0, 1.0);
}

// The tip's least radius across the move (`along`, a unit vector) at `centre` (inside the clay):
// the distance to the surface along eight rays across the move, at most `most`.
double tipRadius(const Volume& vol, Vec3 centre, Vec3 along, double most) {
  double least = most;
  for (const Vec3& ray : raysAcross(along)) {
    // Steps of half a voxel to the first point outside, then halvings to 1/8192 vu.
    double in = 0, out = -1;
    for (double t = 0.5; t < least + 0.5; t += 0.5) {
      if (vol.sample(centre + ray * t) >= 0) {
        out = t;
        break;
      }
      in = t;
    }
    if (out < 0) continue;
    for (int i = 0; i < 12; ++i) {
      const double mid = 0.5 * (in + out);
      (vol.sample(centre + ray * mid) < 0 ? in : out) = mid;
    }
    least = std::min(least, 0.5 * (in + out));
  }
  return least;
}

// The velocity of snakeHook(vol, anchor, target, radius): a grab of vol from the surface point
// it starts from, its segment sunk into the tip (sinkShare()).
Velocity snakeHookVelocity(const Volume& vol, Vec3 anchor, Vec3 target, double radius) {
  if (!isFinite(target)) throw EngineError(ErrorKind::InvalidArgument, "target", "must be three finite numbers");
  requireRange(radius, kMinSnakeHookRadius, kMaxWarpRadius, "radius");
  checkAnchor(vol, anchor);
  // Each resample rounds the tip a little, so the surface drifts off the anchor the caller
  // carries from move to move (1.5 vu over 97 moves of a 200 vu drag): the move starts from the
  // surface point nearest the anchor (two Newton steps along the gradient, within the band).
  Vec3 from = vol.towardSurface(anchor, 2);
  // The move starts from the side of the tip that faces it: the surface point along the move's
  // direction from the tip's inside, the plateau's radius under `from`. At a turn of the path
  // the tip is then pulled out of its side, a tentacle along its own axis again, instead of
  // dragged sideways: that sheared the bend into a sheet thinner than a voxel, which tore (a
  // path of 90 degree turns in 4 vu moves left the tentacle in 4 pieces).
  const Vec3 d = target - from;
  const Vec3 g = vol.gradient(from);
  if (length(target - from) > 0 && length(g) > 0.5 && std::fabs(vol.sample(from)) < vol.band()) {
    const Vec3 dir = normalized(target - from);
    const Vec3 inside = from - normalized(g) * (kPlateau * radius);
    if (vol.sample(inside) < 0) {
      double lo = 0, hi = -1;
      for (double t = 0.5; t <= radius; t += 0.5)
        if (vol.sample(inside + dir * t) >= 0) {
          hi = t;
          break;
        } else {
          lo = t;
        }
      if (hi > 0) {
        for (int i = 0; i < 20; ++i) {
          const double mid = 0.5 * (lo + hi);
          (vol.sample(inside + dir * mid) < 0 ? lo : hi) = mid;
        }
        from = inside + dir * hi;
      }
    }
  }
  checkAnchor(vol, from);
  // The plateau's ball sinks into the tip, up to its own radius, so that from is on its front:
  // the ball then lies in the clay, and the clay in front of it lags behind (the falloff is
  // below 1 there) until it lies on the ball. The tip becomes the ball's front half, a round
  // cap that keeps the tentacle's thickness. With the ball's centre on the surface (before
  // 2026-11-30) the plateau carried the clay it first held, a flat cap, whole at every move, and
  // the clay just beyond its edge lagged more at every move: the rim sharpened with each move
  // (radius of curvature about 2 vu / moves) and the 200 vu tentacle's tip read gradient error
  // 0.19-0.22 (tests/engine/level_set/test_warp.cpp). The ball sinks only as far as the clay
  // clears the support's side: a ball sunk into the body, or into the tentacle's side at a
  // turn of the path, carried a slab of it sideways, sheared against the clay behind. A sunk
  // ball is as wide as the tip (tipRadius()): clay inside the ball never moves against it, so
  // a tip narrower than the plateau kept its flat cap in the ball, and read gradient error
  // 0.120 there after the 200 vu path (0.099 with the ball fitted).
  double ball = kPlateau * radius, share = 0;
  if (length(d) > 0) {
    const Vec3 along = normalized(d);
    const Vec3 sunk = from - along * ball;
    share = sinkShare(vol, sunk, along, radius);
    if (share > 0) {
      ball = std::max(kLeastBall * ball, tipRadius(vol, sunk, along, ball));
      from = from - along * (ball * share);
    }
  }
  // While the ball sinks only in part, the tentacle is young (as in its first moves out of a
  // body), and its foot is still being drawn: the move's support is then wider than the
  // radius, up to half again as the share falls, the ball's size kept, so that the falloff's
  // outer part reaches down the stub and draws the fold where it leaves the body into a broad
  // fillet. With the brush's support the moves' falloff stopped at the same ring on the body,
  // move after move, and the stub rose from it as a wall: a fold whose radius of curvature was
  // about a voxel, where the exact field of that shape read gradient error 0.126 and ours 0.129
  // after the 200 vu path (tests/engine/level_set/test_warp.cpp). The widening fades as the
  // ball sinks: half again the radius at every partial share fed itself (the wider flank kept
  // the ring of sinkShare() in the clay, the share partial), a 70 vu helix in moves of 1 vu
  // widened 64 of its 70 moves and cost 54% more instructions (fading: 3%). A move before the
  // ball sinks at all, off a body, keeps the brush's support, the ring the browser shows: a
  // wider support there draws the fillet as well, but costs every such move 13-19% more
  // (1.09-1.125 radii). Within the brush's support, other falloffs ((1 - u^a)^b) or other balls
  // left the exact field's fold at 0.086-0.143 (docs/benchmark-log.md, Warps).
  const double support =
      share > 0 && share < 1 ? std::min(radius * (1 + kYoungWidening * (1 - share)), snakeHookSupportBound(radius)) : radius;
  return grabVelocity(from, d, radius, ball, support);
}

}  // namespace

struct WarpMap::Field {
  Velocity v;
};

Vec3 WarpMap::forward(Vec3 p) const { return field_->v.flow(p, kWarpMapRefinement * field_->v.substeps(), 1); }

Vec3 WarpMap::inverse(Vec3 p) const { return field_->v.flow(p, kWarpMapRefinement * field_->v.substeps(), -1); }

WarpMap grabMap(Vec3 anchor, Vec3 d, double radius) {
  return WarpMap(std::make_shared<const WarpMap::Field>(WarpMap::Field{grabVelocity(anchor, d, radius, 0, radius)}));
}

WarpMap snakeHookMap(const Volume& vol, Vec3 anchor, Vec3 target, double radius) {
  return WarpMap(std::make_shared<const WarpMap::Field>(WarpMap::Field{snakeHookVelocity(vol, anchor, target, radius)}));
}

Edit grab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  return applyWarp(vol, base, grabVelocity(anchor, d, radius, 0, radius), pool);
}

Edit snakeHook(Volume& vol, Vec3 anchor, Vec3 target, double radius, ThreadPool& pool) {
  const Velocity v = snakeHookVelocity(vol, anchor, target, radius);
  // vol is its own base: applyWarp reads it before it writes the result.
  return applyWarp(vol, vol, v, pool);
}

Edit elasticGrab(Volume& vol, const Volume& base, Vec3 anchor, Vec3 d, double radius, double volume, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  requireRange(radius, kMinWarpRadius, kMaxWarpRadius / kElasticCutoff, "radius");
  requireRange(volume, 0, 0.5, "volume");
  if (!isFinite(d)) throw EngineError(ErrorKind::InvalidArgument, "d", "must be three finite numbers");
  if (!(length(d) <= kMaxElasticTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "d", "must be at most 2 radii long");
  Velocity v;
  v.kind = Velocity::Kind::Elastic;
  v.anchor = anchor;
  v.eps = radius;
  v.nu = volume;
  v.radius = kElasticCutoff * radius;
  v.setPlateau(kPlateau);
  // The load that moves the centre by d, before the flow's search.
  v.load = d * elasticLoadPerTravel(radius, volume);
  v.seg = d;
  landAnchor(v, anchor, d);
  return applyWarp(vol, base, v, pool);
}

Edit twist(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double angle, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  const Vec3 n = unitAxis(axis);
  requireRange(angle, -2 * std::numbers::pi, 2 * std::numbers::pi, "angle");
  Velocity v = affine(anchor, radius);
  // angle * [n]x: the cross product n x r.
  const double m[3][3] = {{0, -n.z, n.y}, {n.z, 0, -n.x}, {-n.y, n.x, 0}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.A[i][j] = angle * m[i][j];
  v.affineBound = twistSlopeBound(angle);
  return applyWarp(vol, base, v, pool);
}

Edit localScale(Volume& vol, const Volume& base, Vec3 anchor, double factor, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  requireRange(factor, 0.25, 4, "factor");
  Velocity v = affine(anchor, radius);
  for (int i = 0; i < 3; ++i) v.A[i][i] = std::log(factor);
  v.affineBound = localScaleSlopeBound(factor);
  return applyWarp(vol, base, v, pool);
}

Edit pinch(Volume& vol, const Volume& base, Vec3 anchor, Vec3 axis, double amount, double radius, ThreadPool& pool) {
  checkBase(vol, base);
  checkAnchor(vol, anchor);
  checkRadius(radius);
  const Vec3 n = unitAxis(axis);
  requireRange(amount, -1, 1, "amount");
  Velocity v = affine(anchor, radius);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.A[i][j] = -amount * ((i == j ? 1 : 0) - n[i] * n[j]);
  v.affineBound = pinchSlopeBound(amount);
  return applyWarp(vol, base, v, pool);
}

Edit pinchAlong(Volume& vol, Vec3 from, Vec3 to, Vec3 normal, double amount, double radius, ThreadPool& pool) {
  checkAnchor(vol, from);
  if (!isFinite(to)) throw EngineError(ErrorKind::InvalidArgument, "to", "must be three finite numbers");
  checkRadius(radius);
  requireRange(amount, -1, 1, "amount");
  if (!isFinite(normal) || !(length(normal) > 0))
    throw EngineError(ErrorKind::InvalidArgument, "normal", "must be a finite non-zero vector");
  const Vec3 d = to - from;
  if (!(length(d) <= kMaxWarpTravelPerRadius * radius))
    throw EngineError(ErrorKind::TooLarge, "to", "must be at most 8 radii from `from`");
  const Vec3 across = cross(normalized(normal), d);
  // A path along the normal has no side to draw in: nothing moves (as for a path of length 0).
  Velocity v;
  v.kind = Velocity::Kind::PathPinch;
  v.anchor = from;
  v.radius = radius;
  v.amount = amount;
  if (length(across) > 1e-9 * length(d)) {
    v.seg = d;
    v.segLength2 = dot(d, d);
    v.across = normalized(across);
    v.scale = amount / (kPathPinchPass * radius);
  }
  // vol is its own base: applyWarp reads it before it writes the result.
  return applyWarp(vol, vol, v, pool);
}

double grabSlopeBound(double travel, double radius) { return capsuleSlope(travel, radius, 0); }

double snakeHookSupportBound(double radius) { return std::min(radius * (1 + kYoungWidening), kMaxWarpRadius); }

// The widest plateau a move has: a sunk ball fitted to a narrower tip has a wider outer part,
// and a smaller bound.
double snakeHookSlopeBound(double travel, double radius) { return capsuleSlope(travel, radius, kPlateau); }

double elasticGrabSlopeBound(double travel, double radius, double volume) {
  return elasticSlope(travel * elasticLoadPerTravel(radius, volume), radius);
}

// |angle [axis]x| = sqrt 2 |angle|, |ln(factor) I| = sqrt 3 |ln factor|, |amount (I - axis axis^T)|
// = sqrt 2 |amount| (Frobenius norms, axis a unit vector).
double twistSlopeBound(double angle) { return affineSlope(std::numbers::sqrt2 * std::fabs(angle)); }

double localScaleSlopeBound(double factor) { return affineSlope(std::numbers::sqrt3 * std::fabs(std::log(factor))); }

double pinchSlopeBound(double amount) { return affineSlope(std::numbers::sqrt2 * std::fabs(amount)); }

// v = -scale I s across, scale = amount / (kPathPinchPass radius): |grad (I s)| <= I + |s| |grad I|,
// |s| <= radius. I <= min(L, 16 radius / 15) (its value on a long path's line), |dI/da| <=
// min(1, L max |K'|) with max |K'| = kQuarticMaxSlope / radius, and the part of grad I across the
// line, (2 h / radius^2) |G(u1) - G(u0)|, is at most min(kQuarticMaxSlope L / radius, sqrt 3)
// (G' in [0, 2c] on the chord, h c <= 0.385 radius, h c^(3/2) <= 0.325 radius).
double pinchAlongSlopeBound(double travel, double amount, double radius) {
  const double L = travel;
  return std::fabs(amount / (kPathPinchPass * radius)) *
         (std::min(L, 16 * radius / 15) + std::min(radius, kQuarticMaxSlope * L) +
          std::min(kQuarticMaxSlope * L, std::numbers::sqrt3 * radius));
}

}  // namespace marzipan
