// Marching cubes over the bricked field (conventions in marching_cubes.hpp).
//
// Cell corners: corner c is at offset (c & 1, c >> 1 & 1, c >> 2 & 1); bit c of a cell's case
// is set when that corner is inside (d < 0). Cell edges: edge e runs along axis a = e / 4 from
// the corner with offsets (r & 1) on axis a+1 and (r >> 1) on axis a+2 (mod 3), r = e % 4.
//
// Work is split into blocks of kBrickSide^3 cells: block B holds the cells whose lowest corner lies in
// brick B, so its corners span bricks B and B+1 on each axis; blocks run from -1 (the cells
// that close the surface against the domain's low sides) to brickDims - 1. Only blocks whose
// bricks hold both signs are visited (uniform bricks tell their sign without being read).
// A block owns the grid edges whose lowest voxel lies in it and numbers their vertices in a
// fixed scan order; an edge on one of its three high sides belongs to a neighbour block, so
// the block records it as (neighbour, slot in the neighbour's low-side planes) and the
// reference is resolved once every block has counted its vertices. Blocks are concatenated
// in z, y, x order, which makes the output independent of the thread count.
#include "marching_cubes.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

#include "brick.hpp"
#include "errors.hpp"
#include "stencil.hpp"

namespace marzipan {

namespace {

// --- the case table, derived once from the face rule ---------------------------------------

constexpr int kMaxCaseTriangles = 12;

struct CaseTable {
  std::uint8_t count[256] = {};
  std::uint8_t edges[256][kMaxCaseTriangles * 3] = {};
};

int edgeAxis(int e) { return e / 4; }

// Offsets of the edge's lower corner.
std::array<int, 3> edgeOffset(int e) {
  const int a = e / 4, r = e % 4;
  std::array<int, 3> o{0, 0, 0};
  o[(a + 1) % 3] = r & 1;
  o[(a + 2) % 3] = r >> 1;
  return o;
}

int cornerOf(const std::array<int, 3>& o) { return o[0] | o[1] << 1 | o[2] << 2; }
int edgeLow(int e) { return cornerOf(edgeOffset(e)); }
int edgeHigh(int e) { return edgeLow(e) | 1 << edgeAxis(e); }

Vec3 edgeMid(int e) {
  const auto o = edgeOffset(e);
  Vec3 p{double(o[0]), double(o[1]), double(o[2])};
  p[edgeAxis(e)] = 0.5;
  return p;
}

Vec3 cornerPoint(int c) { return {double(c & 1), double(c >> 1 & 1), double(c >> 2 & 1)}; }

// Faces f = 2 * axis + side. Each edge lies on two faces.
int edgeFaces(int e) {
  const int a = edgeAxis(e);
  const auto o = edgeOffset(e);
  const int b1 = (a + 1) % 3, b2 = (a + 2) % 3;
  return 1 << (2 * b1 + o[b1]) | 1 << (2 * b2 + o[b2]);
}

// Triangulates one closed loop of edge vertices (in surface order) without a diagonal between
// two vertices of the same cell face: such a diagonal could also be chosen by the neighbour
// cell and the edge would then border four triangles. Among the remaining triangulations it
// takes the one with the shortest diagonals.
void triangulateLoop(const std::vector<int>& loop, std::vector<int>& out) {
  const int k = int(loop.size());
  auto chord = [&](int i, int j) {
    if (j == i + 1 || (i == 0 && j == k - 1)) return 0.0;
    if (edgeFaces(loop[i]) & edgeFaces(loop[j])) return 1e6;
    return length(edgeMid(loop[i]) - edgeMid(loop[j]));
  };
  std::vector<double> cost(std::size_t(k * k), 0.0);
  std::vector<int> split(std::size_t(k * k), -1);
  for (int len = 2; len < k; ++len)
    for (int i = 0; i + len < k; ++i) {
      const int j = i + len;
      double best = std::numeric_limits<double>::infinity();
      for (int m = i + 1; m < j; ++m) {
        const double c = cost[std::size_t(i * k + m)] + cost[std::size_t(m * k + j)] + chord(i, m) + chord(m, j);
        if (c < best) best = c, split[std::size_t(i * k + j)] = m;
      }
      cost[std::size_t(i * k + j)] = best;
    }
  std::vector<std::pair<int, int>> todo{{0, k - 1}};
  while (!todo.empty()) {
    const auto [i, j] = todo.back();
    todo.pop_back();
    if (j - i < 2) continue;
    const int m = split[std::size_t(i * k + j)];
    out.insert(out.end(), {loop[i], loop[m], loop[j]});
    todo.push_back({m, j});
    todo.push_back({i, m});
  }
}

CaseTable buildCaseTable() {
  CaseTable t;
  for (int m = 0; m < 256; ++m) {
    auto inside = [&](int c) { return (m >> c & 1) != 0; };
    auto crossed = [&](int e) { return inside(edgeLow(e)) != inside(edgeHigh(e)); };
    int next[12];
    std::fill(std::begin(next), std::end(next), -1);
    for (int f = 0; f < 6; ++f) {
      const int fa = f / 2, side = f % 2;
      std::vector<int> faceEdges;
      for (int e = 0; e < 12; ++e)
        if ((edgeFaces(e) >> f & 1) && crossed(e)) faceEdges.push_back(e);
      std::vector<std::pair<int, int>> segments;
      if (faceEdges.size() == 2) {
        segments.push_back({faceEdges[0], faceEdges[1]});
      } else if (faceEdges.size() == 4) {
        // Ambiguous face: cut off each inside corner on its own.
        for (int c = 0; c < 8; ++c) {
          if ((c >> fa & 1) != side || !inside(c)) continue;
          std::vector<int> around;
          for (int e : faceEdges)
            if (edgeLow(e) == c || edgeHigh(e) == c) around.push_back(e);
          segments.push_back({around[0], around[1]});
        }
      }
      Vec3 n{0, 0, 0};
      n[fa] = side ? 1 : -1;
      for (auto [a, b] : segments) {
        // Seen from outside the cell, the inside corners lie to the right of a segment that
        // runs counter-clockwise around the solid's outward normal.
        const int in = inside(edgeLow(a)) ? edgeLow(a) : edgeHigh(a);
        const Vec3 pa = edgeMid(a);
        if (dot(n, cross(edgeMid(b) - pa, cornerPoint(in) - pa)) > 0) std::swap(a, b);
        next[a] = b;
      }
    }
    std::vector<int> tris;
    bool seen[12] = {};
    for (int e = 0; e < 12; ++e) {
      if (!crossed(e) || seen[e]) continue;
      std::vector<int> loop;
      for (int v = e; !seen[v]; v = next[v]) {
        seen[v] = true;
        loop.push_back(v);
      }
      triangulateLoop(loop, tris);
    }
    t.count[m] = std::uint8_t(tris.size() / 3);
    std::copy(tris.begin(), tris.end(), t.edges[m]);
  }
  return t;
}

const CaseTable& caseTable() {
  static const CaseTable table = buildCaseTable();
  return table;
}

// --- blocks --------------------------------------------------------------------------------

constexpr int kSide = kBrickSide;    // cells per block side
constexpr std::uint32_t kRow = Bricks::kRowBits;  // one bit per cell of a block row
constexpr int kCorners = kSide + 1;  // corners per block side
static_assert(kCorners <= 32, "a block row's corners are bits of a 32-bit word");
constexpr int kGather = kSide + 3;   // corners plus a ring for central differences
constexpr int kPlaneSlots = 3 * 2 * kSide * kSide;
constexpr std::uint32_t kNeighbourShift = 29;
constexpr std::uint32_t kLocalMask = (1u << kNeighbourShift) - 1;

// Slot of an edge (axis `axis`, lower voxel q with q[plane] == 0) in a block's low-side plane.
int planeSlot(int plane, int axis, const int q[3]) {
  const int k = axis == (plane + 1) % 3 ? 0 : 1;
  return ((plane * 2 + k) * kSide + q[(plane + 1) % 3]) * kSide + q[(plane + 2) % 3];
}

struct BlockOut {
  std::vector<float> positions, normals;
  std::vector<std::uint32_t> refs;  // local vertex index, or neighbour code and plane slot
  std::array<std::uint32_t, kPlaneSlots> planes;
};

struct EdgeInfo {
  int axis;
  int off[3];
};

// Set bits of a row mask, a byte at a time (one byte for rows of 8 cells), without relying on a
// popcount instruction in the target.
int bitCount(std::uint32_t bits) {
  static constexpr auto counts = [] {
    std::array<std::uint8_t, 256> c{};
    for (int i = 1; i < 256; ++i) c[std::size_t(i)] = std::uint8_t((i & 1) + c[std::size_t(i >> 1)]);
    return c;
  }();
  int n = 0;
  for (; bits; bits >>= 8) n += counts[bits & 0xFF];
  return n;
}

// Copies the block's corners and their one-voxel ring (voxels SB-1 .. SB+S+1 per axis, S the
// brick side, which lie in bricks B-1 .. B+1) into v[z][y][x]; voxels outside the domain read +band. Volume::gather
// does the same but looks the brick up again for every row segment.
void gatherBlock(const Volume& vol, Int3 block, float (&v)[kGather][kGather][kGather]) {
  const Int3 dims = vol.dims(), bd = vol.brickDims();
  const float air = vol.band();
  const float* data[3][3][3];
  float uniform[3][3][3];
  for (int z = 0; z < 3; ++z)
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) {
        const Int3 b = block + Int3{x - 1, y - 1, z - 1};
        data[z][y][x] = nullptr;
        uniform[z][y][x] = air;
        if (b.x >= 0 && b.y >= 0 && b.z >= 0 && b.x < bd.x && b.y < bd.y && b.z < bd.z)
          data[z][y][x] = vol.brickData(b, &uniform[z][y][x]);
      }
  // Per axis and gathered position: brick (0..2 for B-1..B+1), local coordinate, in domain.
  int brickOf[3][kGather], localOf[3][kGather];
  bool valid[3][kGather];
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i < kGather; ++i) {
      const int g = block[a] * kSide - 1 + i;
      brickOf[a][i] = Bricks::brickOf(i - 1) + 1;
      localOf[a][i] = Bricks::localOf(i - 1);
      valid[a][i] = g >= 0 && g < dims[a];
    }
  const bool allValidX = valid[0][0] && valid[0][kGather - 1];
  for (int z = 0; z < kGather; ++z)
    for (int y = 0; y < kGather; ++y) {
      float* row = v[z][y];
      if (!valid[2][z] || !valid[1][y]) {
        std::fill(row, row + kGather, air);
        continue;
      }
      const int bz = brickOf[2][z], by = brickOf[1][y];
      const int offset = Bricks::index(0, localOf[1][y], localOf[2][z]);
      if (allValidX) {
        // Ring voxel from brick B-1, the brick's own row, two voxels from brick B+1.
        row[0] = data[bz][by][0] ? data[bz][by][0][offset + kSide - 1] : uniform[bz][by][0];
        if (const float* d = data[bz][by][1]) {
          std::copy(d + offset, d + offset + kSide, row + 1);
        } else {
          std::fill(row + 1, row + 1 + kSide, uniform[bz][by][1]);
        }
        const float* d = data[bz][by][2];
        row[kSide + 1] = d ? d[offset] : uniform[bz][by][2];
        row[kSide + 2] = d ? d[offset + 1] : uniform[bz][by][2];
        continue;
      }
      for (int x = 0; x < kGather; ++x) {
        const int bx = brickOf[0][x];
        const float* d = data[bz][by][bx];
        row[x] = !valid[0][x] ? air : d ? d[offset + localOf[0][x]] : uniform[bz][by][bx];
      }
    }
}

