// Gradient checks of RenderBackward against central finite differences of
// RenderForward, in double precision, for every parameter of random small scenes
// (every parameter group, SH degree and texture mode).
//
// Where a perturbation crosses a non-smooth point of the renderer (the 1/255 cut,
// the 0.99 clamp, the T < 1e-4 stop, u/v clamps, bilinear cell borders, tile
// rectangles, SH and Jacobian clamps, the depth order) the finite difference is not
// a derivative. Those parameters are detected — the render's discrete signature
// (render_test_util.h) differs between θ − h, θ and θ + h — excluded, and counted;
// a check fails if too many are excluded, so it cannot pass vacuously.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <random>
#include <string>

#include "atex/render.h"
#include "render/render_internal.h"
#include "render/render_test_util.h"

namespace atex {
namespace {

using render_testing::SceneOptions;
using render_testing::TextureKind;

constexpr double kStep = 1e-5;  // finite-difference step (double precision, fourth-order stencil)
// |analytic − fd| ≤ 1e-6·max(|analytic|, |fd|) + 5e-8. Measured errors are ≤ 1e-8 in
// absolute terms (gradients are O(0.1–10)); a wrong term is typically off by > 1e-3.
constexpr double kRelTolerance = 1e-6;
constexpr double kAbsTolerance = 5e-8;
constexpr double kRelReportFloor = 1e-3;  // max_rel is reported over entries at least this large

struct GroupReport {
  std::string name;
  int checked = 0;
  int excluded = 0;
  int failures = 0;
  double max_rel = 0;   // max |a − fd| / max(|a|, |fd|) over entries with max(|a|, |fd|) ≥ kRelReportFloor
  double max_abs = 0;   // max |a − fd|
  double max_grad = 0;  // max |fd|
};

struct Scene {
  std::string name;
  Camera camera;
  BasicGaussians<double> g;
  std::optional<BasicTexturePool<double>> textures;
  RenderSettings settings;
  std::vector<double> w_color;  // [H][W][3] loss weights
  std::vector<double> w_alpha;  // [H][W] (empty: no alpha term)

