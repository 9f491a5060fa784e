// Nerfstudio / instant-ngp transforms.json (atex/dataset_formats.h).
#include <algorithm>
#include <cmath>

#include <nlohmann/json.hpp>

#include "atex/dataset_formats.h"
#include "atex/image.h"

namespace atex {
namespace {

using nlohmann::json;

constexpr size_t kMaxFrames = 10'000'000;

// Reads optional finite number `key` of object `o`; kCorrupt naming `at`.key otherwise.
Status OptionalNumber(const json& o, const char* key, const std::string& at, std::optional<double>* out) {
  if (!o.contains(key)) return Status::Ok();
  const json& v = o[key];
  if (!v.is_number() || !std::isfinite(v.get<double>())) {
    return MakeError(StatusCode::kCorrupt, at, key, " is not a finite number (", v.dump().substr(0, 40), ")");
  }
  *out = v.get<double>();
  return Status::Ok();
}

// Intrinsics keys shared by the file and each frame; a frame's keys override the file's.
struct Intrinsics {
  std::optional<double> fl_x, fl_y, cx, cy, w, h, angle_x, angle_y;
  std::string camera_model;
};

Status ReadIntrinsics(const json& o, const std::string& at, Intrinsics* k) {
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "fl_x", at, &k->fl_x));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "fl_y", at, &k->fl_y));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "cx", at, &k->cx));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "cy", at, &k->cy));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "w", at, &k->w));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "h", at, &k->h));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "camera_angle_x", at, &k->angle_x));
  ATEX_RETURN_IF_ERROR(OptionalNumber(o, "camera_angle_y", at, &k->angle_y));
  for (const char* key : {"k1", "k2", "k3", "k4", "p1", "p2"}) {
    std::optional<double> d;
    ATEX_RETURN_IF_ERROR(OptionalNumber(o, key, at, &d));
    if (d && *d != 0.0) {
      return MakeError(StatusCode::kUnsupported, at, key, " = ", *d,
                       ": distorted frames are not supported (undistort them first, e.g. ns-process-data or colmap "
                       "image_undistorter, and set the coefficients to 0)");
    }
  }
  if (o.contains("camera_model")) {
    if (!o["camera_model"].is_string()) return MakeError(StatusCode::kCorrupt, at, "camera_model is not a string");
    k->camera_model = o["camera_model"].get<std::string>();
    static const char* kPinhole[] = {"PINHOLE", "SIMPLE_PINHOLE", "OPENCV", "SIMPLE_RADIAL", "RADIAL"};
    if (std::find(std::begin(kPinhole), std::end(kPinhole), k->camera_model) == std::end(kPinhole)) {
      return MakeError(StatusCode::kUnsupported, at, "camera_model '", k->camera_model,
                       "' is not supported (pinhole models only: PINHOLE, SIMPLE_PINHOLE, or OPENCV / "
                       "SIMPLE_RADIAL / RADIAL with zero distortion)");
    }
  }
  return Status::Ok();
}

Status ReadMatrix(const json& m, int rows, const std::string& at, double* out) {
  if (!m.is_array() || (m.size() != size_t(rows) && !(rows == 4 && m.size() == 3))) {
    return MakeError(StatusCode::kCorrupt, at, " is not a ", rows, "x4 array");
  }
  for (size_t r = 0; r < m.size(); ++r) {
    if (!m[r].is_array() || m[r].size() != 4) {
      return MakeError(StatusCode::kCorrupt, at, "[", r, "] is not 4 numbers");
    }
    for (int c = 0; c < 4; ++c) {
      if (!m[r][c].is_number() || !std::isfinite(m[r][c].get<double>())) {
        return MakeError(StatusCode::kCorrupt, at, "[", r, "][", c, "] is not a finite number");
      }
      out[r * 4 + c] = m[r][c].get<double>();
    }
  }
  if (m.size() == 3) {  // a 3x4 [R | t]: the last row is implied
    out[12] = out[13] = out[14] = 0;
    out[15] = 1;
  }
  return Status::Ok();
}

Status ReadStringList(const json& doc, const char* key, const std::string& what, std::vector<std::string>* out) {
  if (!doc.contains(key)) return Status::Ok();
  const json& list = doc[key];
  if (!list.is_array()) return MakeError(StatusCode::kCorrupt, what, ": ", key, " is not an array");
  for (size_t i = 0; i < list.size(); ++i) {
    if (!list[i].is_string()) return MakeError(StatusCode::kCorrupt, what, ": ", key, "[", i, "] is not a string");
    out->push_back(list[i].get<std::string>());
  }
  return Status::Ok();
}

Status CheckSize(const std::optional<double>& v, const std::string& at, const char* key, int* out) {
  if (!v) return Status::Ok();
  if (!(*v >= 1 && *v <= kMaxImageSide) || *v != std::floor(*v)) {
    return MakeError(StatusCode::kCorrupt, at, key, " = ", *v, " is not an integer in 1..", kMaxImageSide);
  }
  *out = static_cast<int>(*v);
  return Status::Ok();
}

