// BakeTextures: renders of the baked Gaussians by libatex's reference renderer against the
// textured render, edge cases, hostile input, and the glTF export round trip.
#include "atex/converters/texture_bake.h"

#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "atex/converters/gltf.h"
#include "atex/render.h"

namespace atex {
namespace {

// One Gaussian facing the camera (plane x-y, normal z) at z = 3, wide in x and y, opacity `alpha`,
// grey, SH degree 1 (the higher band must be copied untouched), with an h x w texture.
Asset OneTextured(int h, int w, float alpha = 0.3f) {
  Asset asset;
  Gaussians& g = asset.gaussians;
  g.sh_degree = 1;
  g.Resize(1);
  g.positions = {0.1f, -0.05f, 3.0f};
  g.rotations = {1, 0, 0, 0};
  g.log_scales = {std::log(0.6f), std::log(0.45f), std::log(0.02f)};
  g.opacity_logits = {std::log(alpha / (1 - alpha))};
  for (size_t k = 0; k < g.sh.size(); ++k) g.sh[k] = k < 3 ? 0.2f : 0.05f * float(k % 5) - 0.1f;
  TexturePool t;
  t.heights = {uint8_t(h)};
  t.widths = {uint8_t(w)};
  t.axis_u = {0};
  t.axis_v = {1};
  t.RebuildOffsets();
  t.texels.assign(t.texel_count() * 4, 0.0f);
  asset.textures = t;
  return asset;
}

// A checker over the texels: colour ±3 (tanh ≈ ±1, the full ±0.1 of §5) alternating per texel
// with the red and blue channels opposite, opacity parameter ∓3.
void Checker(TexturePool* t) {
  const int h = t->heights[0], w = t->widths[0];
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float s = ((x + y) % 2 == 0) ? 3.0f : -3.0f;
      float* texel = &t->texels[size_t(y * w + x) * 4];
      texel[0] = s, texel[1] = 0.5f * s, texel[2] = -s, texel[3] = -s;
    }
  }
}

Camera FrontCamera() {
  Camera c;
  c.width = 96, c.height = 80;
  c.fx = c.fy = 90, c.cx = 48, c.cy = 40;
  return c;
}

std::vector<float> Render(const Gaussians& g, const TexturePool* t) {
  auto out = RenderForward(FrontCamera(), g, t, RenderSettings{});
  EXPECT_TRUE(out.ok()) << out.status().ToString();
  return out.ok() ? out->color : std::vector<float>{};
}

double Psnr(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double se = 0;
  for (size_t i = 0; i < a.size(); ++i) se += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  const double mse = se / double(a.size());
  return mse <= 0 ? 200.0 : -10 * std::log10(mse);
}

struct Scores {
  double unbaked, baked;
};

// PSNR against the textured render: the Gaussian without its texture, and baked.
Scores Score(const Asset& asset, TextureBakeReport* report = nullptr) {
  const std::vector<float> textured = Render(asset.gaussians, &*asset.textures);
  const std::vector<float> unbaked = Render(asset.gaussians, nullptr);
  auto baked = BakeTextures(asset.gaussians, *asset.textures, {}, report);
  EXPECT_TRUE(baked.ok()) << baked.status().ToString();
  if (!baked.ok()) return {0, 0};
  return {Psnr(unbaked, textured), Psnr(Render(*baked, nullptr), textured)};
}

TEST(TextureBake, CheckerTwoByTwoMatchesTheTexturedRenderBetter) {
  Asset asset = OneTextured(2, 2);
  Checker(&*asset.textures);
  TextureBakeReport report;
  const Scores s = Score(asset, &report);
  EXPECT_EQ(report.output_gaussians, 4u);
  EXPECT_EQ(report.split, 1u);
  EXPECT_LT(report.fit_rms, 0.7 * report.unbaked_rms);
  // A no-op bake scores exactly `unbaked`; the fit must gain clearly more than that.
  // Measured: 45.2 -> 48.9 dB.
  EXPECT_GT(s.baked, s.unbaked + 2.5) << "unbaked " << s.unbaked << " dB, baked " << s.baked << " dB";
  std::printf("2x2 checker: unbaked %.2f dB, baked %.2f dB against the textured render\n", s.unbaked, s.baked);
}

