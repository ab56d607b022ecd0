// The warps' velocity fields (../level_set.hpp, warps; docs/method.md §3, Warps): Velocity, its
// falloffs, its flow and the inverse map with its Jacobian, and the bounds of |grad v| the
// entry points check. A header: the passes (warp.cpp's applyWarp, the lattice, the resample,
// the foot points) evaluate a field inline per voxel and per sub-step, where a call into
// another file per evaluation would cost more than the evaluation. Points are volume
// coordinates (vu); a field moves the clay for unit time, in midpoint sub-steps.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "engine/geometry.hpp"
#include "engine/level_set.hpp"

namespace marzipan::level_set::warp {


// The square root of the falloffs' per-sub-step evaluations: std::sqrt's own (the same
// correctly rounded root) tests its argument for errno's sake and calls the library below 0,
// three instructions a root, two roots an end-cap sub-step of the flow and of the inverse map.
[[gnu::always_inline]] inline double falloffRoot(double x) {
#if defined(__SSE2__)
  const __m128d v = _mm_set_sd(x);
  return _mm_cvtsd_f64(_mm_sqrt_sd(v, v));
#else
  return std::sqrt(x);
#endif
}

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
inline double capsuleSlope(double travel, double radius, double plateau) {
  return travel * maxFalloffSlope(falloffOf(plateau)) / ((1 - plateau) * radius);
}
// An elastic grab's load per vu of travel: at the centre the bi-scale Kelvinlet is
// (3/2 - b) (1 / eps - 1 / (2 eps)) load, b = 1 / (4 (1 - nu)), so that this load moves it by d.
inline double elasticLoadPerTravel(double eps, double nu) { return 2 * eps / (1.5 - 1 / (4 * (1 - nu))); }
// An elastic grab under a load of length `load`: the Kelvinlets' own slope is below
// |load| / eps^2 (their peak is about |load| / eps, reached over eps), plus the cut-off's (at
// kElasticCutoff eps, plateau kPlateau).
inline double elasticSlope(double load, double eps) {
  return load / (eps * eps) + load / eps * kQuarticMaxSlope / ((1 - kPlateau) * (kElasticCutoff * eps));
}
// An affine warp whose A has the Frobenius norm `norm`: |grad (P A r)| <= |A| (P + |P'| |r|).
inline double affineSlope(double norm) { return norm * (1 + kQuarticMaxSlope / (1 - kPlateau)); }

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
  // The falloff P = 1 within the plateau, W(u) (Falloff: without a plateau the quintic, else
  // the quartic) from there to the support's edge, of the squared distance rho2 (vu^2) from
  // the anchor (the segment, for a capsule): u = (t - plateau) / (1 - plateau), t the distance
  // in radii, going from 0 to 1.
  // Inside the plateau the field moves as a whole: an affine warp is exact there, and a snake
  // hook's tip keeps its thickness (with no plateau every move thinned it until the tentacle
  // was a needle thinner than a voxel and the tip was lost). A grab has none: a plateau
  // turned a long grab into a thinner tentacle (gradient error 0.56 at 3 radii, 0.33 without).
  // plateau is 0, kPlateau, or a snake hook's ball fitted to a narrower tip
  // (snakeHookVelocity()).
  // u is sqrt(rho2) uScale - uShift (the quintic's sqrt(rho2) invRadius): the flow of a capsule
  // is a chain of falloffs, each sub-step's two waiting on the one before, and their latency,
  // not their instructions, is its time. Until 2026-11-30 19:55 UTC u came from
  // sqrt(rho2 / radius^2), a division more on that chain, and d P / d rho2 from d P / d t^2 by a
  // division more off it (with capsuleFlow()'s halfStep and fullStep, 3-4% of a tentacle's
  // move's wall time; the flow's doubles moved in their last bits, the pinned warps' fields
  // kept theirs).
  // radius, plateau and what follows from them, set together by setSupport(): flatRho2 (within
  // it P = 1), uScale, uShift, invRadius and falloffOf(plateau) (a test of the plateau here,
  // before the plateau's own, cost a snake hook move 1.7% more instructions). A path pinch's
  // kernel is the falloff in closed form: it sets radius alone.
  double plateau = 0, flatRho2 = 0;
  double uScale = 1, uShift = 0, invRadius = 1;
  Falloff falloffShape = Falloff::Quartic;
  void setSupport(double r, double p) {
    radius = r, plateau = p;
    flatRho2 = p * p * radius * radius;
    invRadius = 1 / radius;
    uScale = 1 / ((1 - p) * radius), uShift = p / (1 - p);
    falloffShape = falloffOf(p);
  }
  double falloff(double rho2) const {
    return falloffShape == Falloff::Quintic ? shapeFalloff<Falloff::Quintic>(rho2) : shapeFalloff<Falloff::Quartic>(rho2);
  }
  // falloff() of the shape kShape (falloffShape). The quintic has no plateau (falloffOf()):
  // u = t, and its value at rho2 = 0 is 1 without the plateau's test (a grab's flow takes two
  // falloffs a sub-step: with capsuleFlow()'s truncation, 1.6% of a 20 vu grab's instructions
  // left out).
  template <Falloff kShape>
  [[gnu::always_inline]] double shapeFalloff(double rho2) const {
    if constexpr (kShape == Falloff::Quintic) {
      const double u = falloffRoot(rho2) * invRadius;
      return 1 - u * u * u * (10 - u * (15 - 6 * u));
    } else {
      if (rho2 <= flatRho2) return 1;
      const double u = falloffRoot(rho2) * uScale - uShift;
      return (1 - u * u) * (1 - u * u);
    }
  }
  // d falloff / d rho2.
  double falloffSlope(double rho2) const { return falloffWithSlope(rho2).second; }

