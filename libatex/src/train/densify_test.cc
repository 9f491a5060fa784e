#include "atex/train/densify.h"

#include <algorithm>
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

// A pinhole camera at `centre` looking along +z (identity rotation), 100x100 pixels, 90° field of view.
Camera LookingAlongZ(double cx, double cy, double cz) {
  Camera c;
  c.width = c.height = 100;
  c.fx = c.fy = 50;
  c.cx = c.cy = 50;
  c.world_to_camera = {1, 0, 0, -cx, 0, 1, 0, -cy, 0, 0, 1, -cz, 0, 0, 0, 1};
  return c;
}

TEST(Densify, CountsCamerasThatSeeTheCentre) {
  Gaussians g = Make({-7, -7, -7, -7}, {0.5f, 0.5f, 0.5f, 0.5f});
  const float points[4][3] = {{0, 0, 5}, {0, 0, 0.1f}, {8, 0, 5}, {0, 0, -1}};
  for (int i = 0; i < 4; ++i) std::copy(points[i], points[i] + 3, &g.positions[i * 3]);
  // Camera a at the origin, b shifted by 4 in x: both see (0,0,5) (b at 45° to the edge: u = 50 - 40 = 10);
  // (0,0,0.1) is before a's 0.2 near plane and 4 units aside for b (u = 50 - 2000 < 0);
  // (8,0,5) is inside b only (u = 50 + 40 = 90), outside a (u = 130); (0,0,-1) is behind both.
  const std::vector<Camera> cameras{LookingAlongZ(0, 0, 0), LookingAlongZ(4, 0, 0)};
  EXPECT_EQ(CountObservingCameras(g, cameras, 0.2f), (std::vector<uint16_t>{2, 0, 1, 0}));
  EXPECT_EQ(CountObservingCameras(g, cameras, 0.01f), (std::vector<uint16_t>{2, 1, 1, 0}));
}

TEST(Densify, PrunesUnderObservedGaussiansWithTheirOffspring) {
  // 0: seen by 3 cameras, kept. 1: seen by 1, high gradient and small (would clone): pruned, no clone.
  // 2: seen by 1, high gradient and large (would split): pruned, no children. 3: seen by 2 = the minimum, kept.
  Gaussians g = Make({std::log(0.001f), std::log(0.001f), std::log(0.5f), std::log(0.001f)}, {0.5f, 0.5f, 0.5f, 0.5f});
  DensifyStats s{{1e-5f, 1e-3f, 1e-3f, 1e-5f}, {1, 1, 1, 1}, {1, 1, 1, 1}};
  DensifyConfig config;
  config.min_observing_cameras = 2;
  const std::vector<uint16_t> observers{3, 1, 1, 2};
  DensifyReport report;
  auto edit = PlanDensification(g, s, config, 1.0, false, 3, &report, &observers);
  ASSERT_TRUE(edit.ok()) << edit.status().ToString();
  EXPECT_EQ(edit->source, (std::vector<uint32_t>{0, 3}));
  EXPECT_EQ(report.pruned, 2u);
  // The same without the rule: everyone stays, 1 is cloned and 2 split.
  config.min_observing_cameras = 0;
  auto all = PlanDensification(g, s, config, 1.0, false, 3, nullptr, nullptr);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->source, (std::vector<uint32_t>{0, 1, 3, 1, 2, 2}));
  // The rule without counts (or with counts of the wrong size) is an error, not a silent no-op.
  config.min_observing_cameras = 2;
  EXPECT_EQ(PlanDensification(g, s, config, 1.0, false, 3, nullptr, nullptr).status().code(),
            StatusCode::kInvalidArgument);
  const std::vector<uint16_t> short_counts{3};
  EXPECT_EQ(PlanDensification(g, s, config, 1.0, false, 3, nullptr, &short_counts).status().code(),
            StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::train
