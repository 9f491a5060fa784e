// Assembles a glTF document: bufferViews and accessors over one binary buffer,
// optionally compressed view by view with EXT_meshopt_compression, then emitted
// as GLB or as JSON + .bin. Knows nothing about Gaussians. Internal header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/converters/gltf.h"
#include "atex/status.h"
#include "gltf/meshopt_codec.h"

namespace atex::gltf {

struct ViewSpec {
  const uint8_t* bytes = nullptr;  // [count][stride]: the view's bytes before the meshopt filter is decoded
  size_t count = 0;
  size_t stride = 0;               // element size in bytes, multiple of 4
  bool vertex_attribute = false;   // sets byteStride and target ARRAY_BUFFER
  MeshoptFilter filter = MeshoptFilter::kNone;  // only with meshopt
};

class GltfWriter {
 public:
  explicit GltfWriter(bool meshopt);

  // Adds a bufferView (4-byte aligned) and returns its index.
  StatusOr<int> AddView(const ViewSpec& spec);
  // Adds a bufferView of `size` opaque bytes (exact byteLength, no stride, never meshopt-compressed:
  // e.g. an SPZ stream) and returns its index. Only without meshopt.
  StatusOr<int> AddBlobView(const uint8_t* bytes, size_t size);
  // Adds an accessor over `view` and returns its index. `type` is "SCALAR", "VEC3", ... A
  // negative `view` writes an accessor without a bufferView (data provided by an extension).
  int AddAccessor(int view, size_t byte_offset, int component_type, bool normalized, size_t count,
                  const char* type, const nlohmann::json& min = nullptr, const nlohmann::json& max = nullptr);

  // The document being built (asset, scenes, nodes, meshes, extensions are the caller's).
  nlohmann::json& doc() { return doc_; }
  // Adds `name` to extensionsUsed (once), and to extensionsRequired when `required`.
  void UseExtension(const std::string& name, bool required);

  // Emits the document. The writer is left in an unspecified state.
  StatusOr<std::vector<uint8_t>> FinishGlb();
  StatusOr<GltfTextFiles> FinishText(const std::string& bin_uri);

  uint64_t uncompressed_bytes() const { return fallback_size_; }

 private:
  Status Finish(bool glb, const std::string& bin_uri);

  bool meshopt_;
  nlohmann::json doc_;
  std::vector<uint8_t> bin_;      // buffer 0: the data (compressed streams with meshopt)
  uint64_t fallback_size_ = 0;    // meshopt: byte length of the URI-less fallback buffer 1
};

// JSON text with invalid UTF-8 replaced (metadata strings come from users).
std::string DumpJson(const nlohmann::json& json);

}  // namespace atex::gltf
