// The warps' resample (warp_passes.hpp, resample): each voxel the flow moves reads the base at
// its preimage X(x), through the lattice's inverse (warp_lattice.hpp) and trilinearly, and next
// to the zero set through the flow integrated at the voxel and the cubic read; a lattice cell
// whose reads are all one block value of the base takes it by a comparison. A painted volume's
// colours move with the clay (their rules are applyWarp's, warp.cpp). Conventions are
// warp_passes.hpp's.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "engine/level_set/warp_passes.hpp"

namespace marzipan::level_set::warp {

// A snake hook's lattice: its error in a value, measured against the flow at the voxel, stayed
// within 1.84 lipschitz() kLatticeStep^2 / radius over [warp]'s tests (0.126 where that is
// 0.069: the trilinear read's own bias beside the cubic one's) and 1.08 of it on the benches'
// tentacles (0.417 of 0.385; 2026-11-30). Twice that and kExactNearFloor more keeps every
// voxel read through the lattice alone on the side of the zero set the flow at it would put it,
// and whether it lies next to the zero set with it. The floor is for the trilinear read's own
// bias, h^2 kappa / 8 along each axis, which does not shrink with the move: over [warp]'s tests
// and the tentacle bench the error at the voxels within 1.5 vu of the zero set came within
// 0.011 vu of twice the scale, so 0.1 leaves 0.11 vu (0.25 before 2026-11-30: 1% more
// instructions a tentacle's move). The kept-voxel pass (warp_feet.cpp) reads the values of
// those next to the zero set through the flow. A tentacle's move read 1,386 voxels through the
// flow (at the floor of 0.25), a third of them only to settle the value of a voxel the
// redistance then replaces. Not for the others: a grab's lattice erred by up to 0.76 vu
// (kExactNear's margin), and a painted volume's colours are read at the preimage the distance is.
constexpr double kLatticeErrorMargin = 2, kExactNearFloor = 0.1;

// The blocks of one value pay where much of the support lies deep inside or far outside (a
// grab's). A snake hook's support of radius 8 is mostly its tentacle's band: 4 of a move's 435
// cells were of one value, and finding the blocks and the nodes' ranges cost more than those
// cells saved (2026-11-30, the same bits either way: a cell's voxels read its one value):
// `snake_hook_tentacle` 5.588M -> 5.338M instructions a move, `snake_hook`'s move off the
// sphere 4.310M -> 4.087M. Up to kSmallSnakeHook (radius 8's support widened by half, as a
// young tentacle's is); larger ones were not measured and keep them.
constexpr double kSmallSnakeHook = 12;

bool readsCells(const Velocity& v, bool painted) {
  return !painted && !(v.kind == Velocity::Kind::Capsule && v.plateau > 0 && v.radius <= kSmallSnakeHook);
}

float exactNear(const Velocity& v, bool painted) {
  if (painted || v.kind != Velocity::Kind::Capsule || !(v.plateau > 0)) return kExactNear;
  const double error = v.lipschitz() * kLatticeStep * kLatticeStep / v.radius;
  return float(std::min(double(kExactNear), kLatticeErrorMargin * error + kExactNearFloor));
}

void resample(const WarpPass& w, const Volume& base, bool painted, bool masked, Runs& runs, std::vector<Box>& changed,
              std::vector<Box>& recoloured, ThreadPool& pool, const ProgressShare& progress) {
  const Velocity& v = w.v;
  WarpScratch& s = w.s;
  const Box& work = w.work;
  const int steps = w.steps;
  const int slices = work.size().z, layers = (slices + kLatticeStep - 1) / kLatticeStep;
  const auto texelIndex = [&](Vec3 q) -> std::ptrdiff_t {
    Int3 c;
    for (int a = 0; a < 3; ++a) c[a] = int(std::floor(q[a] + 0.5));
    return s.base.box.contains(c) ? std::ptrdiff_t(s.base.index(c)) : -1;
  };

  if (w.exactSlopes && s.exactReads.size() < std::size_t(std::max(0, slices))) s.exactReads.resize(std::size_t(slices));
  pool.parallelFor(std::size_t(std::max(0, layers)), [&](std::size_t layer) {
    progress.check();
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
      std::vector<ExactRead>* exactReads = w.exactSlopes ? &s.exactReads[std::size_t(i)] : nullptr;
      if (exactReads) exactReads->clear();
      for (int y = work.lo.y; y < work.hi.y; ++y) {
        // The row's voxels that the flow moves, one run (the support is convex): only they
        // are resampled, and the others never ask for their cells' values.
        // Not a structured binding: the lambdas below read x0, which clang 14 cannot capture
        // from one.
        const std::pair<int, int> rowRange = v.row(y, z, work);
        int x0 = rowRange.first, x1 = rowRange.second;
        while (x0 < x1 && !v.moves({double(x0), double(y), double(z)})) ++x0;
        while (x1 > x0 && !v.moves({double(x1 - 1), double(y), double(z)})) --x1;
        runs.at(y, z) = {x0, x1};
        const int cy = (y - work.lo.y) / kLatticeStep;
        const InverseLattice::Row latticeRow = s.lattice.row(y, z);
        float* cellRow = nullptr;
        if (w.cells && x1 > x0) {
          if (cells.empty()) cells.assign(std::size_t(cellsX) * std::size_t(s.lattice.nodes.y - 1), std::numeric_limits<float>::infinity());
          cellRow = cells.data() + std::size_t(cellsX) * std::size_t(cy);
        }
        // The row's first index, once: once the resample was a file of its own the compiler
        // computed each voxel's from its coordinates, 0.8% more instructions a snake hook move.
        const std::size_t k0 = s.warped.index({x0, y, z});
        // The row's first and last changed voxels, noted once the row is done (note() per
        // voxel was 0.45% of a tentacle's move).
        bool rowChanged = false;
        int first = x0, last = x0;
        const auto changes = [&](int x) __attribute__((always_inline)) {
          if (!rowChanged) first = x, rowChanged = true;
          last = x;
        };
        // The row's reads through the flow are integrated two at a time
        // (Velocity::capsuleInverse2(): the two chains of roots and products overlap, each with
        // its own bits): one waits in `pending` (its place in exactReads; its voxel is pendingX of
        // the row) for the next, or for the row's end. settle() finishes it once its X is known,
        // after voxels past it may have changed. Never on a painted volume (WarpPass::
        // exactSlopes), whose colours below read each voxel's preimage at once.
        std::ptrdiff_t pending = -1;
        int pendingX = 0;
        const auto settle = [&](ExactRead& e, int x) {
          e.phi = w.readNear(e.q);
          const float value = float(e.phi);
          if (value == s.base.v[e.k]) return;
          s.warped.v[e.k] = value;
          first = rowChanged ? std::min(first, x) : x, last = rowChanged ? std::max(last, x) : x;
          rowChanged = true;
        };
        // One voxel. `general`: whether the row may settle cells of one value or carry colours
        // (else a loop without those tests, which the compiler had left in it: 1.6% of a
        // tentacle's move).
        const auto voxel = [&](int x, auto general) __attribute__((always_inline)) {
          const std::size_t k = k0 + std::size_t(x - x0);
          if (decltype(general)::value && cellRow) {
            // x >= work.lo.x: unsigned, the division is a shift (a signed one rounds towards 0).
            const int ci = int(unsigned(x - work.lo.x) / kLatticeStep);
            float& u = cellRow[ci];
            if (u == std::numeric_limits<float>::infinity()) u = s.lattice.cellValue(ci, cy, int(layer));
            // A voxel that reads its own value stays, whether the flow moves it or not.
            if (u == s.base.v[k]) return;
            if (u == u) {
              s.warped.v[k] = u, changes(x);
              return;
            }
          }
          const Vec3 p{double(x), double(y), double(z)};
          Vec3 q = s.lattice.inverse(latticeRow, p, x);
          float value = float(w.read(q));
          // Near the zero set the surface's place is read: there X is integrated at the voxel.
          if (std::fabs(value) < w.exactNear) {
            const Vec3* onNode = s.lattice.imageAt(latticeRow, x);
            if (!onNode && exactReads) {
              ExactRead& e = exactReads->emplace_back(k);
              if (pending < 0) {
                // Waits for the row's next read through the flow, to be integrated with it.
                pending = std::ptrdiff_t(exactReads->size() - 1), pendingX = x;
                return;
              } else {
                ExactRead& waiting = (*exactReads)[std::size_t(pending)];
                const Vec3 at[2] = {{double(pendingX), double(y), double(z)}, p};
                Vec3 to[2], along[2];
                v.capsuleInverse2(at, steps, to, along);
                waiting.q = to[0], waiting.along = along[0], e.q = q = to[1], e.along = along[1];
                settle(waiting, pendingX);
                pending = -1;
              }
              e.phi = w.readNear(q);
              value = float(e.phi);
            } else {
              q = onNode ? *onNode : v.flow(p, steps, -1);
              value = float(w.readNear(q));
            }
          }
          if (decltype(general)::value && painted) {
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
          if (value == s.base.v[k]) return;
          s.warped.v[k] = value;
          changes(x);
        };
        if (cellRow || painted) {
          for (int x = x0; x < x1; ++x) voxel(x, std::true_type{});
        } else {
          for (int x = x0; x < x1; ++x) voxel(x, std::false_type{});
        }
        if (pending >= 0) {
          ExactRead& e = (*exactReads)[std::size_t(pending)];
          e.q = v.capsuleInverse({double(pendingX), double(y), double(z)}, steps, e.along);
          settle(e, pendingX);
          pending = -1;
        }
        if (rowChanged) note(first, y), note(last, y);
      }
      changed[std::size_t(i)] = any ? c : Box{};
      recoloured[std::size_t(i)] = tc;
      progress.advance(1.0 / slices);
    }
  });
}

}  // namespace marzipan::level_set::warp
