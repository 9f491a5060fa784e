#include "gltf/meshopt_codec.h"

#ifdef ATEX_HAVE_MESHOPT
#include <meshoptimizer.h>
#endif

namespace atex::gltf {

const char* MeshoptFilterName(MeshoptFilter filter) {
  switch (filter) {
    case MeshoptFilter::kQuaternion: return "QUATERNION";
    case MeshoptFilter::kExponential: return "EXPONENTIAL";
    default: return "NONE";
  }
}

StatusOr<MeshoptFilter> ParseMeshoptFilter(const std::string& name) {
  if (name == "NONE") return MeshoptFilter::kNone;
  if (name == "QUATERNION") return MeshoptFilter::kQuaternion;
  if (name == "EXPONENTIAL") return MeshoptFilter::kExponential;
  if (name == "OCTAHEDRAL")
    return MakeError(StatusCode::kUnsupported, "meshopt filter OCTAHEDRAL is not used by splat data");
  return MakeError(StatusCode::kCorrupt, "unknown meshopt filter '", name, "'");
}

#ifdef ATEX_HAVE_MESHOPT

bool MeshoptAvailable() { return true; }

StatusOr<std::vector<uint8_t>> EncodeExponential(const float* data, size_t count, size_t components, int bits) {
  if (bits < 1 || bits > 24)
    return MakeError(StatusCode::kInvalidArgument, "exponential filter bits ", bits, " not in 1..24");
  std::vector<uint8_t> out(count * components * 4);  // [count][components] int32
  meshopt_encodeFilterExp(out.data(), count, components * 4, bits, data);
  return out;
}

StatusOr<std::vector<uint8_t>> EncodeQuaternion(const float* xyzw, size_t count, int bits) {
  if (bits < 4 || bits > 16)
    return MakeError(StatusCode::kInvalidArgument, "quaternion filter bits ", bits, " not in 4..16");
  std::vector<uint8_t> out(count * 8);  // [count][4] int16
  meshopt_encodeFilterQuat(out.data(), count, 8, bits, xyzw);
  return out;
}

Status DecodeFilter(MeshoptFilter filter, uint8_t* bytes, size_t count, size_t stride) {
  switch (filter) {
    case MeshoptFilter::kNone:
      return Status::Ok();
    case MeshoptFilter::kQuaternion:
      if (stride != 8) return MakeError(StatusCode::kCorrupt, "QUATERNION filter needs byteStride 8, got ", stride);
      meshopt_decodeFilterQuat(bytes, count, stride);
      return Status::Ok();
    case MeshoptFilter::kExponential:
      if (stride % 4 != 0)
        return MakeError(StatusCode::kCorrupt, "EXPONENTIAL filter needs byteStride % 4 == 0, got ", stride);
      meshopt_decodeFilterExp(bytes, count, stride);
      return Status::Ok();
  }
  return MakeError(StatusCode::kInternal, "unhandled meshopt filter");
}

StatusOr<std::vector<uint8_t>> CompressAttributes(const uint8_t* bytes, size_t count, size_t stride) {
  if (stride == 0 || stride % 4 != 0 || stride > 256) {
    return MakeError(StatusCode::kInvalidArgument, "meshopt ATTRIBUTES stride ", stride,
                     " must be a multiple of 4 <= 256");
  }
  std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, stride));
  const size_t size = meshopt_encodeVertexBuffer(out.data(), out.size(), bytes, count, stride);
  if (size == 0) return MakeError(StatusCode::kInternal, "meshopt_encodeVertexBuffer failed");
  out.resize(size);
  return out;
}

Status DecompressAttributes(const uint8_t* stream, size_t stream_size, size_t count, size_t stride, uint8_t* out) {
  if (stride == 0 || stride % 4 != 0 || stride > 256) {
    return MakeError(StatusCode::kCorrupt, "meshopt ATTRIBUTES byteStride ", stride, " must be a multiple of 4 <= 256");
  }
  const int rc = meshopt_decodeVertexBuffer(out, count, stride, stream, stream_size);
  if (rc != 0) return MakeError(StatusCode::kCorrupt, "meshopt attribute stream does not decode (code ", rc, ")");
  return Status::Ok();
}

#else  // !ATEX_HAVE_MESHOPT

bool MeshoptAvailable() { return false; }

static Status NoMeshopt() {
  return MakeError(StatusCode::kUnsupported, "EXT_meshopt_compression needs meshoptimizer, which this build lacks");
}
StatusOr<std::vector<uint8_t>> EncodeExponential(const float*, size_t, size_t, int) { return NoMeshopt(); }
StatusOr<std::vector<uint8_t>> EncodeQuaternion(const float*, size_t, int) { return NoMeshopt(); }
Status DecodeFilter(MeshoptFilter, uint8_t*, size_t, size_t) { return NoMeshopt(); }
StatusOr<std::vector<uint8_t>> CompressAttributes(const uint8_t*, size_t, size_t) { return NoMeshopt(); }
Status DecompressAttributes(const uint8_t*, size_t, size_t, size_t, uint8_t*) { return NoMeshopt(); }

#endif

}  // namespace atex::gltf
