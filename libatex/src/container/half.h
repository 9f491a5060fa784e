// IEEE 754 binary16 <-> binary32 conversion in software, so that every build
// rounds the same way (round to nearest, ties to even; subnormals kept).
#pragma once

#include <cstdint>

namespace atex::container {

// Converts a finite float. Sets *overflow (and returns +-infinity) when the
// value rounds beyond the largest half, 65504 (|f| >= 65520).
uint16_t FloatToHalf(float value, bool* overflow);

// Exact conversion. Infinity and NaN halves come back as float infinity / NaN;
// callers that must refuse them check IsHalfFinite first.
float HalfToFloat(uint16_t half);

inline bool IsHalfFinite(uint16_t half) { return (half & 0x7C00u) != 0x7C00u; }

}  // namespace atex::container
