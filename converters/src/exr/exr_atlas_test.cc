#include "atex/converters/exr_atlas.h"

#include <gtest/gtest.h>

#include <OpenEXR/ImfArray.h>
#include <OpenEXR/ImfRgbaFile.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <random>

#include "atex/file_io.h"
#include "core/test_support.h"
#include "exr/atlas_layout.h"

namespace atex {
namespace {

// A pool with random dims and axes; texel values are multiples of 1/256 in
// [-8, 8] (exact in half) unless `any_float`.
TexturePool RandomPool(size_t n, uint32_t seed, bool any_float = false) {
  std::mt19937 rng(seed);
  const uint8_t sides[3] = {1, 2, 4};
  TexturePool pool;
  pool.heights.resize(n);
  pool.widths.resize(n);
  pool.axis_u.resize(n);
  pool.axis_v.resize(n);
  for (size_t i = 0; i < n; ++i) {
    // Mostly 1x1, as after training, with some grown textures.
    const bool grown = rng() % 4 == 0;
    pool.heights[i] = grown ? sides[rng() % 3] : 1;
    pool.widths[i] = grown ? sides[rng() % 3] : 1;
    pool.axis_u[i] = static_cast<uint8_t>(rng() % 3);
    pool.axis_v[i] = static_cast<uint8_t>((pool.axis_u[i] + 1 + rng() % 2) % 3);
  }
  pool.RebuildOffsets();
  pool.texels.resize(pool.texel_count() * 4);
  std::uniform_real_distribution<float> u(-8.0f, 8.0f);
  for (float& t : pool.texels) t = any_float ? u(rng) : std::round(u(rng) * 256.0f) / 256.0f;
  return pool;
}

void ExpectSamePool(const TexturePool& a, const TexturePool& b) {
  EXPECT_EQ(a.heights, b.heights);
  EXPECT_EQ(a.widths, b.widths);
  EXPECT_EQ(a.axis_u, b.axis_u);
  EXPECT_EQ(a.axis_v, b.axis_v);
  EXPECT_EQ(a.offsets, b.offsets);
  ASSERT_EQ(a.texels.size(), b.texels.size());
  for (size_t i = 0; i < a.texels.size(); ++i) {
    ASSERT_EQ(std::bit_cast<uint32_t>(a.texels[i]), std::bit_cast<uint32_t>(b.texels[i])) << i;
  }
}

TEST(ExrAtlas, HalfRepresentableRoundTripIsExact) {
  const TexturePool pool = RandomPool(3000, 1);
  auto encoded = EncodeExrAtlas(pool);
  ASSERT_TRUE(encoded.ok()) << encoded.status().ToString();
  auto back = DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), encoded->sidecar_json);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSamePool(pool, *back);
  // Packing is dense: shelves of equal-height blocks leave little unused.
  const double used = static_cast<double>(pool.texel_count());
  EXPECT_GT(used / (double(encoded->width) * encoded->height), 0.8);
}

TEST(ExrAtlas, Float32TexelsAreRoundedToHalf) {
  const TexturePool pool = RandomPool(500, 2, /*any_float=*/true);
  auto encoded = EncodeExrAtlas(pool, {.width = 64});
  ASSERT_TRUE(encoded.ok());
  EXPECT_EQ(encoded->width, 64);
  auto back = DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), encoded->sidecar_json);
  ASSERT_TRUE(back.ok());
  for (size_t i = 0; i < pool.texels.size(); ++i) {
    // Round to nearest half: relative error <= 2^-11 for normal halves.
    ASSERT_NEAR(back->texels[i], pool.texels[i], std::fabs(pool.texels[i]) * std::ldexp(1.0, -11) + 1e-7) << i;
  }
  // A second export of the imported pool is lossless.
  auto again = EncodeExrAtlas(*back, {.width = 64});
  ASSERT_TRUE(again.ok());
  auto back2 = DecodeExrAtlas(again->exr.data(), again->exr.size(), again->sidecar_json);
  ASSERT_TRUE(back2.ok());
  ExpectSamePool(*back, *back2);
}

