// libFuzzer target: PlayCanvas compressed PLY, through the PLY reader (which
// recognises the packed_position layout). Beyond "no crash": every decoded value
// is finite (non-finite chunk bounds are refused).
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "atex/converters/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto g = atex::ReadPlyGaussiansFromMemory(data, size);
  if (!g.ok()) return 0;
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();
    }
  }
  return 0;
}
