// Finite-difference checks (double precision, central differences) of
// DeformBackward and of the regulariser gradient, over every parameter of a
// small field: each plane value, every weight and bias of the trunk and of
// every head, and every canonical parameter (positions through both the
// residual and the sampling coordinates). The worst relative error of each
// group is printed and must stay below 1e-6.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "atex/deform.h"
#include "deform/deform_test_util.h"

namespace atex {
namespace {

using testing::RandomField;
using testing::RandomGaussians;
using testing::SmallConfig;

constexpr double kStep = 1e-5;
constexpr double kTolerance = 1e-6;

// sum_i w_i (a_i - ref_i), accumulated in long double: subtracting the
// unperturbed output first keeps the finite differences' rounding noise near
// the rounding of the residuals themselves.
long double Dot(const std::vector<double>& a, const std::vector<double>& ref, const std::vector<double>& w) {
  long double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += static_cast<long double>(w[i]) * (a[i] - ref[i]);
  return sum;
}

// L = sum over all deformed arrays of weights ⊙ (deformed - reference), whose
// gradient is that of sum weights ⊙ deformed.
double Loss(const BasicDeformationField<double>& field, const BasicGaussians<double>& canonical, double time,
            const BasicGaussians<double>& weights, const BasicGaussians<double>& ref) {
  BasicGaussians<double> out;
  const Status st = DeformForward(field, canonical, time, &out, nullptr);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return static_cast<double>(Dot(out.positions, ref.positions, weights.positions) +
                             Dot(out.rotations, ref.rotations, weights.rotations) +
                             Dot(out.log_scales, ref.log_scales, weights.log_scales) +
                             Dot(out.opacity_logits, ref.opacity_logits, weights.opacity_logits) +
                             Dot(out.sh, ref.sh, weights.sh));
}

// Compares analytic[i] with the central difference of loss() over values[i],
// for every i; returns the worst relative error |a - fd| / max(1e-3, |a|, |fd|).
double CheckGroup(const std::string& name, std::vector<double>& values, const std::vector<double>& analytic,
                  const std::function<double()>& loss) {
  EXPECT_EQ(values.size(), analytic.size()) << name;
  double worst = 0;
  for (size_t i = 0; i < values.size(); ++i) {
    const double saved = values[i];
    values[i] = saved + kStep;
    const double up = loss();
    values[i] = saved - kStep;
    const double down = loss();
    values[i] = saved;
    const double fd = (up - down) / (2 * kStep);
    const double error = std::fabs(analytic[i] - fd) / std::max({1e-3, std::fabs(analytic[i]), std::fabs(fd)});
    worst = std::max(worst, error);
    EXPECT_LT(error, kTolerance) << name << "[" << i << "]: analytic " << analytic[i] << ", finite difference " << fd;
  }
  std::printf("  max relative error %-28s %.3g (%zu values)\n", name.c_str(), worst, values.size());
  return worst;
}

// Runs the full check for one config and set of Gaussians.
void CheckAllGradients(const DeformationConfig& config, int sh_degree, double position_lo, double position_hi,
                       uint64_t seed) {
  BasicDeformationField<double> field = RandomField(config, seed);
  BasicGaussians<double> canonical = RandomGaussians(9, sh_degree, seed + 1, position_lo, position_hi);
  const BasicGaussians<double> weights = RandomGaussians(9, sh_degree, seed + 2, -1.0, 1.0);
  const double time = 0.41;

  BasicGaussians<double> deformed;
  BasicDeformCache<double> cache;
  ASSERT_TRUE(DeformForward(field, canonical, time, &deformed, &cache).ok());
  BasicDeformationField<double> grad_field;
  BasicGaussians<double> grad_canonical;
  ASSERT_TRUE(DeformBackward(field, canonical, time, cache, weights, &grad_field, &grad_canonical).ok());

  auto loss = [&] { return Loss(field, canonical, time, weights, deformed); };
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      CheckGroup("plane s" + std::to_string(s) + " p" + std::to_string(p), field.planes[s][p],
                 grad_field.planes[s][p], loss);
    }
  }
  for (size_t i = 0; i < field.trunk.size(); ++i) {
    CheckGroup("trunk " + std::to_string(i) + " weight", field.trunk[i].weight, grad_field.trunk[i].weight, loss);
    CheckGroup("trunk " + std::to_string(i) + " bias", field.trunk[i].bias, grad_field.trunk[i].bias, loss);
  }
  const char* head_names[kNumDeformHeads] = {"position", "scale", "rotation", "opacity", "sh"};
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    for (int k = 0; k < 2; ++k) {
      const std::string name = std::string(head_names[h]) + " head " + std::to_string(k);
      CheckGroup(name + " weight", field.heads[h][k].weight, grad_field.heads[h][k].weight, loss);
      CheckGroup(name + " bias", field.heads[h][k].bias, grad_field.heads[h][k].bias, loss);
    }
  }
  CheckGroup("canonical positions", canonical.positions, grad_canonical.positions, loss);
  CheckGroup("canonical log-scales", canonical.log_scales, grad_canonical.log_scales, loss);
  CheckGroup("canonical rotations", canonical.rotations, grad_canonical.rotations, loss);
  CheckGroup("canonical opacity logits", canonical.opacity_logits, grad_canonical.opacity_logits, loss);
  CheckGroup("canonical SH", canonical.sh, grad_canonical.sh, loss);
}

