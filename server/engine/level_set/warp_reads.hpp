// Reads of a grid of distances at points between its voxels, for the warps' passes: the
// trilinear read, its central differences and the cubic (Catmull-Rom) read with its gradient.
// A header: each is inlined into the per-voxel loops that call it. Points are volume
// coordinates; off the grid the field reads +band (air).
#pragma once

#include <cstddef>
#include <cstring>

#include "engine/dense_grid.hpp"
#include "engine/geometry.hpp"

namespace marzipan::level_set::warp {

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
// Within the grid, where each of y and z reads the cell below p - h and the next above p + h
// (h = 1/2 always, up to rounding), the four reads across y and z take their values along x at
// p.x from nine rows of the 3 x 3 around them, where each read interpolated its own four (16),
// and the two across z share their middle row's value along y: the same operations on the same
// values, the same bits, with 8 of the 28 lerps left out (16 along x become 9, and one across y).
template <bool kInGrid>
[[gnu::always_inline]] inline Vec3 centralDifferences(const GridReads& g, Vec3 p, double h, float band) {
  ReadAxis at[3], below[3], above[3];
  for (int a = 0; a < 3; ++a) {
    at[a] = readAxis<kInGrid>(p[a], g.lo[a], g.size[a]);
    below[a] = readAxis<kInGrid>(p[a] - h, g.lo[a], g.size[a]);
    above[a] = readAxis<kInGrid>(p[a] + h, g.lo[a], g.size[a]);
  }
  if constexpr (kInGrid) {
    const long dy = at[1].cell - below[1].cell, dz = at[2].cell - below[2].cell;
    if (above[1].cell == below[1].cell + 1 && above[2].cell == below[2].cell + 1 && (dy | dz) >> 1 == 0) {
      const auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
      // along[j][k]: the value along x at p.x on the row (below y + j, below z + k).
      double along[3][3];
      const float* c = g.v + std::size_t(at[0].cell) + g.sx * std::size_t(below[1].cell) + g.sxy * std::size_t(below[2].cell);
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j) {
          const float* r = c + g.sx * std::size_t(j) + g.sxy * std::size_t(k);
          along[j][k] = lerp(r[0], r[1], at[0].t);
        }
      const auto acrossY = [&](long j, double t) {
        return lerp(lerp(along[j][dz], along[j + 1][dz], t), lerp(along[j][dz + 1], along[j + 1][dz + 1], t), at[2].t);
      };
      double inZ[3];  // along y at p.y on the rows below z + k
      for (int k = 0; k < 3; ++k) inZ[k] = lerp(along[dy][k], along[dy + 1][k], at[1].t);
      return {(trilinearAt<true>(g, above[0], at[1], at[2], band) - trilinearAt<true>(g, below[0], at[1], at[2], band)) / (2 * h),
              (acrossY(1, above[1].t) - acrossY(0, below[1].t)) / (2 * h),
              (lerp(inZ[1], inZ[2], above[2].t) - lerp(inZ[0], inZ[1], below[2].t)) / (2 * h)};
    }
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

}  // namespace marzipan::level_set::warp
