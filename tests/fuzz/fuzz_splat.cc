// libFuzzer target: the antimatter15 .splat reader. Beyond "no crash": every
// decoded value is finite and every rotation has unit length.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "atex/converters/web_splats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::WebSplatLimits limits;
  limits.max_gaussians = 1 << 20;
  auto g = atex::ReadSplatGaussiansFromMemory(data, size, limits);
  if (!g.ok()) return 0;
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
  for (size_t i = 0; i < g->size(); ++i) {
    const float* q = &g->rotations[i * 4];
    if (std::fabs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1) > 1e-4f) __builtin_trap();
  }
  return 0;
}