  // falloff(rho2) and falloffSlope(rho2), sharing the root.
  std::pair<double, double> falloffWithSlope(double rho2) const {
    return falloffShape == Falloff::Quintic ? shapeFalloffWithSlope<Falloff::Quintic>(rho2)
                                            : shapeFalloffWithSlope<Falloff::Quartic>(rho2);
  }
  // falloffWithSlope() of the shape kShape (falloffShape), as shapeFalloff(): d W / d rho2 =
  // W'(u) du/dt / (2 t radius^2), t = sqrt(rho2) / radius; the quintic's test is that of
  // rho2 = 0, where the slope would divide by 0.
  template <Falloff kShape>
  [[gnu::always_inline]] std::pair<double, double> shapeFalloffWithSlope(double rho2) const {
    if constexpr (kShape == Falloff::Quintic) {
      if (rho2 <= 0) return {1, 0};
      const double root = falloffRoot(rho2);
      const double u = root * invRadius;
      const double w = u * (1 - u);
      return {1 - u * u * u * (10 - u * (15 - 6 * u)), -15 * invRadius * w * w / root};
    } else {
      if (rho2 <= flatRho2) return {1, 0};
      const double root = falloffRoot(rho2);
      const double u = root * uScale - uShift;
      return {(1 - u * u) * (1 - u * u), -2 * uScale * u * (1 - u * u) / root};
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
      const Vec3 g = off * (2 * scale * falloffSlope(rho2));
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) J[i][j] = seg[i] * g[j];
      return seg * (scale * falloff(rho2));
    }
    const double r2 = dot(r, r);
    if (r2 >= R2) return {};
    const double p = falloff(r2);
    const Vec3 ar{A[0][0] * r.x + A[0][1] * r.y + A[0][2] * r.z, A[1][0] * r.x + A[1][1] * r.y + A[1][2] * r.z,
                  A[2][0] * r.x + A[2][1] * r.y + A[2][2] * r.z};
    const Vec3 g = r * (2 * falloffSlope(r2));
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
      return seg * (scale * falloff(rho2));
    }
    const double r2 = dot(r, r);
    if (r2 >= R2) return {};
    const double p = falloff(r2);
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
  // superset: the support's row, an interval as the support is convex, and a voxel more on
  // each side for the rounding), so that the loops over a box need not test each voxel of its
  // rows outside the support. (With the support grown by a voxel, before 2026-11-30 17:45 UTC, the
  // resample's tests of moves() at the rows' ends were 1% of a tentacle's move.)
  std::pair<int, int> row(int y, int z, const Box& box) const {
    // A millionth of a voxel of slack: at a tangency the roots below may round to none where
    // moves() holds for a voxel (a 2026-11-30 review found 2 such rows in 460.8M random ones).
    const double R = radius + 1e-6, R2 = R * R;
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
    const int x1 = int(std::min(double(box.hi.x), std::ceil(hi) + 1));
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
    const auto falloffAt = [&](double a) {
      const double e = a < 0 ? -a : a > length ? a - length : 0;
      const double rho2 = perp2 + e * e;
      return rho2 < R2 ? shapeFalloff<kShape>(rho2) : 0.0;
    };
    // Where the speed is zero (beyond the end caps) every sub-step stays put.
    if (speed * falloffAt(a0) == 0) return y;
    // A half and a whole sub-step's move at full speed: one product fewer on the chain from one
    // falloff to the next than speed * W, then dt times that.
    const double dt = direction / n, halfStep = 0.5 * dt * speed, fullStep = dt * speed;
    const double step = fullStep * shapeFalloff<kShape>(perp2);
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
      const double mid = a + halfStep * falloffAt(a);
      a += fullStep * falloffAt(mid);
      ++i;
    }
    return y + axis * (a - a0);
  }

  // inverseWithJacobian() of a capsule, on the coordinates of capsuleFlow(): a along seg and
  // q, the squared distance to its line, which the flow keeps. With f(a, q) the speed, the
  // backward flow is a' = -f, and the variational equation follows m = da/da0 and
  // w = da/dq by the same midpoint rule (the general one restricted to this flow):
  // X(y) = y + axis (a - a0), DX = I + axis along^T with along = m axis + 2 w off - axis, handed
  // back as `along` (a slope takes DX^T g = g + along (axis . g), without the matrix). The
  // falloff's shape is a parameter, as capsuleFlow()'s. a takes capsuleFlow(y, n, -1)'s
  // operations, so X is the flow's bit for bit: the resample reads a snake hook's voxels next
  // to the zero set through this, and the kept-voxel pass takes their slopes from what it read
  // (warp_passes.hpp, ExactRead).
  // It integrates kLanes points at once (y[l] to x[l] and along[l]), each lane by its own
  // operations, so that each lane's bits are those of the lane alone. An end cap's sub-step is
  // a serial chain (a falloff's root and products, twice), and a path takes two or
  // three: their latency, not their instructions, is the inverse map's time (15% of a
  // tentacle's move's samples against 7% of its instructions, 2026-11-30). Two lanes both in
  // end caps take their sub-step together in the halves of vectors of doubles (capCapSubStep());
  // a lane between the end planes, or alone, takes its own. The resample and the kept pass
  // integrate their voxels two at a time (capsuleInverse2()).
  template <Falloff kShape, int kLanes>
  [[gnu::noinline]] void capsuleInverseLanes(const Vec3* y, int n, Vec3* x, Vec3* along) const {
    for (int l = 0; l < kLanes; ++l) x[l] = y[l], along[l] = {};
    if (!(segLength2 > 0)) return;
    const double length = segLength, R2 = radius * radius;
    const Vec3 axis = segAxis;
    const double speed = scale * length;
    // capsuleFlow()'s halfStep and fullStep backwards (its dt is -dt: the same bits negated).
    const double dt = 1.0 / n, halfStep = 0.5 * dt * speed, fullStep = dt * speed;
    // A lane: a along seg, m, w and the sub-steps taken; q its squared distance to the line.
    struct Lane {
      Vec3 off;
      double a0 = 0, q = 0, a = 0, m = 1, w = 0, insideFq = 0, step = 0;
      int i = 0;
      bool inside = false, outside = false;
    };
    // The falloff (the speed over `speed`), df/da and df/dq at a.
    struct Speed {
      double fall = 0, fa = 0, fq = 0;
    };
    const auto speedAt = [&](double q, double a) __attribute__((always_inline)) {
      const double e = a < 0 ? -a : a > length ? a - length : 0;
      const double rho2 = q + e * e;
      Speed out;
      if (rho2 >= R2) return out;
      const auto [fall, fallSlope] = shapeFalloffWithSlope<kShape>(rho2);
      const double slope = speed * fallSlope;
      out.fall = fall;
      out.fa = slope * 2 * (a < 0 ? a : e);
      out.fq = slope;
      return out;
    };
    // Between the end planes: speedAt(0).fq and capsuleFlow()'s step there backwards (-dt is
    // its dt, exactly). A snake hook's (the quartic's) segment is short against its support, and
    // most paths stay in an end cap: there they are found once a sub-step starts between the
    // planes (0.3% of a tentacle's move); a grab's is long, and found at once (found as a snake
    // hook's, a grab of 60 vu took 0.7% more instructions).
    const auto findInside = [&](Lane& p) __attribute__((always_inline)) {
      const auto [insideFall, insideSlope] = shapeFalloffWithSlope<kShape>(p.q);
      p.insideFq = speed * insideSlope, p.step = -dt * speed * insideFall, p.inside = true;
    };
    Lane lanes[kLanes];
    for (int l = 0; l < kLanes; ++l) {
      Lane& p = lanes[l];
      const Vec3 r = y[l] - anchor;
      p.a0 = dot(r, axis);
      p.off = r - axis * p.a0;
      p.q = dot(p.off, p.off);
      p.a = p.a0;
      // Beyond the support the point stays put.
      p.outside = p.q >= R2;
      if (p.outside) p.i = n;
      else if constexpr (kShape != Falloff::Quartic) findInside(p);
    }
    const auto between = [&](const Lane& p) { return p.a >= 0 && p.a <= length; };
    const auto advance = [&](Lane& p) __attribute__((always_inline)) {
      if (between(p)) {
        if (kShape == Falloff::Quartic && !p.inside) findInside(p);
        if (p.step != 0) {
          // Sub-steps that start and end between the end planes: f_a = 0 there. room >= 0:
          // truncation is its floor (as in capsuleFlow()).
          const double room = p.step < 0 ? p.a / -p.step : (length - p.a) / p.step;
          const int k = room < n - p.i ? int(room) : n - p.i;
          if (k > 0) {
            p.a += k * p.step;
            p.w -= k * (dt * p.insideFq);
            p.i += k;
            return;
          }
        }
      }
      const Speed s0 = speedAt(p.q, p.a);
      const double mid = p.a - halfStep * s0.fall;
      const double mMid = p.m - 0.5 * dt * s0.fa * p.m, wMid = p.w - 0.5 * dt * (s0.fa * p.w + s0.fq);
      const Speed s1 = speedAt(p.q, mid);
      p.a -= fullStep * s1.fall;
      p.m -= dt * s1.fa * mMid;
      p.w -= dt * (s1.fa * wMid + s1.fq);
      ++p.i;
    };
    for (;;) {
#if defined(__SSE2__)
      if constexpr (kLanes == 2) {
        Lane &p = lanes[0], &r = lanes[1];
        if (p.i < n && r.i < n && !between(p) && !between(r)) {
          capCapSubStep<kShape>(p, r, dt, length, R2, speed, halfStep, fullStep);
          continue;
        }
      }
#endif
      bool busy = false;
      for (int l = 0; l < kLanes; ++l)
        if (lanes[l].i < n) busy = true, advance(lanes[l]);
      if (!busy) break;
    }
    for (int l = 0; l < kLanes; ++l) {
      const Lane& p = lanes[l];
      if (p.outside) continue;
      along[l] = axis * (p.m - 1) + p.off * (2 * p.w);
      x[l] = y[l] + axis * (p.a - p.a0);
    }
  }
