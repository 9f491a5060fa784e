// Texture pools: attachment axes, corner-aligned growth (exact reproduction of the
// bilinear field, Adam moments alongside) and the growth invariance of renders.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "atex/detail/texture.h"
#include "atex/render.h"
#include "render/render_test_util.h"

namespace atex {
namespace {

TEST(AttachTextures, AxesFollowTheCanonicalScales) {
  Gaussians g;
  g.sh_degree = 0;
  // log scales per Gaussian, expected (axis_u, axis_v)
  const std::vector<std::pair<std::array<float, 3>, std::pair<int, int>>> cases = {
      {{0.1f, 0.5f, 0.3f}, {1, 2}},   // largest y, then z
      {{0.9f, -1.0f, 0.2f}, {0, 2}},
      {{-2.0f, -1.0f, 0.0f}, {2, 1}},
      {{0.2f, 0.2f, 0.1f}, {0, 1}},   // tie for largest: lower index first
      {{0.1f, 0.3f, 0.3f}, {1, 2}},
      {{0.3f, 0.1f, 0.3f}, {0, 2}},
      {{0.5f, 0.5f, 0.5f}, {0, 1}},
      {{0.4f, 0.1f, 0.1f}, {0, 1}},   // tie for second: lower index
  };
  g.Resize(cases.size());
  for (size_t i = 0; i < cases.size(); ++i)
    for (int k = 0; k < 3; ++k) g.log_scales[3 * i + k] = std::log(std::exp(cases[i].first[k]));
  for (TextureMode mode : {TextureMode::kUniform, TextureMode::kAdaptive}) {
    auto pool = AttachTextures(g, mode);
    ASSERT_TRUE(pool.ok()) << pool.status().ToString();
    ASSERT_TRUE(ValidateTexturePool(*pool, g.size()).ok());
    const int side = mode == TextureMode::kUniform ? 4 : 1;
    for (size_t i = 0; i < cases.size(); ++i) {
      EXPECT_EQ(pool->axis_u[i], cases[i].second.first) << i;
      EXPECT_EQ(pool->axis_v[i], cases[i].second.second) << i;
      EXPECT_EQ(pool->heights[i], side);
      EXPECT_EQ(pool->widths[i], side);
    }
    EXPECT_EQ(pool->texels.size(), cases.size() * side * side * 4);
    for (float t : pool->texels) EXPECT_EQ(t, 0.0f);
  }
  EXPECT_EQ(AttachTextures(g, TextureMode::kNone).status().code(), StatusCode::kInvalidArgument);
  g.log_scales[4] = std::nanf("");
  EXPECT_EQ(AttachTextures(g, TextureMode::kAdaptive).status().code(), StatusCode::kOutOfRange);
}

TEST(TextureMode, NamesRoundTrip) {
  for (TextureMode mode : {TextureMode::kNone, TextureMode::kUniform, TextureMode::kAdaptive}) {
    auto parsed = ParseTextureMode(TextureModeName(mode));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, mode);
  }
  EXPECT_FALSE(ParseTextureMode("4x4").ok());
}

// Bilinear field of one [h][w][4] texture at (u, v) in [-1, 1]², channel c.
double Field(const std::vector<double>& texels, int h, int w, double u, double v, int c) {
  detail::TexCoord<double> tc{u, v, false, false};
  return detail::SampleTexels(texels.data(), w, detail::MakeBilinearTaps(tc, h, w))[c];
}

TEST(UpsampleTexture, GrowthReproducesTheBilinearFieldExactly) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> value(-2, 2), coord(-1, 1);
  const int sides[] = {1, 2, 4};
  for (int h : sides) {
    for (int w : sides) {
      for (int h2 : sides) {
        for (int w2 : sides) {
          if (h2 < h || w2 < w) continue;
          std::vector<double> src(size_t(h) * w * 4), dst(size_t(h2) * w2 * 4);
          for (double& v : src) v = value(rng);
          detail::UpsampleTexture(src.data(), h, w, dst.data(), h2, w2, 4);
          double max_diff = 0;
          for (int k = 0; k < 200; ++k) {
            const double u = k == 0 ? -1 : (k == 1 ? 1 : coord(rng)), v = k == 0 ? 1 : coord(rng);
            for (int c = 0; c < 4; ++c)
              max_diff = std::max(max_diff, std::abs(Field(src, h, w, u, v, c) - Field(dst, h2, w2, u, v, c)));
          }
          EXPECT_LT(max_diff, 1e-12) << h << "x" << w << " -> " << h2 << "x" << w2;
        }
      }
    }
  }
}

TEST(UpsampleTexture, KnownValues) {
  // 1x2 (values 0 and 3 along u) -> 1x4: 0, 1, 2, 3.
  const double src[8] = {0, 0, 0, 0, 3, 6, -3, 1};
  double dst[16];
  detail::UpsampleTexture(src, 1, 2, dst, 1, 4, 4);
  for (int x = 0; x < 4; ++x) {
    EXPECT_DOUBLE_EQ(dst[4 * x], x);
    EXPECT_DOUBLE_EQ(dst[4 * x + 1], 2 * x);
    EXPECT_DOUBLE_EQ(dst[4 * x + 2], -x);
    EXPECT_DOUBLE_EQ(dst[4 * x + 3], x / 3.0);
  }
  // 1x1 -> 2x2: constant.
  const double one[4] = {1, 2, 3, 4};
  double four[16];
  detail::UpsampleTexture(one, 1, 1, four, 2, 2, 4);
  for (int k = 0; k < 16; ++k) EXPECT_EQ(four[k], one[k % 4]);
}

