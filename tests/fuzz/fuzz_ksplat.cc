// libFuzzer target: the GaussianSplats3D .ksplat reader (levels 0-2). Beyond "no
// crash": every decoded value is finite and the count is what the header says.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "atex/converters/web_splats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::WebSplatLimits limits;
  limits.max_gaussians = 1 << 20;
  auto g = atex::ReadKsplatGaussiansFromMemory(data, size, limits);
  if (!g.ok()) return 0;
  uint32_t total = 0;
  std::memcpy(&total, data + 16, 4);  // little-endian hosts only, as libFuzzer runs here
  if (g->size() != total) __builtin_trap();
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
  return 0;
}