#if defined(__SSE2__)
  // One midpoint sub-step of capsuleInverseLanes() for two lanes p and r in end caps, in the
  // two halves of vectors (p low, r high): speedAt()'s and the sub-step's operations in their
  // order, each selection by its comparison's mask, so that each half's result is its lane's
  // alone. Where both lanes' comparisons agree (the common case) a branch takes the side
  // instead: the CPU predicts it and runs on ahead of the root, as it does
  // along one lane's branches, where the masks' selections had made a pair of paths cost
  // about two single ones (a loop of a shell of points, 2026-11-30).
  template <Falloff kShape, class Lane>
  [[gnu::always_inline]] void capCapSubStep(Lane& p, Lane& r, double dt, double length, double R2,
                                            double speed, double halfStep, double fullStep) const {
    const __m128d zero = _mm_setzero_pd(), one = _mm_set1_pd(1), two = _mm_set1_pd(2);
    const __m128d len = _mm_set1_pd(length), r2 = _mm_set1_pd(R2), sp = _mm_set1_pd(speed);
    const auto select = [](__m128d mask, __m128d a, __m128d b) __attribute__((always_inline)) {
      return _mm_or_pd(_mm_and_pd(mask, a), _mm_andnot_pd(mask, b));
    };
    const __m128d q = _mm_set_pd(r.q, p.q);
    struct Speeds {
      __m128d fall, fa, fq;
    };
    const auto speedAt = [&](__m128d a) __attribute__((always_inline)) {
      // Branches on the lanes' masks where both agree (the common case, which the CPU predicts
      // and runs ahead of the root), the masks' selections where they differ.
      const __m128d below = _mm_cmplt_pd(a, zero), over = _mm_cmpgt_pd(a, len);
      const int belowBits = _mm_movemask_pd(below), overBits = _mm_movemask_pd(over);
      __m128d e;
      if (belowBits == 3) e = _mm_sub_pd(zero, a);
      else if (overBits == 3) e = _mm_sub_pd(a, len);
      else e = select(below, _mm_sub_pd(zero, a), select(over, _mm_sub_pd(a, len), zero));
      const __m128d rho2 = _mm_add_pd(q, _mm_mul_pd(e, e));
      const __m128d within = _mm_cmplt_pd(rho2, r2);  // !(rho2 >= R2): no NaN here
      const int withinBits = _mm_movemask_pd(within);
      if (withinBits == 0) return Speeds{zero, zero, zero};
      __m128d fall, fallSlope;
      const __m128d flat = _mm_cmple_pd(rho2, kShape == Falloff::Quintic ? zero : _mm_set1_pd(flatRho2));
      const int flatBits = _mm_movemask_pd(flat);
      if (flatBits == 3) {
        fall = one, fallSlope = zero;
      } else {
        const __m128d root = _mm_sqrt_pd(rho2);
        if constexpr (kShape == Falloff::Quintic) {
          const __m128d inv = _mm_set1_pd(invRadius);
          const __m128d u = _mm_mul_pd(root, inv);
          const __m128d w = _mm_mul_pd(u, _mm_sub_pd(one, u));
          const __m128d inner = _mm_sub_pd(_mm_set1_pd(15), _mm_mul_pd(_mm_set1_pd(6), u));
          const __m128d poly = _mm_sub_pd(_mm_set1_pd(10), _mm_mul_pd(u, inner));
          fall = _mm_sub_pd(one, _mm_mul_pd(_mm_mul_pd(_mm_mul_pd(u, u), u), poly));
          fallSlope = _mm_div_pd(_mm_mul_pd(_mm_mul_pd(_mm_mul_pd(_mm_set1_pd(-15), inv), w), w), root);
        } else {
          const __m128d scaleU = _mm_set1_pd(uScale);
          const __m128d u = _mm_sub_pd(_mm_mul_pd(root, scaleU), _mm_set1_pd(uShift));
          const __m128d rest = _mm_sub_pd(one, _mm_mul_pd(u, u));
          fall = _mm_mul_pd(rest, rest);
          fallSlope = _mm_div_pd(_mm_mul_pd(_mm_mul_pd(_mm_mul_pd(_mm_set1_pd(-2), scaleU), u), rest), root);
        }
        if (flatBits != 0) fall = select(flat, one, fall), fallSlope = select(flat, zero, fallSlope);
      }
      const __m128d slope = _mm_mul_pd(sp, fallSlope);
      const __m128d side = belowBits == 3 ? a : belowBits == 0 ? e : select(below, a, e);
      const __m128d fa = _mm_mul_pd(_mm_mul_pd(slope, two), side);
      if (withinBits == 3) return Speeds{fall, fa, slope};
      return Speeds{_mm_and_pd(within, fall), _mm_and_pd(within, fa), _mm_and_pd(within, slope)};
    };
    const __m128d half = _mm_set1_pd(0.5 * dt), step = _mm_set1_pd(dt);
    const __m128d halfMove = _mm_set1_pd(halfStep), fullMove = _mm_set1_pd(fullStep);
    __m128d a = _mm_set_pd(r.a, p.a), m = _mm_set_pd(r.m, p.m), w = _mm_set_pd(r.w, p.w);
    const Speeds s0 = speedAt(a);
    const __m128d mid = _mm_sub_pd(a, _mm_mul_pd(halfMove, s0.fall));
    const __m128d mMid = _mm_sub_pd(m, _mm_mul_pd(_mm_mul_pd(half, s0.fa), m));
    const __m128d wMid = _mm_sub_pd(w, _mm_mul_pd(half, _mm_add_pd(_mm_mul_pd(s0.fa, w), s0.fq)));
    const Speeds s1 = speedAt(mid);
    a = _mm_sub_pd(a, _mm_mul_pd(fullMove, s1.fall));
    m = _mm_sub_pd(m, _mm_mul_pd(_mm_mul_pd(step, s1.fa), mMid));
    w = _mm_sub_pd(w, _mm_mul_pd(step, _mm_add_pd(_mm_mul_pd(s1.fa, wMid), s1.fq)));
    _mm_storel_pd(&p.a, a), _mm_storeh_pd(&r.a, a);
    _mm_storel_pd(&p.m, m), _mm_storeh_pd(&r.m, m);
    _mm_storel_pd(&p.w, w), _mm_storeh_pd(&r.w, w);
    ++p.i, ++r.i;
  }
