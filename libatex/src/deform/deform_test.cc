// Behaviour of the deformation field: values worked out independently of the
// implementation, border clamping, disabled heads, errors, determinism across
// thread counts, initialisation, parameter counts and the regularisers.
#include "atex/deform.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "deform/deform_test_util.h"

namespace atex {
namespace {

using testing::RandomField;
using testing::RandomGaussians;
using testing::SmallConfig;

// Plane value of channel c at normalised plane coordinates (ua, ub): an
// affine function, which bilinear interpolation reproduces exactly.
double AffinePlane(int s, int p, int c, double ua, double ub) {
  return 1.0 + 0.1 * p + 0.2 * c + 0.05 * s + 0.1 * (c + 1) * ua - 0.04 * (p + 1) * (s + 1) * ub;
}

double Relu(double x) { return x > 0 ? x : 0; }

// out = W x + b with W [out][in].
std::vector<double> Apply(const BasicLinear<double>& l, const std::vector<double>& x) {
  std::vector<double> y(l.out);
  for (int o = 0; o < l.out; ++o) {
    y[o] = l.bias[o];
    for (int i = 0; i < l.in; ++i) y[o] += l.weight[o * l.in + i] * x[i];
  }
  return y;
}

BasicLinear<double> MakeLinear(int in, int out, std::vector<double> weight, std::vector<double> bias) {
  BasicLinear<double> l;
  l.in = in;
  l.out = out;
  l.weight = std::move(weight);
  l.bias = std::move(bias);
  return l;
}

// A hand-built field: affine planes, a 2-wide trunk and three heads with
// chosen weights; the expected residuals are computed here from the
// definition (normalisation, plane product, ReLU MLP) without the library.
class KnownField : public ::testing::Test {
 protected:
  void SetUp() override {
    DeformationConfig& c = field.config;
    c.grid.channels = 2;
    c.grid.base_resolution = {3, 4, 5, 6};
    c.grid.multires = {1, 2};
    c.mlp_width = 2;
    c.trunk_layers = 1;
    c.heads = {true, true, false, true, false};
    c.sh_coeffs = 1;
    c.aabb_lo = {-2.0f, -1.0f, 3.0f};
    c.aabb_hi = {2.0f, 3.0f, -1.0f};  // z flipped
    c.time_scale = 2.0f;
    c.time_offset = -1.0f;
    field.planes.resize(2);
    for (int s = 0; s < 2; ++s) {
      for (int p = 0; p < kNumHexPlanes; ++p) {
        const int ra = c.grid.resolution(s, kHexPlaneAxes[p][0]);
        const int rb = c.grid.resolution(s, kHexPlaneAxes[p][1]);
        auto& plane = field.planes[s][p];
        plane.resize(2 * ra * rb);
        for (int ch = 0; ch < 2; ++ch)
          for (int b = 0; b < rb; ++b)
            for (int a = 0; a < ra; ++a) {
              const double ua = -1.0 + 2.0 * a / (ra - 1);
              const double ub = -1.0 + 2.0 * b / (rb - 1);
              plane[(ch * rb + b) * ra + a] = AffinePlane(s, p, ch, ua, ub);
            }
      }
    }
    field.trunk.push_back(MakeLinear(4, 2, {0.5, 0, 1, 0, 0, 1, 0, -0.5}, {0.1, -0.2}));
    field.heads[kHeadPosition][0] = MakeLinear(2, 2, {1, 0, 0, 1}, {0, 0});
    field.heads[kHeadPosition][1] = MakeLinear(2, 3, {1, 0, 0, 1, 1, 1}, {0, 0, 0.5});
    field.heads[kHeadScale][0] = MakeLinear(2, 2, {1, 1, -1, 0}, {0, 0.3});
    field.heads[kHeadScale][1] = MakeLinear(2, 3, {1, 0, 0, 1, -1, 2}, {0.1, 0.2, 0.3});
    field.heads[kHeadOpacity][0] = MakeLinear(2, 2, {0, 1, 1, 0}, {-0.1, 0});
    field.heads[kHeadOpacity][1] = MakeLinear(2, 1, {2, -1}, {0.25});
  }

