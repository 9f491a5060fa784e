// libFuzzer target: the .npz reader (zip central directory, stored/deflate
// members, .npy headers) and the bare .npy parser on the same bytes.
// Properties checked beyond "no crash": every accepted array holds exactly
// element_count × dtype-size bytes, and re-encoding it parses back identically.
#include <cstddef>
#include <cstdint>

#include "atex/npy.h"

namespace {

void CheckArray(const atex::NpyArray& array) {
  if (array.data.size() != array.element_count() * atex::NpyDtypeSize(array.dtype)) __builtin_trap();
  const std::vector<uint8_t> again = atex::EncodeNpy(array);
  auto back = atex::DecodeNpy(again.data(), again.size(), "re-encoded");
  if (!back.ok() || back->shape != array.shape || back->data != array.data || back->dtype != array.dtype) {
    __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::ZipLimits limits;
  limits.max_member_bytes = uint64_t{64} << 20;  // keep under libFuzzer's -rss_limit_mb
  auto arrays = atex::DecodeNpz(data, size, "fuzz.npz", limits);
  if (arrays.ok()) {
    for (const auto& [name, array] : *arrays) CheckArray(array);
  }
  auto array = atex::DecodeNpy(data, size, "fuzz.npy");
  if (array.ok()) CheckArray(*array);
  return 0;
}
