// The solid: a sparse, bricked, copy-on-write signed distance field.
//
// Conventions (every engine file follows them):
// - d < 0 inside, d > 0 outside; |grad d| = 1; the outward normal is grad d.
// - Unit: vu (voxel spacing 1). Voxel (i,j,k) sits at the point (i,j,k).
// - Only the band |d| < band() is exact; values beyond are clamped to +-band().
//   Points outside the domain read as +band() (the domain is surrounded by air).
// - Storage: bricks of 8^3 floats, index x + 8*(y + 8*z) inside a brick (brick.hpp: the side
//   and the addressing are defined there once); bricks are grouped in tiles of 8^3 bricks. A brick slot either shares an immutable Brick or is uniform
//   (every voxel -band or +band) and stores nothing, so memory grows with surface area.
// - Copy-on-write: a Volume is a value. Copying it copies only the tile table (O(tiles)) and
//   shares every brick; an edit publishes new bricks and new tiles and leaves copies alone.
//   A copy may be handed to another thread and read there without any lock while the
//   original goes on being edited on its own thread.
// - Channels (channels.hpp): a stored brick may carry a BrickPaint (colour and mask weight of
//   each voxel) in a slot of the same address, kept in tiles of their own that exist only once
//   something is painted: an unpainted volume stores nothing more than a colourless one.
//   A BrickRef names both; an edit of either is a BrickChange like any other (undo, redo).
#pragma once

#include <bitset>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "brick.hpp"
#include "channels.hpp"
#include "geometry.hpp"
#include "protocol/cpp/values.hpp"  // kMaxDomainSide

namespace marzipan {

class ThreadPool;

struct Brick {
  float v[kBrickVoxels];  // index Bricks::index(local voxel)
};

// One slot of the brick table: shared voxel data, or uniform inside/outside when data is null;
// with data, its channels, or null for the base colour and weight 0 throughout.
struct BrickRef {
  BrickRef() = default;
  BrickRef(std::shared_ptr<const Brick> d, bool in, std::shared_ptr<const BrickPaint> p = nullptr)
      : data(std::move(d)), inside(in), paint(std::move(p)) {}

  std::shared_ptr<const Brick> data;
  bool inside = false;  // meaningful only when data is null
  std::shared_ptr<const BrickPaint> paint;  // null when data is null

  bool uniform() const { return !data; }
  friend bool operator==(const BrickRef& a, const BrickRef& b) {
    return a.data == b.data && (a.data || a.inside == b.inside) && a.paint == b.paint;
  }
};

// One brick replaced by an edit: applying `after` over `before` redoes it, the reverse undoes it.
struct BrickChange {
  Int3 brick;  // brick coordinates (Bricks::brickOf(voxel))
  BrickRef before, after;
};

// What a local tool's redistance left out in one brick (level_set/stroke.cpp; docs/method.md
// §5, "The box of what moved"): each voxel of `box` (volume coordinates, within the brick) has
// moved by at most `move` vu since it was last redistanced, every other voxel of the brick by
// nothing; an empty box: nothing is left. A bound the tools keep, not part of the field: no
// digest, file, journal, BrickChange or undo holds it.
struct BrickDrift {
  float move = 0;
  Box box;

  bool none() const { return box.empty(); }
  friend bool operator==(const BrickDrift& a, const BrickDrift& b) = default;
};

class Volume {
 public:
  static constexpr float kDefaultBand = 3.0f;

  // An empty domain of dims voxels (all outside). Each side must be in [8, 1024]; the band
  // half-width in [2, 8] vu. Throws EngineError otherwise.
  explicit Volume(Int3 dims, float band = kDefaultBand);

  Int3 dims() const { return dims_; }
  Box domain() const { return {{0, 0, 0}, dims_}; }
  float band() const { return band_; }
  Int3 brickDims() const { return brickDims_; }

  // The colour of every voxel nothing has painted (channels.hpp). Settable only while nothing is
  // painted (throws EngineError "color" otherwise): it is what an absent BrickPaint means.
  Rgb8 baseColor() const { return base_; }
  void setBaseColor(Rgb8 c);

  // Counts published edits; saved with the volume. The service sets it after undo/redo.
  std::uint64_t revision() const { return revision_; }
  void setRevision(std::uint64_t r) { revision_ = r; }