void processBlock(const Volume& vol, Int3 block, const CaseTable& table, BlockOut& out) {
  const Int3 origin{block.x * kSide, block.y * kSide, block.z * kSide};
  float v[kGather][kGather][kGather];  // [z][y][x], corner (0,0,0) at [1][1][1]
  gatherBlock(vol, block, v);

  std::uint32_t mask[kCorners][kCorners];  // [z][y], bit x: corner inside
  for (int z = 0; z < kCorners; ++z)
    for (int y = 0; y < kCorners; ++y) {
      std::uint32_t m = 0;
      const float* row = &v[z + 1][y + 1][1];
      for (int x = 0; x < kCorners; ++x) m |= std::uint32_t(row[x] < 0) << x;
      mask[z][y] = m;
    }

  auto at = [&](int x, int y, int z) { return v[z + 1][y + 1][x + 1]; };
  auto grad = [&](int x, int y, int z, float g[3]) {
    GradStencil::inArray(&v[z + 1][y + 1][x + 1], 1, kGather, kGather * kGather).gradient(g);
  };

  std::uint32_t local[kSide][kSide][kSide][3];  // written for crossed owned edges only
  std::uint32_t count = 0;
  int crossings = 0;
  for (int z = 0; z < kSide; ++z)
    for (int y = 0; y < kSide; ++y) {
      const std::uint32_t m = mask[z][y];
      crossings += bitCount((m ^ (m >> 1)) & kRow) + bitCount((m ^ mask[z][y + 1]) & kRow) +
                   bitCount((m ^ mask[z + 1][y]) & kRow);
    }
  out.positions.reserve(std::size_t(crossings) * 3);
  out.normals.reserve(std::size_t(crossings) * 3);
  for (int z = 0; z < kSide; ++z)
    for (int y = 0; y < kSide; ++y) {
      const std::uint32_t m = mask[z][y];
      const std::uint32_t c[3] = {(m ^ (m >> 1)) & kRow, (m ^ mask[z][y + 1]) & kRow, (m ^ mask[z + 1][y]) & kRow};
      for (std::uint32_t bits = c[0] | c[1] | c[2]; bits; bits &= bits - 1) {
        const int x = std::countr_zero(bits);
        for (int a = 0; a < 3; ++a) {
          if (!(c[a] >> x & 1)) continue;
          const int p[3] = {x, y, z};
          int q[3] = {x, y, z};
          ++q[a];
          const float d0 = at(p[0], p[1], p[2]), d1 = at(q[0], q[1], q[2]);
          const float t = d0 / (d0 - d1);
          float g0[3], g1[3];
          grad(p[0], p[1], p[2], g0);
          grad(q[0], q[1], q[2], g1);
          Vec3 n;
          for (int i = 0; i < 3; ++i) {
            out.positions.push_back(float(origin[i] + p[i]) + (i == a ? t : 0.0f));
            n[i] = g0[i] + t * (g1[i] - g0[i]);
          }
          n = normalized(n);
          out.normals.insert(out.normals.end(), {float(n.x), float(n.y), float(n.z)});
          local[z][y][x][a] = count;
          for (int plane = 0; plane < 3; ++plane)
            if (plane != a && p[plane] == 0) out.planes[std::size_t(planeSlot(plane, a, p))] = count;
          ++count;
        }
      }
    }

  static const auto edgeInfo = [] {
    std::array<EdgeInfo, 12> info;
    for (int e = 0; e < 12; ++e) {
      const auto o = edgeOffset(e);
      info[std::size_t(e)] = {edgeAxis(e), {o[0], o[1], o[2]}};
    }
    return info;
  }();

  for (int z = 0; z < kSide; ++z)
    for (int y = 0; y < kSide; ++y) {
      const std::uint32_t m00 = mask[z][y], m10 = mask[z][y + 1], m01 = mask[z + 1][y], m11 = mask[z + 1][y + 1];
      const std::uint32_t all = m00 & m10 & m01 & m11, any = m00 | m10 | m01 | m11;
      const std::uint32_t mixed = (any | (any >> 1)) & ~(all & (all >> 1)) & kRow;
      for (std::uint32_t bits = mixed; bits; bits &= bits - 1) {
        const int x = std::countr_zero(bits);
        const int cube = int((m00 >> x & 3) | (m10 >> x & 3) << 2 | (m01 >> x & 3) << 4 | (m11 >> x & 3) << 6);
        const int n = table.count[cube] * 3;
        for (int i = 0; i < n; ++i) {
          const EdgeInfo& e = edgeInfo[table.edges[cube][i]];
          int p[3] = {x + e.off[0], y + e.off[1], z + e.off[2]};
          if (p[0] < kSide && p[1] < kSide && p[2] < kSide) {
            out.refs.push_back(local[p[2]][p[1]][p[0]][e.axis]);
            continue;
          }
          std::uint32_t code = 0;
          int plane = -1;
          for (int a = 2; a >= 0; --a)
            if (p[a] == kSide) p[a] = 0, code |= 1u << a, plane = a;
          out.refs.push_back(code << kNeighbourShift | std::uint32_t(planeSlot(plane, e.axis, p)));
        }
      }
    }
}

}  // namespace

