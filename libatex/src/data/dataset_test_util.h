// Helpers of the dataset-kind tests (nerfstudio, COLMAP): the pixel a camera sees a world point
// at, a text file written with its folders, and small frames whose pixels identify them.
#pragma once

#include <array>
#include <filesystem>
#include <fstream>
#include <string>

#include "atex/camera.h"
#include "atex/image.h"

namespace atex::dataset_testing {

// (u, v, depth) of the world point (x, y, z) in camera `c` (OpenCV, pinhole).
inline std::array<double, 3> Project(const Camera& c, double x, double y, double z) {
  const auto& m = c.world_to_camera;
  const double px = m[0] * x + m[1] * y + m[2] * z + m[3];
  const double py = m[4] * x + m[5] * y + m[6] * z + m[7];
  const double pz = m[8] * x + m[9] * y + m[10] * z + m[11];
  return {c.fx * px / pz + c.cx, c.fy * py / pz + c.cy, pz};
}

inline void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// A small RGB frame whose pixels identify it.
inline Image Frame(int width, int height, int seed) {
  Image image(width, height, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = float((x * 7 + y * 3 + seed * 11 + c * 5) % 256) / 255.0f;
    }
  }
  return image;
}

}  // namespace atex::dataset_testing