  // Expected residuals (position, scale, opacity) for a world point at time t.
  void Expected(const double* x, double t, std::vector<double>* dx, std::vector<double>* ds, double* dop) {
    const DeformationConfig& c = field.config;
    double coord[4];
    for (int a = 0; a < 3; ++a) {
      const double lo = c.aabb_lo[a], hi = c.aabb_hi[a];
      coord[a] = std::clamp((x[a] - lo) * 2.0 / (hi - lo) - 1.0, -1.0, 1.0);
    }
    coord[3] = std::clamp(c.time_scale * t + c.time_offset, -1.0, 1.0);
    std::vector<double> feat;
    for (int s = 0; s < 2; ++s)
      for (int ch = 0; ch < 2; ++ch) {
        double product = 1;
        for (int p = 0; p < kNumHexPlanes; ++p) {
          product *= AffinePlane(s, p, ch, coord[kHexPlaneAxes[p][0]], coord[kHexPlaneAxes[p][1]]);
        }
        feat.push_back(product);
      }
    const std::vector<double> h = Apply(field.trunk[0], feat);
    auto head = [&](int id) {
      std::vector<double> r = h;
      for (double& v : r) v = Relu(v);
      std::vector<double> a = Apply(field.heads[id][0], r);
      for (double& v : a) v = Relu(v);
      return Apply(field.heads[id][1], a);
    };
    *dx = head(kHeadPosition);
    *ds = head(kHeadScale);
    *dop = head(kHeadOpacity)[0];
  }