Mesh extractMesh(const Volume& vol, ThreadPool& pool) {
  const CaseTable& table = caseTable();
  const Int3 bd = vol.brickDims();
  // Which signs each brick holds, over [-1, bd] per axis (the ring is air): bit 0 some voxel
  // outside, bit 1 some voxel inside. A brick reaching past the domain also borders air.
  constexpr std::uint8_t kOut = 1, kIn = 2;
  BrickGrid<std::uint8_t> signs(bd, 1, kOut);
  auto signsAt = [&](int x, int y, int z) -> std::uint8_t& { return signs[Int3{x, y, z}]; };
  const Int3 dims = vol.dims();
  pool.parallelFor(std::size_t(bd.z), [&](std::size_t zi) {
    const int z = int(zi);
    for (int y = 0; y < bd.y; ++y)
      for (int x = 0; x < bd.x; ++x) {
        float u;
        const float* d = vol.brickData({x, y, z}, &u);
        std::uint8_t s = u < 0 ? kIn : kOut;
        if (d) {
          bool in = false, out = false;
          for (int i = 0; i < kBrickVoxels; ++i) in |= d[i] < 0, out |= d[i] >= 0;
          s = std::uint8_t((in ? kIn : 0) | (out ? kOut : 0));
        }
        const bool partial = (x + 1) * kSide > dims.x || (y + 1) * kSide > dims.y || (z + 1) * kSide > dims.z;
        signsAt(x, y, z) = std::uint8_t(s | (partial ? kOut : 0));
      }
  });

  // Blocks over [-1, bd) per axis; a block can hold a sign change only if its 8 bricks hold both.
  BrickGrid<std::int32_t> blockIndex(bd, 1, -1);
  std::vector<Int3> blocks;
  for (int z = -1; z < bd.z; ++z)
    for (int y = -1; y < bd.y; ++y)
      for (int x = -1; x < bd.x; ++x) {
        std::uint8_t seen = 0;
        for (int c = 0; c < 8; ++c) seen |= signsAt(x + (c & 1), y + (c >> 1 & 1), z + (c >> 2 & 1));
        if (seen != (kIn | kOut)) continue;
        blockIndex[Int3{x, y, z}] = std::int32_t(blocks.size());
        blocks.push_back({x, y, z});
      }

  std::vector<BlockOut> outs(blocks.size());
  pool.parallelFor(blocks.size(), [&](std::size_t i) { processBlock(vol, blocks[i], table, outs[i]); });

  std::vector<std::uint64_t> vertexBase(blocks.size() + 1, 0), refBase(blocks.size() + 1, 0);
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    vertexBase[i + 1] = vertexBase[i] + outs[i].positions.size() / 3;
    refBase[i + 1] = refBase[i] + outs[i].refs.size();
  }
  if (vertexBase.back() > std::numeric_limits<std::uint32_t>::max())
    throw EngineError(ErrorKind::TooLarge, "mesh", "more than 2^32 - 1 vertices");

  Mesh mesh;
  mesh.positions.resize(std::size_t(vertexBase.back()) * 3);
  mesh.normals.resize(mesh.positions.size());
  mesh.indices.resize(std::size_t(refBase.back()));
  pool.parallelFor(blocks.size(), [&](std::size_t i) {
    const BlockOut& o = outs[i];
    std::copy(o.positions.begin(), o.positions.end(), mesh.positions.begin() + std::ptrdiff_t(vertexBase[i] * 3));
    std::copy(o.normals.begin(), o.normals.end(), mesh.normals.begin() + std::ptrdiff_t(vertexBase[i] * 3));
    std::uint32_t* dst = mesh.indices.data() + refBase[i];
    for (const std::uint32_t r : o.refs) {
      const std::uint32_t code = r >> kNeighbourShift, slot = r & kLocalMask;
      if (code == 0) {
        *dst++ = std::uint32_t(vertexBase[i]) + slot;
        continue;
      }
      // The owner block exists: it sees the same two voxel signs across this edge.
      const Int3 b = blocks[i] + Int3{int(code & 1), int(code >> 1 & 1), int(code >> 2 & 1)};
      const std::size_t owner = std::size_t(blockIndex[b]);
      *dst++ = std::uint32_t(vertexBase[owner]) + outs[owner].planes[slot];
    }
  });
  if (carriesColor(vol)) {
    mesh.colors.resize(mesh.positions.size());
    constexpr std::size_t kChunk = 4096;  // vertices per task
    pool.parallelFor((mesh.vertexCount() + kChunk - 1) / kChunk, [&](std::size_t c) {
      for (std::size_t v = c * kChunk; v < std::min(mesh.vertexCount(), (c + 1) * kChunk); ++v) {
        const Rgb8 k = colorAt(vol, mesh.position(v));
        mesh.colors[3 * v] = k.r, mesh.colors[3 * v + 1] = k.g, mesh.colors[3 * v + 2] = k.b;
      }
    });
  }
  return mesh;
}

