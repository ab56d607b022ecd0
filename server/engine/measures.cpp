#include "measures.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <numbers>
#include <numeric>
#include <vector>

#include "brick.hpp"
#include "dense_grid.hpp"
#include "stencil.hpp"

namespace marzipan {

namespace {

// A present brick with a one-voxel ring of its neighbours, for stencils at its faces.
struct Neighbourhood {
  static constexpr int kSide = kBrickSide + 2;
  float v[kSide * kSide * kSide];

  Neighbourhood(const Volume& vol, Int3 brick) {
    const Int3 o = Bricks::origin(brick) - Int3{1, 1, 1};
    vol.gather({o, o + Int3{kSide, kSide, kSide}}, v);
  }
  static int index(int x, int y, int z) { return (x + 1) + kSide * ((y + 1) + kSide * (z + 1)); }
  // Local voxel (x,y,z) of the brick, each in [-1, kBrickSide].
  float at(int x, int y, int z) const { return v[index(x, y, z)]; }
  // |grad d| by central differences at local voxel l, each coordinate in [0, kBrickSide).
  double gradientLength(Int3 l) const {
    return GradStencil::inArray(v + index(l.x, l.y, l.z), 1, kSide, kSide * kSide).length();
  }
};

// Calls fn(local, global) for each voxel of a brick that lies in the domain.
template <class F>
void forEachDomainVoxel(const Volume& vol, Int3 b, F&& fn) {
  const Int3 o = Bricks::origin(b);
  const Int3 d = vol.dims();
  for (int z = 0; z < kBrickSide && o.z + z < d.z; ++z)
    for (int y = 0; y < kBrickSide && o.y + y < d.y; ++y)
      for (int x = 0; x < kBrickSide && o.x + x < d.x; ++x) fn(Int3{x, y, z}, o + Int3{x, y, z});
}

const Int3 kSix[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};

}  // namespace

double insideVolume(const Volume& vol) {
  double sum = 0;
  vol.forEachPresentBrick([&](Int3 b, const Brick& br) {
    forEachDomainVoxel(vol, b, [&](Int3 l, Int3) {
      sum += std::clamp(0.5 - double(br.v[Bricks::index(l)]), 0.0, 1.0);
    });
  });
  vol.forEachInsideBrick([&](Int3 b) { forEachDomainVoxel(vol, b, [&](Int3, Int3) { sum += 1; }); });
  return sum;
}

namespace {

// Calls fn(neighbourhood, local, global) for every domain voxel of every stored brick that
// meets `region` (its voxels outside the region included), gathering each neighbourhood once.
template <class F>
void forEachStoredVoxel(const Volume& vol, const Box& region, F&& fn) {
  vol.forEachPresentBrick([&](Int3 b, const Brick&) {
    if (Bricks::box(b).intersect(region).empty()) return;
    const Neighbourhood n(vol, b);
    forEachDomainVoxel(vol, b, [&](Int3 l, Int3 p) { fn(n, l, p); });
  });
}

// The measures that need a voxel's neighbours, each fed voxel by voxel so that measure()
// can feed all of them from one walk.
struct AreaSum {
  static constexpr double kEps = 1.5;  // half width of the raised-cosine delta
  double sum = 0;
  void add(const Neighbourhood& n, Int3 l) {
    const double d = n.at(l.x, l.y, l.z);
    if (std::fabs(d) >= kEps) return;
    sum += (1 + std::cos(std::numbers::pi * d / kEps)) / (2 * kEps) * n.gradientLength(l);
  }
};

struct BoundsOfZeroSet {
  Bounds bb;
  void include(Vec3 p) {
    if (bb.empty) {
      bb.lo = bb.hi = p;
      bb.empty = false;
      return;
    }
    for (int a = 0; a < 3; ++a) bb.lo[a] = std::min(bb.lo[a], p[a]), bb.hi[a] = std::max(bb.hi[a], p[a]);
  }
  void add(const Neighbourhood& n, Int3 l, Int3 p) {
    const double d = n.at(l.x, l.y, l.z);
    if (d >= 0) return;
    const Vec3 pv{double(p.x), double(p.y), double(p.z)};
    include(pv);
    for (int a = 0; a < 3; ++a)
      for (int s = -1; s <= 1; s += 2) {
        Int3 q = l;
        q[a] += s;
        const double dq = n.at(q.x, q.y, q.z);
        if (dq < 0) continue;
        Vec3 c = pv;
        c[a] += s * d / (d - dq);
        include(c);
      }
  }
  // Uniformly inside bricks count with their extent (clipped to the domain).
  Bounds finish(const Volume& vol) {
    vol.forEachInsideBrick([&](Int3 b) {
      const Int3 o = Bricks::origin(b), last = o + Int3{kBrickSide - 1, kBrickSide - 1, kBrickSide - 1};
      const Int3 d = vol.dims();
      include({double(o.x), double(o.y), double(o.z)});
      include({double(std::min(last.x, d.x - 1)), double(std::min(last.y, d.y - 1)), double(std::min(last.z, d.z - 1))});
    });
    return bb;
  }
};

struct GradientErrorSum {
  explicit GradientErrorSum(const Box& r) : region(r) {}
  Box region;
  GradientError e;
  double sum = 0;
  void add(const Neighbourhood& n, Int3 l, Int3 p) {
    if (!region.contains(p)) return;
    const float d = n.at(l.x, l.y, l.z);
    bool adjacent = false;
    for (const Int3& s : kSix) adjacent = adjacent || ((n.at(l.x + s.x, l.y + s.y, l.z + s.z) < 0) != (d < 0));
    if (!adjacent) return;
    const double err = std::fabs(n.gradientLength(l) - 1.0);
    e.max = std::max(e.max, err);
    sum += err;
    ++e.voxels;
  }
  GradientError finish() {
    e.mean = e.voxels ? sum / double(e.voxels) : 0;
    return e;
  }
};

}  // namespace

double surfaceArea(const Volume& vol) {
  AreaSum area;
  forEachStoredVoxel(vol, vol.domain(), [&](const Neighbourhood& n, Int3 l, Int3) { area.add(n, l); });
  return area.sum;
}

int countComponents(const Volume& vol) {
  // Node ids: one per voxel of each present brick, then one per uniformly inside brick; -1 for
  // outside bricks and the ring around the grid.
  BrickGrid<std::int64_t> base(vol.brickDims(), 1, -1);
  BrickGrid<const Brick*> data(vol.brickDims(), 1, nullptr);
  std::int64_t next = 0;
  vol.forEachPresentBrick([&](Int3 b, const Brick& br) {
    base[b] = next;
    data[b] = &br;
    next += kBrickVoxels;
  });
  std::vector<Int3> insideBricks;
  vol.forEachInsideBrick([&](Int3 b) {
    base[b] = next++;
    insideBricks.push_back(b);
  });
  std::vector<std::int64_t> parent(static_cast<std::size_t>(next));
  std::iota(parent.begin(), parent.end(), 0);
  std::vector<std::uint8_t> isInside(static_cast<std::size_t>(next), 0);
  auto find = [&](std::int64_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  auto unite = [&](std::int64_t a, std::int64_t b) {
    a = find(a), b = find(b);
    if (a != b) parent[std::max(a, b)] = std::min(a, b);
  };
  const Box domain = vol.domain();
  // The node of an inside voxel at global p, or -1 when p is outside the solid or the domain.
  auto nodeAt = [&](Int3 p) -> std::int64_t {
    if (!domain.contains(p)) return -1;
    const std::size_t s = base.index(Bricks::brickOf(p));
    if (base[s] < 0) return -1;
    if (!data[s]) return base[s];
    const int l = Bricks::indexOf(p);
    return data[s]->v[l] < 0 ? base[s] + l : -1;
  };
  vol.forEachPresentBrick([&](Int3 b, const Brick&) {
    forEachDomainVoxel(vol, b, [&](Int3, Int3 p) {
      const std::int64_t self = nodeAt(p);
      if (self < 0) return;
      isInside[self] = 1;
      for (const Int3& d : kSix)
        if (const std::int64_t o = nodeAt(p + d); o >= 0) unite(self, o);
    });
  });
  for (const Int3& b : insideBricks) {
    const std::int64_t self = base[b];
    isInside[self] = 1;
    for (const Int3& d : kSix)
      if (base[b + d] >= 0 && !data[b + d]) unite(self, base[b + d]);
  }
  int count = 0;
  for (std::int64_t i = 0; i < next; ++i)
    if (isInside[i] && find(i) == i) ++count;
  return count;
}

Bounds boundingBox(const Volume& vol) {
  BoundsOfZeroSet bounds;
  forEachStoredVoxel(vol, vol.domain(), [&](const Neighbourhood& n, Int3 l, Int3 p) { bounds.add(n, l, p); });
  return bounds.finish(vol);
}

GradientError gradientError(const Volume& vol) { return gradientError(vol, vol.domain()); }

GradientError gradientError(const Volume& vol, const Box& region) {
  GradientErrorSum error{region};
  forEachStoredVoxel(vol, region, [&](const Neighbourhood& n, Int3 l, Int3 p) { error.add(n, l, p); });
  return error.finish();
}

namespace {

std::uint64_t mixWord(std::uint64_t h, std::uint64_t w) {
  h ^= w * 0x9e3779b97f4a7c15ull;
  return std::rotl(h, 29) * 0xbf58476d1ce4e5b9ull;
}

std::uint64_t finalMix(std::uint64_t h) {
  h ^= h >> 31;
  h *= 0x94d049bb133111ebull;
  h ^= h >> 29;
  return h;
}

std::uint64_t brickKey(Int3 b) { return std::uint64_t(b.x) | std::uint64_t(b.y) << 20 | std::uint64_t(b.z) << 40; }

}  // namespace

std::uint64_t brickDigestTerm(Int3 brick, const BrickRef& ref) {
  if (!ref.data && !ref.inside) return 0;
  std::uint64_t h = mixWord(0x6a09e667f3bcc908ull, brickKey(brick) | (ref.data ? 1ull : 2ull) << 62);
  if (ref.data) {
    // Eight words a pass, the same words in the same order: one a pass took 9 instructions a
    // word, 4 of them the loop's, where 8 take 5.4 (a session hashes each brick a message
    // changed, ~30 for a stroke message of two r 8 dabs).
    static_assert(kBrickVoxels % 16 == 0);
    const float* v = ref.data->v;
    for (int i = 0; i < kBrickVoxels; i += 16)
      for (int k = 0; k < 16; k += 2) {
        std::uint64_t w;
        std::memcpy(&w, v + i + k, sizeof w);
        h = mixWord(h, w);
      }
    if (ref.paint) {
      h = mixWord(h, 0x3c6ef372fe94f82bull);
      for (int i = 0; i < kBrickVoxels; i += 2) {
        const Texel a = ref.paint->t[i], b = ref.paint->t[i + 1];
        h = mixWord(h, std::uint64_t(a.r) | std::uint64_t(a.g) << 8 | std::uint64_t(a.b) << 16 | std::uint64_t(a.mask) << 24 |
                           std::uint64_t(b.r) << 32 | std::uint64_t(b.g) << 40 | std::uint64_t(b.b) << 48 |
                           std::uint64_t(b.mask) << 56);
      }
    }
  }
  // Terms are summed: each must be well spread on its own.
  return finalMix(h);
}

std::uint64_t digestFromTerms(Int3 dims, float band, std::uint64_t termSum, Rgb8 base) {
  std::uint64_t h = mixWord(0xbb67ae8584caa73bull, std::uint64_t(dims.x) | std::uint64_t(dims.y) << 20 | std::uint64_t(dims.z) << 40);
  h = mixWord(h, std::bit_cast<std::uint32_t>(band));
  h = mixWord(h, termSum);
  if (base != kClayColor) h = mixWord(h, 0x1000000ull | std::uint64_t(base.r) | std::uint64_t(base.g) << 8 | std::uint64_t(base.b) << 16);
  return finalMix(h);
}

std::uint64_t digest(const Volume& vol) {
  return digestFromTerms(vol.dims(), vol.band(), digestTermSum(vol), vol.baseColor());
}

std::uint64_t digestTermSum(const Volume& vol) {
  std::uint64_t sum = 0;
  vol.forEachPresentBrick([&](Int3 b, const Brick& br) {
    BrickRef ref;
    // Aliases without ownership: the volume holds both for the call.
    ref.data = std::shared_ptr<const Brick>(std::shared_ptr<const Brick>(), &br);
    if (const BrickPaint* p = vol.brickPaint(b)) ref.paint = std::shared_ptr<const BrickPaint>(std::shared_ptr<const BrickPaint>(), p);
    sum += brickDigestTerm(b, ref);
  });
  vol.forEachInsideBrick([&](Int3 b) { sum += brickDigestTerm(b, BrickRef{nullptr, true}); });
  return sum;
}

std::string digestText(std::uint64_t h) {
  static const char* hex = "0123456789abcdef";
  std::string s(16, '0');
  for (int i = 15; i >= 0; --i, h >>= 4) s[std::size_t(i)] = hex[h & 15];
  return s;
}

std::string digestHex(const Volume& vol) { return digestText(digest(vol)); }

Measures measure(const Volume& vol) {
  Measures m;
  AreaSum area;
  BoundsOfZeroSet bounds;
  GradientErrorSum error{vol.domain()};
  forEachStoredVoxel(vol, vol.domain(), [&](const Neighbourhood& n, Int3 l, Int3 p) {
    area.add(n, l);
    bounds.add(n, l, p);
    error.add(n, l, p);
  });
  m.insideVolume = insideVolume(vol);
  m.surfaceArea = area.sum;
  m.components = countComponents(vol);
  m.bounds = bounds.finish(vol);
  m.gradientError = error.finish();
  m.digest = digestHex(vol);
  return m;
}

}  // namespace marzipan
