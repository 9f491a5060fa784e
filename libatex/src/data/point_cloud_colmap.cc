// COLMAP sparse points (points3D.txt and points3D.bin, the layouts of COLMAP's
// documentation, restated in atex/point_cloud.h) and ReadPointCloud's dispatch.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "atex/file_io.h"
#include "atex/point_cloud.h"
#include "data/byte_reader.h"
#include "data/text_tokens.h"

namespace atex {
namespace {

constexpr size_t kColmapFixedBytes = 8 + 3 * 8 + 3 + 8 + 8;  // id, xyz, rgb, error, track length

}  // namespace

StatusOr<PointCloud> ParseColmapPointsText(std::string_view text, const std::string& what) {
  PointCloud cloud;
  size_t pos = 0;
  uint64_t line_number = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_number;
    const std::vector<std::string_view> t = SplitTokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    auto bad = [&](const std::string& why) {
      return MakeError(StatusCode::kCorrupt, what, ": COLMAP points3D line ", line_number, ": ", why);
    };
    if (t.size() < 8) return bad("expected POINT3D_ID X Y Z R G B ERROR [IMAGE_ID POINT2D_IDX]...");
    if ((t.size() - 8) % 2 != 0) return bad("the track has an odd number of values");
    uint64_t id;
    if (!ParseNumber(t[0], &id)) return bad("bad POINT3D_ID");
    if (cloud.size() >= kMaxPointCloudPoints) {
      return MakeError(StatusCode::kLimitExceeded, what, ": more than ", kMaxPointCloudPoints, " points");
    }
    for (int a = 0; a < 3; ++a) {
      double x;
      if (!ParseNumber(t[1 + a], &x) || !std::isfinite(x) || std::abs(x) > 3.0e38) {
        return bad("coordinate is not a finite number");
      }
      cloud.positions.push_back(float(x));
    }
    for (int a = 0; a < 3; ++a) {
      int c;
      if (!ParseNumber(t[4 + a], &c) || c < 0 || c > 255) return bad("colour is not an integer in 0..255");
      cloud.colours.push_back(float(c) / 255.0f);
    }
    double error;
    if (!ParseNumber(t[7], &error)) return bad("bad ERROR");
    for (size_t k = 8; k < t.size(); ++k) {
      int64_t index;
      if (!ParseNumber(t[k], &index)) return bad("bad track entry");
    }
  }
  return cloud;
}

StatusOr<PointCloud> ParseColmapPointsBinary(const uint8_t* data, size_t size, const std::string& what) {
  ByteReader in(data, size);
  uint64_t count;
  if (!in.U64(count)) return MakeError(StatusCode::kTruncated, what, ": COLMAP points3D.bin shorter than its count");
  if (count > kMaxPointCloudPoints) {
    return MakeError(StatusCode::kLimitExceeded, what, ": COLMAP points3D.bin announces ", count, " points (limit ",
                     kMaxPointCloudPoints, ")");
  }
  if (count > in.remaining() / kColmapFixedBytes) {
    return MakeError(StatusCode::kTruncated, what, ": COLMAP points3D.bin announces ", count, " points but only ",
                     in.remaining(), " bytes follow (", kColmapFixedBytes, " at least per point)");
  }
  PointCloud cloud;
  cloud.positions.reserve(count * 3);
  cloud.colours.reserve(count * 3);
  for (uint64_t i = 0; i < count; ++i) {
    const size_t start = in.position();
    if (in.remaining() < kColmapFixedBytes) {
      return MakeError(StatusCode::kTruncated, what, ": COLMAP point ", i, " at byte ", start, " is cut off");
    }
    const uint8_t* p = in.current();
    for (int a = 0; a < 3; ++a) {
      const double x = LoadLEDouble(p + 8 + 8 * a);
      if (!std::isfinite(x) || std::abs(x) > 3.0e38) {
        return MakeError(StatusCode::kOutOfRange, what, ": COLMAP point ", i, " at byte ", start,
                         " has a non-finite coordinate");
      }
      cloud.positions.push_back(float(x));
    }
    for (int a = 0; a < 3; ++a) cloud.colours.push_back(float(p[32 + a]) / 255.0f);
    const uint64_t track = LoadLE64(p + 43);
    in.Skip(kColmapFixedBytes);
    if (track > in.remaining() / 8) {
      return MakeError(StatusCode::kTruncated, what, ": COLMAP point ", i, " at byte ", start, " announces a track of ",
                       track, " entries but only ", in.remaining(), " bytes follow");
    }
    in.Skip(track * 8);
  }
  if (in.remaining() != 0) {
    return MakeError(StatusCode::kCorrupt, what, ": COLMAP points3D.bin has ", in.remaining(),
                     " bytes after its last point (byte ", in.position(), ")");
  }
  return cloud;
}

StatusOr<PointCloud> ReadPointCloud(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".ply" && ext != ".txt" && ext != ".bin") {
    return MakeError(StatusCode::kInvalidArgument, path,
                     ": unknown point cloud extension (.ply, or COLMAP points3D .txt / .bin)");
  }
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  if (ext == ".ply") return ParsePlyPoints(bytes.data(), bytes.size(), path);
  if (ext == ".txt") {
    return ParseColmapPointsText(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()), path);
  }
  return ParseColmapPointsBinary(bytes.data(), bytes.size(), path);
}

}  // namespace atex
