#include "container/attribute_stream.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "container/byte_io.h"

namespace atex::container {
namespace {

std::vector<float> RandomValues(size_t n, float lo, float hi, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = d(rng);
  return v;
}

std::vector<float> Decode(const std::vector<uint8_t>& raw, uint32_t c, uint64_t rows) {
  std::vector<float> out;
  const Status s = DecodeStream(raw.data(), raw.size(), c, rows, &out);
  EXPECT_TRUE(s.ok()) << s.ToString();
  return out;
}

TEST(AttributeStream, HeaderBytesFollowTheSpec) {
  const float values[] = {1.0f, -2.0f};
  auto raw = EncodeStream(values, 1, 2, ScalarEncoding::kFloat32, "x");
  ASSERT_TRUE(raw.ok());
  // §6: encoding 0, reserved, components 2 (LE u16), 4 reserved, rows 1 (LE u64), values.
  const std::vector<uint8_t> expected = {0, 0, 2, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0,
                                         0x00, 0x00, 0x80, 0x3F, 0x00, 0x00, 0x00, 0xC0};
  EXPECT_EQ(*raw, expected);
}

TEST(AttributeStream, Quant8HandComputed) {
  // One component, rows 0, 1, 0.5, 0.25: min 0, max 1,
  // q = floor(v * 255 + 0.5) = 0, 255, 128, 64.
  const float values[] = {0.0f, 1.0f, 0.5f, 0.25f};
  auto raw = EncodeStream(values, 4, 1, ScalarEncoding::kQuant8, "x");
  ASSERT_TRUE(raw.ok());
  ASSERT_EQ(raw->size(), 16u + 8u + 4u);
  EXPECT_EQ((*raw)[0], 3);
  EXPECT_EQ(LoadLE<float>(raw->data() + 16), 0.0f);
  EXPECT_EQ(LoadLE<float>(raw->data() + 20), 1.0f);
  EXPECT_EQ((std::vector<uint8_t>(raw->begin() + 24, raw->end())), (std::vector<uint8_t>{0, 255, 128, 64}));
  const auto back = Decode(*raw, 1, 4);
  EXPECT_EQ(back[0], 0.0f);
  EXPECT_EQ(back[1], 1.0f);
  EXPECT_EQ(back[2], static_cast<float>(128.0 / 255.0));
  EXPECT_EQ(back[3], static_cast<float>(64.0 / 255.0));
}

TEST(AttributeStream, Float32IsBitExact) {
  std::vector<float> v = RandomValues(300, -1e6f, 1e6f, 1);
  v[0] = -0.0f;
  v[1] = std::numeric_limits<float>::denorm_min();
  v[2] = std::numeric_limits<float>::max();
  auto raw = EncodeStream(v.data(), 100, 3, ScalarEncoding::kFloat32, "x");
  ASSERT_TRUE(raw.ok());
  const auto back = Decode(*raw, 3, 100);
  ASSERT_EQ(back.size(), v.size());
  EXPECT_EQ(std::memcmp(back.data(), v.data(), v.size() * 4), 0);
}

TEST(AttributeStream, Float16WithinHalfPrecision) {
  const auto v = RandomValues(4000, -100.0f, 100.0f, 2);
  auto raw = EncodeStream(v.data(), 1000, 4, ScalarEncoding::kFloat16, "x");
  ASSERT_TRUE(raw.ok());
  EXPECT_EQ(raw->size(), 16u + 8000u);
  const auto back = Decode(*raw, 4, 1000);
  for (size_t i = 0; i < v.size(); ++i) {
    // Relative error of round-to-nearest binary16 is at most 2^-11 (normal range).
    ASSERT_LE(std::fabs(back[i] - v[i]), std::fabs(v[i]) * std::ldexp(1.0f, -11) + std::ldexp(1.0f, -25)) << i;
  }
}

TEST(AttributeStream, QuantisedWithinHalfAStep) {
  for (ScalarEncoding e : {ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
    const double levels = e == ScalarEncoding::kQuant16 ? 65535.0 : 255.0;
    std::vector<float> v(3 * 500);
    std::mt19937 rng(3);
    for (size_t i = 0; i < v.size(); ++i) {
      const float scale = (i % 3 == 0) ? 1.0f : (i % 3 == 1) ? 100.0f : 0.001f;  // per-component ranges differ
      v[i] = scale * std::uniform_real_distribution<float>(-1, 1)(rng);
    }
    v[4] = 1000.0f;  // component 1's maximum
    auto raw = EncodeStream(v.data(), 500, 3, e, "x");
    ASSERT_TRUE(raw.ok());
    const auto back = Decode(*raw, 3, 500);
    for (uint32_t c = 0; c < 3; ++c) {
      float lo = v[c], hi = v[c];
      for (size_t r = 0; r < 500; ++r) {
        lo = std::min(lo, v[r * 3 + c]);
        hi = std::max(hi, v[r * 3 + c]);
      }
      const double step = (static_cast<double>(hi) - lo) / levels;
      for (size_t r = 0; r < 500; ++r) {
        const size_t i = r * 3 + c;
        ASSERT_LE(std::fabs(static_cast<double>(back[i]) - v[i]), step / 2 + std::fabs(v[i]) * 1.2e-7)
            << "encoding " << int(e) << " row " << r << " component " << c;
        ASSERT_GE(back[i], lo);
        ASSERT_LE(back[i], hi);
      }
    }
    EXPECT_EQ(back[4], 1000.0f);  // extremes are exact
  }
}

TEST(AttributeStream, ConstantComponentAndNoRows) {
  const float same[] = {2.5f, 2.5f, 2.5f};
  auto raw = EncodeStream(same, 3, 1, ScalarEncoding::kQuant8, "x");
  ASSERT_TRUE(raw.ok());
  EXPECT_EQ(Decode(*raw, 1, 3), (std::vector<float>{2.5f, 2.5f, 2.5f}));
  auto empty = EncodeStream(nullptr, 0, 4, ScalarEncoding::kQuant16, "x");
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->size(), 16u + 32u);
  EXPECT_TRUE(Decode(*empty, 4, 0).empty());
}

TEST(AttributeStream, EncodeRefusesNonFiniteAndHalfOverflow) {
  std::vector<float> v(12, 1.0f);
  v[7] = std::numeric_limits<float>::quiet_NaN();
  for (ScalarEncoding e :
       {ScalarEncoding::kFloat32, ScalarEncoding::kFloat16, ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
    auto raw = EncodeStream(v.data(), 4, 3, e, "rotations");
    ASSERT_FALSE(raw.ok());
    EXPECT_EQ(raw.status().code(), StatusCode::kOutOfRange);
    EXPECT_NE(raw.status().message().find("rotations row 2 component 1"), std::string::npos) << raw.status().message();
  }
  v[7] = 70000.0f;
  auto raw = EncodeStream(v.data(), 4, 3, ScalarEncoding::kFloat16, "texels");
  ASSERT_FALSE(raw.ok());
  EXPECT_EQ(raw.status().code(), StatusCode::kOutOfRange);
  EXPECT_NE(raw.status().message().find("texels row 2 component 1"), std::string::npos);
}

TEST(AttributeStream, DecodeRefusesBadHeaders) {
  const std::vector<float> v = RandomValues(12, -1, 1, 4);
  const auto good = *EncodeStream(v.data(), 4, 3, ScalarEncoding::kQuant16, "x");
  struct Damage {
    const char* name;
    size_t at;
    uint8_t value;
    StatusCode code;
  };
  const Damage damages[] = {
      {"encoding", 0, 4, StatusCode::kCorrupt},       {"reserved byte", 1, 1, StatusCode::kCorrupt},
      {"reserved word", 5, 1, StatusCode::kCorrupt},  {"components", 2, 4, StatusCode::kCorrupt},
      {"rows", 8, 5, StatusCode::kCorrupt},           {"rows high byte", 15, 0x80, StatusCode::kCorrupt},
      {"encoding f16", 0, 1, StatusCode::kCorrupt},   // size no longer matches
  };
  for (const Damage& d : damages) {
    auto raw = good;
    raw[d.at] = d.value;
    std::vector<float> out;
    EXPECT_EQ(DecodeStream(raw.data(), raw.size(), 3, 4, &out).code(), d.code) << d.name;
  }
  std::vector<float> out;
  EXPECT_EQ(DecodeStream(good.data(), good.size(), 4, 4, &out).code(), StatusCode::kCorrupt);  // components
  EXPECT_EQ(DecodeStream(good.data(), good.size(), 3, 5, &out).code(), StatusCode::kCorrupt);  // rows
  EXPECT_EQ(DecodeStream(good.data(), 10, 3, 4, &out).code(), StatusCode::kCorrupt);          // short header
  // Ranges: NaN and min > max.
  auto raw = good;
  StoreLE<float>(raw.data() + 16 + 8, std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(DecodeStream(raw.data(), raw.size(), 3, 4, &out).code(), StatusCode::kCorrupt);
  raw = good;
  StoreLE<float>(raw.data() + 16, 5.0f);
  StoreLE<float>(raw.data() + 20, 4.0f);
  EXPECT_EQ(DecodeStream(raw.data(), raw.size(), 3, 4, &out).code(), StatusCode::kCorrupt);
}

TEST(AttributeStream, DecodeRefusesNonFiniteValues) {
  const std::vector<float> v = RandomValues(12, -1, 1, 5);
  auto f32 = *EncodeStream(v.data(), 4, 3, ScalarEncoding::kFloat32, "x");
  StoreLE<float>(f32.data() + 16 + 4 * 10, std::numeric_limits<float>::infinity());
  std::vector<float> out;
  Status s = DecodeStream(f32.data(), f32.size(), 3, 4, &out);
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_NE(s.message().find("row 3 component 1"), std::string::npos) << s.message();
  auto f16 = *EncodeStream(v.data(), 4, 3, ScalarEncoding::kFloat16, "x");
  StoreLE<uint16_t>(f16.data() + 16 + 2 * 5, 0x7E00);
  s = DecodeStream(f16.data(), f16.size(), 3, 4, &out);
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_NE(s.message().find("row 1 component 2"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace atex::container
