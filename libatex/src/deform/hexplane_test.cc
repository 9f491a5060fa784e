// The per-sample HexPlane maths of atex/detail/hexplane.h against values
// worked out by hand from the grid_sample definition (align_corners=True,
// border padding) and against finite differences.
#include "atex/detail/hexplane.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace atex::detail {
namespace {

TEST(HexPlaneAxisTap, CornerAlignedIndexAndWeights) {
  // res 5: c = -1 -> knot 0, c = 1 -> knot 4, c = 0 -> knot 2, c = 0.3 -> 2.6.
  AxisTap<double> t = MakeAxisTap(0.3, 5);
  EXPECT_EQ(t.i0, 2);
  EXPECT_EQ(t.i1, 3);
  EXPECT_NEAR(t.w1, 0.6, 1e-12);
  EXPECT_DOUBLE_EQ(t.dg_dc, 2.0);

  t = MakeAxisTap(0.0, 5);
  EXPECT_EQ(t.i0, 2);
  EXPECT_EQ(t.i1, 3);
  EXPECT_DOUBLE_EQ(t.w1, 0.0);
  EXPECT_DOUBLE_EQ(t.dg_dc, 2.0);
}

TEST(HexPlaneAxisTap, BorderClampsWithZeroGradient) {
  for (double c : {-1.0, -1.5, -1e30, -std::numeric_limits<double>::infinity()}) {
    const AxisTap<double> t = MakeAxisTap(c, 7);
    EXPECT_EQ(t.i0, 0) << c;
    EXPECT_DOUBLE_EQ(t.w1, 0.0) << c;
    EXPECT_DOUBLE_EQ(t.dg_dc, 0.0) << c;
  }
  for (double c : {1.0, 1.0001, 42.0, std::numeric_limits<double>::infinity()}) {
    const AxisTap<double> t = MakeAxisTap(c, 7);
    EXPECT_EQ(t.i0, 6) << c;
    EXPECT_EQ(t.i1, 6) << c;
    EXPECT_DOUBLE_EQ(t.w1, 0.0) << c;
    EXPECT_DOUBLE_EQ(t.dg_dc, 0.0) << c;
  }
  const AxisTap<float> nan = MakeAxisTap(std::numeric_limits<float>::quiet_NaN(), 7);
  EXPECT_EQ(nan.i0, 0);
  EXPECT_EQ(nan.i1, 1);
  EXPECT_EQ(nan.w1, 0.0f);
  EXPECT_EQ(nan.dg_dc, 0.0f);
}

TEST(HexPlaneAxisTap, SingleKnotAxis) {
  const AxisTap<double> t = MakeAxisTap(0.25, 1);
  EXPECT_EQ(t.i0, 0);
  EXPECT_EQ(t.i1, 0);
  EXPECT_DOUBLE_EQ(t.w1, 0.0);
  EXPECT_DOUBLE_EQ(t.dg_dc, 0.0);
}

// Bilinear interpolation reproduces a function linear in each knot index
// exactly, so a plane holding v = 100c + 10·b + a samples to 100c + 10·gb + ga.
TEST(HexPlaneSample, ReproducesBilinearFunctionOfTheContinuousIndex) {
  const int channels = 2, res_a = 4, res_b = 3;
  std::vector<double> plane(channels * res_a * res_b);
  for (int c = 0; c < channels; ++c)
    for (int b = 0; b < res_b; ++b)
      for (int a = 0; a < res_a; ++a) plane[(c * res_b + b) * res_a + a] = 100.0 * c + 10.0 * b + a;

  const double ca = 0.2, cb = -0.7;
  const double ga = (ca + 1) / 2 * (res_a - 1);  // 1.8
  const double gb = (cb + 1) / 2 * (res_b - 1);  // 0.3
  double out[2];
  SamplePlane(plane.data(), channels, MakePlaneTap(ca, cb, res_a, res_b), out);
  EXPECT_NEAR(out[0], 10.0 * gb + ga, 1e-12);
  EXPECT_NEAR(out[1], 100.0 + 10.0 * gb + ga, 1e-12);

  // Outside on both axes: the value at the corner knot (a = 3, b = 0).
  SamplePlane(plane.data(), channels, MakePlaneTap(5.0, -2.0, res_a, res_b), out);
  EXPECT_DOUBLE_EQ(out[0], 3.0);
  EXPECT_DOUBLE_EQ(out[1], 103.0);
}

TEST(HexPlaneSample, CornersAndWeightsSumToOne) {
  const PlaneTap<double> tap = MakePlaneTap(0.1, 0.9, 6, 9);
  double total = 0;
  for (int k = 0; k < 4; ++k) {
    total += tap.weight(k);
    EXPECT_GE(tap.corner(k), 0);
    EXPECT_LT(tap.corner(k), 6 * 9);
  }
  EXPECT_NEAR(total, 1.0, 1e-15);
}

TEST(HexPlaneScaleProduct, ConstantPlanesGiveTheProductOfTheConstants) {
  const int channels = 2;
  const int res[4] = {3, 4, 5, 6};
  std::vector<std::vector<double>> planes(kHexPlanes);
  HexPlaneScale<double> scale;
  scale.channels = channels;
  for (int a = 0; a < 4; ++a) scale.resolution[a] = res[a];
  double expected[2] = {1, 1};
  for (int p = 0; p < kHexPlanes; ++p) {
    const int size = channels * res[HexPlaneAxis(p, 0)] * res[HexPlaneAxis(p, 1)];
    planes[p].resize(size);
    for (int c = 0; c < channels; ++c) {
      const double value = 1.0 + 0.1 * p + 0.5 * c;
      for (int i = 0; i < size / channels; ++i) planes[p][c * (size / channels) + i] = value;
      expected[c] *= value;
    }
    scale.planes[p] = planes[p].data();
  }
  const double coord[4] = {0.3, -0.2, 0.9, -0.4};
  double samples[kHexPlanes * 2], feature[2];
  SampleHexPlaneScale(scale, coord, samples, feature);
  EXPECT_NEAR(feature[0], expected[0], 1e-12);
  EXPECT_NEAR(feature[1], expected[1], 1e-12);
}

TEST(HexPlaneScaleProduct, ProductVjpHandlesZeroSamples) {
  const int channels = 1;
  double samples[kHexPlanes] = {2, 0, 3, 5, 7, 11};
  const double grad_feature[1] = {1.0};
  double grad[kHexPlanes];
  HexPlaneProductVjp(samples, channels, grad_feature, grad);
  EXPECT_DOUBLE_EQ(grad[1], 2.0 * 3 * 5 * 7 * 11);  // the only non-zero product of the others
  for (int p : {0, 2, 3, 4, 5}) EXPECT_DOUBLE_EQ(grad[p], 0.0);
}

// Finite differences of L = sum_c r_c · feature_c(coord, planes).
TEST(HexPlaneScaleVjp, MatchesFiniteDifferences) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  const int channels = 3;
  const int res[4] = {4, 5, 3, 6};
  std::vector<std::vector<double>> planes(kHexPlanes);
  HexPlaneScale<double> scale;
  scale.channels = channels;
  for (int a = 0; a < 4; ++a) scale.resolution[a] = res[a];
  for (int p = 0; p < kHexPlanes; ++p) {
    planes[p].resize(channels * res[HexPlaneAxis(p, 0)] * res[HexPlaneAxis(p, 1)]);
    for (double& v : planes[p]) v = u(rng);
    scale.planes[p] = planes[p].data();
  }
  const double r[3] = {0.7, -1.3, 0.4};
  auto loss = [&](const double* coord) {
    double samples[kHexPlanes * 3], feature[3];
    SampleHexPlaneScale(scale, coord, samples, feature);
    return r[0] * feature[0] + r[1] * feature[1] + r[2] * feature[2];
  };
  double coord[4] = {0.31, -0.47, 0.12, 0.66};
  double samples[kHexPlanes * 3], feature[3], grad_samples[kHexPlanes * 3];
  SampleHexPlaneScale(scale, coord, samples, feature);
  HexPlaneProductVjp(samples, channels, r, grad_samples);
  double grad_coord[4] = {0, 0, 0, 0};
  HexPlaneCoordVjp(scale, coord, grad_samples, grad_coord);