// An opaque parent: children composite sub-additively and cannot follow its profile well, so the
// bake must at least not make it worse (it falls back to folding when the fit gains too little).
TEST(TextureBake, OpaqueCheckerIsNotMadeWorse) {
  Asset asset = OneTextured(2, 2, 0.9f);
  Checker(&*asset.textures);
  TextureBakeReport report;
  const Scores s = Score(asset, &report);
  EXPECT_GT(s.baked, s.unbaked - 0.5) << "unbaked " << s.unbaked << " dB, baked " << s.baked << " dB";
  std::printf("opaque 2x2 checker: unbaked %.2f dB, baked %.2f dB (%zu Gaussians)\n", s.unbaked, s.baked,
              report.output_gaussians);
}

TEST(TextureBake, RampsSplitAlongTheirTexturedAxesOnly) {
  for (auto [h, w, children] : {std::array<int, 3>{4, 4, 4}, {2, 4, 4}, {1, 4, 2}, {4, 1, 2}, {1, 2, 2}}) {
    Asset asset = OneTextured(h, w);
    // A colour ramp along u and an opacity ramp along v (what 2 children per axis can carry).
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        float* texel = &asset.textures->texels[size_t(y * w + x) * 4];
        texel[0] = w > 1 ? -3.0f + 6.0f * x / (w - 1) : 0.0f;
        texel[2] = -texel[0];
        texel[3] = h > 1 ? -3.0f + 6.0f * y / (h - 1) : 0.0f;
      }
    }
    TextureBakeReport report;
    const Scores s = Score(asset, &report);
    EXPECT_EQ(report.output_gaussians, size_t(children)) << h << "x" << w;
    // Measured: +6.2 to +6.5 dB.
    EXPECT_GT(s.baked, s.unbaked + 3.0) << h << "x" << w << ": unbaked " << s.unbaked << ", baked " << s.baked;
    std::printf("%dx%d ramp: unbaked %.2f dB, baked %.2f dB\n", h, w, s.unbaked, s.baked);
  }
}

// A 4x4 checker alternates faster than 2 children per axis can follow: folded, never worse.
TEST(TextureBake, FineCheckerFallsBackToFolding) {
  Asset asset = OneTextured(4, 4);
  Checker(&*asset.textures);
  TextureBakeReport report;
  const Scores s = Score(asset, &report);
  EXPECT_GT(s.baked, s.unbaked - 0.5);
  EXPECT_EQ(report.fold_better + report.split, 1u);
  std::printf("4x4 checker: unbaked %.2f dB, baked %.2f dB (%zu Gaussians)\n", s.unbaked, s.baked,
              report.output_gaussians);
}

TEST(TextureBake, OneByOneFoldsIntoColourAndOpacity) {
  Asset asset = OneTextured(1, 1);
  asset.textures->texels = {0.8f, -0.4f, 0.2f, 0.5f};
  asset.gaussians.opacity_logits = {0.0f};  // α = 0.5: the factor stays below the 0.99 clamp
  TextureBakeReport report;
  const Scores s = Score(asset, &report);
  EXPECT_EQ(report.output_gaussians, 1u);
  EXPECT_EQ(report.folded, 1u);
  EXPECT_GT(s.baked, 60.0);  // exact up to float rounding
  EXPECT_LT(s.unbaked, 45.0);
  std::printf("1x1: unbaked %.2f dB, baked %.2f dB\n", s.unbaked, s.baked);
}

TEST(TextureBake, UntexturedZeroTexelsChangeNothing) {
  Asset asset = OneTextured(2, 4);  // all texels zero: constant, folded, bit-exact
  auto baked = BakeTextures(asset.gaussians, *asset.textures);
  ASSERT_TRUE(baked.ok());
  EXPECT_EQ(baked->positions, asset.gaussians.positions);
  EXPECT_EQ(baked->log_scales, asset.gaussians.log_scales);
  EXPECT_EQ(baked->opacity_logits, asset.gaussians.opacity_logits);
  EXPECT_EQ(baked->sh, asset.gaussians.sh);
}

TEST(TextureBake, ZeroScalesAndTimeWindowsStayFinite) {
  Asset asset = OneTextured(2, 2);
  Checker(&*asset.textures);
  asset.gaussians.time_windows = {0.5f, 2.0f};
  for (float ls : {-200.0f, -std::numeric_limits<float>::infinity()}) {
    asset.gaussians.log_scales = {ls, ls, ls};
    auto baked = BakeTextures(asset.gaussians, *asset.textures);
    ASSERT_TRUE(baked.ok()) << baked.status().ToString();
    ASSERT_EQ(baked->size(), 4u);
    for (float p : baked->positions) EXPECT_TRUE(std::isfinite(p));
    for (float v : baked->sh) EXPECT_TRUE(std::isfinite(v));
    for (float v : baked->opacity_logits) EXPECT_TRUE(std::isfinite(v));
    EXPECT_EQ(baked->time_windows.size(), 8u);
    EXPECT_EQ(baked->time_windows[6], 0.5f);
  }
}

