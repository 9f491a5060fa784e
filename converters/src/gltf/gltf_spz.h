// KHR_gaussian_splatting_compression_spz_2: a splat primitive's base attributes stored as one SPZ
// stream in a bufferView (the attributes' accessors then have no bufferView). Internal header of
// the glTF exporter and importer.
#pragma once

#ifdef ATEX_HAVE_TINYGLTF
#include "gltf/tinygltf_config.h"
#endif

#include <cstddef>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::gltf {

inline constexpr const char* kKhrSpz2 = "KHR_gaussian_splatting_compression_spz_2";
// The SPZ stream version written: 3 (gzip), the format of the SPZ 2.x library the extension names.
inline constexpr int kSpzInGltfVersion = 3;

// The SPZ stream of `g`, Gaussians in the primitive's (mesh-local) glTF coordinates. The extension
// fixes the stream's axes as SPZ's LUF reading of them: glTF's own axes (+X left, +Y up, +Z front),
// so the Gaussians are turned by 180° about +Y into SPZ's stored RUB axes (positions, quaternions
// and SH). Errors: EncodeSpz's (kOutOfRange for a position beyond the 24-bit range).
StatusOr<std::vector<uint8_t>> EncodeSpzForGltf(const Gaussians& g);

// Inverse of EncodeSpzForGltf: the Gaussians of an SPZ stream in glTF coordinates. Refuses streams
// announcing more than `max_points` Gaussians (kLimitExceeded); DecodeSpz's errors otherwise.
StatusOr<Gaussians> DecodeSpzForGltf(const uint8_t* data, size_t size, uint64_t max_points);

#ifdef ATEX_HAVE_TINYGLTF
// The Gaussians of a primitive whose KHR_gaussian_splatting object `khr` carries kKhrSpz2: the
// bufferView it names (bounds checked against its buffer), decoded, and their count checked
// against the POSITION accessor's. Errors name the extension and the bufferView.
StatusOr<Gaussians> ReadSpzPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                     const nlohmann::json& khr, uint64_t max_points);
#endif

}  // namespace atex::gltf
