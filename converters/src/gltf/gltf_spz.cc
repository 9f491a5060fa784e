// SPZ inside glTF (gltf_spz.h): the axis turn between glTF's LUF and SPZ's stored RUB, and the
// bufferView that holds the stream.
#include "gltf/gltf_spz.h"

#include <array>
#include <string>

#include "atex/converters/spz.h"
#include "convert/world_turn.h"
#include "gltf/gltf_json_util.h"
#include "gltf/gltf_names.h"

namespace atex::gltf {
namespace {

// LUF <-> RUB: x and z change sign, a proper rotation (180° about +Y) and its own inverse.
constexpr std::array<double, 9> kTurnAboutY = {-1, 0, 0, 0, 1, 0, 0, 0, -1};

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeSpzForGltf(const Gaussians& g) {
  Gaussians stored = g;
  convert::RotateGaussians(kTurnAboutY, &stored);
  SpzWriteOptions options;
  options.version = kSpzInGltfVersion;
  options.axes = SpzAxes::kStored;
  return EncodeSpz(stored, options);
}

StatusOr<Gaussians> DecodeSpzForGltf(const uint8_t* data, size_t size, uint64_t max_points) {
  SpzReadOptions options;
  options.axes = SpzAxes::kStored;
  options.max_points = max_points;
  ATEX_ASSIGN_OR_RETURN(Gaussians g, DecodeSpz(data, size, options));
  convert::RotateGaussians(kTurnAboutY, &g);
  return g;
}

#ifdef ATEX_HAVE_TINYGLTF
StatusOr<Gaussians> ReadSpzPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                                     const nlohmann::json& khr, uint64_t max_points) {
  const std::string where = std::string(kKhrGaussianSplatting) + ".extensions." + kKhrSpz2;
  const nlohmann::json& ext = khr.at("extensions").at(kKhrSpz2);
  if (!ext.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
  uint64_t view_index = 0;
  ATEX_RETURN_IF_ERROR(ReadIndex(ext, "bufferView", model.bufferViews.size(), where, &view_index));
  const tinygltf::BufferView& view = model.bufferViews[view_index];
  const std::string view_name = "bufferViews[" + std::to_string(view_index) + "]";
  if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size()) {
    return MakeError(StatusCode::kCorrupt, view_name, ".buffer ", view.buffer, " does not exist");
  }
  const std::vector<unsigned char>& buffer = model.buffers[size_t(view.buffer)].data;
  if (view.byteOffset > buffer.size() || view.byteLength > buffer.size() - view.byteOffset) {
    return MakeError(StatusCode::kTruncated, view_name, " (offset ", view.byteOffset, ", ", view.byteLength,
                     " bytes) runs past its buffer of ", buffer.size(), " bytes");
  }
  auto decoded = DecodeSpzForGltf(buffer.data() + view.byteOffset, view.byteLength, max_points);
  if (!decoded.ok()) return decoded.status().WithContext(where);
  auto position = primitive.attributes.find(kAttrPosition);
  if (position == primitive.attributes.end() || position->second < 0 ||
      size_t(position->second) >= model.accessors.size()) {
    return MakeError(StatusCode::kCorrupt, where, ": the primitive has no valid POSITION accessor");
  }
  const size_t count = model.accessors[size_t(position->second)].count;
  if (count != decoded->size()) {
    return MakeError(StatusCode::kCorrupt, where, ": the SPZ stream holds ", decoded->size(),
                     " Gaussians, the POSITION accessor counts ", count);
  }
  return decoded;
}
#endif

}  // namespace atex::gltf
