// Names and numbers of the glTF vocabulary that the exporter and importer share,
// so that both sides spell every attribute and extension the same way.
#pragma once

#include <string>

namespace atex::gltf {

// glTF accessor component types (glTF 2.0, "accessor.componentType").
inline constexpr int kComponentByte = 5120;
inline constexpr int kComponentUnsignedByte = 5121;
inline constexpr int kComponentShort = 5122;
inline constexpr int kComponentUnsignedShort = 5123;
inline constexpr int kComponentUnsignedInt = 5125;
inline constexpr int kComponentFloat = 5126;
inline constexpr int kTargetArrayBuffer = 34962;
inline constexpr int kModePoints = 0;

// Extensions.
inline constexpr const char* kKhrGaussianSplatting = "KHR_gaussian_splatting";
inline constexpr const char* kAtexTextures = "ATEX_gaussian_textures";
inline constexpr const char* kAtexDeformation = "ATEX_gaussian_deformation";
inline constexpr const char* kExtMeshopt = "EXT_meshopt_compression";
inline constexpr const char* kKhrMeshQuantization = "KHR_mesh_quantization";

// KHR_gaussian_splatting attribute semantics.
inline constexpr const char* kAttrPosition = "POSITION";
inline constexpr const char* kAttrColor = "COLOR_0";
inline constexpr const char* kAttrRotation = "KHR_gaussian_splatting:ROTATION";
inline constexpr const char* kAttrScale = "KHR_gaussian_splatting:SCALE";
inline constexpr const char* kAttrOpacity = "KHR_gaussian_splatting:OPACITY";
// "KHR_gaussian_splatting:SH_DEGREE_<l>_COEF_<n>", n = 0 .. 2l; our coefficient k = l^2 + n.
inline std::string ShAttribute(int degree, int coef) {
  return "KHR_gaussian_splatting:SH_DEGREE_" + std::to_string(degree) + "_COEF_" + std::to_string(coef);
}

// ATEX_gaussian_textures attribute: VEC4 UNSIGNED_BYTE (height, width, axis_u, axis_v).
inline constexpr const char* kAttrTextureLayout = "ATEX_gaussian_textures:LAYOUT";
// ATEX_gaussian_deformation raw training parameters (all float).
inline constexpr const char* kAttrRawRotation =
    "ATEX_gaussian_deformation:RAW_ROTATION";  // VEC4 (x, y, z, w) unnormalised
inline constexpr const char* kAttrRawLogScale = "ATEX_gaussian_deformation:RAW_LOG_SCALE";  // VEC3
inline constexpr const char* kAttrRawLogit = "ATEX_gaussian_deformation:RAW_OPACITY_LOGIT"; // SCALAR

// Names of the deformation heads in the extension JSON, indexed by atex::DeformHead.
inline constexpr const char* kHeadNames[5] = {"position", "scale", "rotation", "opacity", "sh"};

// Version of our extension payload layout (root extras.atex.version).
inline constexpr int kAtexGltfVersion = 1;

// Raw texture values pass through tanh and are scaled by these factors
// (docs/conventions.md section 5); recorded in the extension for other readers.
inline constexpr double kTextureColorScale = 0.1;
inline constexpr double kTextureAlphaScale = 0.1;

}  // namespace atex::gltf
