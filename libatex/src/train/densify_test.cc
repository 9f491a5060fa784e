#include "atex/train/densify.h"

#include <cmath>

#include <gtest/gtest.h>

namespace atex::train {
namespace {

Gaussians Make(const std::vector<float>& log_scale, const std::vector<float>& opacity) {
  Gaussians g;
  g.sh_degree = 0;
  g.Resize(opacity.size());
  for (size_t i = 0; i < opacity.size(); ++i) {
    g.positions[i * 3] = static_cast<float>(i);
    g.rotations[i * 4] = 1.0f;
    for (int k = 0; k < 3; ++k) g.log_scales[i * 3 + k] = log_scale[i];
    g.opacity_logits[i] = std::log(opacity[i] / (1 - opacity[i]));
  }
  return g;
}

TEST(Densify, CloneSplitPrune) {
  // 0: small, high gradient → clone. 1: large, high gradient → split. 2: low gradient → keep.
  // 3: transparent → prune. 4: never visible → keep.
  Gaussians g = Make({std::log(0.001f), std::log(0.5f), std::log(0.001f), std::log(0.001f), std::log(0.001f)},
                     {0.5f, 0.5f, 0.5f, 0.001f, 0.5f});
  DensifyStats s;
  s.grad_norm_sum = {3e-4f * 2, 5e-4f, 1e-5f, 1e-5f, 0};
  s.visible_count = {2, 1, 1, 1, 0};
  s.max_radius = {1, 1, 1, 1, 0};
  DensifyConfig config;
  DensifyReport report;
  auto edit = PlanDensification(g, s, config, /*extent=*/1.0, false, 7, &report);
  ASSERT_TRUE(edit.ok()) << edit.status().ToString();
  // Kept originals 0, 2, 4; clone of 0; two children of 1.
  EXPECT_EQ(edit->source, (std::vector<uint32_t>{0, 2, 4, 0, 1, 1}));
  EXPECT_EQ(edit->reset_moments, (std::vector<uint8_t>{0, 0, 0, 1, 1, 1}));
  EXPECT_EQ(report.cloned, 1u);
  EXPECT_EQ(report.split, 1u);
  EXPECT_EQ(report.pruned, 1u);
  EXPECT_EQ(report.after, 6u);
  // Split children: scales divided by 1.6, positions within a few sigma of the parent.
  for (size_t j = 4; j < 6; ++j) {
    EXPECT_NEAR(std::exp(edit->log_scales[j * 3]), 0.5f / 1.6f, 1e-6);
    EXPECT_NEAR(edit->positions[j * 3], 1.0f, 0.5f * 5);
    EXPECT_NE(edit->positions[j * 3], 1.0f);
  }
  // Deterministic from the seed.
  auto again = PlanDensification(g, s, config, 1.0, false, 7, nullptr);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->positions, edit->positions);
}

TEST(Densify, RespectsMaximumCount) {
  Gaussians g = Make({-7, -7, -7}, {0.5f, 0.5f, 0.5f});
  DensifyStats s{{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
  DensifyConfig config;
  config.max_gaussians = 4;  // room for one more
  DensifyReport report;
  auto edit = PlanDensification(g, s, config, 1.0, false, 1, &report);
  ASSERT_TRUE(edit.ok());
  EXPECT_EQ(edit->source.size(), 4u);
}

TEST(Densify, MismatchedStatsAreAnError) {
  Gaussians g = Make({-7}, {0.5f});
  DensifyStats s{{1, 1}, {1, 1}, {1, 1}};
  EXPECT_EQ(PlanDensification(g, s, DensifyConfig{}, 1.0, false, 1, nullptr).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::train
