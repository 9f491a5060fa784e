// World-axis conventions: which way is up in an asset, and the rotation of the
// glTF node that turns it to glTF's +Y up (right-handed in both).
#include <cmath>

#include "atex/converters/gltf.h"
#include "atex/world_up.h"

namespace atex {

StatusOr<UpAxis> GltfUpAxisFor(const std::string& axes) {
  const std::string legacy = LegacyUpAxis(axes);
  if (legacy.empty()) {
    return MakeError(StatusCode::kInvalidArgument, "metadata.axes '", axes,
                     "' does not say which way is up; pass an explicit up axis (+x, -x, +y, -y, +z, -z)");
  }
  return ParseUpAxis(legacy);
}

StatusOr<UpAxis> UpAxisOf(const Metadata& metadata) {
  ATEX_ASSIGN_OR_RETURN(std::string name, WorldUpAxis(metadata));
  return ParseUpAxis(name);
}

StatusOr<UpAxis> ParseUpAxis(const std::string& text) {
  if (text == "+y" || text == "y") return UpAxis::kPosY;
  if (text == "-y") return UpAxis::kNegY;
  if (text == "+z" || text == "z") return UpAxis::kPosZ;
  if (text == "-z") return UpAxis::kNegZ;
  if (text == "+x" || text == "x") return UpAxis::kPosX;
  if (text == "-x") return UpAxis::kNegX;
  return MakeError(StatusCode::kInvalidArgument, "up axis '", text, "' is not one of +x, -x, +y, -y, +z, -z");
}

std::string UpAxisName(UpAxis up) {
  switch (up) {
    case UpAxis::kPosY: return "+y";
    case UpAxis::kNegY: return "-y";
    case UpAxis::kPosZ: return "+z";
    case UpAxis::kNegZ: return "-z";
    case UpAxis::kPosX: return "+x";
    case UpAxis::kNegX: return "-x";
  }
  return "+y";
}

std::array<double, 4> GltfRootRotation(UpAxis up) {
  const double h = std::sqrt(0.5);
  switch (up) {
    case UpAxis::kNegY: return {1, 0, 0, 0};   // 180 degrees about x: (x, y, z) -> (x, -y, -z)
    case UpAxis::kPosZ: return {-h, 0, 0, h};  // -90 degrees about x: +z -> +y
    case UpAxis::kNegZ: return {h, 0, 0, h};   // +90 degrees about x: -z -> +y
    case UpAxis::kPosX: return {0, 0, h, h};   // +90 degrees about z: +x -> +y
    case UpAxis::kNegX: return {0, 0, -h, h};  // -90 degrees about z: -x -> +y
    default: return {0, 0, 0, 1};
  }
}

std::array<double, 9> UpRotationMatrix(UpAxis up) {
  switch (up) {
    case UpAxis::kNegY: return {1, 0, 0, 0, -1, 0, 0, 0, -1};
    case UpAxis::kPosZ: return {1, 0, 0, 0, 0, 1, 0, -1, 0};
    case UpAxis::kNegZ: return {1, 0, 0, 0, 0, -1, 0, 1, 0};
    case UpAxis::kPosX: return {0, -1, 0, 1, 0, 0, 0, 0, 1};
    case UpAxis::kNegX: return {0, 1, 0, -1, 0, 0, 0, 0, 1};
    default: return {1, 0, 0, 0, 1, 0, 0, 0, 1};
  }
}

}  // namespace atex
