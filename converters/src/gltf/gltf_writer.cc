#include "gltf/gltf_writer.h"

#include <cstring>

#include "gltf/gltf_names.h"

namespace atex::gltf {
namespace {

constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kGlbChunkBin = 0x004E4942;   // "BIN\0"

size_t Align4(size_t n) { return (n + 3) & ~size_t{3}; }

void PadTo4(std::vector<uint8_t>& bytes, uint8_t fill) {
  bytes.resize(Align4(bytes.size()), fill);
}

void PutU32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

}  // namespace

std::string DumpJson(const nlohmann::json& json) {
  return json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

GltfWriter::GltfWriter(bool meshopt) : meshopt_(meshopt) {
  doc_ = nlohmann::json::object();
  doc_["bufferViews"] = nlohmann::json::array();
  doc_["accessors"] = nlohmann::json::array();
}

void GltfWriter::UseExtension(const std::string& name, bool required) {
  auto add = [&](const char* key) {
    nlohmann::json& list = doc_[key];
    if (!list.is_array()) list = nlohmann::json::array();
    for (const auto& e : list) {
      if (e == name) return;
    }
    list.push_back(name);
  };
  add("extensionsUsed");
  if (required) add("extensionsRequired");
}

StatusOr<int> GltfWriter::AddView(const ViewSpec& spec) {
  if (spec.stride == 0 || spec.stride % 4 != 0 || spec.count == 0) {
    return MakeError(StatusCode::kInternal, "bufferView with stride ", spec.stride, " and count ", spec.count);
  }
  const size_t length = spec.count * spec.stride;
  nlohmann::json view = nlohmann::json::object();
  view["byteLength"] = length;
  if (spec.vertex_attribute) {
    view["byteStride"] = spec.stride;
    view["target"] = kTargetArrayBuffer;
  }
  if (!meshopt_) {
    PadTo4(bin_, 0);
    view["buffer"] = 0;
    view["byteOffset"] = bin_.size();
    bin_.insert(bin_.end(), spec.bytes, spec.bytes + length);
  } else {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> stream, CompressAttributes(spec.bytes, spec.count, spec.stride));
    PadTo4(bin_, 0);
    nlohmann::json ext = {{"buffer", 0},
                          {"byteOffset", bin_.size()},
                          {"byteLength", stream.size()},
                          {"byteStride", spec.stride},
                          {"mode", "ATTRIBUTES"},
                          {"count", spec.count}};
    if (spec.filter != MeshoptFilter::kNone) ext["filter"] = MeshoptFilterName(spec.filter);
    bin_.insert(bin_.end(), stream.begin(), stream.end());
    fallback_size_ = Align4(fallback_size_);
    view["buffer"] = 1;
    view["byteOffset"] = fallback_size_;
    view["extensions"][kExtMeshopt] = ext;
    fallback_size_ += length;
  }
  doc_["bufferViews"].push_back(view);
  return static_cast<int>(doc_["bufferViews"].size() - 1);
}

StatusOr<int> GltfWriter::AddBlobView(const uint8_t* bytes, size_t size) {
  if (meshopt_ || size == 0) return MakeError(StatusCode::kInternal, "blob bufferView of ", size, " bytes");
  PadTo4(bin_, 0);
  nlohmann::json view = {{"buffer", 0}, {"byteOffset", bin_.size()}, {"byteLength", size}};
  bin_.insert(bin_.end(), bytes, bytes + size);
  doc_["bufferViews"].push_back(view);
  return static_cast<int>(doc_["bufferViews"].size() - 1);
}

int GltfWriter::AddAccessor(int view, size_t byte_offset, int component_type, bool normalized, size_t count,
                            const char* type, const nlohmann::json& min, const nlohmann::json& max) {
  nlohmann::json accessor = {{"componentType", component_type}, {"count", count}, {"type", type}};
  if (view >= 0) accessor["bufferView"] = view;
  if (byte_offset != 0) accessor["byteOffset"] = byte_offset;
  if (normalized) accessor["normalized"] = true;
  if (!min.is_null()) accessor["min"] = min;
  if (!max.is_null()) accessor["max"] = max;
  doc_["accessors"].push_back(accessor);
  return static_cast<int>(doc_["accessors"].size() - 1);
}

Status GltfWriter::Finish(bool glb, const std::string& bin_uri) {
  PadTo4(bin_, 0);
  nlohmann::json buffers = nlohmann::json::array();
  nlohmann::json data_buffer = {{"byteLength", bin_.size()}};
  if (!glb) data_buffer["uri"] = bin_uri;
  buffers.push_back(data_buffer);
  if (meshopt_) {
    // The uncompressed layout exists only as a size: the fallback buffer has no data,
    // so the extension is required (EXT_meshopt_compression, "Fallback buffers").
    buffers.push_back({{"byteLength", Align4(fallback_size_)}, {"extensions", {{kExtMeshopt, {{"fallback", true}}}}}});
    UseExtension(kExtMeshopt, true);
  }
  doc_["buffers"] = buffers;
  return Status::Ok();
}

StatusOr<std::vector<uint8_t>> GltfWriter::FinishGlb() {
  ATEX_RETURN_IF_ERROR(Finish(true, ""));
  std::string json = DumpJson(doc_);
  json.resize(Align4(json.size()), ' ');
  const uint64_t total = 12 + 8 + json.size() + 8 + bin_.size();
  if (total > UINT32_MAX) {
    return MakeError(StatusCode::kLimitExceeded, "GLB would be ", total,
                     " bytes; the format's limit is 4 GiB (use .gltf)");
  }
  std::vector<uint8_t> out;
  out.reserve(total);
  PutU32(out, kGlbMagic);
  PutU32(out, 2);
  PutU32(out, static_cast<uint32_t>(total));
  PutU32(out, static_cast<uint32_t>(json.size()));
  PutU32(out, kGlbChunkJson);
  out.insert(out.end(), json.begin(), json.end());
  PutU32(out, static_cast<uint32_t>(bin_.size()));
  PutU32(out, kGlbChunkBin);
  out.insert(out.end(), bin_.begin(), bin_.end());
  return out;
}

StatusOr<GltfTextFiles> GltfWriter::FinishText(const std::string& bin_uri) {
  ATEX_RETURN_IF_ERROR(Finish(false, bin_uri));
  GltfTextFiles files;
  files.json = DumpJson(doc_);
  files.bin = std::move(bin_);
  return files;
}

}  // namespace atex::gltf
