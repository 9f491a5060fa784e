// The first stage of glTF import: the file container. Splits GLB into its JSON and
// binary chunks (or takes a text glTF), resolves every buffer (GLB chunk, data: URI,
// external file), decodes EXT_meshopt_compression views, and rewrites the document
// into a plain single-buffer GLB that tinygltf then parses. Every offset, length and
// count is checked against the bytes present; expansion is bounded. Internal header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/converters/gltf.h"
#include "atex/status.h"

namespace atex::gltf {

// Loads an external buffer named by a (percent-decoded, relative) URI; `max_bytes` is
// the most the caller accepts. Absent (empty function): external URIs are refused.
using UriLoader = std::function<StatusOr<std::vector<uint8_t>>(const std::string& uri, uint64_t max_bytes)>;

struct NormalizedGltf {
  nlohmann::json doc;         // the document, buffers rewritten to one buffer, meshopt views decoded
  std::vector<uint8_t> glb;   // the same document as a GLB for tinygltf
  bool had_meshopt = false;
};

StatusOr<NormalizedGltf> NormalizeGltf(const uint8_t* data, size_t size, const UriLoader& loader,
                                       const GltfImportOptions& options);

// "a%20b.bin" -> "a b.bin"; kCorrupt on a malformed escape.
StatusOr<std::string> PercentDecode(const std::string& uri);
// Escapes everything but RFC 3986 unreserved characters and '/'.
std::string PercentEncode(const std::string& text);

}  // namespace atex::gltf