  // --- reading -------------------------------------------------------------------------
  BrickRef brick(Int3 b) const;  // b must be within brickDims()
  // The brick's voxels, or null with *uniformValue set to -band/+band.
  const float* brickData(Int3 b, float* uniformValue) const;
  float at(Int3 p) const;  // +band outside the domain
  float at(int i, int j, int k) const { return at(Int3{i, j, k}); }

  // Copies box into out (x fastest, then y, then z); voxels outside the domain read +band.
  void gather(const Box& box, float* out) const;

  // Trilinear interpolation of d and its analytic gradient at any point.
  double sample(Vec3 p) const;
  Vec3 gradient(Vec3 p) const;
  // Central-difference gradient at a voxel.
  Vec3 voxelGradient(Int3 p) const;
  // p carried up to `steps` Newton steps towards the zero set along the gradient,
  // p - n d(p) / |grad d(p)| with n the unit gradient; it stops where d(p) is 0 or no longer in
  // the band, or where the slope falls under 0.5 (clamped or flat values give no direction).
  // The surface point nearest p when p lies near a smooth part of the surface.
  Vec3 towardSurface(Vec3 p, int steps) const;

  // The brick's channels, or null (base colour, weight 0); b must be within brickDims().
  const BrickPaint* brickPaint(Int3 b) const;
  // The channels of voxel p: the base colour and weight 0 where nothing is painted or outside
  // the domain.
  Texel texel(Int3 p) const;
  // Copies the channels of box into out (x fastest, then y, then z), as gather() the distances.
  void gatherTexels(const Box& box, Texel* out) const;
  // Stored bricks that carry channels; 0 for a volume never painted (or painted back to base).
  std::size_t paintedBricks() const { return paintedBricks_; }
  // Calls fn(brickCoord, const BrickPaint&) for every brick with channels, in z,y,x order.
  template <class F>
  void forEachPaintedBrick(F&& fn) const;

  std::size_t presentBricks() const { return presentBricks_; }
  // Calls fn(brickCoord, const Brick&) for every brick that stores data, in z,y,x order.
  template <class F>
  void forEachPresentBrick(F&& fn) const;
  // Calls fn(brickCoord) for every uniformly inside brick slot, in z,y,x order.
  template <class F>
  void forEachInsideBrick(F&& fn) const;

  // Bytes held by this version: bricks, tiles and the tile table, and the channels' bricks and tiles.
  std::size_t memoryBytes() const;

  // Bricks are held in tiles of kTileSide^3 bricks, which a copy of the volume shares with it
  // until either is edited there.
  static constexpr int kTileSide = 8;
  // Whether the tile holding brick b (within brickDims()) is the very one `other` (of the same
  // dims) holds, channels included: then each of its bricks is the same in both, without
  // looking at them (what changed since a copy lies in the tiles that are not shared).
  bool sharesTile(const Volume& other, Int3 b) const;

  // --- editing -------------------------------------------------------------------------
  // Replaces the voxels of `region` (clipped to the domain) by those of src, an array over
  // srcBox (x fastest) that must contain the clipped region. Values are clamped to +-band.
  // Publishes one new brick per brick whose values really changed (a brick that becomes
  // uniform is stored as such) and returns the changes, old bricks included.
  // The mask: a voxel of weight w (channels.hpp) takes old + (1 - w/255) (new - old) in float,
  // its old value exactly at 255; a brick that then equals its old one is no change. A changed
  // brick that stays stored keeps its channels, one that becomes uniform loses them.
  std::vector<BrickChange> scatter(const Box& region, const float* src, const Box& srcBox);
  // The same with the comparison (diff) spread over the pool: the same changes in the same order.
  std::vector<BrickChange> scatter(const Box& region, const float* src, const Box& srcBox, ThreadPool& pool);
  // The changes scatter() would publish, without publishing them, in z,y,x order of the bricks.
  // Safe to call from several threads at once on one volume that nobody edits meanwhile. With
  // a pool, a region of kParallelDiffVoxels or more is compared in fixed pieces (brick layers
  // along z) on its threads and their changes joined in order: the result does not depend on
  // the thread count (with NaN in the source it throws as well, whichever piece finds it).
  std::vector<BrickChange> diff(const Box& region, const float* src, const Box& srcBox) const;
  std::vector<BrickChange> diff(const Box& region, const float* src, const Box& srcBox, ThreadPool& pool) const;
  // Smaller regions are compared on the calling thread: waking the pool costs more than it saves.
  static constexpr std::int64_t kParallelDiffVoxels = std::int64_t(1) << 16;