// Reads the written EXR with OpenEXR's own RGBA interface (not our reader) and checks
// that each texel sits at the pixel the sidecar names.
TEST(ExrAtlas, FilesMatchTheSidecarMapping) {
  const TexturePool pool = RandomPool(200, 3);
  testing::TempDir dir;
  const std::string path = (dir / "atlas.exr").string();
  ASSERT_TRUE(WriteExrAtlas(path, pool, {.width = 16}).ok());
  ASSERT_TRUE(std::filesystem::exists(ExrAtlasSidecarPath(path)));

  Imf::RgbaInputFile file(path.c_str());
  const Imath::Box2i window = file.dataWindow();
  const int width = window.max.x - window.min.x + 1, height = window.max.y - window.min.y + 1;
  EXPECT_EQ(width, 16);
  Imf::Array2D<Imf::Rgba> pixels(height, width);
  file.setFrameBuffer(&pixels[0][0], 1, width);
  file.readPixels(window.min.y, window.max.y);

  std::ifstream in(ExrAtlasSidecarPath(path));
  const auto sidecar = nlohmann::json::parse(in);
  ASSERT_EQ(sidecar["count"].get<size_t>(), pool.size());
  EXPECT_EQ(sidecar["atlas_height"].get<int>(), height);
  std::vector<int> owner(static_cast<size_t>(width) * height, -1);
  for (size_t i = 0; i < pool.size(); ++i) {
    const int x = sidecar["x"][i], y = sidecar["y"][i], h = sidecar["h"][i], w = sidecar["w"][i];
    EXPECT_EQ(h, pool.heights[i]);
    EXPECT_EQ(w, pool.widths[i]);
    EXPECT_EQ(sidecar["axis_u"][i].get<int>(), pool.axis_u[i]);
    EXPECT_EQ(sidecar["axis_v"][i].get<int>(), pool.axis_v[i]);
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        ASSERT_LT(x + u, width);
        ASSERT_LT(y + v, height);
        int& o = owner[static_cast<size_t>(y + v) * width + x + u];
        ASSERT_EQ(o, -1) << "blocks overlap at (" << x + u << ", " << y + v << ")";
        o = static_cast<int>(i);
        const float* t = &pool.texels[(pool.offsets[i] + v * w + u) * 4];
        const Imf::Rgba& p = pixels[y + v][x + u];
        EXPECT_EQ(float(p.r), t[0]);
        EXPECT_EQ(float(p.g), t[1]);
        EXPECT_EQ(float(p.b), t[2]);
        EXPECT_EQ(float(p.a), t[3]);
      }
    }
  }
  auto back = ReadExrAtlas(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSamePool(pool, *back);
}

TEST(ExrAtlas, EmptyPool) {
  TexturePool pool;
  pool.RebuildOffsets();
  auto encoded = EncodeExrAtlas(pool);
  ASSERT_TRUE(encoded.ok()) << encoded.status().ToString();
  auto back = DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), encoded->sidecar_json);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->size(), 0u);
}

TEST(ExrAtlas, ExportRefusesUnrepresentableTexels) {
  TexturePool pool = RandomPool(10, 4);
  pool.texels[13] = 1e6f;
  auto big = EncodeExrAtlas(pool);
  ASSERT_FALSE(big.ok());
  EXPECT_EQ(big.status().code(), StatusCode::kOutOfRange);
  pool.texels[13] = std::nanf("");
  EXPECT_EQ(EncodeExrAtlas(pool).status().code(), StatusCode::kOutOfRange);
  TexturePool bad = RandomPool(10, 4);
  bad.heights[3] = 3;
  EXPECT_EQ(EncodeExrAtlas(bad).status().code(), StatusCode::kInvalidArgument);
  TexturePool short_texels = RandomPool(10, 4);
  short_texels.texels.pop_back();
  EXPECT_EQ(EncodeExrAtlas(short_texels).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeExrAtlas(RandomPool(10, 4), {.width = 2}).status().code(), StatusCode::kInvalidArgument);
}

