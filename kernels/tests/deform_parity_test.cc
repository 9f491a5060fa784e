// Parity of the CUDA deformation engine with the CPU reference (libatex DeformForward /
// DeformBackward / DeformRegularizer, float), on random fields and Gaussians.
//
// Float GPU and float CPU results differ by rounding only, except where the function
// itself is discontinuous: a ReLU pre-activation at 0 and a sampling coordinate on a grid
// knot (the bilinear slope jumps there). A Gaussian that comes within a margin of either
// (judged from a double-precision CPU pass) is left out, so the comparison measures
// rounding, not which side of a kink each engine landed on. The number left out is printed.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "deform_test_util.h"

namespace atex::cuda {
namespace {

using namespace deform_testing;  // NOLINT: the helpers of these tests

// ---- cases --------------------------------------------------------------------------

struct Case {
  std::string name;
  DeformationConfig config;
  int sh_degree = 0;
  size_t n = 0;
  float time = 0;
  double outside_fraction = 0;
  bool null_opacity_gradient = false;  // pass no dL/d(deformed opacity) (counts as zero)
};

std::vector<Case> Cases() {
  std::vector<Case> cases;
  {
    // D-NeRF-like: heads x, s, r; float4 path; 4 threads per Gaussian (shuffle reduction).
    Case c{"dnerf_like", BaseConfig(8, {12, 10, 14, 9}, {1, 2}, 32, 1, {true, true, true, false, false}, 0), 0, 3000,
           0.3137f, 0.2};
    cases.push_back(c);
  }
  {
    // N3DV-like: all five heads, SH degree 3 (48 SH outputs); float4 path, 8 threads per Gaussian.
    Case c{"n3dv_like", BaseConfig(16, {10, 12, 8, 15}, {1, 2}, 64, 1, {true, true, true, true, true}, 3), 3, 2500,
           0.63f, 0.2};
    cases.push_back(c);
  }
  {
    // multires [1, 2, 4], C = 6 (scalar path, 18 threads per Gaussian: atomic reduction), two trunk
    // layers, an imported-style AABB stored as (max, min), 40% of the points outside the AABB and a
    // time beyond the range (time coordinate clamped).
    Case c{"multires3_scalar", BaseConfig(6, {7, 9, 6, 11}, {1, 2, 4}, 48, 2, {true, false, true, true, false}, 1),
           1, 2000, 1.2f, 0.4};
    std::swap(c.config.aabb_lo, c.config.aabb_hi);
    cases.push_back(c);
  }
  {
    // C = 12 (float4 path, 6 threads per Gaussian: atomic reduction), three trunk layers, all heads
    // with SH degree 2, no gradient for the opacity output, native time mapping of [2, 5].
    Case c{"deep_trunk_sh2", BaseConfig(12, {9, 8, 10, 7}, {1, 2}, 40, 3, {true, true, true, true, true}, 2), 2,
           2000, 3.8359375f, 0.3, true};
    c.config.time_scale = 2.0f / 3.0f;
    c.config.time_offset = -7.0f / 3.0f;
    cases.push_back(c);
  }
  return cases;
}

class DeformParityTest : public ::testing::TestWithParam<Case> {};

// Over 120 lines on purpose: one case reads top to bottom (CPU references, upload, forward,
// backward, comparisons), and its fatal gtest assertions must stay in the test body.
TEST_P(DeformParityTest, ForwardAndBackwardMatchCpu) {
  ATEX_REQUIRE_CUDA_DEVICE();
  const Case& c = GetParam();
  const DeformationConfig& config = c.config;
  const DeformationField field = RandomField(config, 1000 + c.n);
  // The time coordinate must not sit on a time knot either (same for every scale).
  const int res_t = config.grid.base_resolution[3];
  ASSERT_FALSE(NearKnot(ContinuousIndex(NormalisedTime(config, c.time), res_t), res_t, 1e-3)) << "bad case time";

  const Gaussians all = RandomGaussians(config, c.n, c.sh_degree, c.outside_fraction, 2000 + c.n);
  const std::vector<size_t> keep = SafeGaussians(field, all, c.time);
  const Gaussians canonical = Subset(all, keep);
  const size_t n = canonical.size();
  ASSERT_GT(n, c.n * 8 / 10) << "too many Gaussians near a kink";
  const int k = canonical.sh_coeffs();

  // CPU reference.
  Gaussians cpu_deformed;
  DeformCache cache;
  ATEX_ASSERT_OK(DeformForward(field, canonical, static_cast<double>(c.time), &cpu_deformed, &cache));

  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  DeviceField device_field;
  ATEX_ASSERT_OK(device_field.Upload(field, gpu.stream()));
  DeviceGaussians d_canonical, d_deformed;
  ATEX_ASSERT_OK(d_canonical.Upload(canonical));
  ATEX_ASSERT_OK(d_deformed.Poison(canonical));
  DeformEngine engine(gpu.cublas(), gpu.stream());
  ATEX_ASSERT_OK(engine.Forward(device_field.layout, device_field.grid.data(), device_field.mlp.data(),
                                static_cast<int>(n), k, c.time, d_canonical.tensors(), d_deformed.tensors()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  const Gaussians gpu_deformed = d_deformed.Download(c.sh_degree);

  struct Named {
    const char* name;
    const std::vector<float>* gpu;
    const std::vector<float>* cpu;
  };
  const Named forward[] = {{"positions", &gpu_deformed.positions, &cpu_deformed.positions},
                           {"log_scales", &gpu_deformed.log_scales, &cpu_deformed.log_scales},
                           {"rotations", &gpu_deformed.rotations, &cpu_deformed.rotations},
                           {"opacity", &gpu_deformed.opacity_logits, &cpu_deformed.opacity_logits},
                           {"sh", &gpu_deformed.sh, &cpu_deformed.sh}};
  std::printf("[deform parity] %s: %zu of %zu Gaussians compared (the rest within a margin of a kink)\n",
              c.name.c_str(), n, c.n);
  for (const Named& t : forward) {
    EXPECT_EQ(FirstNonFinite(*t.gpu), -1) << "forward " << t.name << ": element not written (or not finite)";
    const double error = RelativeError(*t.gpu, *t.cpu);
    std::printf("[deform parity] %s forward %-10s relative error %.3g\n", c.name.c_str(), t.name, error);
    EXPECT_LE(error, kForwardTolerance) << "forward " << t.name;
  }
  // The residual itself (deformed - canonical) must match too, not just the sum.
  {
    std::vector<double> gpu_residual, cpu_residual;
    for (size_t i = 0; i < canonical.positions.size(); ++i) {
      gpu_residual.push_back(double(gpu_deformed.positions[i]) - canonical.positions[i]);
      cpu_residual.push_back(double(cpu_deformed.positions[i]) - canonical.positions[i]);
    }
    const double error = RelativeError(gpu_residual, cpu_residual);
    std::printf("[deform parity] %s forward dx residual relative error %.3g\n", c.name.c_str(), error);
    EXPECT_LE(error, kForwardTolerance);
  }

  // Backward: random upstream gradients; every output starts from a random base and must
  // ACCUMULATE onto it.
  Gaussians grad_deformed = RandomLike(canonical, 1.0, 3000 + c.n);
  if (c.null_opacity_gradient) std::fill(grad_deformed.opacity_logits.begin(), grad_deformed.opacity_logits.end(), 0.f);
  const DeformationField base_field = RandomFieldLike(field, 0.1, 4000 + c.n);
  const Gaussians base_canonical = RandomLike(canonical, 0.1, 5000 + c.n);

  DeformationField cpu_grad_field = base_field;
  Gaussians cpu_grad_canonical = base_canonical;
  ATEX_ASSERT_OK(DeformBackward(field, canonical, static_cast<double>(c.time), cache, grad_deformed, &cpu_grad_field,
                                &cpu_grad_canonical));

  DeviceField d_grad_field;
  ATEX_ASSERT_OK(d_grad_field.Upload(base_field, gpu.stream()));
  DeviceGaussians d_grad_deformed, d_grad_canonical;
  ATEX_ASSERT_OK(d_grad_deformed.Upload(grad_deformed));
  ATEX_ASSERT_OK(d_grad_canonical.Upload(base_canonical));
  GaussianTensors upstream = d_grad_deformed.tensors();
  if (c.null_opacity_gradient) upstream.opacity = nullptr;
  ATEX_ASSERT_OK(engine.Backward(device_field.layout, device_field.grid.data(), device_field.mlp.data(),
                                 static_cast<int>(n), k, c.time, d_canonical.tensors(), upstream,
                                 d_grad_field.grid.data(), d_grad_field.mlp.data(), d_grad_canonical.tensors()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  const StatusOr<DeformationField> gpu_grad_field = d_grad_field.Download(gpu.stream());
  ATEX_ASSERT_OK(gpu_grad_field.status());
  const Gaussians gpu_grad_canonical = d_grad_canonical.Download(c.sh_degree);

  auto check_gradient = [&](const char* name, const std::vector<float>& got, const std::vector<float>& want,
                            const std::vector<float>& base) {
    EXPECT_EQ(FirstNonFinite(got), -1) << "gradient " << name << " not finite";
    const double error = RelativeError(got, want, base);
    std::printf("[deform parity] %s gradient %-10s relative error %.3g\n", c.name.c_str(), name, error);
    EXPECT_LE(error, kGradientTolerance) << "gradient " << name;
  };
  check_gradient("grid", FlattenPlanes(*gpu_grad_field), FlattenPlanes(cpu_grad_field), FlattenPlanes(base_field));
  check_gradient("mlp", FlattenMlp(*gpu_grad_field), FlattenMlp(cpu_grad_field), FlattenMlp(base_field));
  check_gradient("positions", gpu_grad_canonical.positions, cpu_grad_canonical.positions, base_canonical.positions);
  check_gradient("log_scales", gpu_grad_canonical.log_scales, cpu_grad_canonical.log_scales,
                 base_canonical.log_scales);
  check_gradient("rotations", gpu_grad_canonical.rotations, cpu_grad_canonical.rotations, base_canonical.rotations);
  check_gradient("opacity", gpu_grad_canonical.opacity_logits, cpu_grad_canonical.opacity_logits,
                 base_canonical.opacity_logits);
  check_gradient("sh", gpu_grad_canonical.sh, cpu_grad_canonical.sh, base_canonical.sh);

  // A second backward from the same forward, wanting only the position gradient (grid and MLP
  // gradients skipped): the position path must not depend on them.
  Gaussians cpu_positions_only;  // empty: DeformBackward fills zeros
  ATEX_ASSERT_OK(DeformBackward(field, canonical, static_cast<double>(c.time), cache, grad_deformed, nullptr,
                                &cpu_positions_only));
  DeviceBuffer<float> d_positions_only;
  ATEX_ASSERT_OK(ToDevice(std::vector<float>(3 * n, 0.0f), &d_positions_only));
  GaussianTensors positions_only;
  positions_only.positions = d_positions_only.data();
  ATEX_ASSERT_OK(engine.Backward(device_field.layout, device_field.grid.data(), device_field.mlp.data(),
                                 static_cast<int>(n), k, c.time, d_canonical.tensors(), upstream, nullptr, nullptr,
                                 positions_only));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  check_gradient("positions (only)", ToHost(d_positions_only), cpu_positions_only.positions, {});
}

INSTANTIATE_TEST_SUITE_P(Configs, DeformParityTest, ::testing::ValuesIn(Cases()),
                         [](const ::testing::TestParamInfo<Case>& info) { return info.param.name; });

}  // namespace
}  // namespace atex::cuda