  BasicDeformationField<double> field;
};

TEST_F(KnownField, ResidualsMatchTheDefinition) {
  ASSERT_TRUE(CheckDeformationField(field).ok()) << CheckDeformationField(field).ToString();
  BasicGaussians<double> g = RandomGaussians(5, 2, 11, -1.0, 1.0);
  // Inside, near corners, and outside the box on some axes.
  const double points[5][3] = {{0.3, 0.7, 1.2}, {-1.9, 2.9, -0.9}, {1.5, -0.5, 2.5}, {3.0, 1.0, 0.0},
                               {-7.0, 5.0, 9.0}};
  for (int i = 0; i < 5; ++i)
    for (int a = 0; a < 3; ++a) g.positions[3 * i + a] = points[i][a];
  for (double t : {0.0, 0.3, 0.85, 1.4}) {
    BasicGaussians<double> out;
    ASSERT_TRUE(DeformForward(field, g, t, &out, nullptr).ok());
    for (int i = 0; i < 5; ++i) {
      std::vector<double> dx, ds;
      double dop;
      Expected(points[i], t, &dx, &ds, &dop);
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(out.positions[3 * i + a] - g.positions[3 * i + a], dx[a], 1e-12) << "t " << t << " i " << i;
        EXPECT_NEAR(out.log_scales[3 * i + a] - g.log_scales[3 * i + a], ds[a], 1e-12) << "t " << t << " i " << i;
      }
      EXPECT_NEAR(out.opacity_logits[i] - g.opacity_logits[i], dop, 1e-12);
      // Disabled heads (rotation, SH) leave their parameters untouched.
      for (int k = 0; k < 4; ++k) EXPECT_EQ(out.rotations[4 * i + k], g.rotations[4 * i + k]);
    }
    EXPECT_EQ(out.sh, g.sh);
    EXPECT_EQ(out.sh_degree, g.sh_degree);
  }
}

TEST_F(KnownField, TimeMappingUsesScaleAndOffset) {
  // Only the time planes vary with t; with t_norm = 2t - 1, t = 0.25 and t = 0.75
  // sample t_norm = -0.5 and 0.5. Check against the definition at both.
  BasicGaussians<double> g = RandomGaussians(1, 0, 3, -0.5, 0.5);
  for (double t : {0.25, 0.75}) {
    BasicGaussians<double> out;
    ASSERT_TRUE(DeformForward(field, g, t, &out, nullptr).ok());
    std::vector<double> dx, ds;
    double dop;
    Expected(g.positions.data(), t, &dx, &ds, &dop);
    EXPECT_NEAR(out.positions[0] - g.positions[0], dx[0], 1e-12);
  }
  // With time_scale = 1, offset = 0 (imported 4DGaussians), t enters unchanged.
  field.config.time_scale = 1.0f;
  field.config.time_offset = 0.0f;
  BasicGaussians<double> a, b;
  ASSERT_TRUE(DeformForward(field, g, 0.5, &a, nullptr).ok());
  field.config.time_scale = 2.0f;
  field.config.time_offset = -0.5f;  // 2 * 0.5 - 0.5 = 0.5 as well
  ASSERT_TRUE(DeformForward(field, g, 0.5, &b, nullptr).ok());
  EXPECT_EQ(a.positions, b.positions);
}

TEST(DeformBorder, OutsideTheBoxGivesTheClampedValueAndNoCoordinateGradient) {
  const DeformationConfig config = SmallConfig();
  const BasicDeformationField<double> field = RandomField(config, 5);
  BasicGaussians<double> g = RandomGaussians(2, 1, 9, -0.5, 0.5);
  // Gaussian 1 = Gaussian 0 moved beyond the x face of the box (x_norm > 1).
  for (int k = 0; k < 3; ++k) g.positions[3 + k] = g.positions[k];
  g.positions[0] = config.aabb_hi[0] + 1e-9;  // just outside
  g.positions[3] = config.aabb_hi[0] + 0.7;   // far outside
  BasicGaussians<double> out;
  BasicDeformCache<double> cache;
  ASSERT_TRUE(DeformForward(field, g, 0.4, &out, &cache).ok());
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(out.positions[3 + k] - g.positions[3 + k], out.positions[k] - g.positions[k], 1e-14);
  }
  BasicGaussians<double> ones = g;
  for (auto* v : {&ones.positions, &ones.rotations, &ones.log_scales, &ones.opacity_logits, &ones.sh})
    std::fill(v->begin(), v->end(), 1.0);
  BasicGaussians<double> grad;
  ASSERT_TRUE(DeformBackward(field, g, 0.4, cache, ones, nullptr, &grad).ok());
  // Only the identity term remains along x.
  EXPECT_EQ(grad.positions[0], 1.0);
  EXPECT_EQ(grad.positions[3], 1.0);
  EXPECT_NE(grad.positions[4], 1.0);  // y is inside: the coordinate path contributes
}