bool carriesColor(const Volume& vol) { return vol.paintedBricks() > 0 || !(vol.baseColor() == kClayColor); }

Rgb8 colorAt(const Volume& vol, Vec3 p) {
  const Vec3 f{std::floor(p.x), std::floor(p.y), std::floor(p.z)};
  const Vec3 t = p - f;
  const Int3 o{int(f.x), int(f.y), int(f.z)};
  double sum[3] = {0, 0, 0};
  for (int c = 0; c < 8; ++c) {
    double w = 1;
    for (int a = 0; a < 3; ++a) w *= (c >> a & 1) ? t[a] : 1 - t[a];
    if (w == 0) continue;  // a vertex on a grid edge reads its two end voxels only
    const Texel k = vol.texel(o + Int3{c & 1, c >> 1 & 1, c >> 2 & 1});
    sum[0] += w * k.r, sum[1] += w * k.g, sum[2] += w * k.b;
  }
  auto byte = [](double v) { return std::uint8_t(std::clamp(std::lround(v), 0l, 255l)); };
  return {byte(sum[0]), byte(sum[1]), byte(sum[2])};
}

double meshArea(const Mesh& m) {
  double area = 0;
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.position(m.indices[3 * t]), b = m.position(m.indices[3 * t + 1]),
               c = m.position(m.indices[3 * t + 2]);
    area += 0.5 * length(cross(b - a, c - a));
  }
  return area;
}

