#include "atex/train/colour_correction.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "atex/metrics.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "atex/train/camera_colours.h"
#include "render/render_test_util.h"

namespace atex::train {
namespace {

Image RandomImage(int w, int h, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(0.05f, 0.95f);
  Image im(w, h, 3);
  for (float& v : im.pixels) v = u(rng);
  return im;
}

Image Transformed(const Image& in, const ColourAffine& a) {
  Image out = in;
  a.Apply(out.pixels.data(), size_t(in.width) * in.height);
  return out;
}

TEST(ColourCorrection, FitRecoversTheAffineOfACamera) {
  std::mt19937 rng(1);
  const ColourAffine truth{{1.08f, 0.95f, 1.02f}, {-0.03f, 0.02f, 0.01f}};
  Image r0 = RandomImage(40, 30, rng), r1 = RandomImage(40, 30, rng);
  Image t0 = Transformed(r0, truth), t1 = Transformed(r1, truth);
  auto fit = FitColourAffine({{&r0, &t0}, {&r1, &t1}}, 1.0);
  ASSERT_TRUE(fit.ok()) << fit.status().message();
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(fit->gain[c], truth.gain[c], 1e-4);
    EXPECT_NEAR(fit->offset[c], truth.offset[c], 1e-4);
  }
}

TEST(ColourCorrection, TrimmedFitIgnoresWhatTheModelGetsWrong) {
  std::mt19937 rng(2);
  const ColourAffine truth{{0.9f, 1.1f, 1.0f}, {0.02f, -0.04f, 0.05f}};
  Image r = RandomImage(50, 40, rng);
  Image t = Transformed(r, truth);
  // 5 % of the pixels show an object the model misses: far off in every channel.
  std::uniform_int_distribution<int> pixel(0, 50 * 40 - 1);
  for (int k = 0; k < 100; ++k) {
    const int p = pixel(rng);
    for (int c = 0; c < 3; ++c) t.pixels[3 * p + c] = 1.0f - 0.8f * r.pixels[3 * p + c];
  }
  auto plain = FitColourAffine({{&r, &t}}, 1.0);
  auto trimmed = FitColourAffine({{&r, &t}}, 0.9);
  ASSERT_TRUE(plain.ok() && trimmed.ok());
  double plain_error = 0, trimmed_error = 0;
  for (int c = 0; c < 3; ++c) {
    plain_error += std::abs(plain->gain[c] - truth.gain[c]);
    trimmed_error += std::abs(trimmed->gain[c] - truth.gain[c]);
    EXPECT_NEAR(trimmed->gain[c], truth.gain[c], 5e-3);
    EXPECT_NEAR(trimmed->offset[c], truth.offset[c], 5e-3);
  }
  EXPECT_GT(plain_error, 10 * trimmed_error) << "the outliers should bend the untrimmed fit";
}

TEST(ColourCorrection, FitRefusesBadInputAndClampsWildGains) {
  Image a(4, 4, 3, 0.5f), b(4, 3, 3, 0.5f);
  EXPECT_EQ(FitColourAffine({}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(FitColourAffine({{&a, &b}}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(FitColourAffine({{&a, &a}}, 0.0).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(FitColourAffine({{&a, nullptr}}).status().code(), StatusCode::kInvalidArgument);
  // A flat render: no gain can be fitted, only the offset.
  Image flat(4, 4, 3, 0.5f), brighter(4, 4, 3, 0.6f);
  auto fit = FitColourAffine({{&flat, &brighter}}, 1.0);
  ASSERT_TRUE(fit.ok());
  EXPECT_EQ(fit->gain[0], 1.0f);
  EXPECT_NEAR(fit->offset[0], 0.1f, 1e-6);
  // A target 5x the render: the gain stops at the clamp.
  std::mt19937 rng(3);
  Image r = RandomImage(8, 8, rng);
  Image t = Transformed(r, {{5, 5, 5}, {0, 0, 0}});
  auto wild = FitColourAffine({{&r, &t}}, 1.0);
  ASSERT_TRUE(wild.ok());
  EXPECT_EQ(wild->gain[1], kMaxColourGain);
}

TEST(ColourCorrection, NormalisingMakesTheAverageCameraTheIdentity) {
  std::vector<ColourAffine> a = {{{1.2f, 1.0f, 0.9f}, {0.05f, 0.0f, -0.02f}},
                                 {{1.0f, 1.1f, 0.9f}, {0.01f, 0.02f, 0.00f}},
                                 {{1.1f, 0.9f, 1.2f}, {0.03f, -0.02f, 0.05f}}};
  const std::vector<ColourAffine> before = a;
  NormaliseColourAffines(&a);
  for (int c = 0; c < 3; ++c) {
    double g = 0, o = 0, gb = 0, ob = 0;
    for (size_t i = 0; i < a.size(); ++i) g += a[i].gain[c], o += a[i].offset[c], gb += before[i].gain[c],
                                          ob += before[i].offset[c];
    g /= 3, o /= 3, gb /= 3, ob /= 3;
    EXPECT_NEAR(g, 1.0, 1e-6);
    EXPECT_NEAR(o, 0.0, 1e-6);
    // Each camera maps the same colour the same way, through the re-expressed colour space
    // x' = ḡx + ō: g'_i x' + o'_i = g_i x + o_i for every x.
    for (size_t i = 0; i < a.size(); ++i) {
      for (double x : {0.0, 0.3, 1.0}) {
        EXPECT_NEAR(a[i].gain[c] * (gb * x + ob) + a[i].offset[c], before[i].gain[c] * x + before[i].offset[c], 1e-5);
      }
    }
  }
}

// Fits are clamped to the bounds, but re-expressing them around their mean can carry a camera
// past them (a 2-GPU Panoptic run stopped when the other rank read an offset of -0.256 back):
// the normalised set must still be storable.
TEST(ColourCorrection, NormalisedCorrectionsStayWithinTheStoredBounds) {
  std::vector<ColourAffine> a = {{{1.0f, 2.0f, 1.0f}, {-kMaxColourOffset, 0.0f, 0.0f}},
                                 {{1.0f, 2.0f, 1.0f}, {kMaxColourOffset, 0.0f, 0.0f}},
                                 {{1.0f, 0.5f, 1.0f}, {kMaxColourOffset, 0.0f, 0.0f}}};
  NormaliseColourAffines(&a);
  nlohmann::json stored = nlohmann::json::object();
  for (size_t i = 0; i < a.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_GE(a[i].gain[c], kMinColourGain) << i << " " << c;
      EXPECT_LE(a[i].gain[c], kMaxColourGain) << i << " " << c;
      EXPECT_LE(std::abs(a[i].offset[c]), kMaxColourOffset) << i << " " << c;
    }
    stored[std::to_string(i)] = {{"gain", a[i].gain}, {"offset", a[i].offset}};
  }
  EXPECT_FLOAT_EQ(a[0].offset[0], -kMaxColourOffset);  // -0.333 before the clamp
  EXPECT_FLOAT_EQ(a[2].gain[1], kMinColourGain);       // 0.333 before the clamp
  auto read = CameraColours::FromJson(stored);
  EXPECT_TRUE(read.ok()) << read.status().message();
}

TEST(ColourCorrection, CameraColoursSurviveJsonAndRefuseGarbage) {
  auto parsed = CameraColours::FromJson(nlohmann::json::parse(
      R"({"3": {"gain": [1.1, 0.9, 1.0], "offset": [0.01, -0.02, 0.0]},)"
      R"( "12": {"gain": [1, 1, 1], "offset": [0, 0, 0]}})"));
  ASSERT_TRUE(parsed.ok()) << parsed.status().message();
  EXPECT_EQ(parsed->size(), 2u);
  EXPECT_FLOAT_EQ(parsed->For(3).gain[0], 1.1f);
  EXPECT_TRUE(parsed->For(7).IsIdentity());  // unknown camera
  auto again = CameraColours::FromJson(parsed->ToJson());
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->ToJson(), parsed->ToJson());
  for (const char* bad : {R"([1, 2])", R"({"x": {"gain": [1, 1, 1], "offset": [0, 0, 0]}})",
                          R"({"-1": {"gain": [1, 1, 1], "offset": [0, 0, 0]}})", R"({"1": {"gain": [1, 1]}})",
                          R"({"1": {"gain": [1, 1, "a"], "offset": [0, 0, 0]}})",
                          R"({"1": {"gain": [9, 1, 1], "offset": [0, 0, 0]}})",
                          R"({"1": {"gain": [1, 1, 1], "offset": [0, 0.9, 0]}})"}) {
    EXPECT_EQ(CameraColours::FromJson(nlohmann::json::parse(bad)).status().code(), StatusCode::kInvalidArgument)
        << bad;
  }
}

// The CPU backend compares the target with gain · render + offset, and chains the gradient.
TEST(ColourCorrection, CpuBackendLossIsTheCorrectedRendersLoss) {
  std::mt19937 rng(5);
  const Camera camera = render_testing::RandomCamera(48, 36, rng);
  render_testing::SceneOptions options;
  options.count = 120;
  options.sh_degree = 0;
  options.extras = false;
  ModelState state;
  state.gaussians = render_testing::RandomGaussians<float>(camera, options, rng);
  ResetMoments(&state);
  auto backend = MakeCpuBackend();
  ASSERT_TRUE(backend->Load(state).ok());
  RenderRequest render;
  render.active_sh_degree = 0;
  render.apply_deformation = false;
  render.use_textures = false;
  auto image = backend->Render(camera, render);
  ASSERT_TRUE(image.ok());
  const ColourAffine colour{{1.1f, 0.9f, 1.05f}, {0.02f, -0.01f, 0.03f}};
  const Image target = Transformed(*image, colour);

  StepRequest step;  // all learning rates 0: nothing moves, the loss is read only
  step.active_sh_degree = 0;
  TrainView corrected{&camera, &target, 1, colour};
  auto with = backend->Step(step, std::span<const TrainView>(&corrected, 1));
  ASSERT_TRUE(with.ok()) << with.status().message();
  EXPECT_LT(with->loss, 1e-6) << "the corrected render is the target";
  TrainView plain{&camera, &target, 1};
  auto without = backend->Step(step, std::span<const TrainView>(&plain, 1));
  ASSERT_TRUE(without.ok());
  const float expected = PhotometricLoss<float>(image->pixels.data(), target.pixels.data(), camera.width,
                                                camera.height, 0.2, nullptr);
  EXPECT_NEAR(without->loss, expected, 1e-5 * expected + 1e-7);
  EXPECT_GT(without->loss, 1e-3);

  // Gradients, chained through the gain: with the L1 loss alone (λ = 0) and a gain g in every
  // channel, mean|g·R − T| = g·mean|R − T/g|, so the corrected step's gradients are g times
  // those of an uncorrected step against T/g.
  const float g = 1.25f;
  Image off = target;
  for (float& v : off.pixels) v = std::min(1.0f, v + 0.05f);
  Image scaled = off;
  for (float& v : scaled.pixels) v /= g;
  step.lambda_dssim = 0.0;
  TrainView gained{&camera, &off, 2, {{g, g, g}, {0, 0, 0}}};
  ASSERT_TRUE(backend->Step(step, std::span<const TrainView>(&gained, 1)).ok());
  ModelState grad_gained, grad_scaled;
  ASSERT_TRUE(backend->ReadGradients(&grad_gained).ok());
  TrainView against_scaled{&camera, &scaled, 3};
  ASSERT_TRUE(backend->Step(step, std::span<const TrainView>(&against_scaled, 1)).ok());
  ASSERT_TRUE(backend->ReadGradients(&grad_scaled).ok());
  double norm = 0;
  ASSERT_EQ(grad_gained.gaussians.sh.size(), grad_scaled.gaussians.sh.size());
  for (size_t i = 0; i < grad_gained.gaussians.sh.size(); ++i) {
    norm += std::abs(grad_gained.gaussians.sh[i]);
    EXPECT_NEAR(grad_gained.gaussians.sh[i], g * grad_scaled.gaussians.sh[i],
                1e-4 * std::abs(grad_gained.gaussians.sh[i]) + 1e-9) << i;
  }
  EXPECT_GT(norm, 0) << "a target off by 0.05 must move the colours";
}

}  // namespace
}  // namespace atex::train