#endif
  // capsuleInverseLanes() of one point, of the field's falloff shape.
  Vec3 capsuleInverse(Vec3 y, int n, Vec3& along) const {
    Vec3 x;
    if (falloffShape == Falloff::Quintic) capsuleInverseLanes<Falloff::Quintic, 1>(&y, n, &x, &along);
    else capsuleInverseLanes<Falloff::Quartic, 1>(&y, n, &x, &along);
    return x;
  }
  // capsuleInverse() of two points, y[l] to x[l] and along[l], each with its own bits.
  void capsuleInverse2(const Vec3 (&y)[2], int n, Vec3 (&x)[2], Vec3 (&along)[2]) const {
    if (falloffShape == Falloff::Quintic) capsuleInverseLanes<Falloff::Quintic, 2>(y, n, x, along);
    else capsuleInverseLanes<Falloff::Quartic, 2>(y, n, x, along);
  }

  // The same backwards, with the Jacobian of the map y -> X(y) (the variational equation
  // dJ/dt = -grad v J, by the same midpoint rule).
  Vec3 inverseWithJacobian(Vec3 y, int n, double X[3][3]) const {
    if (kind == Kind::Capsule) {
      Vec3 along;
      const Vec3 x = capsuleInverse(y, n, along);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) X[i][j] = (i == j ? 1 : 0) + segAxis[i] * along[j];
      return x;
    }
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

}  // namespace marzipan::level_set::warp