  const BasicTexturePool<double>* tex() const { return textures ? &*textures : nullptr; }
};

struct SceneConfig {
  const char* name;
  uint32_t seed;
  int sh_degree;
  int active_sh_degree;
  TextureKind textures;
  bool opaque;
  bool background;
  bool alpha_loss;
};

Scene MakeScene(const SceneConfig& config) {
  std::mt19937 rng(config.seed);
  Scene s;
  s.name = config.name;
  s.camera = render_testing::RandomCamera(24, 20, rng);
  SceneOptions options;
  options.count = 16;
  options.sh_degree = config.sh_degree;
  options.textures = config.textures;
  options.opaque = config.opaque;
  s.g = render_testing::RandomGaussians<double>(s.camera, options, rng);
  if (config.textures != TextureKind::kNone) {
    s.textures = render_testing::RandomTextures(s.g, config.textures, options.texel_range, rng);
  }
  s.settings.active_sh_degree = config.active_sh_degree;
  if (config.background) s.settings.background = {0.3f, 0.6f, 0.2f};
  std::uniform_real_distribution<double> weight(-1.0, 1.0);
  const size_t pixels = size_t(s.camera.width) * s.camera.height;
  s.w_color.resize(pixels * 3);
  for (double& w : s.w_color) w = weight(rng);
  if (config.alpha_loss) {
    s.w_alpha.resize(pixels);
    for (double& w : s.w_alpha) w = weight(rng);
  }
  return s;
}

double Loss(const Scene& s, const BasicRenderOutput<double>& out) {
  double loss = 0;
  for (size_t k = 0; k < out.color.size(); ++k) loss += s.w_color[k] * out.color[k];
  for (size_t k = 0; k < s.w_alpha.size(); ++k) loss += s.w_alpha[k] * out.alpha[k];
  return loss;
}

// Checks analytic[k] against the central difference of `evaluate` while `param(k)`
// is perturbed; `evaluate` returns (loss, signature).
void CheckGroup(const std::function<double&(size_t)>& param, size_t count, const std::vector<double>& analytic,
                size_t analytic_offset, size_t analytic_stride, size_t analytic_count,
                const std::function<std::pair<double, std::vector<int64_t>>()>& evaluate,
                const std::vector<int64_t>& base_signature, GroupReport* report) {
  for (size_t k = 0; k < count; ++k) {
    // Map k onto the analytic layout: blocks of `analytic_count` values every `analytic_stride`.
    const size_t index = analytic_offset + (k / analytic_count) * analytic_stride + k % analytic_count;
    double& p = param(k);
    const double original = p;
    double values[4];  // L(θ + h), L(θ − h), L(θ + 2h), L(θ − 2h)
    bool smooth = true;
    const double offsets[4] = {kStep, -kStep, 2 * kStep, -2 * kStep};
    for (int j = 0; j < 4; ++j) {
      p = original + offsets[j];
      const auto result = evaluate();
      values[j] = result.first;
      smooth = smooth && result.second == base_signature;
    }
    p = original;
    ++report->checked;
    if (!smooth) {
      ++report->excluded;
      continue;
    }
    // Fourth-order central difference: the renderer's curvature (grazing texture
    // planes, small footprints) makes the plain two-point formula's h² error visible.
    const double fd = (8 * (values[0] - values[1]) - (values[2] - values[3])) / (12 * kStep);
    const double a = analytic[index];
    const double err = std::abs(a - fd);
    const double magnitude = std::max(std::abs(a), std::abs(fd));
    report->max_abs = std::max(report->max_abs, err);
    report->max_grad = std::max(report->max_grad, std::abs(fd));
    if (magnitude >= kRelReportFloor) report->max_rel = std::max(report->max_rel, err / magnitude);
    if (err > kRelTolerance * magnitude + kAbsTolerance) {
      if (++report->failures <= 5) {
        ADD_FAILURE() << report->name << "[" << index << "]: analytic " << a << " vs finite difference " << fd
                      << " (error " << err << ")";
      }
    }
  }
}

void ExpectReport(const std::string& scene, const GroupReport& r, bool expect_nonzero = true) {
  std::printf("[gradcheck] %-22s %-16s checked %5d excluded %3d  max rel err %.2e  max abs err %.2e  max |grad| %.2e\n",
              scene.c_str(), r.name.c_str(), r.checked, r.excluded, r.max_rel, r.max_abs, r.max_grad);
  EXPECT_EQ(r.failures, 0) << scene << " " << r.name;
  EXPECT_LE(r.excluded, std::max(3, r.checked / 20)) << scene << " " << r.name << ": too many non-smooth points";
  if (expect_nonzero) {
    EXPECT_GT(r.max_grad, 1e-4) << scene << " " << r.name << ": the check saw no gradient";
  }
}

class RenderGradientTest : public ::testing::TestWithParam<SceneConfig> {};

TEST_P(RenderGradientTest, EveryParameterMatchesFiniteDifferences) {
  Scene s = MakeScene(GetParam());
  auto forward = RenderForward(s.camera, s.g, s.tex(), s.settings);
  ASSERT_TRUE(forward.ok()) << forward.status().ToString();
  // The scene must exercise the renderer: several visible Gaussians, textures sampled.
  int visible = 0;
  for (int32_t r : forward->radius) visible += r > 0;
  ASSERT_GE(visible, 10);
  const auto base_signature = render_testing::RenderSignature(s.camera, s.g, s.tex(), s.settings, *forward);

  // dL/dÎ and dL/dalpha of the weighted-sum loss are the weights.
  BasicRenderGradients<double> grads;
  const Status st = RenderBackward(s.camera, s.g, s.tex(), s.settings, *forward, s.w_color.data(),
                                   s.w_alpha.empty() ? nullptr : s.w_alpha.data(), &grads);
  ASSERT_TRUE(st.ok()) << st.ToString();

  const auto evaluate = [&]() -> std::pair<double, std::vector<int64_t>> {
    auto out = RenderForward(s.camera, s.g, s.tex(), s.settings);
    EXPECT_TRUE(out.ok());
    return {Loss(s, *out), render_testing::RenderSignature(s.camera, s.g, s.tex(), s.settings, *out)};
  };
  const size_t n = s.g.size();
  const auto check = [&](const char* name, std::vector<double>& params, const std::vector<double>& analytic) {
    GroupReport r;
    r.name = name;
    CheckGroup([&](size_t k) -> double& { return params[k]; }, params.size(), analytic, 0, 1, 1, evaluate,
               base_signature, &r);
    ExpectReport(s.name, r);
  };
  check("positions", s.g.positions, grads.gaussians.positions);
  check("rotations", s.g.rotations, grads.gaussians.rotations);
  check("log_scales", s.g.log_scales, grads.gaussians.log_scales);
  check("opacity_logits", s.g.opacity_logits, grads.gaussians.opacity_logits);

  // SH, one band (degree) at a time; bands above the active degree must get exactly zero.
  const int coeffs = s.g.sh_coeffs();
  const int active = std::min(s.settings.active_sh_degree, s.g.sh_degree);
  for (int band = 0; band <= s.g.sh_degree; ++band) {
    const int first = band * band, band_count = 2 * band + 1;
    GroupReport r;
    r.name = "sh degree " + std::to_string(band);
    // Parameter k of this band: Gaussian k / (3 band_count), coefficient first + (k / 3) % band_count, channel k % 3.
    const auto sh_index = [&](size_t k) {
      const size_t i = k / (3 * band_count), rest = k % (3 * band_count);
      return (i * coeffs + first) * 3 + rest;
    };
    CheckGroup([&](size_t k) -> double& { return s.g.sh[sh_index(k)]; }, n * 3 * band_count, grads.gaussians.sh,
               first * 3, coeffs * 3, 3 * band_count, evaluate, base_signature, &r);
    ExpectReport(s.name, r, band <= active);
    if (band > active) {
      for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < band_count * 3; ++k) EXPECT_EQ(grads.gaussians.sh[(i * coeffs + first) * 3 + k], 0.0);
    }
  }
  if (s.textures) {
    ASSERT_EQ(grads.texels.size(), s.textures->texels.size());
    check("texels", s.textures->texels, grads.texels);
  } else {
    EXPECT_TRUE(grads.texels.empty());
  }
  // Invisible Gaussians (the one behind the camera is the last) get exactly zero.
  ASSERT_EQ(forward->radius[n - 1], 0);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(grads.gaussians.positions[3 * (n - 1) + k], 0.0);
  EXPECT_EQ(grads.gaussians.opacity_logits[n - 1], 0.0);
}

// The projected-centre gradient (pixels) against finite differences of the
// rasteriser with the centre itself perturbed (tile lists held fixed).
TEST_P(RenderGradientTest, Mean2dMatchesFiniteDifferencesOfTheRasteriser) {
  Scene s = MakeScene(GetParam());
  auto forward = RenderForward(s.camera, s.g, s.tex(), s.settings);
  ASSERT_TRUE(forward.ok()) << forward.status().ToString();
  BasicRenderGradients<double> grads;
  ASSERT_TRUE(RenderBackward(s.camera, s.g, s.tex(), s.settings, *forward, s.w_color.data(),
                             s.w_alpha.empty() ? nullptr : s.w_alpha.data(), &grads)
                  .ok());
  const auto cam = detail::MakeCameraModel<double>(s.camera, s.settings.near_plane);
  BasicRenderOutput<double> work = *forward;
  const auto base_signature = render_testing::PixelSignature(s.camera, s.tex(), work);
  const auto evaluate = [&]() -> std::pair<double, std::vector<int64_t>> {
    render_internal::RasterizeForward(cam, s.tex(), s.settings, &work);
    return {Loss(s, work), render_testing::PixelSignature(s.camera, s.tex(), work)};
  };
  GroupReport r;
  r.name = "mean2d";
  // Only visible Gaussians are rasterised; others have no projected centre to perturb.
  std::vector<size_t> params;
  for (size_t i = 0; i < s.g.size(); ++i)
    if (forward->radius[i] > 0) params.insert(params.end(), {2 * i, 2 * i + 1});
  std::vector<double> analytic;
  for (size_t k : params) analytic.push_back(grads.mean2d[k]);
  CheckGroup([&](size_t k) -> double& { return work.mean2d[params[k]]; }, params.size(), analytic, 0, 1, 1, evaluate,
             base_signature, &r);
  ExpectReport(s.name, r);
}

const SceneConfig kScenes[] = {
    // name, seed, sh_degree, active, textures, opaque, background, alpha_loss
    {"plain_sh0", 11, 0, 3, TextureKind::kNone, false, false, false},
    {"plain_sh1", 12, 1, 3, TextureKind::kNone, false, true, true},
    {"plain_sh2", 13, 2, 3, TextureKind::kNone, false, false, true},
    {"plain_sh3_bg_alpha", 14, 3, 3, TextureKind::kNone, false, true, true},
    {"plain_sh3_active1", 15, 3, 1, TextureKind::kNone, false, false, false},
    {"plain_opaque", 16, 2, 2, TextureKind::kNone, true, true, true},
    {"uniform_sh3", 21, 3, 3, TextureKind::kUniform, false, true, true},
    {"uniform_sh1", 22, 1, 1, TextureKind::kUniform, false, false, false},
    {"uniform_opaque_sh0", 23, 0, 0, TextureKind::kUniform, true, false, true},
    {"adaptive_sh3", 31, 3, 3, TextureKind::kAdaptiveMixed, false, true, true},
    {"adaptive_sh2_active0", 32, 2, 0, TextureKind::kAdaptiveMixed, false, false, true},
    {"adaptive_opaque", 33, 1, 1, TextureKind::kAdaptiveMixed, true, true, false},
};

INSTANTIATE_TEST_SUITE_P(Scenes, RenderGradientTest, ::testing::ValuesIn(kScenes),
                         [](const ::testing::TestParamInfo<SceneConfig>& info) {
                           return std::string(info.param.name);
                         });

}  // namespace
}  // namespace atex
