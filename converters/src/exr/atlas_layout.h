// Where each Gaussian's texture block goes in a texel atlas, and the JSON
// sidecar that records it. No OpenEXR here. Internal to converters/src/exr.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "atex/converters/exr_atlas.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex::converters::exr {

struct AtlasLayout {
  int width = 0;
  int height = 0;
  std::vector<uint32_t> x;  // [N] left column of Gaussian i's block
  std::vector<uint32_t> y;  // [N] top row
};

inline constexpr int kMaxAtlasSide = 1 << 20;  // EXR coordinates are int32; keep far below

// A width that makes an atlas of `texels` roughly square: a multiple of 4, >= 4.
int AutoAtlasWidth(uint64_t texels);

// Shelf packing in Gaussian order: a block of height h goes on the current shelf
// of height h, a new shelf starts when the row is full. Requires width >= 4.
StatusOr<AtlasLayout> PackShelves(const std::vector<uint8_t>& heights, const std::vector<uint8_t>& widths, int width);

// The sidecar text for a layout and the pool's dims/axes.
std::string SidecarJson(const AtlasLayout& layout, const TexturePool& pool);

// Parses a sidecar: fills dims/axes of `pool` (offsets rebuilt, texels empty) and
// the layout. Validates counts, dims, axes and that every block is inside the atlas.
Status ParseSidecar(std::string_view json, const ExrAtlasReadOptions& options, AtlasLayout* layout,
                    TexturePool* pool);

}  // namespace atex::converters::exr