TEST(DeformErrors, ShapeMismatchesAreRejected) {
  DeformationConfig config = SmallConfig();
  const BasicDeformationField<double> field = RandomField(config, 1);
  BasicGaussians<double> g = RandomGaussians(3, 2, 1);  // K = 9, SH head expects K = 4
  BasicGaussians<double> out;
  Status st = DeformForward(field, g, 0.0, &out, nullptr);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("SH head"), std::string::npos) << st.message();

  g = RandomGaussians(3, 1, 1);
  EXPECT_EQ(DeformForward(field, g, 0.0, &g, nullptr).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(DeformForward(field, g, 0.0, nullptr, nullptr).code(), StatusCode::kInvalidArgument);

  BasicGaussians<double> short_positions = g;
  short_positions.positions.pop_back();
  EXPECT_EQ(DeformForward(field, short_positions, 0.0, &out, nullptr).code(), StatusCode::kInvalidArgument);

  BasicDeformationField<double> bad = field;
  bad.planes[1][4].pop_back();
  st = DeformForward(bad, g, 0.0, &out, nullptr);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("scale 1, plane 4"), std::string::npos) << st.message();

  bad = field;
  bad.heads[kHeadOpacity][1].bias.push_back(0.0);
  EXPECT_EQ(DeformForward(bad, g, 0.0, &out, nullptr).code(), StatusCode::kInvalidArgument);

  bad = field;
  bad.config.aabb_hi[1] = bad.config.aabb_lo[1];
  EXPECT_EQ(DeformForward(bad, g, 0.0, &out, nullptr).code(), StatusCode::kInvalidArgument);

  // A cache from another time or another set of Gaussians.
  BasicDeformCache<double> cache;
  ASSERT_TRUE(DeformForward(field, g, 0.2, &out, &cache).ok());
  BasicGaussians<double> grad_out = g;
  EXPECT_EQ(DeformBackward(field, g, 0.3, cache, grad_out, nullptr, nullptr).code(), StatusCode::kInvalidArgument);
  const BasicGaussians<double> other = RandomGaussians(4, 1, 2);
  EXPECT_EQ(DeformBackward(field, other, 0.2, cache, other, nullptr, nullptr).code(), StatusCode::kInvalidArgument);
  BasicDeformationField<double> wrong_grad = ZerosLike(field);
  wrong_grad.trunk[1].bias.push_back(0.0);
  EXPECT_EQ(DeformBackward(field, g, 0.2, cache, grad_out, &wrong_grad, nullptr).code(),
            StatusCode::kInvalidArgument);
}

TEST(DeformEmpty, NoGaussiansIsFine) {
  const BasicDeformationField<double> field = RandomField(SmallConfig(), 1);
  BasicGaussians<double> g;
  g.sh_degree = 1;
  BasicGaussians<double> out, grad_canonical;
  BasicDeformCache<double> cache;
  ASSERT_TRUE(DeformForward(field, g, 0.5, &out, &cache).ok());
  EXPECT_EQ(out.size(), 0u);
  BasicDeformationField<double> grad_field;
  ASSERT_TRUE(DeformBackward(field, g, 0.5, cache, g, &grad_field, &grad_canonical).ok());
  EXPECT_EQ(ParameterCount(grad_field), ParameterCount(field));
}

TEST(DeformPrecision, FloatAgreesWithDouble) {
  const BasicDeformationField<double> fd = RandomField(SmallConfig(), 21);
  const BasicGaussians<double> gd = RandomGaussians(300, 1, 22, -1.5, 1.5);
  const DeformationField ff = Cast<float>(fd);
  const Gaussians gf = Cast<float>(gd);
  BasicGaussians<double> od;
  Gaussians of;
  ASSERT_TRUE(DeformForward(fd, gd, 0.37, &od, nullptr).ok());
  ASSERT_TRUE(DeformForward(ff, gf, 0.37, &of, nullptr).ok());
  for (size_t i = 0; i < od.positions.size(); ++i) EXPECT_NEAR(of.positions[i], od.positions[i], 1e-4);
  for (size_t i = 0; i < od.sh.size(); ++i) EXPECT_NEAR(of.sh[i], od.sh[i], 1e-4);
}

