// libFuzzer target: the 3DGS PLY reader (binary LE/BE and ASCII).
//
// Properties checked beyond "no crash": Gaussians the reader accepts are finite
// (it refuses NaN/Inf), the writer accepts them, and PLY -> Gaussians -> PLY ->
// Gaussians is bit-exact (the writer's bytes read back to the same bytes).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/converters/ply.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto g = atex::ReadPlyGaussiansFromMemory(data, size);
  if (!g.ok()) return 0;
  for (const auto* array : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    for (float v : *array) {
      if (!std::isfinite(v)) __builtin_trap();  // the reader let a non-finite value through
    }
  }
  auto bytes = atex::EncodePlyGaussians(*g);
  if (!bytes.ok()) __builtin_trap();  // the writer refuses what the reader accepted
  auto again = atex::ReadPlyGaussiansFromMemory(bytes->data(), bytes->size());
  if (!again.ok()) __builtin_trap();  // the writer produced an unreadable file
  auto twice = atex::EncodePlyGaussians(*again);
  if (!twice.ok() || *twice != *bytes) __builtin_trap();  // the round trip is not bit-exact
  return 0;
}
