// RGBA half-float EXR images in memory through OpenEXR. Internal to converters/src/exr.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/status.h"

namespace atex::converters::exr {

struct HalfImage {
  int width = 0;
  int height = 0;
  std::vector<uint16_t> rgba;  // [height][width][4] IEEE half bit patterns
  int atlas_version = 0;       // header attribute "atexAtlasVersion" (0 if absent)
  int64_t atlas_count = -1;    // header attribute "atexAtlasCount" (-1 if absent)
};

// Encodes an RGBA half image with ZIP compression and the atlas attributes.
StatusOr<std::vector<uint8_t>> EncodeHalfImage(const HalfImage& image);

// Decodes an EXR with R, G, B and A channels (any pixel type, converted to half).
// Refuses images above max_pixels before allocating; OpenEXR exceptions become kCorrupt.
StatusOr<HalfImage> DecodeHalfImage(const uint8_t* data, size_t size, uint64_t max_pixels);

// IEEE half <-> float (through Imath's half: round to nearest even).
uint16_t FloatToHalfBits(float value);
float HalfBitsToFloat(uint16_t bits);

}  // namespace atex::converters::exr
