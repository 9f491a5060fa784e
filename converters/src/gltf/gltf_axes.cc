// World-axis conventions: which way is up in an asset, and the rotation of the
// glTF node that turns it to glTF's +Y up (right-handed in both).
#include <cmath>

#include "atex/converters/gltf.h"

namespace atex {

StatusOr<UpAxis> GltfUpAxisFor(const std::string& axes) {
  // "opencv": the camera-style world of the multi-view datasets (x right, y down, z forward).
  if (axes == "opencv" || axes == "colmap" || axes == "y_down") return UpAxis::kNegY;
  if (axes == "blender" || axes == "z_up") return UpAxis::kPosZ;
  if (axes == "gltf" || axes == "opengl" || axes == "y_up") return UpAxis::kPosY;
  if (axes == "z_down") return UpAxis::kNegZ;
  return MakeError(StatusCode::kInvalidArgument, "metadata.axes '", axes,
                   "' does not say which way is up; pass an explicit up axis (+y, -y, +z, -z)");
}

StatusOr<UpAxis> ParseUpAxis(const std::string& text) {
  if (text == "+y" || text == "y") return UpAxis::kPosY;
  if (text == "-y") return UpAxis::kNegY;
  if (text == "+z" || text == "z") return UpAxis::kPosZ;
  if (text == "-z") return UpAxis::kNegZ;
  return MakeError(StatusCode::kInvalidArgument, "up axis '", text, "' is not one of +y, -y, +z, -z");
}

std::array<double, 4> GltfRootRotation(UpAxis up) {
  const double h = std::sqrt(0.5);
  switch (up) {
    case UpAxis::kNegY: return {1, 0, 0, 0};   // 180 degrees about x: (x, y, z) -> (x, -y, -z)
    case UpAxis::kPosZ: return {-h, 0, 0, h};  // -90 degrees about x: +z -> +y
    case UpAxis::kNegZ: return {h, 0, 0, h};   // +90 degrees about x: -z -> +y
    default: return {0, 0, 0, 1};
  }
}

}  // namespace atex