  const double h = 1e-6;
  for (int a = 0; a < 4; ++a) {
    double plus[4], minus[4];
    for (int k = 0; k < 4; ++k) plus[k] = minus[k] = coord[k];
    plus[a] += h;
    minus[a] -= h;
    const double fd = (loss(plus) - loss(minus)) / (2 * h);
    EXPECT_NEAR(grad_coord[a], fd, 1e-7 * (1 + std::fabs(fd))) << "axis " << a;
  }
  // Plane gradients through SamplePlaneVjp's adder, for every plane value.
  for (int p = 0; p < kHexPlanes; ++p) {
    std::vector<double> grad_plane(planes[p].size(), 0.0);
    double ga = 0, gb = 0;
    SamplePlaneVjp(scale.planes[p], channels, scale.tap(p, coord), grad_samples + p * channels,
                   [&](long long i, double v) { grad_plane[i] += v; }, &ga, &gb);
    for (size_t i = 0; i < planes[p].size(); ++i) {
      const double saved = planes[p][i];
      planes[p][i] = saved + h;
      const double up = loss(coord);
      planes[p][i] = saved - h;
      const double down = loss(coord);
      planes[p][i] = saved;
      const double fd = (up - down) / (2 * h);
      EXPECT_NEAR(grad_plane[i], fd, 1e-7 * (1 + std::fabs(fd))) << "plane " << p << " value " << i;
    }
  }
}

TEST(HexPlaneNormalize, MatchesTheAabbFormulaAndAllowsFlippedBoxes) {
  const double scale = AabbScale(2.0, 6.0);  // 0.5
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(2.0, 2.0, scale), -1.0);
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(6.0, 2.0, scale), 1.0);
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(5.0, 2.0, scale), 0.5);
  // 4DGaussians' (max, min) order: lo = 1.6, hi = -1.6 maps 1.6 -> -1 and -1.6 -> 1.
  const double flipped = AabbScale(1.6, -1.6);
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(1.6, 1.6, flipped), -1.0);
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(-1.6, 1.6, flipped), 1.0);
  EXPECT_DOUBLE_EQ(NormalizeCoordinate(0.8, 1.6, flipped), -0.5);
}

}  // namespace
}  // namespace atex::detail
