// Coloured point clouds: the initialisation's external input (stage1.init_method=file)
// and the multi-view stereo output (atex/mvs.h).
//
// Readers (all treat their input as hostile: counts are checked against the bytes present
// before anything is allocated from them; errors name the file, the line or byte offset
// and the element; non-finite coordinates are refused):
//   PLY    ascii 1.0, binary_little_endian 1.0 or binary_big_endian 1.0; the `vertex`
//          element's x, y, z (any scalar type) and, when present, colour from red/green/blue
//          (integer types scaled by their maximum, float types taken as [0, 1]) or from the
//          3DGS SH DC terms f_dc_0..2 (colour = 0.5 + C0·f_dc, clamped to [0, 1]). Other
//          elements (faces, lists) are parsed and skipped. So an INRIA 3DGS PLY gives its
//          Gaussian centres with their base colours.
//   COLMAP points3D.txt  one point per line, `POINT3D_ID X Y Z R G B ERROR (IMAGE_ID
//          POINT2D_IDX)*`; lines starting with '#' and blank lines are skipped.
//   COLMAP points3D.bin  little-endian: uint64 point count, then per point uint64 id,
//          3 × double X Y Z, 3 × uint8 R G B, double error, uint64 track length and
//          track length × (uint32 image id, uint32 point2D index). Trailing bytes are refused.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "atex/status.h"

namespace atex {

struct PointCloud {
  std::vector<float> positions;  // [N][3] world units
  std::vector<float> colours;    // [N][3] RGB in [0, 1], or empty when the source has none
  size_t size() const { return positions.size() / 3; }
  bool has_colours() const { return !colours.empty(); }
};

// Safety limit of the readers: more points are refused with kLimitExceeded.
inline constexpr uint64_t kMaxPointCloudPoints = uint64_t{1} << 28;

// Parsers over bytes in memory; `what` names the input in errors.
StatusOr<PointCloud> ParsePlyPoints(const uint8_t* data, size_t size, const std::string& what);
StatusOr<PointCloud> ParseColmapPointsText(std::string_view text, const std::string& what);
StatusOr<PointCloud> ParseColmapPointsBinary(const uint8_t* data, size_t size, const std::string& what);

// Reads a file by its extension: .ply, .txt (COLMAP points3D.txt), .bin (COLMAP points3D.bin).
// kInvalidArgument for any other extension.
StatusOr<PointCloud> ReadPointCloud(const std::string& path);

// Writes a binary little-endian PLY with float x, y, z and, when the cloud has colours,
// uchar red, green, blue (rounded from [0, 1]); written to a temporary file and renamed.
Status WritePlyPoints(const std::string& path, const PointCloud& cloud);

}  // namespace atex