TEST(ExrAtlasHostile, SidecarProblems) {
  const TexturePool pool = RandomPool(20, 5);
  auto encoded = EncodeExrAtlas(pool, {.width = 8});
  ASSERT_TRUE(encoded.ok());
  const auto good = nlohmann::json::parse(encoded->sidecar_json);
  auto decode = [&](const nlohmann::json& sidecar) {
    return DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), sidecar.dump());
  };
  ASSERT_TRUE(decode(good).ok());
  struct Case {
    const char* what;
    std::function<void(nlohmann::json&)> mutate;
  };
  const Case cases[] = {
      {"block outside", [](nlohmann::json& j) { j["x"][3] = 7; j["w"][3] = 4; }},
      {"bad side", [](nlohmann::json& j) { j["h"][0] = 3; }},
      {"equal axes", [](nlohmann::json& j) { j["axis_v"][1] = j["axis_u"][1]; }},
      {"axis 3", [](nlohmann::json& j) { j["axis_u"][1] = 3; }},
      {"short array", [](nlohmann::json& j) { j["y"].erase(0); }},
      {"count", [](nlohmann::json& j) { j["count"] = 21; }},
      {"negative", [](nlohmann::json& j) { j["x"][0] = -1; }},
      {"string", [](nlohmann::json& j) { j["x"][0] = "0"; }},
      {"huge atlas", [](nlohmann::json& j) { j["atlas_width"] = 1 << 20; j["atlas_height"] = 1 << 20; }},
      {"size mismatch", [](nlohmann::json& j) { j["atlas_height"] = j["atlas_height"].get<int>() + 1; }},
      {"format", [](nlohmann::json& j) { j["format"] = "other"; }},
      {"version", [](nlohmann::json& j) { j["version"] = 2; }},
      {"missing", [](nlohmann::json& j) { j.erase("axis_u"); }},
  };
  for (const auto& c : cases) {
    nlohmann::json j = good;
    c.mutate(j);
    auto result = decode(j);
    ASSERT_FALSE(result.ok()) << c.what;
    EXPECT_FALSE(result.status().message().empty());
  }
  EXPECT_FALSE(DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), "{not json").ok());
  EXPECT_FALSE(DecodeExrAtlas(encoded->exr.data(), encoded->exr.size(), "[]").ok());
}

TEST(ExrAtlasHostile, ExrProblems) {
  const TexturePool pool = RandomPool(50, 6);
  auto encoded = EncodeExrAtlas(pool);
  ASSERT_TRUE(encoded.ok());
  const auto& exr = encoded->exr;
  EXPECT_EQ(DecodeExrAtlas(exr.data(), 3, encoded->sidecar_json).status().code(), StatusCode::kBadMagic);
  for (size_t cut = 4; cut < exr.size(); cut += 7) {
    auto result = DecodeExrAtlas(exr.data(), cut, encoded->sidecar_json);
    ASSERT_FALSE(result.ok()) << "cut " << cut;
  }
  std::mt19937 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    auto copy = exr;
    copy[4 + rng() % (copy.size() - 4)] ^= static_cast<uint8_t>(1 + rng() % 255);
    (void)DecodeExrAtlas(copy.data(), copy.size(), encoded->sidecar_json);  // must not crash
  }
  ExrAtlasReadOptions small;
  small.max_pixels = 16;
  EXPECT_EQ(DecodeExrAtlas(exr.data(), exr.size(), encoded->sidecar_json, small).status().code(),
            StatusCode::kLimitExceeded);
}

TEST(ExrAtlasLayout, ShelvesKeepBlocksApartAndInside) {
  using converters::exr::PackShelves;
  std::vector<uint8_t> h = {4, 1, 2, 1, 4, 4, 1, 2, 2, 1};
  std::vector<uint8_t> w = {4, 1, 2, 2, 1, 4, 4, 2, 1, 1};
  auto layout = PackShelves(h, w, 8);
  ASSERT_TRUE(layout.ok());
  std::vector<int> owner(static_cast<size_t>(8) * layout->height, -1);
  for (size_t i = 0; i < h.size(); ++i) {
    for (int v = 0; v < h[i]; ++v) {
      for (int u = 0; u < w[i]; ++u) {
        ASSERT_LT(layout->x[i] + u, 8u);
        ASSERT_LT(layout->y[i] + v, static_cast<uint32_t>(layout->height));
        int& o = owner[(layout->y[i] + v) * 8 + layout->x[i] + u];
        ASSERT_EQ(o, -1);
        o = static_cast<int>(i);
      }
    }
  }
  EXPECT_EQ(converters::exr::AutoAtlasWidth(1), 4);
  EXPECT_EQ(converters::exr::AutoAtlasWidth(1000000), 1000);
}

}  // namespace
}  // namespace atex
