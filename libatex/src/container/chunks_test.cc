#include "container/chunks.h"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>

#include "container/byte_io.h"

namespace atex::container {
namespace {

TEST(TextureLayout, EveryByteValue) {
  // §7.4, checked independently for all 256 bytes.
  for (int b = 0; b < 256; ++b) {
    const int lh = b & 3, lw = (b >> 2) & 3, u = (b >> 4) & 3, v = (b >> 6) & 3;
    const bool valid = lh != 3 && lw != 3 && u != 3 && v != 3 && u != v;
    const uint8_t byte = static_cast<uint8_t>(b);
    TexturePool t;
    const Status s = DecodeTextureLayout(&byte, 1, 1, &t);
    ASSERT_EQ(s.ok(), valid) << b << ": " << s.ToString();
    if (!valid) {
      EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
      continue;
    }
    EXPECT_EQ(t.heights[0], 1 << lh);
    EXPECT_EQ(t.widths[0], 1 << lw);
    EXPECT_EQ(t.axis_u[0], u);
    EXPECT_EQ(t.axis_v[0], v);
    EXPECT_EQ(t.offsets, (std::vector<uint64_t>{0, uint64_t(1) << (lh + lw)}));
    EXPECT_EQ(EncodeTextureLayout(t), std::vector<uint8_t>{byte});
  }
}

TEST(TextureLayout, OffsetsArePrefixSumsAndErrorsNameTheGaussian) {
  // 1x1, 4x2 (h=4: log2 2, w=2: log2 1), 2x4: offsets 0, 1, 9, 17.
  const std::vector<uint8_t> bytes = {0x10, 0x06 | 0x20, 0x09 | 0x90};
  TexturePool t;
  ASSERT_TRUE(DecodeTextureLayout(bytes.data(), bytes.size(), 3, &t).ok());
  EXPECT_EQ(t.offsets, (std::vector<uint64_t>{0, 1, 9, 17}));
  EXPECT_EQ(t.heights, (std::vector<uint8_t>{1, 4, 2}));
  EXPECT_EQ(t.widths, (std::vector<uint8_t>{1, 2, 4}));
  const std::vector<uint8_t> bad = {0x10, 0x10, 0x13};  // Gaussian 2: log2 h = 3
  const Status s = DecodeTextureLayout(bad.data(), bad.size(), 3, &t);
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_NE(s.message().find("Gaussian 2"), std::string::npos);
  EXPECT_EQ(DecodeTextureLayout(bytes.data(), bytes.size(), 4, &t).code(), StatusCode::kCorrupt);
}

DeformationConfig SampleConfig() {
  DeformationConfig c;
  c.grid.channels = 16;
  c.grid.base_resolution = {64, 32, 48, 150};
  c.grid.multires = {1, 2, 4};
  c.mlp_width = 128;
  c.trunk_layers = 2;
  c.heads = {true, false, true, true, true};
  c.sh_coeffs = 16;
  c.aabb_lo = {1.5f, -2.0f, 3.0f};
  c.aabb_hi = {-1.5f, 2.0f, -3.0f};  // lo > hi allowed (4DGaussians' order)
  c.time_scale = 1.0f;
  c.time_offset = 0.0f;
  return c;
}

TEST(DeformationConfigChunk, LayoutAndRoundTrip) {
  const DeformationConfig c = SampleConfig();
  const auto bytes = EncodeDeformationConfig(c);
  ASSERT_EQ(bytes.size(), 104u);
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 0), 16u);
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 16), 150u);
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 20), 3u);
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 32), 4u);  // multires[2]
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 36), 0u);  // unused multires[3]
  EXPECT_EQ(LoadLE<uint32_t>(bytes.data() + 64), 0x1Du);  // heads 0, 2, 3, 4
  EXPECT_EQ(LoadLE<float>(bytes.data() + 84), -1.5f);
  auto back = DecodeDeformationConfig(bytes.data(), bytes.size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->grid.channels, c.grid.channels);
  EXPECT_EQ(back->grid.base_resolution, c.grid.base_resolution);
  EXPECT_EQ(back->grid.multires, c.grid.multires);
  EXPECT_EQ(back->mlp_width, c.mlp_width);
  EXPECT_EQ(back->trunk_layers, c.trunk_layers);
  EXPECT_EQ(back->heads, c.heads);
  EXPECT_EQ(back->sh_coeffs, c.sh_coeffs);
  EXPECT_EQ(back->aabb_lo, c.aabb_lo);
  EXPECT_EQ(back->aabb_hi, c.aabb_hi);
  EXPECT_EQ(back->time_scale, c.time_scale);
  EXPECT_EQ(back->time_offset, c.time_offset);
}