#ifdef _OPENMP
// One block (no parallel region: lazy products) and many blocks (a team).
void ExpectThreadCountIndependent(size_t n) {
  DeformationConfig config = SmallConfig();
  config.mlp_width = 24;
  const DeformationField field = Cast<float>(RandomField(config, 31));
  const Gaussians g = Cast<float>(RandomGaussians(n, 1, 32));
  const Gaussians grad_out = Cast<float>(RandomGaussians(n, 1, 33));
  struct Result {
    Gaussians deformed, grad_canonical;
    DeformationField grad_field;
  };
  auto run = [&](int threads) {
    const int saved = omp_get_max_threads();
    omp_set_num_threads(threads);
    Result r;
    DeformCache cache;
    EXPECT_TRUE(DeformForward(field, g, 0.6, &r.deformed, &cache).ok());
    EXPECT_TRUE(DeformBackward(field, g, 0.6, cache, grad_out, &r.grad_field, &r.grad_canonical).ok());
    omp_set_num_threads(saved);
    return r;
  };
  const Result one = run(1), three = run(3);
  EXPECT_EQ(one.deformed.positions, three.deformed.positions) << n;
  EXPECT_EQ(one.deformed.sh, three.deformed.sh) << n;
  EXPECT_EQ(one.grad_canonical.positions, three.grad_canonical.positions) << n;
  for (int s = 0; s < 2; ++s)
    for (int p = 0; p < kNumHexPlanes; ++p) EXPECT_EQ(one.grad_field.planes[s][p], three.grad_field.planes[s][p]) << n;
  for (size_t i = 0; i < one.grad_field.trunk.size(); ++i) {
    EXPECT_EQ(one.grad_field.trunk[i].weight, three.grad_field.trunk[i].weight) << n;
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    EXPECT_EQ(one.grad_field.heads[h][0].weight, three.grad_field.heads[h][0].weight) << n;
    EXPECT_EQ(one.grad_field.heads[h][1].bias, three.grad_field.heads[h][1].bias) << n;
  }
}

TEST(DeformDeterminism, ResultsDoNotDependOnTheThreadCount) {
  ExpectThreadCountIndependent(200);   // one block
  ExpectThreadCountIndependent(3000);  // twelve blocks
}
#endif

TEST(DeformInit, FollowsTheConventions) {
  DeformationConfig config;  // D-NeRF shapes
  auto made = InitDeformationField(config, 42);
  ASSERT_TRUE(made.ok()) << made.status().ToString();
  const DeformationField& f = *made;
  ASSERT_TRUE(CheckDeformationField(f).ok());
  double spatial_sum = 0;
  size_t spatial_count = 0;
  for (const auto& scale : f.planes) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      for (float v : scale[p]) {
        if (kHexPlaneAxes[p][1] == 3) {
          ASSERT_EQ(v, 1.0f);
        } else {
          ASSERT_GE(v, 0.1f);
          ASSERT_LE(v, 0.5f);
          spatial_sum += v;
          ++spatial_count;
        }
      }
    }
  }
  EXPECT_NEAR(spatial_sum / spatial_count, 0.3, 0.002);
  auto check_xavier = [](const Linear& l, double gain) {
    const double bound = gain * std::sqrt(6.0 / (l.in + l.out));
    double max_abs = 0;
    for (float w : l.weight) max_abs = std::max(max_abs, double(std::fabs(w)));
    EXPECT_LE(max_abs, bound * (1 + 1e-6));
    EXPECT_GE(max_abs, bound * 0.9);  // uses the whole range
    for (float b : l.bias) EXPECT_EQ(b, 0.0f);
  };
  check_xavier(f.trunk[0], 1.0);
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) {
      EXPECT_TRUE(f.heads[h][0].weight.empty());
      EXPECT_TRUE(f.heads[h][1].weight.empty());
      continue;
    }
    check_xavier(f.heads[h][0], 1.0);
    check_xavier(f.heads[h][1], 0.01);
  }
  auto again = InitDeformationField(config, 42);
  auto other = InitDeformationField(config, 43);
  EXPECT_EQ(again->planes[1][3], f.planes[1][3]);
  EXPECT_EQ(again->heads[0][1].weight, f.heads[0][1].weight);
  EXPECT_NE(other->planes[1][3], f.planes[1][3]);

  config.grid.channels = 0;
  EXPECT_EQ(InitDeformationField(config, 1).status().code(), StatusCode::kInvalidArgument);
  config.grid.channels = 4096;
  config.grid.multires = {1, 2, 4, 8, 16};
  config.grid.base_resolution = {256, 256, 256, 300};
  EXPECT_EQ(InitDeformationField(config, 1).status().code(), StatusCode::kLimitExceeded);
}

