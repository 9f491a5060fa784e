// COLMAP sparse model: cameras and images, text and binary (atex/dataset_formats.h).
// points3D has its own reader (point_cloud_colmap.cc).
#include <charconv>
#include <cmath>
#include <cstring>

#include "atex/dataset_formats.h"
#include "atex/image.h"
#include "data/byte_reader.h"
#include "data/text_tokens.h"

namespace atex {
namespace {

// The smallest records of the binary files, for checking announced counts against the bytes present.
constexpr size_t kCameraFixedBytes = 4 + 4 + 8 + 8;
constexpr size_t kImageFixedBytes = 4 + 7 * 8 + 4 + 1 + 8;
constexpr size_t kPoint2dBytes = 8 + 8 + 8;
constexpr uint64_t kMaxRecords = uint64_t{1} << 24;  // cameras or images in one model

// Lines of a text file with their 1-based numbers.
class LineReader {
 public:
  explicit LineReader(std::string_view text) : text_(text) {}
  bool Next(std::string_view* line) {
    if (pos_ >= text_.size()) return false;
    size_t end = text_.find('\n', pos_);
    if (end == std::string_view::npos) end = text_.size();
    *line = text_.substr(pos_, end - pos_);
    pos_ = end + 1;
    ++number_;
    return true;
  }
  uint64_t number() const { return number_; }