  // The slot a newly computed brick becomes, for anything that builds bricks itself: voxels
  // past the domain's edge are set to +band (never read; equal fields get equal bricks), and a
  // brick whose voxels in the domain are all -band or all +band is uniform and stores nothing.
  // Writes the padding into `data`; safe to call from several threads at once.
  BrickRef canonicalBrick(Int3 brick, std::shared_ptr<Brick> data) const;

  // Colour follows the surface: in changes (bricks of this volume, not yet published), every
  // voxel that enters the band (|d| >= band before, < band after) takes the texel this volume
  // holds at the voxel nearest the old surface point it came from: its foot point on the new
  // surface, p - d n (n the central-difference normal of the new field), carried back along -n
  // while the old field is clamped there, then to its foot point on the old surface; when that
  // line misses the old surface (16 steps without reaching its band: an overhang), the old
  // surface point nearest p along one of the 26 neighbour directions.
  // Does nothing to a volume with no channels. scatter calls it; whoever publishes diff()'s
  // changes itself should too (chunked_pass.cpp does).
  void extendChannels(std::vector<BrickChange>& changes) const;

  // The channels' slot for newly computed texels: null when every texel is the base colour
  // with weight 0, else `paint` with its `masked` flag set. Safe to call from several threads.
  std::shared_ptr<const BrickPaint> canonicalPaint(std::shared_ptr<BrickPaint> paint) const;

  // Sets every voxel of the domain to the given uniform side and drops every channel: a new
  // start, not a tool (the mask does not hold it).
  std::vector<BrickChange> fill(bool inside);
  // Sets every voxel of the domain outside `keep` to +band (air) and publishes the changes: an
  // intersection's clearing. The mask holds as in scatter, a brick that stays stored keeps its
  // channels, and colour follows the surface (extendChannels) where a held voxel enters the band.
  std::vector<BrickChange> clearOutside(const Box& keep);

  // Re-publishes recorded changes: forward sets `after` (redo), backward sets `before` (undo).
  void publish(const std::vector<BrickChange>& changes, bool forward);

  // --- drift (BrickDrift) ----------------------------------------------------------------
  // Kept in tiles of their own, copied on write and shared by copies as the bricks are: a copy
  // (a reader's, a failed stroke's way back) has the drift of its field. A new volume, and so a
  // loaded one, has none: a saved field's voxels may carry up to the tools' limit (stroke.cpp,
  // kDriftLimit) not yet redistanced, forgotten once per load. A whole-volume redistance and
  // a global pass clear it (but where something is painted: the mask may hold voxels back), so
  // does fill. CSG and warps leave it: what they change they redistance, so it says more than
  // is left there (at worst a later tool redistances a brick sooner than it had to). Undo and
  // redo leave it too: after an undone application a brick that application redistanced reads
  // less than its restored voxels may carry, by at most the limit, once per undo.
  // b must be within brickDims().
  BrickDrift brickDrift(Int3 b) const;
  // The drift of every brick of `bricks` (a box of brick coordinates within brickDims()), x
  // fastest, into out.
  void brickDrifts(const Box& bricks, BrickDrift* out) const;
  // Sets each listed brick's drift (within brickDims(); an empty box clears it), copying the
  // tiles it touches (copies keep theirs).
  void setBrickDrift(std::span<const std::pair<Int3, BrickDrift>> drifts);
  // Forgets every brick's drift: the whole field was redistanced.
  void clearBrickDrift() { driftTiles_.clear(); }
  // Bricks with drift (for tests).
  std::size_t driftedBricks() const;

 private:
  static constexpr int kTileBricks = kTileSide * kTileSide * kTileSide;
  struct Tile {
    std::shared_ptr<const Brick> bricks[kTileBricks];
    std::bitset<kTileBricks> inside;
    int present = 0;
  };
  // The channels of a tile's bricks; a tile with none has no PaintTile.
  struct PaintTile {
    std::shared_ptr<const BrickPaint> paint[kTileBricks];
    int present = 0;
  };