TEST(DeformInit, ParameterCountsOfThePublishedConfigs) {
  // D-NeRF: C = 32, [64, 64, 64, 25], multires [1, 2], W = 64, heads x, s, r.
  DeformationConfig dnerf;
  auto a = InitDeformationField(dnerf, 1);
  ASSERT_TRUE(a.ok());
  const size_t dnerf_grid = 32 * (3 * 64 * 64 + 3 * 64 * 25) + 32 * (3 * 128 * 128 + 3 * 128 * 25);
  const size_t dnerf_mlp = (64 * 64 + 64) + 3 * (64 * 64 + 64) + 2 * (64 * 3 + 3) + (64 * 4 + 4);
  EXPECT_EQ(ParameterCount(*a), dnerf_grid + dnerf_mlp);

  // N3DV: C = 16, [64, 64, 64, 150], W = 128, all five heads, SH degree 3.
  DeformationConfig n3dv;
  n3dv.grid.channels = 16;
  n3dv.grid.base_resolution = {64, 64, 64, 150};
  n3dv.mlp_width = 128;
  n3dv.heads = {true, true, true, true, true};
  n3dv.sh_coeffs = 16;
  auto b = InitDeformationField(n3dv, 1);
  ASSERT_TRUE(b.ok());
  size_t grid = 0;
  for (const auto& scale : b->planes)
    for (const auto& plane : scale) grid += plane.size();
  EXPECT_EQ(grid, 2365440u);  // REFERENCE.md: "N3DV grid ≈ 2.37 M parameters"
  // MLP without 4DGaussians' unused timenet (2,720 parameters; REFERENCE.md counts ≈ 97 k with it).
  EXPECT_EQ(ParameterCount(*b) - grid + 2720, 97115u);
}

TEST(DeformRegularizer, KnownValues) {
  DeformationConfig config;
  config.grid.channels = 2;
  config.grid.base_resolution = {4, 5, 6, 7};
  config.grid.multires = {1};
  config.mlp_width = 2;
  config.heads = {true, false, false, false, false};
  BasicDeformationField<double> f = RandomField(config, 3);
  // Spatial planes quadratic along b (second difference 2k everywhere),
  // time planes linear along b (no curvature) at 1.5 +- ..., so |1 - P| is known.
  const double k = 0.3;
  double l1_expected = 0;
  for (int p = 0; p < kNumHexPlanes; ++p) {
    const int ra = config.grid.resolution(0, kHexPlaneAxes[p][0]);
    const int rb = config.grid.resolution(0, kHexPlaneAxes[p][1]);
    double abs_sum = 0;
    for (int c = 0; c < 2; ++c)
      for (int b = 0; b < rb; ++b)
        for (int a = 0; a < ra; ++a) {
          double& v = f.planes[0][p][(c * rb + b) * ra + a];
          if (kHexPlaneAxes[p][1] == 3) {
            v = 1.5 + 0.25 * b + 0.01 * a;
            abs_sum += std::fabs(1 - v);
          } else {
            v = k * b * b + 0.7 * a - c;
          }
        }
    if (kHexPlaneAxes[p][1] == 3) l1_expected += abs_sum / (2.0 * ra * rb);
  }
  RegularizerWeights w;
  w.plane_tv = 0.5f;
  w.time_smoothness = 3.0f;
  w.time_l1 = 0.25f;
  const double expected = 0.5 * 3 * (2 * k) * (2 * k) + 3.0 * 0.0 + 0.25 * l1_expected;
  EXPECT_NEAR(DeformRegularizer(f, w, nullptr), expected, 1e-9);

  // Planes with fewer than three rows contribute nothing to the smoothness terms.
  config.grid.base_resolution = {4, 2, 2, 2};
  BasicDeformationField<double> flat = RandomField(config, 4, 1.0, 1.0);
  EXPECT_EQ(DeformRegularizer(flat, w, nullptr), 0.0);

  BasicDeformationField<double> broken = flat;
  broken.planes[0][0].pop_back();
  EXPECT_TRUE(std::isnan(DeformRegularizer(broken, w, nullptr)));
}

}  // namespace
}  // namespace atex