double meshVolume(const Mesh& m) {
  double vol = 0;
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const Vec3 a = m.position(m.indices[3 * t]), b = m.position(m.indices[3 * t + 1]),
               c = m.position(m.indices[3 * t + 2]);
    vol += dot(a, cross(b, c));
  }
  return vol / 6.0;
}

namespace {

// Directed edges (from << 32 | to), sorted by their undirected key.
std::vector<std::uint64_t> sortedEdges(const Mesh& m) {
  std::vector<std::uint64_t> edges;
  edges.reserve(m.indices.size());
  for (std::size_t t = 0; t < m.triangleCount(); ++t)
    for (int k = 0; k < 3; ++k)
      edges.push_back(std::uint64_t(m.indices[3 * t + std::size_t(k)]) << 32 |
                      m.indices[3 * t + std::size_t((k + 1) % 3)]);
  auto key = [](std::uint64_t e) {
    const std::uint64_t a = e >> 32, b = e & 0xFFFFFFFFu;
    return a < b ? a << 32 | b : b << 32 | a;
  };
  std::sort(edges.begin(), edges.end(), [&](std::uint64_t x, std::uint64_t y) {
    const std::uint64_t kx = key(x), ky = key(y);
    return kx != ky ? kx < ky : x < y;
  });
  return edges;
}

std::uint64_t undirected(std::uint64_t e) {
  const std::uint64_t a = e >> 32, b = e & 0xFFFFFFFFu;
  return a < b ? a << 32 | b : b << 32 | a;
}

}  // namespace

long long eulerCharacteristic(const Mesh& m) {
  const auto edges = sortedEdges(m);
  long long e = 0;
  for (std::size_t i = 0; i < edges.size(); ++i)
    if (i == 0 || undirected(edges[i]) != undirected(edges[i - 1])) ++e;
  return (long long)m.vertexCount() - e + (long long)m.triangleCount();
}

EdgeCheck checkEdges(const Mesh& m) {
  EdgeCheck c;
  for (std::size_t t = 0; t < m.triangleCount(); ++t) {
    const std::uint32_t* i = &m.indices[3 * t];
    if (i[0] == i[1] || i[1] == i[2] || i[2] == i[0]) ++c.degenerate;
  }
  const auto edges = sortedEdges(m);
  for (std::size_t i = 0; i < edges.size();) {
    std::size_t j = i;
    while (j < edges.size() && undirected(edges[j]) == undirected(edges[i])) ++j;
    ++c.edges;
    if (j - i == 1) {
      ++c.boundary;
    } else if (j - i > 2) {
      ++c.nonManifold;
    } else if (edges[i] == edges[i + 1]) {
      ++c.misoriented;
    }
    i = j;
  }
  return c;
}

}  // namespace marzipan