 private:
  std::string_view text_;
  size_t pos_ = 0;
  uint64_t number_ = 0;
};

Status CheckSize(uint64_t width, uint64_t height, const std::string& at) {
  if (width < 1 || height < 1 || width > uint64_t(kMaxImageSide) || height > uint64_t(kMaxImageSide)) {
    return MakeError(StatusCode::kCorrupt, at, ": image size ", width, "x", height, " is outside 1..", kMaxImageSide);
  }
  return Status::Ok();
}

}  // namespace

bool ColmapModelInfo(int model_id, std::string* name, int* param_count) {
  // COLMAP's src/colmap/sensor/models.h, in id order.
  static const struct {
    const char* name;
    int params;
  } kModels[] = {{"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4},         {"SIMPLE_RADIAL", 4},
                 {"RADIAL", 5},         {"OPENCV", 8},          {"OPENCV_FISHEYE", 8},
                 {"FULL_OPENCV", 12},   {"FOV", 5},             {"SIMPLE_RADIAL_FISHEYE", 4},
                 {"RADIAL_FISHEYE", 5}, {"THIN_PRISM_FISHEYE", 12}, {"RAD_TAN_THIN_PRISM_FISHEYE", 16}};
  if (model_id < 0 || model_id >= int(std::size(kModels))) return false;
  *name = kModels[model_id].name;
  *param_count = kModels[model_id].params;
  return true;
}

StatusOr<std::vector<ColmapCamera>> ParseColmapCamerasText(std::string_view text, const std::string& what) {
  std::vector<ColmapCamera> cameras;
  LineReader lines(text);
  std::string_view line;
  while (lines.Next(&line)) {
    const auto t = SplitTokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string at = StrCat(what, ": COLMAP cameras line ", lines.number());
    if (t.size() < 4) return MakeError(StatusCode::kCorrupt, at, ": expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...");
    ColmapCamera camera;
    if (!ParseNumber(t[0], &camera.id)) return MakeError(StatusCode::kCorrupt, at, ": bad CAMERA_ID");
    camera.model = std::string(t[1]);
    int count = -1;
    std::string name;
    for (int id = 0; ColmapModelInfo(id, &name, &count); ++id) {
      if (name == camera.model) {
        camera.model_id = id;
        break;
      }
    }
    if (camera.model_id < 0) {
      return MakeError(StatusCode::kUnsupported, at, ": unknown camera model '", camera.model, "'");
    }
    if (!ParseNumber(t[2], &camera.width) || !ParseNumber(t[3], &camera.height)) {
      return MakeError(StatusCode::kCorrupt, at, ": bad WIDTH or HEIGHT");
    }
    ATEX_RETURN_IF_ERROR(CheckSize(camera.width, camera.height, at));
    if (t.size() != size_t(4 + count)) {
      return MakeError(StatusCode::kCorrupt, at, ": model ", camera.model, " has ", count, " parameters, the line ",
                       t.size() - 4);
    }
    for (int k = 0; k < count; ++k) {
      double v;
      if (!ParseNumber(t[4 + k], &v)) {
        return MakeError(StatusCode::kCorrupt, at, ": parameter ", k, " is not a finite number");
      }
      camera.params.push_back(v);
    }
    if (cameras.size() >= kMaxRecords)
      return MakeError(StatusCode::kLimitExceeded, what, ": more than ", kMaxRecords, " cameras");
    cameras.push_back(std::move(camera));
  }
  return cameras;
}

StatusOr<std::vector<ColmapCamera>> ParseColmapCamerasBinary(const uint8_t* data, size_t size,
                                                             const std::string& what) {
  ByteReader in(data, size);
  uint64_t count;
  if (!in.U64(count)) return MakeError(StatusCode::kTruncated, what, ": COLMAP cameras.bin shorter than its count");
  if (count > kMaxRecords || count > in.remaining() / kCameraFixedBytes) {
    return MakeError(count > kMaxRecords ? StatusCode::kLimitExceeded : StatusCode::kTruncated, what,
                     ": COLMAP cameras.bin announces ", count, " cameras but ", in.remaining(), " bytes follow");
  }
  std::vector<ColmapCamera> cameras;
  cameras.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    const size_t start = in.position();
    const std::string at = StrCat(what, ": COLMAP camera ", i, " at byte ", start);
    if (in.remaining() < kCameraFixedBytes) return MakeError(StatusCode::kTruncated, at, " is cut off");
    ColmapCamera camera;
    uint32_t model = 0;
    in.U32(camera.id);
    in.U32(model);
    in.U64(camera.width);
    in.U64(camera.height);
    camera.model_id = static_cast<int32_t>(model);
    int params = 0;
    if (!ColmapModelInfo(camera.model_id, &camera.model, &params)) {
      return MakeError(StatusCode::kUnsupported, at, ": unknown camera model id ", camera.model_id);
    }
    ATEX_RETURN_IF_ERROR(CheckSize(camera.width, camera.height, at));
    if (in.remaining() < size_t(params) * 8) {
      return MakeError(StatusCode::kTruncated, at, ": ", camera.model, " needs ", params, " parameters, ",
                       in.remaining(), " bytes follow");
    }
    for (int k = 0; k < params; ++k) {
      const double v = LoadLEDouble(in.current());
      if (!std::isfinite(v)) return MakeError(StatusCode::kCorrupt, at, ": parameter ", k, " is not finite");
      camera.params.push_back(v);
      in.Skip(8);
    }
    cameras.push_back(std::move(camera));
  }
  if (in.remaining() != 0) {
    return MakeError(StatusCode::kCorrupt, what, ": COLMAP cameras.bin has ", in.remaining(),
                     " bytes after its last camera (byte ", in.position(), ")");
  }
  return cameras;
}

StatusOr<std::vector<ColmapImage>> ParseColmapImagesText(std::string_view text, const std::string& what) {
  std::vector<ColmapImage> images;
  LineReader lines(text);
  std::string_view line;
  while (lines.Next(&line)) {
    const auto t = SplitTokens(line);
    if (t.empty() || t[0][0] == '#') continue;
    const std::string at = StrCat(what, ": COLMAP images line ", lines.number());
    if (t.size() != 10) {
      return MakeError(StatusCode::kCorrupt, at, ": expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME (",
                       t.size(), " fields; names with spaces are not supported)");
    }
    ColmapImage image;
    if (!ParseNumber(t[0], &image.id)) return MakeError(StatusCode::kCorrupt, at, ": bad IMAGE_ID");
    for (int k = 0; k < 4; ++k) {
      if (!ParseNumber(t[1 + k], &image.qvec[k])) return MakeError(StatusCode::kCorrupt, at, ": bad quaternion");
    }
    for (int k = 0; k < 3; ++k) {
      if (!ParseNumber(t[5 + k], &image.tvec[k])) return MakeError(StatusCode::kCorrupt, at, ": bad translation");
    }
    if (!ParseNumber(t[8], &image.camera_id)) return MakeError(StatusCode::kCorrupt, at, ": bad CAMERA_ID");
    image.name = std::string(t[9]);
    // The next line holds the image's 2D points (possibly empty): read and checked, not kept.
    if (lines.Next(&line)) {
      const auto p = SplitTokens(line);
      if (p.size() % 3 != 0) {
        return MakeError(StatusCode::kCorrupt, what, ": COLMAP images line ", lines.number(),
                         ": 2D points are not (X Y POINT3D_ID) triples");
      }
    }
    if (images.size() >= kMaxRecords)
      return MakeError(StatusCode::kLimitExceeded, what, ": more than ", kMaxRecords, " images");
    images.push_back(std::move(image));
  }
  return images;
}

StatusOr<std::vector<ColmapImage>> ParseColmapImagesBinary(const uint8_t* data, size_t size,
                                                           const std::string& what) {
  ByteReader in(data, size);
  uint64_t count;
  if (!in.U64(count)) return MakeError(StatusCode::kTruncated, what, ": COLMAP images.bin shorter than its count");
  if (count > kMaxRecords || count > in.remaining() / kImageFixedBytes) {
    return MakeError(count > kMaxRecords ? StatusCode::kLimitExceeded : StatusCode::kTruncated, what,
                     ": COLMAP images.bin announces ", count, " images but ", in.remaining(), " bytes follow");
  }
  std::vector<ColmapImage> images;
  images.reserve(count);
  for (uint64_t i = 0; i < count; ++i) {
    const size_t start = in.position();
    const std::string at = StrCat(what, ": COLMAP image ", i, " at byte ", start);
    if (in.remaining() < kImageFixedBytes) return MakeError(StatusCode::kTruncated, at, " is cut off");
    ColmapImage image;
    in.U32(image.id);
    for (int k = 0; k < 7; ++k) {
      const double v = LoadLEDouble(in.current());
      in.Skip(8);
      if (!std::isfinite(v)) return MakeError(StatusCode::kCorrupt, at, ": pose value ", k, " is not finite");
      (k < 4 ? image.qvec[k] : image.tvec[k - 4]) = v;
    }
    in.U32(image.camera_id);
    const void* nul = std::memchr(in.current(), 0, in.remaining());
    if (nul == nullptr) return MakeError(StatusCode::kTruncated, at, ": the name has no NUL terminator");
    const size_t length = static_cast<const uint8_t*>(nul) - in.current();
    if (length == 0) return MakeError(StatusCode::kCorrupt, at, ": empty image name");
    image.name.assign(reinterpret_cast<const char*>(in.current()), length);
    in.Skip(length + 1);
    uint64_t points;
    if (!in.U64(points)) return MakeError(StatusCode::kTruncated, at, ": cut off before its 2D point count");
    if (points > in.remaining() / kPoint2dBytes) {
      return MakeError(StatusCode::kTruncated, at, " announces ", points, " 2D points but ", in.remaining(),
                       " bytes follow");
    }
    in.Skip(points * kPoint2dBytes);
    images.push_back(std::move(image));
  }
  if (in.remaining() != 0) {
    return MakeError(StatusCode::kCorrupt, what, ": COLMAP images.bin has ", in.remaining(),
                     " bytes after its last image (byte ", in.position(), ")");
  }
  return images;
}

StatusOr<std::array<double, 4>> ColmapPinholeIntrinsics(const ColmapCamera& camera, const std::string& what) {
  const std::vector<double>& p = camera.params;
  const std::string at = StrCat(what, ": camera ", camera.id, " (", camera.model, ")");
  std::array<double, 4> k{};
  size_t first_distortion = 0;
  if (camera.model == "SIMPLE_PINHOLE" || camera.model == "SIMPLE_RADIAL" || camera.model == "RADIAL") {
    if (p.size() < 3) return MakeError(StatusCode::kCorrupt, at, ": too few parameters");
    k = {p[0], p[0], p[1], p[2]};
    first_distortion = 3;
  } else if (camera.model == "PINHOLE" || camera.model == "OPENCV" || camera.model == "FULL_OPENCV") {
    if (p.size() < 4) return MakeError(StatusCode::kCorrupt, at, ": too few parameters");
    k = {p[0], p[1], p[2], p[3]};
    first_distortion = 4;
  } else {
    return MakeError(StatusCode::kUnsupported, at,
                     ": camera model not supported (PINHOLE, SIMPLE_PINHOLE, or SIMPLE_RADIAL / RADIAL / OPENCV / "
                     "FULL_OPENCV with zero distortion; undistort the images first, e.g. colmap image_undistorter)");
  }
  for (size_t i = first_distortion; i < p.size(); ++i) {
    if (p[i] != 0.0) {
      return MakeError(StatusCode::kUnsupported, at, ": distortion parameter ", i - first_distortion, " is ", p[i],
                       "; frames are not undistorted here (undistort them first, e.g. colmap image_undistorter)");
    }
  }
  if (!(k[0] > 0 && k[1] > 0)) return MakeError(StatusCode::kCorrupt, at, ": focal length ", k[0], ", ", k[1]);
  return k;
}

StatusOr<std::array<double, 16>> ColmapWorldToCamera(const ColmapImage& image, const std::string& what) {
  const auto& q = image.qvec;
  const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  bool finite = std::isfinite(norm);
  for (double t : image.tvec) finite = finite && std::isfinite(t);
  if (!finite || norm < 1e-6) {
    return MakeError(StatusCode::kCorrupt, what, ": image ", image.id, " ('", image.name,
                     "'): pose is not finite or its quaternion is zero");
  }
  const double w = q[0] / norm, x = q[1] / norm, y = q[2] / norm, z = q[3] / norm;
  const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                       2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
  std::array<double, 16> m{};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) m[i * 4 + j] = r[i * 3 + j];
    m[i * 4 + 3] = image.tvec[i];
  }
  m[15] = 1;
  return m;
}

}  // namespace atex
