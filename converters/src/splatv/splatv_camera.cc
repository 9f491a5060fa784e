// The cameras of a .splatv file (splatv_camera.h).
#include "splatv/splatv_camera.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace atex::splatv {
namespace {

// A camera that frames the bounds, looking horizontally with `up` up (OpenCV axes).
SplatvCamera DefaultCamera(const Bounds& b, UpAxis up) {
  std::array<double, 3> down{0, 1, 0}, forward{0, 0, 1};  // kNegY unless changed below
  switch (up) {
    case UpAxis::kNegY: down = {0, 1, 0}, forward = {0, 0, 1}; break;
    case UpAxis::kPosY: down = {0, -1, 0}, forward = {0, 0, -1}; break;
    case UpAxis::kPosZ: down = {0, 0, -1}, forward = {0, 1, 0}; break;
    case UpAxis::kNegZ: down = {0, 0, 1}, forward = {0, -1, 0}; break;
    case UpAxis::kPosX: down = {-1, 0, 0}, forward = {0, 0, 1}; break;
    case UpAxis::kNegX: down = {1, 0, 0}, forward = {0, 0, -1}; break;
  }
  const std::array<double, 3> right = {down[1] * forward[2] - down[2] * forward[1],
                                       down[2] * forward[0] - down[0] * forward[2],
                                       down[0] * forward[1] - down[1] * forward[0]};
  SplatvCamera c;
  const double distance = 1.5 * std::max(b.diagonal(), 1e-6);
  for (int k = 0; k < 3; ++k) {
    c.position[size_t(k)] = 0.5 * (b.lo[k] + b.hi[k]) - distance * forward[size_t(k)];
    // Camera-to-world rows: row k = (right_k, down_k, forward_k).
    c.rotation[size_t(k * 3 + 0)] = right[size_t(k)];
    c.rotation[size_t(k * 3 + 1)] = down[size_t(k)];
    c.rotation[size_t(k * 3 + 2)] = forward[size_t(k)];
  }
  return c;
}

}  // namespace

double Bounds::diagonal() const {
  double s = 0;
  for (int k = 0; k < 3; ++k) s += (hi[k] - lo[k]) * (hi[k] - lo[k]);
  return std::sqrt(s);
}

Bounds PositionBounds(const Gaussians& g) {
  Bounds b;
  b.lo.fill(std::numeric_limits<double>::infinity());
  b.hi.fill(-std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      b.lo[k] = std::min(b.lo[k], double(g.positions[i * 3 + k]));
      b.hi[k] = std::max(b.hi[k], double(g.positions[i * 3 + k]));
    }
  }
  return b;
}

std::vector<SplatvCamera> ChooseCameras(const Asset& asset, const SplatvOptions& options, const Bounds& bounds) {
  std::vector<SplatvCamera> cameras = options.cameras;
  if (cameras.empty()) {
    UpAxis up = UpAxis::kNegY;
    if (options.up) {
      up = *options.up;
    } else {
      auto from_metadata = UpAxisOf(asset.metadata);
      if (from_metadata.ok()) up = *from_metadata;
    }
    cameras.push_back(DefaultCamera(bounds, up));
  }
  return cameras;
}

nlohmann::json CameraJson(const SplatvCamera& c, size_t id) {
  const auto& r = c.rotation;
  return {{"id", id},
          {"img_name", c.name},
          {"width", c.width},
          {"height", c.height},
          {"position", c.position},
          {"rotation", {{r[0], r[1], r[2]}, {r[3], r[4], r[5]}, {r[6], r[7], r[8]}}},
          {"fx", c.fx},
          {"fy", c.fy}};
}

Camera ToCamera(const SplatvCamera& c) {
  Camera camera;
  camera.width = c.width, camera.height = c.height;
  camera.fx = c.fx, camera.fy = c.fy, camera.cx = c.width / 2.0, camera.cy = c.height / 2.0;  // the viewer's model
  const auto& r = c.rotation;  // camera-to-world rows: world-to-camera is [R^T | -R^T c]
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) camera.world_to_camera[size_t(i * 4 + j)] = r[size_t(j * 3 + i)];
    camera.world_to_camera[size_t(i * 4 + 3)] =
        -(r[size_t(i)] * c.position[0] + r[size_t(3 + i)] * c.position[1] + r[size_t(6 + i)] * c.position[2]);
  }
  return camera;
}

}  // namespace atex::splatv
