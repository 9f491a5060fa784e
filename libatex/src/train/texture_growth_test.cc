#include "atex/train/texture_growth.h"

#include <gtest/gtest.h>

namespace atex::train {
namespace {

TexturePool Layout(std::vector<uint8_t> h, std::vector<uint8_t> w) {
  TexturePool pool;
  pool.heights = std::move(h);
  pool.widths = std::move(w);
  pool.axis_u.assign(pool.heights.size(), 0);
  pool.axis_v.assign(pool.heights.size(), 1);
  pool.RebuildOffsets();
  pool.texels.assign(pool.texel_count() * 4, 0.0f);
  return pool;
}

// One Gaussian, bins given as (sum of q, visible count, sum s_u, sum s_v).
TextureStats Stats(int bins, const std::vector<std::vector<std::array<float, 4>>>& per_gaussian) {
  TextureStats s;
  s.bins = bins;
  for (const auto& g : per_gaussian) {
    for (int b = 0; b < bins; ++b) {
      s.demand_sum.push_back(g[b][0]);
      s.visible_count.push_back(g[b][1]);
      s.scale_u_sum.push_back(g[b][2]);
      s.scale_v_sum.push_back(g[b][3]);
    }
  }
  return s;
}

TEST(GrowthEvidence, VisibilityNormalisedMeanAndPeak) {
  // Bin 0: two visits with total demand 4e-5 (mean 2e-5); bin 1 empty; bin 2: one visit, 1e-4.
  TextureStats s = Stats(3, {{{4e-5f, 2, 0.02f, 0.02f}, {0, 0, 0, 0}, {1e-4f, 1, 0.05f, 0.004f}}});
  GrowthEvidence e = ComputeGrowthEvidence(s, {});
  // mean over non-empty bins = (2e-5 + 1e-4)/2 = 6e-5; max = 1e-4; g = 8e-5.
  EXPECT_NEAR(e.score[0], 8e-5, 1e-10);
  EXPECT_FLOAT_EQ(e.scale_u[0], 0.05f);  // from the peak bin
  EXPECT_FLOAT_EQ(e.scale_v[0], 0.004f);

  GrowthAblations no_peak;
  no_peak.temporal_peak = false;
  EXPECT_NEAR(ComputeGrowthEvidence(s, no_peak).score[0], 6e-5, 1e-10);

  GrowthAblations no_norm;
  no_norm.visibility_normalization = false;  // sums: bin 0 = 4e-5, bin 2 = 1e-4 → mean 7e-5, max 1e-4
  EXPECT_NEAR(ComputeGrowthEvidence(s, no_norm).score[0], 8.5e-5, 1e-10);
}

TEST(GrowthEvidence, NeverVisibleScoresZero) {
  TextureStats s = Stats(2, {{{0, 0, 0, 0}, {0, 0, 0, 0}}});
  EXPECT_EQ(ComputeGrowthEvidence(s, {}).score[0], 0.0f);
}

TEST(TextureGrowth, AnisotropicRule) {
  TexturePool layout = Layout({1, 1, 1, 1}, {1, 1, 1, 1});
  GrowthEvidence e;
  e.score = {1e-3f, 1e-3f, 1e-3f, 1e-3f};
  // 0: long along u and thin → (h, 2w); 1: long along v and thin → (2h, w);
  // 2: elongated but not thin (s_v = 0.02 ≥ 0.01) → both; 3: isotropic → both.
  e.scale_u = {0.05f, 0.002f, 0.2f, 0.01f};
  e.scale_v = {0.005f, 0.05f, 0.02f, 0.01f};
  Stage2Config config;
  GrowthReport report;
  auto resize = PlanTextureGrowth(layout, e, config, 1000, &report);
  ASSERT_TRUE(resize.ok()) << resize.status().ToString();
  EXPECT_EQ(resize->heights, (std::vector<uint8_t>{1, 2, 2, 2}));
  EXPECT_EQ(resize->widths, (std::vector<uint8_t>{2, 1, 2, 2}));
  EXPECT_EQ(report.grown_u_only, 1u);
  EXPECT_EQ(report.grown_v_only, 1u);
  EXPECT_EQ(report.grown_both, 2u);
  EXPECT_FALSE(resize->rescale_moments) << "off by default";

  config.rescale_grown_moments = true;  // the plan carries the option to the backend
  resize = PlanTextureGrowth(layout, e, config, 1000, &report);
  ASSERT_TRUE(resize.ok());
  EXPECT_TRUE(resize->rescale_moments);
  config.rescale_grown_moments = false;

  config.ablations.anisotropic = false;
  resize = PlanTextureGrowth(layout, e, config, 1000, &report);
  ASSERT_TRUE(resize.ok());
  EXPECT_EQ(resize->heights, (std::vector<uint8_t>{2, 2, 2, 2}));
  EXPECT_EQ(resize->widths, (std::vector<uint8_t>{2, 2, 2, 2}));
}

TEST(TextureGrowth, ThresholdCapsAndOrder) {
  // Gaussian 0 is already 4x4; 1 is below threshold; 2 is 4x2 and grows to 4x4; 3 is 1x4 with a u-proposal (capped).
  TexturePool layout = Layout({4, 1, 4, 1}, {4, 1, 2, 4});
  GrowthEvidence e;
  e.score = {1.0f, 1e-5f, 1e-3f, 1e-3f};
  e.scale_u = {0.01f, 0.01f, 0.01f, 0.05f};
  e.scale_v = {0.01f, 0.01f, 0.01f, 0.005f};
  GrowthReport report;
  auto resize = PlanTextureGrowth(layout, e, Stage2Config{}, 1000, &report);
  ASSERT_TRUE(resize.ok());
  EXPECT_EQ(resize->heights, (std::vector<uint8_t>{4, 1, 4, 1}));
  EXPECT_EQ(resize->widths, (std::vector<uint8_t>{4, 1, 4, 4}));
  EXPECT_EQ(report.candidates, 2u);  // 0 is full, 1 is below 2e-5
  EXPECT_EQ(report.grown, 1u);
}

TEST(TextureGrowth, BudgetIsNeverExceededAndHighestScoresWin) {
  const size_t n = 50;
  TexturePool layout = Layout(std::vector<uint8_t>(n, 1), std::vector<uint8_t>(n, 1));
  GrowthEvidence e;
  for (size_t i = 0; i < n; ++i) {
    e.score.push_back(1e-4f * (1 + i));  // higher index, higher score
    e.scale_u.push_back(0.01f);
    e.scale_v.push_back(0.01f);
  }
  const uint64_t budget = n + 3 * 10 + 2;  // room for ten 1x1→2x2 growths and change
  GrowthReport report;
  auto resize = PlanTextureGrowth(layout, e, Stage2Config{}, budget, &report);
  ASSERT_TRUE(resize.ok());
  uint64_t total = 0;
  for (size_t i = 0; i < n; ++i) total += uint64_t{resize->heights[i]} * resize->widths[i];
  EXPECT_LE(total, budget);
  EXPECT_EQ(report.texels_after, total);
  EXPECT_EQ(report.grown, 10u);
  for (size_t i = n - 10; i < n; ++i) EXPECT_EQ(resize->heights[i], 2) << i;  // the ten best
  for (size_t i = 0; i < n - 10; ++i) EXPECT_EQ(resize->heights[i], 1) << i;
}

}  // namespace
}  // namespace atex::train
