// The compression of the `atex view` payload (view_codec.h).
#include "view/view_codec.h"

#include <zlib.h>

namespace atex::view {
namespace {

uint32_t Get(const uint8_t* data, size_t element_size, size_t i) {
  return element_size == 2 ? uint32_t(data[2 * i]) | uint32_t(data[2 * i + 1]) << 8 : data[i];
}

}  // namespace

StatusOr<std::vector<uint8_t>> CompressArray(const uint8_t* data, size_t element_size, size_t elements, size_t frames) {
  if (element_size != 1 && element_size != 2) {
    return MakeError(StatusCode::kInternal, "view: element size ", element_size, " is not 1 or 2");
  }
  const size_t count = elements * frames, mask = element_size == 2 ? 0xffff : 0xff;
  std::vector<uint8_t> planes(count * element_size);
  for (size_t i = 0; i < count; ++i) {
    const uint32_t v = Get(data, element_size, i);
    const uint32_t delta = i < elements ? v : uint32_t((v - Get(data, element_size, i - elements)) & mask);
    planes[i] = uint8_t(delta);
    if (element_size == 2) planes[count + i] = uint8_t(delta >> 8);
  }
  uLongf size = compressBound(uLong(planes.size()));
  std::vector<uint8_t> out(size);
  if (compress2(out.data(), &size, planes.data(), uLong(planes.size()), 6) != Z_OK) {
    return MakeError(StatusCode::kInternal, "view: zlib could not compress ", planes.size(), " bytes");
  }
  out.resize(size);
  return out;
}

StatusOr<std::vector<uint8_t>> DecompressArray(const std::vector<uint8_t>& compressed, size_t element_size,
                                               size_t elements, size_t frames, size_t expected_bytes) {
  const size_t count = elements * frames;
  if ((element_size != 1 && element_size != 2) || count * element_size != expected_bytes) {
    return MakeError(StatusCode::kCorrupt, "view payload: ", expected_bytes, " bytes do not hold ", count,
                     " elements of ", element_size, " bytes");
  }
  std::vector<uint8_t> planes(expected_bytes);
  uLongf size = uLongf(planes.size());
  const int rc = uncompress(planes.data(), &size, compressed.data(), uLong(compressed.size()));
  if (rc != Z_OK || size != planes.size()) {
    return MakeError(StatusCode::kCorrupt, "view payload: the deflate stream of ", compressed.size(),
                     " bytes does not inflate to ", expected_bytes, " bytes (zlib ", rc, ")");
  }
  const uint32_t mask = element_size == 2 ? 0xffff : 0xff;
  std::vector<uint8_t> out(expected_bytes);
  for (size_t i = 0; i < count; ++i) {
    uint32_t v = element_size == 2 ? uint32_t(planes[i]) | uint32_t(planes[count + i]) << 8 : planes[i];
    if (i >= elements) v = (v + Get(out.data(), element_size, i - elements)) & mask;
    out[i * element_size] = uint8_t(v);
    if (element_size == 2) out[i * element_size + 1] = uint8_t(v >> 8);
  }
  return out;
}

}  // namespace atex::view
