// The quantised attribute arrays of an SPZ file, independent of how the file
// compresses them (gzip single stream in v1-3, zstd streams in v4).
// Internal to converters/src/spz.
#pragma once

#include <cstdint>
#include <vector>

#include "atex/converters/spz.h"
#include "atex/model.h"
#include "atex/status.h"
#include "spz/spz_axes.h"

namespace atex::converters::spz {

inline constexpr uint32_t kMagic = 0x5053474e;  // "NGSP" read as a little-endian u32
inline constexpr uint8_t kFlagAntialiased = 0x1;
inline constexpr uint8_t kFlagHasExtensions = 0x2;
inline constexpr int kMaxStoredShDegree = 4;
inline constexpr int kMaxFractionalBits = 23;

// Coefficients per channel beyond DC stored for an SPZ degree (0, 3, 8, 15, 24).
inline int StoredShDim(int degree) { return (degree + 1) * (degree + 1) - 1; }

struct PackedSpz {
  int version = 4;
  uint32_t num_points = 0;
  int sh_degree = 0;  // as stored, 0..4
  int fractional_bits = 12;
  uint8_t flags = 0;
  std::vector<uint8_t> positions;  // [N][3][3] 24-bit LE fixed point ([N][3][2] halves in v1)
  std::vector<uint8_t> alphas;     // [N]
  std::vector<uint8_t> colors;     // [N][3]
  std::vector<uint8_t> scales;     // [N][3]
  std::vector<uint8_t> rotations;  // [N][4] smallest-three (v3+) or [N][3] first-three (v1, v2)
  std::vector<uint8_t> sh;         // [N][StoredShDim][3], channel innermost

  bool uses_half_positions() const { return version == 1; }
  bool uses_smallest_three() const { return version >= 3; }
  size_t position_bytes() const { return uses_half_positions() ? 6 : 9; }
  size_t rotation_bytes() const { return uses_smallest_three() ? 4 : 3; }
  size_t sh_bytes() const { return static_cast<size_t>(StoredShDim(sh_degree)) * 3; }
};

// Quantises `g` (converted to the file's axes by `to_file`).
StatusOr<PackedSpz> PackGaussians(const Gaussians& g, const SpzWriteOptions& options, const AxisFlip& to_file);

// Dequantises (converting by `from_file`); SH degree 4 is cut to 3.
// Precondition: the arrays have the sizes the header implies.
Gaussians UnpackGaussians(const PackedSpz& packed, const AxisFlip& from_file);

}  // namespace atex::converters::spz
