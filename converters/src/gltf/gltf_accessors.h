// Bounds-checked reading of glTF accessors from a tinygltf model (after
// NormalizeGltf: one buffer, no compression). Internal header.
#pragma once

#ifdef ATEX_HAVE_TINYGLTF

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "gltf/tinygltf_config.h"

#include "atex/status.h"

namespace atex::gltf {

struct AccessorData {
  const uint8_t* first = nullptr;  // element 0
  size_t count = 0;
  size_t stride = 0;               // bytes between elements
  int components = 0;              // 1 (SCALAR) .. 4 (VEC4)
  int component_type = 0;          // kComponent*
  bool normalized = false;
};

// Resolves accessor `index` and checks that every element lies inside its bufferView and
// buffer. `where` names the referrer for messages (e.g. "attribute POSITION").
StatusOr<AccessorData> ResolveAccessor(const tinygltf::Model& model, int64_t index, const std::string& where);

// Expected shape: components per element and the component types allowed; checks too
// that count == expected_count when expected_count != 0.
Status CheckAccessor(const AccessorData& a, int components, std::initializer_list<int> component_types,
                     size_t expected_count, const std::string& where);

// Converts every component to float ([count][components]): floats are copied bit for bit,
// normalized integers map to [0, 1] / [-1, 1] (glTF 2.0 "Animations", normalization
// rules), other integers convert by value. Non-finite floats give kOutOfRange.
Status ReadFloats(const AccessorData& a, const std::string& where, std::vector<float>* out);
// Unsigned bytes ([count][components]); the accessor must be UNSIGNED_BYTE.
Status ReadBytes(const AccessorData& a, const std::string& where, std::vector<uint8_t>* out);

}  // namespace atex::gltf

#endif  // ATEX_HAVE_TINYGLTF
