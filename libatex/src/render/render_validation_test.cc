// The renderer's refusals: invalid cameras, Gaussians, textures and gradients come back as a
// Status naming the problem, never a crash or a silent render.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "atex/render.h"
#include "render/render_test_util.h"

namespace atex {
namespace {

// ---- invalid input → Status ------------------------------------------------------
class RenderValidation : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937 rng(3);
    camera = render_testing::RandomCamera(24, 20, rng);
    render_testing::SceneOptions options;
    options.count = 5;
    g = render_testing::RandomGaussians<float>(camera, options, rng);
    pool = render_testing::RandomTextures(g, render_testing::TextureKind::kAdaptiveMixed, 1.0, rng);
  }
  StatusCode ForwardCode() const {
    auto out = RenderForward(camera, g, &pool, settings);
    return out.ok() ? StatusCode::kOk : out.status().code();
  }
  Camera camera;
  Gaussians g;
  TexturePool pool;
  RenderSettings settings;
};

TEST_F(RenderValidation, RejectsBadInputWithAStatus) {
  EXPECT_EQ(ForwardCode(), StatusCode::kOk);
  {
    auto saved = camera;
    camera.width = 0;
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    camera = saved;
    camera.width = 1 << 20;
    EXPECT_EQ(ForwardCode(), StatusCode::kLimitExceeded);
    camera = saved;
    camera.fx = 0;
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    camera = saved;
    camera.world_to_camera[0] = 2;  // not rigid
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    camera = saved;
    camera.cy = std::nan("");
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    camera = saved;
  }
  {
    auto saved = g;
    g.positions.pop_back();
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    g = saved;
    g.sh.push_back(0);
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    g = saved;
    g.positions[4] = std::nanf("");
    auto out = RenderForward(camera, g, &pool, settings);
    ASSERT_FALSE(out.ok());
    EXPECT_EQ(out.status().code(), StatusCode::kOutOfRange);
    EXPECT_NE(out.status().message().find("element 1"), std::string::npos) << out.status().message();
    g = saved;
    g.opacity_logits[2] = INFINITY;
    EXPECT_EQ(ForwardCode(), StatusCode::kOutOfRange);
    g = saved;
    for (int k = 0; k < 4; ++k) g.rotations[8 + k] = 0;  // zero quaternion
    EXPECT_EQ(ForwardCode(), StatusCode::kOutOfRange);
    g = saved;
    g.sh_degree = 4;
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    g = saved;
  }
  {
    auto saved = pool;
    pool.heights[1] = 3;
    EXPECT_EQ(ForwardCode(), StatusCode::kOutOfRange);
    pool = saved;
    pool.axis_v[0] = pool.axis_u[0];
    EXPECT_EQ(ForwardCode(), StatusCode::kOutOfRange);
    pool = saved;
    pool.texels.pop_back();
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    pool = saved;
    pool.offsets[2] += 1;
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    pool = saved;
    pool.texels[7] = std::nanf("");
    EXPECT_EQ(ForwardCode(), StatusCode::kOutOfRange);
    pool = saved;
    pool.axis_u.pop_back();
    EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
    pool = saved;
  }
  settings.near_plane = -1;
  EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
  settings = RenderSettings{};
  settings.active_sh_degree = 7;
  EXPECT_EQ(ForwardCode(), StatusCode::kInvalidArgument);
  settings = RenderSettings{};
}

TEST_F(RenderValidation, BackwardRejectsMismatchedForwardAndBadGradients) {
  auto out = RenderForward(camera, g, &pool, settings);
  ASSERT_TRUE(out.ok());
  std::vector<float> grad(out->color.size(), 0.5f);
  RenderGradients grads;
  EXPECT_TRUE(RenderBackward(camera, g, &pool, settings, *out, grad.data(), nullptr, &grads).ok());
  EXPECT_EQ(RenderBackward(camera, g, &pool, settings, *out, nullptr, nullptr, &grads).code(),
            StatusCode::kInvalidArgument);
  // Textures in forward but not in backward.
  EXPECT_EQ(RenderBackward<float>(camera, g, nullptr, settings, *out, grad.data(), nullptr, &grads).code(),
            StatusCode::kInvalidArgument);
  auto other = camera;
  other.width = 30;
  EXPECT_EQ(RenderBackward(other, g, &pool, settings, *out, grad.data(), nullptr, &grads).code(),
            StatusCode::kInvalidArgument);
  auto broken = *out;
  if (!broken.state.tile_gaussians.empty()) broken.state.tile_gaussians[0] = 1000;
  EXPECT_EQ(RenderBackward(camera, g, &pool, settings, broken, grad.data(), nullptr, &grads).code(),
            StatusCode::kInvalidArgument);
  broken = *out;
  broken.state.contributor_end[0] = 1 << 20;
  EXPECT_EQ(RenderBackward(camera, g, &pool, settings, broken, grad.data(), nullptr, &grads).code(),
            StatusCode::kInvalidArgument);
  grad[5] = std::nanf("");
  EXPECT_EQ(RenderBackward(camera, g, &pool, settings, *out, grad.data(), nullptr, &grads).code(),
            StatusCode::kOutOfRange);
}

}  // namespace
}  // namespace atex
