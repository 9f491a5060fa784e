// Parsers of the camera files of two dataset layouts (atex/dataset.h, kNerfstudio and
// kColmap), over bytes in memory so that tests and fuzz targets reach them without files.
// They treat their input as hostile: counts are checked against the bytes present before
// anything is allocated from them, and errors name the file, the element and its
// position (JSON path, text line or byte offset).
//
// Nerfstudio / instant-ngp transforms.json:
//   { [camera_model], [fl_x], [fl_y], [cx], [cy], [w], [h], [camera_angle_x],
//     [camera_angle_y], [k1 k2 k3 k4 p1 p2], [applied_transform], [ply_file_path],
//     [train_filenames], [val_filenames], [test_filenames],
//     frames: [{file_path, transform_matrix (4x4 camera-to-world, OpenGL axes: x right,
//               y up, z back), [time] | [timestep], [camera_id], [mask_path], and any of
//               the global intrinsics keys, which override the global ones}] }
//   Intrinsics: fl_x from fl_x, else from camera_angle_x and the width; fl_y from fl_y,
//   else camera_angle_y, else fl_x; cx, cy default to w/2, h/2. w and h may be absent
//   (0 here: the loader takes them from the image). camera_model: absent, PINHOLE,
//   SIMPLE_PINHOLE, OPENCV, SIMPLE_RADIAL or RADIAL; any non-zero distortion
//   coefficient and any other model (fisheye, equirectangular) are refused: frames are
//   not undistorted. applied_transform (nerfstudio's record of what it already applied to
//   the poses) is validated and not applied again.
//
// COLMAP sparse model (COLMAP's documented text and binary layouts):
//   cameras.txt   `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...` per line
//   cameras.bin   uint64 count, then per camera uint32 id, int32 model id, uint64 width,
//                 uint64 height, double params[count of the model]
//   images.txt    two lines per image: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`, then
//                 its 2D points `(X Y POINT3D_ID)*` (possibly empty; read, not kept)
//   images.bin    uint64 count, then per image uint32 id, double qw qx qy qz tx ty tz,
//                 uint32 camera id, NAME with a NUL terminator, uint64 point count and
//                 that many (double x, double y, int64 point3D id)
//   Every model id is recognised (its parameter count); the loader accepts PINHOLE and
//   SIMPLE_PINHOLE, and SIMPLE_RADIAL, RADIAL, OPENCV and FULL_OPENCV whose distortion
//   parameters are all zero. The rotation (quaternion w, x, y, z) and translation map
//   world to camera in OpenCV axes, the library's convention.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "atex/status.h"

namespace atex {

// ---- transforms.json ------------------------------------------------------------
struct TransformsFrame {
  size_t index = 0;             // position in the file's "frames" array
  std::string file_path;        // as written (relative to the file's folder)
  std::string mask_path;        // empty: none
  std::array<double, 16> camera_to_world{};  // row-major, OpenGL camera axes
  double fx = 0, fy = 0;        // 0: from camera_angle_x / _y once the width is known
  double angle_x = 0, angle_y = 0;  // radians, 0 = absent
  std::optional<double> cx, cy; // absent: the image centre
  int width = 0, height = 0;    // 0: from the image file
  std::optional<double> time;   // "time"
  std::optional<int64_t> timestep;  // "timestep"
  int camera_id = -1;           // "camera_id", -1 when absent
};

struct TransformsFile {
  std::vector<TransformsFrame> frames;
  // nerfstudio's split lists (file paths as written); empty when absent.
  std::vector<std::string> train_files, val_files, test_files;
  std::string ply_file_path;  // nerfstudio's sparse point cloud, relative; empty when absent
};

// Parses a transforms.json text; `what` names it in errors. kCorrupt for invalid JSON (the
// byte offset), a missing or mistyped key (its JSON path, e.g. frames[3].transform_matrix[1][2]),
// non-finite numbers, sizes outside 1..kMaxImageSide; kUnsupported for distortion or a
// non-pinhole camera model (naming the frame and key); kLimitExceeded past 10^7 frames.
StatusOr<TransformsFile> ParseTransformsJson(std::string_view text, const std::string& what);

// ---- COLMAP sparse model ----------------------------------------------------------
struct ColmapCamera {
  uint32_t id = 0;
  int model_id = -1;
  std::string model;  // COLMAP's model name, e.g. "PINHOLE"
  uint64_t width = 0, height = 0;
  std::vector<double> params;
};

struct ColmapImage {
  uint32_t id = 0;
  std::array<double, 4> qvec{};  // w, x, y, z (world-to-camera rotation)
  std::array<double, 3> tvec{};
  uint32_t camera_id = 0;
  std::string name;  // path relative to the images folder
};

// COLMAP's model name for a model id and its parameter count; false for an unknown id.
bool ColmapModelInfo(int model_id, std::string* name, int* param_count);

StatusOr<std::vector<ColmapCamera>> ParseColmapCamerasText(std::string_view text, const std::string& what);
StatusOr<std::vector<ColmapCamera>> ParseColmapCamerasBinary(const uint8_t* data, size_t size, const std::string& what);
StatusOr<std::vector<ColmapImage>> ParseColmapImagesText(std::string_view text, const std::string& what);
StatusOr<std::vector<ColmapImage>> ParseColmapImagesBinary(const uint8_t* data, size_t size, const std::string& what);

// Pinhole intrinsics (fx, fy, cx, cy) of a camera whose model is pinhole or whose
// distortion parameters are all zero; kUnsupported naming the camera and its model (or
// the first non-zero distortion parameter) otherwise.
StatusOr<std::array<double, 4>> ColmapPinholeIntrinsics(const ColmapCamera& camera, const std::string& what);

// The world-to-camera matrix (row-major 4x4, OpenCV axes) of an image: the quaternion
// normalised (COLMAP writes unit quaternions; hand-written ones may be slightly off); kCorrupt
// when a value is not finite or the quaternion's norm is below 1e-6.
StatusOr<std::array<double, 16>> ColmapWorldToCamera(const ColmapImage& image, const std::string& what);

}  // namespace atex
