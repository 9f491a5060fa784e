// Compositing of a few pixels of a tile, for the incremental probe renders
// (incremental_probes.h). Not part of the public API.
//
// A candidate that changes or removes a few splats changes only the pixels where one of
// them may contribute: where a splat's falloff stays below the bound of
// render_internal::SkipPowerBelow it is skipped by the compositing loop and changes
// nothing (not the colour, not the transmittance, not where the loop stops). So the
// incremental renderer marks those pixels (MarkPixels, the old and the new splat) and
// composites only them (CompositePixels), with the loop of render_internal::RasterizeTile
// (the reference): the same operations in the same order, so the same values. 1×1
// textures (most adaptive ones) come with their activations computed once per splat
// (detail::ConstantTexel, which gives the same results).
#pragma once

#include <cstdint>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"

namespace atex::fit::internal {

inline constexpr int kTilePixels = detail::kTileSize * detail::kTileSize;

// Where the compositing loop of each pixel stopped (transmittance below
// detail::kMinTransmittance): the (depth, index) of the splat it stopped at, in the
// compositing order; kNeverStopped when it ran through the tile's list. A splat after
// that point in the order is never evaluated at that pixel, so changing or removing it
// changes nothing there (an occluded splat).
struct StopKey {
  float depth;
  uint32_t index;
};
inline constexpr StopKey kNeverStopped{__builtin_inff(), 0xFFFFFFFFu};
inline bool Before(float depth, uint32_t index, const StopKey& stop) {
  return depth < stop.depth || (depth == stop.depth && index <= stop.index);
}

// Pixels [x0, x1) × [y0, y1) of an image.
struct PixelBox {
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// What the compositing loop needs of a splat beyond its parameters: the skip bound of the
// reference loop (render_internal::SkipPowerBelow) and the pixels of the image where the
// splat can pass it (a conservative box, empty when it passes nowhere). Computed once per
// splat and probe.
struct SplatReach {
  float skip_below = 0;
  PixelBox box;
};
SplatReach ReachOf(const detail::CameraModel<float>& cam, const detail::SplatParams<float>& splat);

// Marks (mask[pixel in tile] = 1) the pixels of tile `t` where `splat`, at (depth, index)
// in the compositing order, may contribute: pixels where it passes the reference loop's
// skip test and where the loop did not stop before reaching it (`stops`, [height][width]).
// Returns whether it marked any.
bool MarkPixels(const detail::CameraModel<float>& cam, int t, const detail::SplatParams<float>& splat,
                const SplatReach& reach, float depth, uint32_t index, const StopKey* stops,
                uint8_t mask[kTilePixels]);

// The splats of one tile's list, in compositing order.
struct TileList {
  const detail::SplatParams<float>* splats;
  const SplatReach* reach;
  const float* depths;
  const uint32_t* indices;
  int count;
};

// Composites the marked pixels of tile `t` from `list` over `background`, into `color`
// ([height][width][3]) and `stops` ([height][width]); the image's other pixels are untouched.
// With `weights` ([list.count], not null), adds each splat's blending weight over the pixels
// in the reference's order (row-major), as render_internal::RasterizeTile sums them.
void CompositePixels(const detail::CameraModel<float>& cam, int t, const TileList& list,
                     const detail::Vec3<float>& background, const uint8_t mask[kTilePixels], float* color,
                     StopKey* stops, float* weights = nullptr);

}  // namespace atex::fit::internal