TEST(TextureBake, DeterministicAndHigherBandsCopied) {
  Asset asset = OneTextured(4, 2);
  Checker(&*asset.textures);
  auto a = BakeTextures(asset.gaussians, *asset.textures);
  auto b = BakeTextures(asset.gaussians, *asset.textures);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(0, std::memcmp(a->positions.data(), b->positions.data(), a->positions.size() * 4));
  EXPECT_EQ(a->sh, b->sh);
  EXPECT_EQ(a->opacity_logits, b->opacity_logits);
  const size_t k = size_t(asset.gaussians.sh_coeffs()) * 3;
  for (size_t c = 0; c < a->size(); ++c) {
    for (size_t j = 3; j < k; ++j) EXPECT_EQ(a->sh[c * k + j], asset.gaussians.sh[j]);
    EXPECT_EQ(a->log_scales[c * 3 + 2], asset.gaussians.log_scales[2]);  // the normal axis
  }
}

TEST(TextureBake, HostileInputIsRefused) {
  Asset asset = OneTextured(2, 2);
  Checker(&*asset.textures);
  TexturePool two = *asset.textures;
  two.heights.push_back(1), two.widths.push_back(1), two.axis_u.push_back(0), two.axis_v.push_back(1);
  two.RebuildOffsets();
  two.texels.resize(two.texel_count() * 4);
  EXPECT_EQ(BakeTextures(asset.gaussians, two).status().code(), StatusCode::kInvalidArgument);
  TexturePool nan = *asset.textures;
  nan.texels[5] = std::nanf("");
  EXPECT_EQ(BakeTextures(asset.gaussians, nan).status().code(), StatusCode::kOutOfRange);
  Gaussians bad = asset.gaussians;
  bad.positions[1] = std::numeric_limits<float>::infinity();
  auto s = BakeTextures(bad, *asset.textures).status();
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_NE(s.ToString().find("element 0"), std::string::npos) << s.ToString();
  TextureBakeOptions iterations;
  iterations.fit_iterations = -1;
  EXPECT_EQ(BakeTextures(asset.gaussians, *asset.textures, iterations).status().code(), StatusCode::kInvalidArgument);
  TextureBakeOptions o;
  o.grid = 2;
  EXPECT_EQ(BakeTextures(asset.gaussians, *asset.textures, o).status().code(), StatusCode::kInvalidArgument);
}

TEST(TextureBake, GltfExportWritesTheBakedGaussiansWithoutTextures) {
#ifndef ATEX_HAVE_TINYGLTF
  GTEST_SKIP() << "this build has no glTF import (TinyGLTF) to read the export back";
#else
  Asset asset = OneTextured(2, 2);
  Checker(&*asset.textures);
  asset.metadata.axes = "gltf";
  asset.metadata.texture_mode = "adaptive";
  GltfExportOptions options;
  options.bake_textures = true;
  TextureBakeReport report;
  options.bake_report = &report;
  auto glb = EncodeGlb(asset, options);
  ASSERT_TRUE(glb.ok()) << glb.status().ToString();
  auto back = DecodeGltf(glb->data(), glb->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->gaussians.size(), 4u);
  EXPECT_EQ(back->gaussians.size(), report.output_gaussians);
  EXPECT_FALSE(back->textures.has_value());
  auto direct = BakeTextures(asset.gaussians, *asset.textures);
  ASSERT_TRUE(direct.ok());
  EXPECT_EQ(back->gaussians.positions, direct->positions);  // raw float accessors: exact
  EXPECT_EQ(back->gaussians.sh, direct->sh);
  // Without the option the texture survives and the count stays 1.
  auto plain = EncodeGlb(asset, {});
  ASSERT_TRUE(plain.ok());
  auto plain_back = DecodeGltf(plain->data(), plain->size());
  ASSERT_TRUE(plain_back.ok());
  EXPECT_EQ(plain_back->gaussians.size(), 1u);
  EXPECT_TRUE(plain_back->textures.has_value());
#endif
}

}  // namespace
}  // namespace atex
