// Pinhole camera in the OpenCV convention (docs/conventions.md, "Cameras").
#pragma once

#include <array>
#include <string>

namespace atex {

struct Camera {
  int width = 0;   // pixels
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixel units; pixel (i, j) has its centre at (i + 0.5, j + 0.5)
  // Row-major 4x4 world-to-camera transform; camera axes x right, y down, z forward.
  std::array<double, 16> world_to_camera{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  double time = 0;   // scene time of this view, in the asset's time units
  std::string name;  // e.g. "cam 10 / t 3"

  // Camera centre in world coordinates (-R^T t).
  std::array<double, 3> Center() const {
    const auto& m = world_to_camera;
    return {-(m[0] * m[3] + m[4] * m[7] + m[8] * m[11]),
            -(m[1] * m[3] + m[5] * m[7] + m[9] * m[11]),
            -(m[2] * m[3] + m[6] * m[7] + m[10] * m[11])};
  }
};

// Pixel coordinates (u, v) of world point `x` in `cam`. False when the point is not beyond
// `near_plane` (camera z > near_plane) or projects outside the image.
inline bool ProjectToImage(const Camera& cam, const double x[3], double near_plane, double* u, double* v) {
  const auto& m = cam.world_to_camera;
  const double cz = m[8] * x[0] + m[9] * x[1] + m[10] * x[2] + m[11];
  if (!(cz > near_plane)) return false;
  const double cx = m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + m[3];
  const double cy = m[4] * x[0] + m[5] * x[1] + m[6] * x[2] + m[7];
  *u = cam.fx * cx / cz + cam.cx;
  *v = cam.fy * cy / cz + cam.cy;
  return *u >= 0 && *v >= 0 && *u < cam.width && *v < cam.height;
}

}  // namespace atex