StatusOr<TransformsFrame> ReadFrame(const json& f, size_t i, const Intrinsics& global, const std::string& what) {
  const std::string at = StrCat(what, ": frames[", i, "].");
  if (!f.is_object()) return MakeError(StatusCode::kCorrupt, what, ": frames[", i, "] is not an object");
  TransformsFrame frame;
  frame.index = i;
  if (!f.contains("file_path") || !f["file_path"].is_string() || f["file_path"].get<std::string>().empty()) {
    return MakeError(StatusCode::kCorrupt, at, "file_path is missing or not a non-empty string");
  }
  frame.file_path = f["file_path"].get<std::string>();
  if (f.contains("mask_path")) {
    if (!f["mask_path"].is_string()) return MakeError(StatusCode::kCorrupt, at, "mask_path is not a string");
    frame.mask_path = f["mask_path"].get<std::string>();
  }
  if (!f.contains("transform_matrix")) return MakeError(StatusCode::kCorrupt, at, "transform_matrix is missing");
  ATEX_RETURN_IF_ERROR(ReadMatrix(f["transform_matrix"], 4, at + "transform_matrix", frame.camera_to_world.data()));
  const auto& m = frame.camera_to_world;
  if (m[12] != 0 || m[13] != 0 || m[14] != 0 || m[15] != 1) {
    return MakeError(StatusCode::kCorrupt, at, "transform_matrix's last row is not (0, 0, 0, 1)");
  }
  ATEX_RETURN_IF_ERROR(OptionalNumber(f, "time", at, &frame.time));
  if (f.contains("timestep")) {
    const json& t = f["timestep"];
    if (!t.is_number_integer() || t.get<int64_t>() < 0 || t.get<int64_t>() > (int64_t{1} << 30)) {
      return MakeError(StatusCode::kCorrupt, at, "timestep is not an integer in 0..2^30");
    }
    frame.timestep = t.get<int64_t>();
  }
  if (f.contains("camera_id")) {
    const json& c = f["camera_id"];
    if (!c.is_number_integer() || c.get<int64_t>() < 0 || c.get<int64_t>() > (int64_t{1} << 30)) {
      return MakeError(StatusCode::kCorrupt, at, "camera_id is not an integer in 0..2^30");
    }
    frame.camera_id = static_cast<int>(c.get<int64_t>());
  }
  Intrinsics k = global;
  Intrinsics own;
  ATEX_RETURN_IF_ERROR(ReadIntrinsics(f, at, &own));
  for (auto [mine, theirs] : {std::pair{&own.fl_x, &k.fl_x}, {&own.fl_y, &k.fl_y}, {&own.cx, &k.cx},
                              {&own.cy, &k.cy}, {&own.w, &k.w}, {&own.h, &k.h}, {&own.angle_x, &k.angle_x},
                              {&own.angle_y, &k.angle_y}}) {
    if (*mine) *theirs = *mine;
  }
  ATEX_RETURN_IF_ERROR(CheckSize(k.w, at, "w", &frame.width));
  ATEX_RETURN_IF_ERROR(CheckSize(k.h, at, "h", &frame.height));
  for (auto [v, key] : {std::pair{k.fl_x, "fl_x"}, {k.fl_y, "fl_y"}}) {
    if (v && !(*v > 0)) return MakeError(StatusCode::kCorrupt, at, key, " = ", *v, " is not positive");
  }
  for (auto [v, key] : {std::pair{k.angle_x, "camera_angle_x"}, {k.angle_y, "camera_angle_y"}}) {
    if (v && !(*v > 0 && *v < M_PI)) return MakeError(StatusCode::kCorrupt, at, key, " = ", *v, " is not in (0, pi)");
  }
  if (!k.fl_x && !k.angle_x) {
    return MakeError(StatusCode::kCorrupt, at, "no focal length (fl_x or camera_angle_x, in the frame or the file)");
  }
  frame.fx = k.fl_x.value_or(0);
  frame.fy = k.fl_y.value_or(0);
  frame.angle_x = k.angle_x.value_or(0);
  frame.angle_y = k.angle_y.value_or(0);
  frame.cx = k.cx;
  frame.cy = k.cy;
  return frame;
}

}  // namespace

StatusOr<TransformsFile> ParseTransformsJson(std::string_view text, const std::string& what) {
  json doc;
  try {
    doc = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    return MakeError(StatusCode::kCorrupt, what, ": invalid JSON at byte ", e.byte, ": ", e.what());
  } catch (const json::exception& e) {  // e.g. out_of_range for a number beyond double's range
    return MakeError(StatusCode::kCorrupt, what, ": invalid JSON: ", e.what());
  }
  if (!doc.is_object()) return MakeError(StatusCode::kCorrupt, what, ": not a JSON object");
  if (!doc.contains("frames") || !doc["frames"].is_array()) {
    return MakeError(StatusCode::kCorrupt, what, ": needs 'frames' (an array)");
  }
  const json& frames = doc["frames"];
  if (frames.size() > kMaxFrames) {
    return MakeError(StatusCode::kLimitExceeded, what, ": ", frames.size(), " frames (limit ", kMaxFrames, ")");
  }
  Intrinsics global;
  ATEX_RETURN_IF_ERROR(ReadIntrinsics(doc, what + ": ", &global));
  if (doc.contains("applied_transform")) {
    double m[16];
    ATEX_RETURN_IF_ERROR(ReadMatrix(doc["applied_transform"], 3, what + ": applied_transform", m));
  }
  TransformsFile file;
  if (doc.contains("ply_file_path")) {
    if (!doc["ply_file_path"].is_string())
      return MakeError(StatusCode::kCorrupt, what, ": ply_file_path is not a string");
    file.ply_file_path = doc["ply_file_path"].get<std::string>();
  }
  ATEX_RETURN_IF_ERROR(ReadStringList(doc, "train_filenames", what, &file.train_files));
  ATEX_RETURN_IF_ERROR(ReadStringList(doc, "val_filenames", what, &file.val_files));
  ATEX_RETURN_IF_ERROR(ReadStringList(doc, "test_filenames", what, &file.test_files));
  file.frames.reserve(frames.size());
  for (size_t i = 0; i < frames.size(); ++i) {
    ATEX_ASSIGN_OR_RETURN(TransformsFrame frame, ReadFrame(frames[i], i, global, what));
    file.frames.push_back(std::move(frame));
  }
  return file;
}

}  // namespace atex
