// libFuzzer target: the glTF importer (GLB or text glTF with data: URIs; GLB container,
// buffers, EXT_meshopt_compression views, accessors, node transforms, our extensions).
//
// Properties checked beyond "no crash": an accepted asset passes ValidateAsset, the
// exporter accepts it, its export reads back, and export -> import -> export is
// byte-identical (import of our own files is lossless, export is deterministic).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/converters/gltf.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::GltfImportOptions options;
  options.max_decoded_bytes = 64u << 20;  // libFuzzer's default RSS limit is 2 GB
  options.max_gaussians = 1u << 20;
  auto asset = atex::DecodeGltf(data, size, options);
  if (!asset.ok()) return 0;
  if (!atex::ValidateAsset(*asset).ok()) __builtin_trap();  // the importer let an invalid asset through
  if (asset->gaussians.size() == 0) __builtin_trap();       // "no splats" must be an error
  auto glb = atex::EncodeGlb(*asset);
  if (!glb.ok()) {
    // Only assets whose metadata names no known up axis may be refused.
    if (glb.status().code() != atex::StatusCode::kInvalidArgument) __builtin_trap();
    return 0;
  }
  auto again = atex::DecodeGltf(glb->data(), glb->size(), options);
  if (!again.ok()) __builtin_trap();  // our own export does not read back
  auto twice = atex::EncodeGlb(*again);
  if (!twice.ok() || *twice != *glb) __builtin_trap();  // the round trip is not lossless
  return 0;
}
