// libFuzzer target: the EXR texel-atlas reader (OpenEXR image + JSON sidecar).
//
// Input layout: u16 little-endian sidecar length L, L bytes of sidecar JSON, then
// the EXR bytes. Properties checked beyond "no crash": an accepted atlas gives a
// consistent texture pool with finite texels, and re-exporting it and importing
// the result gives the same pool bit for bit (its texels are halves already).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string_view>

#include "atex/converters/exr_atlas.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const size_t json_size = std::min<size_t>(data[0] | (data[1] << 8), size - 2);
  const std::string_view sidecar(reinterpret_cast<const char*>(data + 2), json_size);
  const uint8_t* exr = data + 2 + json_size;
  const size_t exr_size = size - 2 - json_size;
  atex::ExrAtlasReadOptions options;
  options.max_pixels = 1 << 22;  // keep under libFuzzer's -rss_limit_mb
  options.max_gaussians = 1 << 20;
  auto pool = atex::DecodeExrAtlas(exr, exr_size, sidecar, options);
  if (!pool.ok()) return 0;
  if (pool->texels.size() != pool->texel_count() * atex::kTexelChannels) __builtin_trap();
  for (float t : pool->texels) {
    if (!std::isfinite(t)) __builtin_trap();
  }
  auto encoded = atex::EncodeExrAtlas(*pool);
  if (!encoded.ok()) __builtin_trap();  // the writer refuses what the reader accepted
  auto again = atex::DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), encoded->sidecar_json, options);
  if (!again.ok()) __builtin_trap();
  if (again->heights != pool->heights || again->axis_u != pool->axis_u || again->axis_v != pool->axis_v ||
      again->texels.size() != pool->texels.size() ||
      (!pool->texels.empty() &&
       std::memcmp(again->texels.data(), pool->texels.data(), pool->texels.size() * sizeof(float)) != 0)) {
    __builtin_trap();
  }
  return 0;
}