TEST(DeformGradient, AllHeadsTwoTrunkLayersMatchFiniteDifferences) {
  std::printf("all heads, 2 trunk layers, SH degree 1:\n");
  // Positions inside the box: every coordinate path is active.
  CheckAllGradients(SmallConfig(), 1, -0.85, 0.85, 100);
}

TEST(DeformGradient, DnerfHeadsOutsidePointsMatchFiniteDifferences) {
  std::printf("heads x, s, r, 1 trunk layer, SH degree 3 (no SH head), points partly outside the box:\n");
  DeformationConfig config = SmallConfig();
  config.trunk_layers = 1;
  config.heads = {true, true, true, false, false};
  config.grid.multires = {1, 3};
  CheckAllGradients(config, 3, -1.6, 1.6, 200);
}

TEST(DeformGradient, BackwardAccumulates) {
  const DeformationConfig config = SmallConfig();
  const BasicDeformationField<double> field = RandomField(config, 7);
  const BasicGaussians<double> canonical = RandomGaussians(20, 1, 8, -0.8, 0.8);
  const BasicGaussians<double> weights = RandomGaussians(20, 1, 9);
  BasicGaussians<double> deformed;
  BasicDeformCache<double> cache;
  ASSERT_TRUE(DeformForward(field, canonical, 0.3, &deformed, &cache).ok());
  BasicDeformationField<double> once, twice;
  BasicGaussians<double> g_once, g_twice;
  ASSERT_TRUE(DeformBackward(field, canonical, 0.3, cache, weights, &once, &g_once).ok());
  ASSERT_TRUE(DeformBackward(field, canonical, 0.3, cache, weights, &twice, &g_twice).ok());
  ASSERT_TRUE(DeformBackward(field, canonical, 0.3, cache, weights, &twice, &g_twice).ok());
  for (size_t i = 0; i < once.planes[1][2].size(); ++i) {
    EXPECT_NEAR(twice.planes[1][2][i], 2 * once.planes[1][2][i], 1e-12);
  }
  for (size_t i = 0; i < once.heads[kHeadSH][1].weight.size(); ++i) {
    EXPECT_NEAR(twice.heads[kHeadSH][1].weight[i], 2 * once.heads[kHeadSH][1].weight[i], 1e-12);
  }
  for (size_t i = 0; i < g_once.positions.size(); ++i) {
    EXPECT_NEAR(g_twice.positions[i], 2 * g_once.positions[i], 1e-12);
  }
  // Canonical gradients alone (no field gradient) are the same.
  BasicGaussians<double> g_only;
  ASSERT_TRUE(DeformBackward(field, canonical, 0.3, cache, weights, nullptr, &g_only).ok());
  EXPECT_EQ(g_only.positions, g_once.positions);
}

TEST(DeformGradient, RegularizerMatchesFiniteDifferences) {
  DeformationConfig config;
  config.grid.channels = 2;
  config.grid.base_resolution = {4, 5, 3, 6};
  config.grid.multires = {1, 2};
  config.mlp_width = 2;
  config.heads = {true, false, false, false, false};
  // Planes away from 1 so that |1 - P| is differentiable at every value.
  BasicDeformationField<double> field = RandomField(config, 12, 1.05, 1.6);
  for (int s = 0; s < 2; ++s)
    for (int p : {1, 4})  // some values below 1 as well
      for (double& v : field.planes[s][p]) v -= 0.7;
  RegularizerWeights w;
  w.plane_tv = 0.3f;
  w.time_smoothness = 0.7f;
  w.time_l1 = 0.2f;
  BasicDeformationField<double> grad = ZerosLike(field);
  const double value = DeformRegularizer(field, w, &grad);
  EXPECT_GT(value, 0.0);
  auto loss = [&] { return DeformRegularizer(field, w, nullptr); };
  std::printf("regulariser:\n");
  for (int s = 0; s < 2; ++s)
    for (int p = 0; p < kNumHexPlanes; ++p)
      CheckGroup("regulariser s" + std::to_string(s) + " p" + std::to_string(p), field.planes[s][p],
                 grad.planes[s][p], loss);
}

}  // namespace
}  // namespace atex
