// libFuzzer target: the PlayCanvas SOG reader, on .sog bundles (zip of meta.json
// and WebP images). Beyond "no crash": every decoded value is finite.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "atex/converters/web_splats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::WebSplatLimits limits;
  limits.max_gaussians = 1 << 16;  // images of this size decode well under libFuzzer's -rss_limit_mb
  auto g = atex::ReadSogBundleFromMemory(data, size, limits);
  if (!g.ok()) return 0;
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
  return 0;
}