TEST(ResizeTextures, ResamplesTexelsAndExtraArrays) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> value(-1, 1);
  Gaussians g;
  g.Resize(4);
  auto attached = AttachTextures(g, TextureMode::kAdaptive);
  ASSERT_TRUE(attached.ok());
  TexturePool pool = *attached;
  pool.heights = {1, 2, 1, 4};
  pool.widths = {2, 2, 1, 1};
  pool.RebuildOffsets();
  pool.texels.resize(pool.texel_count() * 4);
  for (float& v : pool.texels) v = value(rng);
  std::vector<float> m1(pool.texels.size()), m2(pool.texels.size());
  for (float& v : m1) v = value(rng);
  for (float& v : m2) v = value(rng);
  const std::vector<float> m1_old = m1;
  const std::vector<uint8_t> heights = {1, 4, 2, 4}, widths = {4, 2, 2, 1};
  std::vector<float>* extra[] = {&m1, &m2};
  auto grown = ResizeTextures<float>(pool, heights, widths, extra);
  ASSERT_TRUE(grown.ok()) << grown.status().ToString();
  ASSERT_TRUE(ValidateTexturePool(*grown, 4).ok());
  EXPECT_EQ(grown->heights, heights);
  EXPECT_EQ(grown->widths, widths);
  EXPECT_EQ(grown->axis_u, pool.axis_u);
  ASSERT_EQ(m1.size(), grown->texels.size());
  ASSERT_EQ(m2.size(), grown->texels.size());
  // Gaussian 0 (1x2 -> 1x4): the moments follow the same corner-aligned rule.
  for (int c = 0; c < 4; ++c) {
    EXPECT_FLOAT_EQ(m1[c], m1_old[c]);
    EXPECT_FLOAT_EQ(m1[4 + c], (2 * m1_old[c] + m1_old[4 + c]) / 3);
    EXPECT_FLOAT_EQ(m1[12 + c], m1_old[4 + c]);
  }
  // Bad requests.
  const std::vector<uint8_t> bad = {1, 3, 1, 1};
  EXPECT_EQ(ResizeTextures<float>(pool, bad, widths).status().code(), StatusCode::kOutOfRange);
  const std::vector<uint8_t> short_list = {1, 1};
  EXPECT_EQ(ResizeTextures<float>(pool, short_list, widths).status().code(), StatusCode::kInvalidArgument);
  std::vector<float> wrong(3);
  std::vector<float>* bad_extra[] = {&wrong};
  EXPECT_EQ(ResizeTextures<float>(pool, heights, widths, bad_extra).status().code(), StatusCode::kInvalidArgument);
}

// The requirement: growing textures (1→2, 2→4, one or both axes) leaves every
// rendered pixel unchanged up to float rounding (≤ 1e-5).
TEST(ResizeTextures, GrowthLeavesTheRenderUnchanged) {
  std::mt19937 rng(21);
  const Camera camera = render_testing::RandomCamera(64, 48, rng);
  render_testing::SceneOptions options;
  options.count = 300;
  const auto g = render_testing::RandomGaussians<float>(camera, options, rng);
  auto pool = render_testing::RandomTextures(g, render_testing::TextureKind::kAdaptiveMixed, 1.5, rng);
  RenderSettings settings;
  settings.background = {0.2f, 0.4f, 0.6f};
  auto before = RenderForward(camera, g, &pool, settings);
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  std::vector<uint8_t> heights = pool.heights, widths = pool.widths;
  std::uniform_int_distribution<int> pick(0, 3);
  int grown_u = 0, grown_v = 0, grown_both = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    const int choice = pick(rng);  // 0: keep, 1: u only, 2: v only, 3: both
    const bool grow_u = (choice == 1 || choice == 3) && widths[i] < 4;
    const bool grow_v = (choice == 2 || choice == 3) && heights[i] < 4;
    if (grow_u) widths[i] *= 2;
    if (grow_v) heights[i] *= 2;
    grown_u += grow_u && !grow_v;
    grown_v += grow_v && !grow_u;
    grown_both += grow_u && grow_v;
  }
  EXPECT_GT(grown_u, 20);
  EXPECT_GT(grown_v, 20);
  EXPECT_GT(grown_both, 20);
  auto grown = ResizeTextures<float>(pool, heights, widths);
  ASSERT_TRUE(grown.ok()) << grown.status().ToString();
  EXPECT_GT(grown->texel_count(), pool.texel_count());
  auto after = RenderForward(camera, g, &*grown, settings);
  ASSERT_TRUE(after.ok());
  float max_diff = 0, max_value = 0;
  for (size_t k = 0; k < before->color.size(); ++k) {
    max_diff = std::max(max_diff, std::abs(before->color[k] - after->color[k]));
    max_value = std::max(max_value, std::abs(before->color[k] - settings.background[k % 3]));
  }
  EXPECT_LE(max_diff, 1e-5f);
  EXPECT_GT(max_value, 0.3f);  // the scene does cover the image
  std::printf("[growth] %d u-only, %d v-only, %d both: max |pixel difference| %.3g\n", grown_u, grown_v, grown_both,
              max_diff);
  // A second growth step (2→4 everywhere possible) as well.
  std::vector<uint8_t> full_h(g.size(), 4), full_w(g.size(), 4);
  auto full = ResizeTextures<float>(*grown, full_h, full_w);
  ASSERT_TRUE(full.ok());
  auto after_full = RenderForward(camera, g, &*full, settings);
  ASSERT_TRUE(after_full.ok());
  max_diff = 0;
  for (size_t k = 0; k < before->color.size(); ++k)
    max_diff = std::max(max_diff, std::abs(before->color[k] - after_full->color[k]));
  EXPECT_LE(max_diff, 1e-5f);
  std::printf("[growth] then all to 4x4: max |pixel difference| %.3g\n", max_diff);
}

}  // namespace
}  // namespace atex