TEST(DeformationConfigChunk, RangeChecks) {
  const auto good = EncodeDeformationConfig(SampleConfig());
  struct Edit {
    const char* name;
    size_t at;
    uint32_t value;
    StatusCode code;
  };
  const Edit edits[] = {
      {"channels 0", 0, 0, StatusCode::kOutOfRange},         {"channels big", 0, 1025, StatusCode::kOutOfRange},
      {"res x 0", 4, 0, StatusCode::kOutOfRange},            {"res t big", 16, 9000, StatusCode::kOutOfRange},
      {"scales 0", 20, 0, StatusCode::kOutOfRange},          {"scales 9", 20, 9, StatusCode::kOutOfRange},
      {"multires 0", 24, 0, StatusCode::kOutOfRange},        {"multires 65", 28, 65, StatusCode::kOutOfRange},
      {"multires 256", 32, 256, StatusCode::kOutOfRange},
      {"unused multires", 40, 1, StatusCode::kCorrupt},      {"width 0", 56, 0, StatusCode::kOutOfRange},
      {"trunk 0", 60, 0, StatusCode::kOutOfRange},           {"trunk 65", 60, 65, StatusCode::kOutOfRange},
      {"head bit 5", 64, 0x3F, StatusCode::kOutOfRange},     {"sh coeffs 5", 68, 5, StatusCode::kOutOfRange},
      {"aabb nan", 72, 0x7FC00000u, StatusCode::kOutOfRange}, {"aabb equal", 84, 0x3FC00000u, StatusCode::kOutOfRange},
      {"time inf", 96, 0x7F800000u, StatusCode::kOutOfRange},
  };
  for (const Edit& e : edits) {
    auto bytes = good;
    StoreLE<uint32_t>(bytes.data() + e.at, e.value);
    const auto s = DecodeDeformationConfig(bytes.data(), bytes.size()).status();
    EXPECT_EQ(s.code(), e.code) << e.name << ": " << s.ToString();
  }
  // Spatial resolution above 65536: base 8192 (x) with multires 16.
  auto bytes = good;
  StoreLE<uint32_t>(bytes.data() + 4, 8192);
  StoreLE<uint32_t>(bytes.data() + 32, 16);
  EXPECT_EQ(DecodeDeformationConfig(bytes.data(), bytes.size()).status().code(), StatusCode::kOutOfRange);
  EXPECT_EQ(DecodeDeformationConfig(good.data(), 103).status().code(), StatusCode::kCorrupt);
}

TEST(DeformationStreams, CountsFollowTheSpec) {
  DeformationConfig c;
  c.grid.channels = 2;
  c.grid.base_resolution = {3, 4, 5, 6};
  c.grid.multires = {1, 2};
  c.mlp_width = 8;
  c.trunk_layers = 2;
  c.heads = {true, false, false, true, true};
  c.sh_coeffs = 4;
  // Scale 0: xy 3*4, xz 3*5, xt 3*6, yz 4*5, yt 4*6, zt 5*6 = 12+15+18+20+24+30 = 119.
  // Scale 1: x 6, y 8, z 10: 48+60+36+80+48+60 = 332. Times C = 2: 902.
  EXPECT_EQ(GridValueCount(c), 902u);
  // Trunk: (4 -> 8) 40, (8 -> 8) 72. Heads 0, 3, 4: each 72 + (8 -> out): 27, 9, 108.
  EXPECT_EQ(MlpValueCount(c), 40u + 72u + 3 * 72u + 27u + 9u + 108u);
}

TEST(MetaChunk, RoundTripAndLimits) {
  Metadata m;
  m.texture_mode = "adaptive";
  m.extra = {{"note", "caf\xC3\xA9"}};
  auto bytes = EncodeMeta(m);
  ASSERT_TRUE(bytes.ok());
  const std::string text(bytes->begin(), bytes->end());
  EXPECT_EQ(text.front(), '{');
  EXPECT_NE(text.find("caf\xC3\xA9"), std::string::npos);  // UTF-8, not \u escapes
  EXPECT_LT(text.find("\"axes\""), text.find("\"background\""));  // sorted keys
  auto back = DecodeMeta(bytes->data(), bytes->size());
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->extra, m.extra);

  std::string deep(65, '[');
  deep += std::string(65, ']');
  auto s = DecodeMeta(reinterpret_cast<const uint8_t*>(deep.data()), deep.size()).status();
  EXPECT_EQ(s.code(), StatusCode::kLimitExceeded);
  std::string deep_in_string = "{\"extra\":{\"s\":\"" + std::string(100, '[') + "\"}}";
  EXPECT_TRUE(DecodeMeta(reinterpret_cast<const uint8_t*>(deep_in_string.data()), deep_in_string.size()).ok());
  const std::string bom = "\xEF\xBB\xBF{}";
  EXPECT_EQ(DecodeMeta(reinterpret_cast<const uint8_t*>(bom.data()), bom.size()).status().code(), StatusCode::kCorrupt);
  const std::string broken = "{\"axes\": ";
  EXPECT_EQ(DecodeMeta(reinterpret_cast<const uint8_t*>(broken.data()), broken.size()).status().code(),
            StatusCode::kCorrupt);
  const std::string bad_utf8 = "{\"units\": \"\xC3\x28\"}";
  EXPECT_EQ(DecodeMeta(reinterpret_cast<const uint8_t*>(bad_utf8.data()), bad_utf8.size()).status().code(),
            StatusCode::kCorrupt);
}

TEST(GaussianHeaderChunk, LayoutAndChecks) {
  const auto bytes = EncodeGhdr({0x0102030405ull, 3});
  EXPECT_EQ(bytes, (std::vector<uint8_t>{5, 4, 3, 2, 1, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0}));
  auto h = DecodeGhdr(bytes.data(), bytes.size());
  ASSERT_TRUE(h.ok());
  EXPECT_EQ(h->count, 0x0102030405ull);
  EXPECT_EQ(h->sh_degree, 3);
  auto bad = bytes;
  bad[8] = 4;
  EXPECT_EQ(DecodeGhdr(bad.data(), bad.size()).status().code(), StatusCode::kOutOfRange);
  bad = bytes;
  bad[15] = 1;
  EXPECT_EQ(DecodeGhdr(bad.data(), bad.size()).status().code(), StatusCode::kCorrupt);
  EXPECT_EQ(DecodeGhdr(bytes.data(), 15).status().code(), StatusCode::kCorrupt);
}

}  // namespace
}  // namespace atex::container
