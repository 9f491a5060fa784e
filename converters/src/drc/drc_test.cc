#include "atex/converters/drc.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "atex/converters/ply.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"

namespace atex {
namespace {

using converters::testing::RandomGaussians;

// Draco's position quantisation: one cubic range (the largest axis extent) from
// the per-axis minimum, 2^bits - 1 steps.
struct Grid {
  float min[3];
  double step;
  std::array<int64_t, 3> Cell(const float* p) const {
    return {std::llround((p[0] - min[0]) / step), std::llround((p[1] - min[1]) / step),
            std::llround((p[2] - min[2]) / step)};
  }
};

Grid GridOf(const std::vector<float>& positions, int bits) {
  Grid grid;
  float max[3];
  for (int k = 0; k < 3; ++k) {
    grid.min[k] = max[k] = positions[k];
  }
  for (size_t i = 0; i < positions.size(); ++i) {
    grid.min[i % 3] = std::min(grid.min[i % 3], positions[i]);
    max[i % 3] = std::max(max[i % 3], positions[i]);
  }
  double range = 0;
  for (int k = 0; k < 3; ++k) range = std::max(range, double(max[k]) - grid.min[k]);
  grid.step = range / ((1 << bits) - 1);
  return grid;
}

TEST(Draco, SequentialKeepsOrderWithinQuantisation) {
  const Gaussians g = RandomGaussians(2000, 1, 3, 10.0f);
  DracoExportOptions options;
  options.kd_tree = false;
  options.colors = options.opacity = options.scales = options.rotations = true;
  auto bytes = EncodeDracoPointCloud(g, options);
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  auto pc = DecodeDracoPointCloud(bytes->data(), bytes->size());
  ASSERT_TRUE(pc.ok()) << pc.status().ToString();
  ASSERT_EQ(pc->size(), g.size());
  const double step = GridOf(g.positions, 16).step;
  for (size_t i = 0; i < g.positions.size(); ++i) {
    ASSERT_NEAR(pc->positions[i], g.positions[i], 0.5 * step * 1.001 + 1e-6) << i;
  }
  ASSERT_EQ(pc->colors.size(), g.size() * 3);
  ASSERT_EQ(pc->opacity.size(), g.size());
  ASSERT_EQ(pc->log_scales.size(), g.size() * 3);
  ASSERT_EQ(pc->rotations.size(), g.size() * 4);
  for (size_t i = 0; i < g.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const float expected = std::clamp(0.5f + 0.28209479f * g.sh[i * 12 + c], 0.0f, 1.0f) * 255.0f;
      ASSERT_NEAR(pc->colors[i * 3 + c], expected, 0.51f);
    }
    ASSERT_NEAR(pc->opacity[i], 1.0f / (1.0f + std::exp(-g.opacity_logits[i])), 1.0 / 4095);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(pc->log_scales[i * 3 + k], g.log_scales[i * 3 + k], 3.0 / 4095);
    const float* r = &g.rotations[i * 4];
    const float norm = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (int k = 0; k < 4; ++k) ASSERT_NEAR(pc->rotations[i * 4 + k], r[k] / norm, 2.0 / 4095);
  }
}

TEST(Draco, KdTreeReordersButKeepsEveryPointAndItsAttributes) {
  const Gaussians g = RandomGaussians(3000, 0, 9, 50.0f);
  DracoExportOptions options;
  options.position_bits = 14;
  options.opacity = true;
  auto bytes = EncodeDracoPointCloud(g, options);
  ASSERT_TRUE(bytes.ok());
  auto pc = DecodeDracoPointCloud(bytes->data(), bytes->size());
  ASSERT_TRUE(pc.ok()) << pc.status().ToString();
  ASSERT_EQ(pc->size(), g.size());
  // Match each decoded point to an unused original within half a quantisation step
  // per axis that carries the same opacity. (The kd-tree coder's grid origin is its
  // own, so candidates are looked up in the 27 neighbouring cells of a step-sized hash grid.)
  const double step = GridOf(g.positions, 14).step;
  auto cell_of = [&](const float* p) {
    return std::array<int64_t, 3>{static_cast<int64_t>(std::floor(p[0] / step)),
                                  static_cast<int64_t>(std::floor(p[1] / step)),
                                  static_cast<int64_t>(std::floor(p[2] / step))};
  };
  std::multimap<std::array<int64_t, 3>, size_t> cells;
  for (size_t i = 0; i < g.size(); ++i) cells.emplace(cell_of(&g.positions[i * 3]), i);
  std::vector<bool> used(g.size(), false);
  size_t matched = 0;
  for (size_t j = 0; j < pc->size(); ++j) {
    const float* p = &pc->positions[j * 3];
    const auto c = cell_of(p);
    bool found = false;
    for (int dx = -1; dx <= 1 && !found; ++dx) {
      for (int dy = -1; dy <= 1 && !found; ++dy) {
        for (int dz = -1; dz <= 1 && !found; ++dz) {
          auto [begin, end] = cells.equal_range({c[0] + dx, c[1] + dy, c[2] + dz});
          for (auto it = begin; it != end && !found; ++it) {
            const size_t i = it->second;
            if (used[i]) continue;
            bool near = true;
            for (int k = 0; k < 3; ++k) near = near && std::fabs(p[k] - g.positions[i * 3 + k]) <= 0.5 * step * 1.01;
            const float alpha = 1.0f / (1.0f + std::exp(-g.opacity_logits[i]));
            if (near && std::fabs(pc->opacity[j] - alpha) <= 1.0 / 4095) {
              used[i] = true;
              found = true;
            }
          }
        }
      }
    }
    ASSERT_TRUE(found) << "decoded point " << j << " matches no unused original (position and opacity)";
    ++matched;
  }
  EXPECT_EQ(matched, g.size());
}

TEST(Draco, RealPlyBitsPerPoint) {
  ATEX_REQUIRE_DATA_FILE(path, "splats/kacytran1122_try_iter7000_point_cloud.ply");
  auto g = ReadPlyGaussians(path.string());
  ASSERT_TRUE(g.ok());
  for (int bits : {11, 16}) {
    DracoExportOptions options;
    options.position_bits = bits;
    auto bytes = EncodeDracoPointCloud(*g, options);
    ASSERT_TRUE(bytes.ok());
    auto pc = DecodeDracoPointCloud(bytes->data(), bytes->size());
    ASSERT_TRUE(pc.ok());
    ASSERT_EQ(pc->size(), g->size());
    // Sorted coordinates of each axis move by at most half a step.
    const double step = GridOf(g->positions, bits).step;
    for (int axis = 0; axis < 3; ++axis) {
      std::vector<float> a, b;
      for (size_t i = 0; i < g->size(); ++i) {
        a.push_back(g->positions[i * 3 + axis]);
        b.push_back(pc->positions[i * 3 + axis]);
      }
      std::sort(a.begin(), a.end());
      std::sort(b.begin(), b.end());
      for (size_t i = 0; i < a.size(); ++i) ASSERT_NEAR(a[i], b[i], 0.5 * step * 1.001 + 1e-4);
    }
    // Sanity: entropy coding must beat the raw quantised 3 x bits.
    EXPECT_LT(8.0 * bytes->size() / g->size(), 3.0 * bits);
  }
}

TEST(Draco, RefusesBadInput) {
  Gaussians g = RandomGaussians(5, 0, 1);
  EXPECT_EQ(EncodeDracoPointCloud(g, {.position_bits = 0}).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodeDracoPointCloud(Gaussians{}).status().code(), StatusCode::kInvalidArgument);
  g.positions[4] = NAN;
  EXPECT_EQ(EncodeDracoPointCloud(g).status().code(), StatusCode::kOutOfRange);
  const uint8_t junk[16] = {'D', 'R', 'A', 'C', 'O', 2, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  EXPECT_FALSE(DecodeDracoPointCloud(junk, sizeof junk).ok());
  EXPECT_FALSE(DecodeDracoPointCloud(junk, 3).ok());
}

}  // namespace
}  // namespace atex
