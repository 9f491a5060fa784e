// The texture lever of the fitter: shrinking one texture axis at a time, least
// damage per texel first.
#pragma once

#include <array>
#include <cstdint>
#include <mutex>
#include <unordered_map>
#include <vector>

#include "container/fingerprint.h"

#include "atex/model.h"
#include "atex/status.h"

namespace atex::fit {

// Least-squares resampling of one corner-aligned bilinear texture to a smaller
// size: the new h'×w' grid whose bilinear field is closest (L2 over the plane
// [-1,1]², separably per axis) to the old field. The raw values are projected: the
// renderer interpolates raw texels and activates the result. Sides must be in
// {1, 2, 4} with new ≤ old.
void ShrinkTexture(const float* src /* [h][w][4] */, int height, int width, float* dst /* [h'][w'][4] */,
                   int new_height, int new_width);

// Mean squared difference of the activated texels (0.1·tanh, what the renderer adds)
// between a texture and the bilinear field of its shrunk version, at the old texel
// positions (the damage per unit of coverage).
double ShrinkResidual(const float* src /* [h][w][4] */, int height, int width, int new_height, int new_width);

// ShrinkResidual of halving a texture's width and of halving its height (0 for a side of 1).
struct HalvingResiduals {
  double width = 0, height = 0;
};
HalvingResiduals HalvingResidualsOf(const float* src /* [h][w][4] */, int height, int width);

// Remembers HalvingResidualsOf by the texture's content (a fingerprint of its texels and
// size): a fit applies the texture lever to hundreds of states that share most textures, and
// the residuals are most of a texture move's work. Holds at most about two million textures
// (tens of MB). Thread-safe; the values are those HalvingResidualsOf computes.
class TextureShrinkMemo {
 public:
  HalvingResiduals Residuals(const float* src /* [h][w][4] */, int height, int width);

 private:
  struct KeyHash {
    size_t operator()(const container::Fingerprint& f) const { return static_cast<size_t>(f.b); }
  };
  struct Shard {
    std::mutex mutex;
    std::unordered_map<container::Fingerprint, HalvingResiduals, KeyHash> residuals;
  };
  static constexpr size_t kShards = 64, kEntriesPerShard = 32768;
  std::array<Shard, kShards> shards_;
};

// Performs `count` shrink operations on `asset`'s texture pool, greedily: each
// operation halves one axis of one texture (whichever axis does less damage; on a
// tie the axis with the smaller peak scale), choosing the texture whose damage per
// removed texel (importance × ShrinkResidual / texels removed) is smallest; ties go
// to the lower training demand, then the lower index. Stops early when every
// texture is 1×1. Returns the number of operations done. `memo` (may be null) spares
// recomputing the residuals of textures seen before; the result is the same.
StatusOr<uint64_t> ShrinkTextures(Asset* asset, uint64_t count, TextureShrinkMemo* memo = nullptr);

// HalvingResidualsOf every texture of a pool, by index: what a fit state carries so that a
// texture move from it, or from a state derived from it, finds them without computing or
// looking them up (a Panoptic pool holds 360,000 textures).
using PoolResiduals = std::vector<HalvingResiduals>;

// ShrinkTextures without changing `asset`: its texture pool shrunk, written to `out` (the
// returned count of operations done; `asset`'s statistics order them). For a caller that
// copies the rest of the asset: the input pool need not be copied first. `known` (may be
// null) holds the residuals of `asset`'s pool, one per texture; `out_residuals` (may be null)
// gets those of `out` (its halvings' are computed on the way). The pool is the same either way.
// kInvalidArgument when the asset has no texture pool or `known` does not match it.
StatusOr<uint64_t> ShrinkTexturePool(const Asset& asset, uint64_t count, TextureShrinkMemo* memo, TexturePool* out,
                                     const PoolResiduals* known = nullptr, PoolResiduals* out_residuals = nullptr);

// What ShrinkTextures does to the metadata after `done` operations: a uniform pool that
// lost texels is adaptive.
void MarkTexturesShrunk(Asset* asset, uint64_t done);

// Halves the longer axis of every texture larger than 1×1 at once (the height when
// both sides are equal), by the same least-squares projection: capacity scaled down
// without moving it between Gaussians, so a uniform pool stays uniform (and keeps its
// texture_mode) and an adaptive pool keeps its shape of allocation.
// kInvalidArgument when every texture is already 1×1 or the asset has none.
Status HalveAllTextures(Asset* asset);

// Texels that ShrinkTextures could still remove (all textures down to 1×1).
uint64_t ShrinkableTexels(const TexturePool& pool);

}  // namespace atex::fit
