#ifdef ATEX_HAVE_TINYGLTF

#include "gltf/gltf_accessors.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "gltf/gltf_names.h"

namespace atex::gltf {
namespace {

int ComponentSize(int type) {
  switch (type) {
    case kComponentByte:
    case kComponentUnsignedByte: return 1;
    case kComponentShort:
    case kComponentUnsignedShort: return 2;
    case kComponentUnsignedInt:
    case kComponentFloat: return 4;
    default: return 0;
  }
}

int ComponentsOf(int tinygltf_type) {
  switch (tinygltf_type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    default: return 0;  // matrices never appear in splat data
  }
}

template <typename T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

}  // namespace

StatusOr<AccessorData> ResolveAccessor(const tinygltf::Model& model, int64_t index, const std::string& where) {
  if (index < 0 || size_t(index) >= model.accessors.size()) {
    return MakeError(StatusCode::kCorrupt, where, ": accessor ", index, " does not exist (", model.accessors.size(),
                     " accessors)");
  }
  const tinygltf::Accessor& a = model.accessors[size_t(index)];
  const std::string name = StrCat("accessors[", index, "] (", where, ")");
  if (a.sparse.isSparse) return MakeError(StatusCode::kUnsupported, name, " is sparse");
  if (a.bufferView < 0 || size_t(a.bufferView) >= model.bufferViews.size()) {
    return MakeError(StatusCode::kCorrupt, name, " has no valid bufferView (", a.bufferView, ")");
  }
  const tinygltf::BufferView& v = model.bufferViews[size_t(a.bufferView)];
  if (v.buffer < 0 || size_t(v.buffer) >= model.buffers.size()) {
    return MakeError(StatusCode::kCorrupt, "bufferViews[", a.bufferView, "] has no valid buffer (", v.buffer, ")");
  }
  const std::vector<unsigned char>& buffer = model.buffers[size_t(v.buffer)].data;
  if (v.byteOffset > buffer.size() || v.byteLength > buffer.size() - v.byteOffset) {
    return MakeError(StatusCode::kCorrupt, "bufferViews[", a.bufferView, "]: bytes ", v.byteOffset, "+", v.byteLength,
                     " exceed its buffer (", buffer.size(), " bytes)");
  }
  AccessorData d;
  d.components = ComponentsOf(a.type);
  d.component_type = a.componentType;
  d.normalized = a.normalized;
  d.count = a.count;
  const int component_size = ComponentSize(a.componentType);
  if (d.components == 0)
    return MakeError(StatusCode::kUnsupported, name, " has type ", a.type, " (not SCALAR or VEC2..4)");
  if (component_size == 0) return MakeError(StatusCode::kCorrupt, name, " has component type ", a.componentType);
  const size_t element = size_t(d.components) * size_t(component_size);
  d.stride = v.byteStride != 0 ? v.byteStride : element;
  if (d.stride < element)
    return MakeError(StatusCode::kCorrupt, name, ": byteStride ", d.stride, " < element size ", element);
  if (d.count == 0) return MakeError(StatusCode::kCorrupt, name, " has count 0");
  if (a.byteOffset > v.byteLength || element > v.byteLength - a.byteOffset) {
    return MakeError(StatusCode::kCorrupt, name, ": byteOffset ", a.byteOffset, " leaves no room in its bufferView (",
                     v.byteLength, " bytes)");
  }
  // Last element must end inside the view: byteOffset + (count-1)*stride + element <= byteLength.
  const size_t room = v.byteLength - a.byteOffset - element;
  if (d.count - 1 > room / d.stride) {
    return MakeError(StatusCode::kCorrupt, name, ": ", d.count, " elements of stride ", d.stride,
                     " exceed its bufferView (", v.byteLength, " bytes from offset ", a.byteOffset, ")");
  }
  d.first = buffer.data() + v.byteOffset + a.byteOffset;
  return d;
}

Status CheckAccessor(const AccessorData& a, int components, std::initializer_list<int> component_types,
                     size_t expected_count, const std::string& where) {
  if (a.components != components) {
    return MakeError(StatusCode::kCorrupt, where, " has ", a.components, " components per element, expected ",
                     components);
  }
  if (std::find(component_types.begin(), component_types.end(), a.component_type) == component_types.end()) {
    return MakeError(StatusCode::kCorrupt, where, " has component type ", a.component_type, ", which it may not use");
  }
  if (expected_count != 0 && a.count != expected_count) {
    return MakeError(StatusCode::kCorrupt, where, " has ", a.count, " elements, expected ", expected_count);
  }
  return Status::Ok();
}

Status ReadFloats(const AccessorData& a, const std::string& where, std::vector<float>* out) {
  const size_t comps = size_t(a.components);
  out->resize(a.count * comps);
  float* dst = out->data();
  for (size_t i = 0; i < a.count; ++i) {
    const uint8_t* p = a.first + i * a.stride;
    for (size_t c = 0; c < comps; ++c) {
      float v = 0;
      switch (a.component_type) {
        case kComponentFloat:
          v = Load<float>(p + 4 * c);
          if (!std::isfinite(v)) {
            return MakeError(StatusCode::kOutOfRange, where, " element ", i, " component ", c, " is not finite");
          }
          break;
        case kComponentByte: {
          const int8_t x = Load<int8_t>(p + c);
          v = a.normalized ? std::max(float(x) / 127.0f, -1.0f) : float(x);
          break;
        }
        case kComponentUnsignedByte: {
          const uint8_t x = Load<uint8_t>(p + c);
          v = a.normalized ? float(x) / 255.0f : float(x);
          break;
        }
        case kComponentShort: {
          const int16_t x = Load<int16_t>(p + 2 * c);
          v = a.normalized ? std::max(float(x) / 32767.0f, -1.0f) : float(x);
          break;
        }
        case kComponentUnsignedShort: {
          const uint16_t x = Load<uint16_t>(p + 2 * c);
          v = a.normalized ? float(x) / 65535.0f : float(x);
          break;
        }
        case kComponentUnsignedInt:
          v = float(Load<uint32_t>(p + 4 * c));
          break;
        default:
          return MakeError(StatusCode::kCorrupt, where, " has component type ", a.component_type);
      }
      dst[i * comps + c] = v;
    }
  }
  return Status::Ok();
}

Status ReadBytes(const AccessorData& a, const std::string& where, std::vector<uint8_t>* out) {
  if (a.component_type != kComponentUnsignedByte) {
    return MakeError(StatusCode::kCorrupt, where, " is not UNSIGNED_BYTE");
  }
  const size_t comps = size_t(a.components);
  out->resize(a.count * comps);
  for (size_t i = 0; i < a.count; ++i) std::memcpy(out->data() + i * comps, a.first + i * a.stride, comps);
  return Status::Ok();
}

}  // namespace atex::gltf

#endif  // ATEX_HAVE_TINYGLTF
