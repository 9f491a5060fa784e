// IEEE 754 binary16 <-> binary32, as GLSL's packHalf2x16 / unpackHalf2x16 do it
// (round to nearest even; overflow to infinity). Internal header.
#pragma once

#include <bit>
#include <cstdint>

namespace atex::splatv {

inline uint16_t FloatToHalf(float value) {
  const uint32_t f = std::bit_cast<uint32_t>(value);
  const uint32_t sign = (f >> 16) & 0x8000u;
  const uint32_t abs = f & 0x7fffffffu;
  if (abs >= 0x7f800000u) {  // inf or NaN
    return uint16_t(sign | 0x7c00u | (abs > 0x7f800000u ? 0x200u : 0u));
  }
  if (abs >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // rounds to >= 65520: infinity
  if (abs < 0x38800000u) {                                    // below the smallest normal half: subnormal or zero
    if (abs < 0x33000000u) return uint16_t(sign);              // < 2^-25 rounds to zero
    const uint32_t exponent = abs >> 23;
    const uint32_t mantissa = (abs & 0x7fffffu) | 0x800000u;
    const uint32_t shift = 126 - exponent;                     // 14 .. 24
    const uint32_t half_mantissa = mantissa >> shift;
    const uint32_t rest = mantissa & ((1u << shift) - 1);
    const uint32_t halfway = 1u << (shift - 1);
    uint32_t h = half_mantissa;
    if (rest > halfway || (rest == halfway && (h & 1u))) ++h;
    return uint16_t(sign | h);
  }
  uint32_t h = ((abs - 0x38000000u) >> 13);  // rebias exponent 127 -> 15
  const uint32_t rest = abs & 0x1fffu;
  if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) ++h;
  return uint16_t(sign | h);
}

inline float HalfToFloat(uint16_t h) {
  const uint32_t sign = uint32_t(h & 0x8000u) << 16;
  const uint32_t exponent = (h >> 10) & 0x1fu;
  uint32_t mantissa = h & 0x3ffu;
  if (exponent == 0) {
    if (mantissa == 0) return std::bit_cast<float>(sign);
    int e = -1;
    do {
      ++e;
      mantissa <<= 1;
    } while ((mantissa & 0x400u) == 0);
    return std::bit_cast<float>(sign | uint32_t(127 - 15 - e) << 23 | (mantissa & 0x3ffu) << 13);
  }
  if (exponent == 31) return std::bit_cast<float>(sign | 0x7f800000u | mantissa << 13);
  return std::bit_cast<float>(sign | (exponent + 127 - 15) << 23 | mantissa << 13);
}

// packHalf2x16(vec2(a, b)): a in the low 16 bits.
inline uint32_t PackHalf2(float a, float b) { return uint32_t(FloatToHalf(a)) | uint32_t(FloatToHalf(b)) << 16; }
inline float UnpackHalfLow(uint32_t v) { return HalfToFloat(uint16_t(v & 0xffffu)); }
inline float UnpackHalfHigh(uint32_t v) { return HalfToFloat(uint16_t(v >> 16)); }

}  // namespace atex::splatv
