// The world's up axis: metadata.up, the legacy rule from metadata.axes, and the
// rule the trainer uses to record it from the training cameras.
#include "atex/world_up.h"

#include <cmath>

namespace atex {

bool IsUpAxisName(std::string_view name) {
  return name.size() == 2 && (name[0] == '+' || name[0] == '-') && (name[1] == 'x' || name[1] == 'y' || name[1] == 'z');
}

std::string LegacyUpAxis(std::string_view axes) {
  if (axes == "opencv" || axes == "colmap" || axes == "y_down") return "-y";
  if (axes == "blender" || axes == "z_up") return "+z";
  if (axes == "gltf" || axes == "opengl" || axes == "y_up") return "+y";
  if (axes == "z_down") return "-z";
  return "";
}

StatusOr<std::string> WorldUpAxis(const Metadata& metadata) {
  if (!metadata.up.empty()) {
    if (!IsUpAxisName(metadata.up)) {
      return MakeError(StatusCode::kInvalidArgument, "metadata.up '", metadata.up,
                       "' is not one of +x, -x, +y, -y, +z, -z");
    }
    return metadata.up;
  }
  std::string legacy = LegacyUpAxis(metadata.axes);
  if (legacy.empty()) {
    return MakeError(StatusCode::kInvalidArgument, "the asset records no metadata.up and metadata.axes '",
                     metadata.axes,
                     "' does not say which way is up; pass an explicit up axis (+x, -x, +y, -y, +z, -z)");
  }
  return legacy;
}

std::optional<std::string> UpAxisFromCameras(const std::vector<Camera>& cameras, double min_agreement) {
  double mean[3] = {0, 0, 0};
  size_t used = 0;
  for (const Camera& camera : cameras) {
    // Row 1 of the world-to-camera rotation is the camera's +y (image down) in world coordinates.
    const auto& m = camera.world_to_camera;
    const double down[3] = {m[4], m[5], m[6]};
    const double length = std::sqrt(down[0] * down[0] + down[1] * down[1] + down[2] * down[2]);
    if (!(length > 0) || !std::isfinite(length)) continue;
    for (int k = 0; k < 3; ++k) mean[k] -= down[k] / length;
    ++used;
  }
  if (used == 0) return std::nullopt;
  for (double& v : mean) v /= double(used);
  const double length = std::sqrt(mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]);
  if (!(length >= min_agreement)) return std::nullopt;
  int axis = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::fabs(mean[k]) > std::fabs(mean[axis])) axis = k;
  }
  std::string name = mean[axis] >= 0 ? "+" : "-";
  name += char('x' + axis);
  return name;
}

}  // namespace atex
