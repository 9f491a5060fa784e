#include "container/half.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>

namespace atex::container {
namespace {

// Reference: the value of a half from its fields, by the IEEE 754 definition.
double HalfValue(uint16_t h) {
  const int sign = (h >> 15) ? -1 : 1;
  const int e = (h >> 10) & 31;
  const int m = h & 1023;
  if (e == 0) return sign * std::ldexp(m, -24);
  return sign * std::ldexp(1024 + m, e - 25);
}

TEST(Half, EveryFiniteHalfRoundTripsExactly) {
  for (uint32_t h = 0; h < 65536; ++h) {
    const auto half = static_cast<uint16_t>(h);
    if (!IsHalfFinite(half)) continue;
    const float f = HalfToFloat(half);
    ASSERT_EQ(static_cast<double>(f), HalfValue(half)) << std::hex << h;
    bool overflow = true;
    ASSERT_EQ(FloatToHalf(f, &overflow), half) << std::hex << h;
    ASSERT_FALSE(overflow);
  }
}

TEST(Half, NonFiniteHalvesAreReported) {
  EXPECT_FALSE(IsHalfFinite(0x7C00));
  EXPECT_FALSE(IsHalfFinite(0xFC00));
  EXPECT_FALSE(IsHalfFinite(0x7E00));
  EXPECT_TRUE(std::isinf(HalfToFloat(0x7C00)));
  EXPECT_TRUE(std::isnan(HalfToFloat(0x7E01)));
}

// Round to nearest, ties to even, checked against the exact midpoints.
TEST(Half, RoundsToNearestEven) {
  bool overflow = false;
  // 1 + 2^-11 is halfway between 1 and 1 + 2^-10: ties to even (1.0 = 0x3C00).
  EXPECT_EQ(FloatToHalf(1.0f + std::ldexp(1.0f, -11), &overflow), 0x3C00);
  // 1 + 3*2^-11 is halfway between 0x3C01 and 0x3C02: even is 0x3C02.
  EXPECT_EQ(FloatToHalf(1.0f + 3 * std::ldexp(1.0f, -11), &overflow), 0x3C02);
  // Just above the midpoint rounds up.
  EXPECT_EQ(FloatToHalf(std::nextafter(1.0f + std::ldexp(1.0f, -11), 2.0f), &overflow), 0x3C01);
  // Subnormals: 2^-25 is half the smallest subnormal -> 0; a bit more -> 1 ulp.
  EXPECT_EQ(FloatToHalf(std::ldexp(1.0f, -25), &overflow), 0x0000);
  EXPECT_EQ(FloatToHalf(std::nextafter(std::ldexp(1.0f, -25), 1.0f), &overflow), 0x0001);
  EXPECT_EQ(FloatToHalf(3 * std::ldexp(1.0f, -25), &overflow), 0x0002);  // 1.5 ulp ties to even 2
  EXPECT_EQ(FloatToHalf(-std::ldexp(1.0f, -24), &overflow), 0x8001);
  // Largest subnormal rounding up into the smallest normal.
  EXPECT_EQ(FloatToHalf(std::ldexp(1.0f, -14) - std::ldexp(1.0f, -26), &overflow), 0x0400);
  EXPECT_FALSE(overflow);
  EXPECT_EQ(FloatToHalf(-0.0f, &overflow), 0x8000);
}

TEST(Half, OverflowThreshold) {
  bool overflow = false;
  EXPECT_EQ(FloatToHalf(65504.0f, &overflow), 0x7BFF);
  EXPECT_FALSE(overflow);
  EXPECT_EQ(FloatToHalf(std::nextafter(65520.0f, 0.0f), &overflow), 0x7BFF);
  EXPECT_FALSE(overflow);
  FloatToHalf(65520.0f, &overflow);
  EXPECT_TRUE(overflow);
  FloatToHalf(-1e10f, &overflow);
  EXPECT_TRUE(overflow);
}

TEST(Half, NearestForRandomFloats) {
  // For floats within range, the result is one of the two neighbouring halves and
  // the nearer one.
  uint32_t state = 12345;
  for (int i = 0; i < 200000; ++i) {
    state = state * 1664525u + 1013904223u;
    const float f = std::bit_cast<float>((state & 0x807FFFFFu) | ((100u + (state >> 24) % 43u) << 23));
    if (std::fabs(f) >= 65504.0f) continue;
    bool overflow = false;
    const uint16_t h = FloatToHalf(f, &overflow);
    ASSERT_FALSE(overflow);
    const double err = std::fabs(HalfValue(h) - f);
    const uint16_t up = static_cast<uint16_t>(h + 1), down = static_cast<uint16_t>(h - 1);
    if ((h & 0x7FFF) != 0x7BFF) {
      ASSERT_LE(err, std::fabs(HalfValue(up) - f)) << f;
    }
    if ((h & 0x7FFF) != 0) {
      ASSERT_LE(err, std::fabs(HalfValue(down) - f)) << f;
    }
  }
}

}  // namespace
}  // namespace atex::container