  // Sets n slots: slotAt(i) gives the i-th one's brick and a pointer to its new BrickRef. Each
  // reference is copied once, into its tile (volume.cpp).
  template <class SlotAt>
  void setSlots(std::size_t n, SlotAt slotAt);
  // Whether writing src (over srcBox) into `here`, a part of brick b, changes it; old is the
  // brick's voxels, or null when it is uniformly `uniform`. Throws on NaN among the voxels read.
  bool brickChanges(Int3 b, const Box& here, const float* old, float uniform, const float* src,
                    const Box& srcBox) const;
  // diff() over the bricks of layers [bz0, bz1) of `bricks` (the bricks of r, the clipped region),
  // appending to out.
  void diffLayers(const Box& r, const Box& bricks, int bz0, int bz1, const float* src, const Box& srcBox,
                  std::vector<BrickChange>& out) const;
  // The old surface point (this volume's) nearest p along the 26 directions of the grid's
  // neighbours, within 32 vu; `otherwise` when none meets the band there. extendChannels's way
  // back for a voxel whose normal line misses the old surface.
  Vec3 nearestOldSurface(Vec3 p, Vec3 otherwise) const;
  std::size_t tileIndex(Int3 b) const;
  static int slotInTile(Int3 b);

  Int3 dims_;
  Int3 brickDims_;
  Int3 tileDims_;
  float band_;
  std::uint64_t revision_ = 0;
  std::size_t presentBricks_ = 0;
  // A null tile is uniform: every brick of it inside (tileInside_ = 1) or outside.
  std::vector<std::shared_ptr<const Tile>> tiles_;
  std::vector<std::uint8_t> tileInside_;
  // Empty until something is painted; then one per tile, null for a tile without channels.
  std::vector<std::shared_ptr<const PaintTile>> paintTiles_;
  std::uint32_t paintedBricks_ = 0;
  Rgb8 base_ = kClayColor;
  // BrickDrift in 12 bytes: its box relative to the brick's origin (hi[0] = 0: none).
  struct DriftSlot {
    float move = 0;
    std::uint8_t lo[3] = {}, hi[3] = {};
  };
  static BrickDrift driftOf(const DriftSlot& d, Int3 b);
  struct DriftTile {
    DriftSlot slots[kTileBricks];
    int present = 0;
  };
  // Empty until a tool leaves drift; then one per tile, null for a tile without any.
  std::vector<std::shared_ptr<const DriftTile>> driftTiles_;
};

template <class F>
void Volume::forEachPresentBrick(F&& fn) const {
  for (int bz = 0; bz < brickDims_.z; ++bz)
    for (int by = 0; by < brickDims_.y; ++by)
      for (int bx = 0; bx < brickDims_.x; ++bx) {
        const Int3 b{bx, by, bz};
        const Tile* t = tiles_[tileIndex(b)].get();
        if (!t) {
          bx = (bx / kTileSide + 1) * kTileSide - 1;  // skip the rest of this uniform tile's row
          continue;
        }
        if (const Brick* br = t->bricks[slotInTile(b)].get()) fn(b, *br);
      }
}

template <class F>
void Volume::forEachPaintedBrick(F&& fn) const {
  if (paintedBricks_ == 0) return;
  for (int bz = 0; bz < brickDims_.z; ++bz)
    for (int by = 0; by < brickDims_.y; ++by)
      for (int bx = 0; bx < brickDims_.x; ++bx) {
        const Int3 b{bx, by, bz};
        const PaintTile* t = paintTiles_[tileIndex(b)].get();
        if (!t) {
          bx = (bx / kTileSide + 1) * kTileSide - 1;
          continue;
        }
        if (const BrickPaint* p = t->paint[slotInTile(b)].get()) fn(b, *p);
      }
}

template <class F>
void Volume::forEachInsideBrick(F&& fn) const {
  for (int bz = 0; bz < brickDims_.z; ++bz)
    for (int by = 0; by < brickDims_.y; ++by)
      for (int bx = 0; bx < brickDims_.x; ++bx) {
        const Int3 b{bx, by, bz};
        const std::size_t ti = tileIndex(b);
        const Tile* t = tiles_[ti].get();
        if (t ? (!t->bricks[slotInTile(b)] && t->inside[slotInTile(b)]) : tileInside_[ti] != 0) fn(b);
      }
}

}  // namespace marzipan
