// Parity of the CUDA deformation engine with the CPU reference (libatex DeformForward /
// DeformBackward / DeformRegularizer, float), on random fields and Gaussians.
//
// Float GPU and float CPU results differ by rounding only, except where the function
// itself is discontinuous: a ReLU pre-activation at 0 and a sampling coordinate on a grid
// knot (the bilinear slope jumps there). A Gaussian that comes within a margin of either
// (judged from a double-precision CPU pass) is left out, so the comparison measures
// rounding, not which side of a kink each engine landed on. The number left out is printed.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <cublas_v2.h>
#include <gtest/gtest.h>

#include "atex/deform.h"
#include "atex/model.h"
#include "deform/deform_cuda.h"
#include "gpu_test_support.h"

namespace atex::cuda {
namespace {

using ::atex::cuda::testing::CudaDeviceCount;
using ::atex::cuda::testing::FirstNonFinite;
using ::atex::cuda::testing::PoisonedDevice;
using ::atex::cuda::testing::RelativeError;
using ::atex::cuda::testing::ToDevice;
using ::atex::cuda::testing::ToHost;

constexpr double kForwardTolerance = 1e-4;
constexpr double kGradientTolerance = 1e-3;

// ---- random inputs ------------------------------------------------------------------

std::vector<float> Uniform(size_t n, double lo, double hi, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = static_cast<float>(u(rng));
  return v;
}

Linear RandomLinear(int in, int out, std::mt19937_64& rng) {
  Linear l;
  l.in = in;
  l.out = out;
  const double a = std::sqrt(3.0 / in);  // unit-variance outputs for unit-variance inputs
  l.weight = Uniform(static_cast<size_t>(in) * out, -a, a, rng);
  l.bias = Uniform(static_cast<size_t>(out), -0.2, 0.2, rng);
  return l;
}

// Shapes built here from the config (independently of the CPU module); values random.
DeformationField RandomField(const DeformationConfig& config, uint64_t seed, double plane_lo = 0.6,
                             double plane_hi = 1.4) {
  std::mt19937_64 rng(seed);
  DeformationField f;
  f.config = config;
  const HexPlaneConfig& g = config.grid;
  f.planes.resize(static_cast<size_t>(g.scales()));
  for (int s = 0; s < g.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const size_t size = static_cast<size_t>(g.channels) * g.resolution(s, kHexPlaneAxes[p][0]) *
                          g.resolution(s, kHexPlaneAxes[p][1]);
      f.planes[s][p] = Uniform(size, plane_lo, plane_hi, rng);
    }
  }
  for (int l = 0; l < config.trunk_layers; ++l) {
    f.trunk.push_back(RandomLinear(l == 0 ? g.feature_dim() : config.mlp_width, config.mlp_width, rng));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!config.heads[h]) continue;
    f.heads[h][0] = RandomLinear(config.mlp_width, config.mlp_width, rng);
    f.heads[h][1] = RandomLinear(config.mlp_width, config.head_outputs(h), rng);
  }
  return f;
}

// Positions inside the AABB, except a fraction drawn from a box 40% larger on every side.
Gaussians RandomGaussians(const DeformationConfig& config, size_t n, int sh_degree, double outside_fraction,
                          uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Gaussians g;
  g.sh_degree = sh_degree;
  g.Resize(n);
  for (size_t i = 0; i < n; ++i) {
    const bool outside = unit(rng) < outside_fraction;
    for (int a = 0; a < 3; ++a) {
      const double lo = std::min(config.aabb_lo[a], config.aabb_hi[a]);
      const double hi = std::max(config.aabb_lo[a], config.aabb_hi[a]);
      const double margin = outside ? 0.4 * (hi - lo) : 0.0;
      g.positions[3 * i + a] = static_cast<float>(lo - margin + unit(rng) * (hi - lo + 2 * margin));
    }
  }
  g.log_scales = Uniform(g.log_scales.size(), -4.0, -1.0, rng);
  g.rotations = Uniform(g.rotations.size(), -1.0, 1.0, rng);
  g.opacity_logits = Uniform(g.opacity_logits.size(), -2.0, 2.0, rng);
  g.sh = Uniform(g.sh.size(), -0.5, 0.5, rng);
  return g;
}

Gaussians RandomLike(const Gaussians& like, double scale, uint64_t seed) {
  std::mt19937_64 rng(seed);
  Gaussians g;
  g.sh_degree = like.sh_degree;
  g.positions = Uniform(like.positions.size(), -scale, scale, rng);
  g.log_scales = Uniform(like.log_scales.size(), -scale, scale, rng);
  g.rotations = Uniform(like.rotations.size(), -scale, scale, rng);
  g.opacity_logits = Uniform(like.opacity_logits.size(), -scale, scale, rng);
  g.sh = Uniform(like.sh.size(), -scale, scale, rng);
  return g;
}

DeformationField RandomFieldLike(const DeformationField& like, double scale, uint64_t seed) {
  std::mt19937_64 rng(seed);
  DeformationField f = like;
  for (auto& scale_planes : f.planes) {
    for (auto& plane : scale_planes) plane = Uniform(plane.size(), -scale, scale, rng);
  }
  auto randomise = [&](Linear& l) {
    l.weight = Uniform(l.weight.size(), -scale, scale, rng);
    l.bias = Uniform(l.bias.size(), -scale, scale, rng);
  };
  for (Linear& l : f.trunk) randomise(l);
  for (auto& head : f.heads) {
    for (Linear& l : head) randomise(l);
  }
  return f;
}

Gaussians Subset(const Gaussians& g, const std::vector<size_t>& keep) {
  Gaussians out;
  out.sh_degree = g.sh_degree;
  out.Resize(keep.size());
  const size_t k3 = static_cast<size_t>(g.sh_coeffs()) * 3;
  for (size_t j = 0; j < keep.size(); ++j) {
    const size_t i = keep[j];
    std::copy_n(g.positions.begin() + 3 * i, 3, out.positions.begin() + 3 * j);
    std::copy_n(g.log_scales.begin() + 3 * i, 3, out.log_scales.begin() + 3 * j);
    std::copy_n(g.rotations.begin() + 4 * i, 4, out.rotations.begin() + 4 * j);
    out.opacity_logits[j] = g.opacity_logits[i];
    std::copy_n(g.sh.begin() + k3 * i, k3, out.sh.begin() + k3 * j);
  }
  return out;
}

// ---- where the function is discontinuous --------------------------------------------

// True when a continuous grid index is within `margin` of a knot it can reach (0..res-1),
// i.e. where the bilinear slope or the border clamp switches.
bool NearKnot(double g, int res, double margin) {
  if (g < -margin || g > (res - 1) + margin) return false;  // clamped either way
  return std::abs(g - std::round(g)) < margin;
}

double ContinuousIndex(double normalised, int res) { return (normalised + 1.0) / 2.0 * (res - 1); }

double NormalisedTime(const DeformationConfig& config, float time) {
  return static_cast<double>(config.time_scale) * time + static_cast<double>(config.time_offset);
}

// Indices of the Gaussians whose every sampling coordinate is at least 1e-3 (index units)
// from a knot and whose every ReLU input is at least 1e-4 x the layer's RMS from 0.
std::vector<size_t> SafeGaussians(const DeformationField& field, const Gaussians& gaussians, float time) {
  const DeformationConfig& config = field.config;
  const size_t n = gaussians.size();
  std::vector<bool> safe(n, true);
  for (size_t i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double lo = config.aabb_lo[a], hi = config.aabb_hi[a];
      const double c = (gaussians.positions[3 * i + a] - lo) * (2.0 / (hi - lo)) - 1.0;
      for (int s = 0; s < config.grid.scales(); ++s) {
        const int res = config.grid.resolution(s, a);
        if (NearKnot(ContinuousIndex(c, res), res, 1e-3)) safe[i] = false;
      }
    }
  }
  const BasicDeformationField<double> field64 = Cast<double>(field);
  const BasicGaussians<double> gaussians64 = Cast<double>(gaussians);
  BasicGaussians<double> deformed64;
  BasicDeformCache<double> cache;
  const Status status = DeformForward(field64, gaussians64, static_cast<double>(time), &deformed64, &cache);
  EXPECT_TRUE(status.ok()) << status.ToString();
  const int width = config.mlp_width;
  auto mark_small = [&](const std::vector<double>& values) {
    if (values.size() != n * width) return;
    double rms = 0;
    for (double v : values) rms += v * v;
    rms = std::sqrt(rms / std::max<size_t>(1, values.size()));
    for (size_t i = 0; i < n; ++i) {
      for (int j = 0; j < width; ++j) {
        if (std::abs(values[i * width + j]) < 1e-4 * rms) safe[i] = false;
      }
    }
  };
  for (const auto& layer : cache.trunk) mark_small(layer);
  for (const auto& hidden : cache.head_hidden) mark_small(hidden);
  std::vector<size_t> keep;
  for (size_t i = 0; i < n; ++i) {
    if (safe[i]) keep.push_back(i);
  }
  return keep;
}

// ---- device-side Gaussians ----------------------------------------------------------

struct DeviceGaussians {
  DeviceBuffer<float> positions, log_scales, rotations, opacity, sh;

  Status Upload(const Gaussians& g) {
    ATEX_RETURN_IF_ERROR(ToDevice(g.positions, &positions));
    ATEX_RETURN_IF_ERROR(ToDevice(g.log_scales, &log_scales));
    ATEX_RETURN_IF_ERROR(ToDevice(g.rotations, &rotations));
    ATEX_RETURN_IF_ERROR(ToDevice(g.opacity_logits, &opacity));
    return ToDevice(g.sh, &sh);
  }
  Status Poison(const Gaussians& like) {
    ATEX_RETURN_IF_ERROR(PoisonedDevice(like.positions.size(), &positions));
    ATEX_RETURN_IF_ERROR(PoisonedDevice(like.log_scales.size(), &log_scales));
    ATEX_RETURN_IF_ERROR(PoisonedDevice(like.rotations.size(), &rotations));
    ATEX_RETURN_IF_ERROR(PoisonedDevice(like.opacity_logits.size(), &opacity));
    return PoisonedDevice(like.sh.size(), &sh);
  }
  Gaussians Download(int sh_degree) const {
    Gaussians g;
    g.sh_degree = sh_degree;
    g.positions = ToHost(positions);
    g.log_scales = ToHost(log_scales);
    g.rotations = ToHost(rotations);
    g.opacity_logits = ToHost(opacity);
    g.sh = ToHost(sh);
    return g;
  }
  GaussianTensors tensors() {
    GaussianTensors t;
    t.positions = positions.data();
    t.log_scales = log_scales.data();
    t.rotations = rotations.data();
    t.opacity = opacity.data();
    t.sh = sh.data();
    return t;
  }
};

std::vector<float> FlattenPlanes(const DeformationField& f) {
  std::vector<float> out;
  for (const auto& scale_planes : f.planes) {
    for (const auto& plane : scale_planes) out.insert(out.end(), plane.begin(), plane.end());
  }
  return out;
}

std::vector<float> FlattenMlp(const DeformationField& f) {
  std::vector<float> out;
  auto add = [&](const Linear& l) {
    out.insert(out.end(), l.weight.begin(), l.weight.end());
    out.insert(out.end(), l.bias.begin(), l.bias.end());
  };
  for (const Linear& l : f.trunk) add(l);
  for (const auto& head : f.heads) {
    for (const Linear& l : head) add(l);
  }
  return out;
}

// A stream and a cuBLAS handle for one test.
class GpuContext {
 public:
  GpuContext() {
    ok_ = cudaStreamCreate(&stream_) == cudaSuccess && cublasCreate(&cublas_) == CUBLAS_STATUS_SUCCESS;
  }
  ~GpuContext() {
    if (cublas_) cublasDestroy(cublas_);
    if (stream_) cudaStreamDestroy(stream_);
  }
  bool ok() const { return ok_; }
  cudaStream_t stream() const { return stream_; }
  cublasHandle_t cublas() const { return cublas_; }

 private:
  bool ok_ = false;
  cudaStream_t stream_ = nullptr;
  cublasHandle_t cublas_ = nullptr;
};

// The field's parameters on the device in the engine's layout.
struct DeviceField {
  DeformLayout layout;
  DeviceBuffer<float> grid, mlp;
  Status Upload(const DeformationField& field, cudaStream_t stream) {
    layout = DeformLayout::Make(field.config);
    ATEX_RETURN_IF_ERROR(grid.Resize(layout.grid_size));
    ATEX_RETURN_IF_ERROR(mlp.Resize(layout.mlp_size));
    return UploadDeformation(field, layout, grid.data(), mlp.data(), stream);
  }
  StatusOr<DeformationField> Download(cudaStream_t stream) const {
    DeformationField field;
    ATEX_RETURN_IF_ERROR(DownloadDeformation(grid.data(), mlp.data(), layout, &field, stream));
    return field;
  }
};

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

DeformationConfig BaseConfig(int channels, std::array<int, 4> resolution, std::vector<int> multires, int width,
                             int trunk_layers, std::array<bool, kNumDeformHeads> heads, int sh_degree) {
  DeformationConfig c;
  c.grid.channels = channels;
  c.grid.base_resolution = resolution;
  c.grid.multires = std::move(multires);
  c.mlp_width = width;
  c.trunk_layers = trunk_layers;
  c.heads = heads;
  c.sh_coeffs = ShCoeffCount(sh_degree);
  c.aabb_lo = {-1.3f, -0.8f, -2.0f};
  c.aabb_hi = {1.1f, 1.6f, 0.5f};
  return c;
}

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

// The engine must leave the caller's cuBLAS handle as it found it, run FP32 GEMMs even when the
// handle allows TF32, and honour set_allow_tf32 (looser tolerance: TF32 has a 10-bit mantissa).
TEST(DeformEngineTest, RestoresHandleSettingsAndHonoursTf32) {
  ATEX_REQUIRE_CUDA_DEVICE();
  const DeformationConfig config =
      BaseConfig(8, {12, 10, 14, 9}, {1, 2}, 32, 1, {true, true, true, false, false}, 0);
  const DeformationField field = RandomField(config, 42);
  const Gaussians all = RandomGaussians(config, 1500, 0, 0.1, 43);
  const Gaussians canonical = Subset(all, SafeGaussians(field, all, 0.25f));
  const size_t n = canonical.size();
  Gaussians cpu_deformed;
  ATEX_ASSERT_OK(DeformForward(field, canonical, 0.25, &cpu_deformed, nullptr));

  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  cudaStream_t other_stream = nullptr;
  ATEX_ASSERT_CUDA(cudaStreamCreate(&other_stream));
  ASSERT_EQ(cublasSetStream(gpu.cublas(), other_stream), CUBLAS_STATUS_SUCCESS);
  ASSERT_EQ(cublasSetMathMode(gpu.cublas(), CUBLAS_TF32_TENSOR_OP_MATH), CUBLAS_STATUS_SUCCESS);

  DeviceField device_field;
  ATEX_ASSERT_OK(device_field.Upload(field, gpu.stream()));
  DeviceGaussians d_canonical, d_deformed;
  ATEX_ASSERT_OK(d_canonical.Upload(canonical));
  DeformEngine engine(gpu.cublas(), gpu.stream());
  for (int run = 0; run < 4; ++run) {
    const bool tf32 = run % 2 == 1, fuse = run < 2;
    engine.set_allow_tf32(tf32);
    engine.set_fuse_bias_relu(fuse);
    ATEX_ASSERT_OK(d_deformed.Poison(canonical));
    ATEX_ASSERT_OK(engine.Forward(device_field.layout, device_field.grid.data(), device_field.mlp.data(),
                                  static_cast<int>(n), 1, 0.25f, d_canonical.tensors(), d_deformed.tensors()));
    ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
    const Gaussians gpu_deformed = d_deformed.Download(0);
    const double error = RelativeError(gpu_deformed.positions, cpu_deformed.positions);
    std::printf("[deform parity] forward positions with %s GEMMs (%d hidden layers fused, %d not) on a TF32-enabled "
                "handle: relative error %.3g\n",
                tf32 ? "TF32" : "FP32", engine.last_forward_fused_layers(), engine.last_forward_unfused_layers(),
                error);
    EXPECT_EQ(FirstNonFinite(gpu_deformed.positions), -1);
    EXPECT_LE(error, tf32 ? 2e-2 : kForwardTolerance);
    // Training and rendering run TF32 with the fused epilogue: it must actually be taken on
    // the GPUs we build for, or the measured speed is not the code's.
    if (tf32 && fuse) {
      EXPECT_EQ(engine.last_forward_unfused_layers(), 0);
    }
    if (!fuse) {
      EXPECT_EQ(engine.last_forward_fused_layers(), 0);
    }
    cudaStream_t stream_after = nullptr;
    cublasMath_t math_after = CUBLAS_DEFAULT_MATH;
    ASSERT_EQ(cublasGetStream(gpu.cublas(), &stream_after), CUBLAS_STATUS_SUCCESS);
    ASSERT_EQ(cublasGetMathMode(gpu.cublas(), &math_after), CUBLAS_STATUS_SUCCESS);
    EXPECT_EQ(stream_after, other_stream);
    EXPECT_EQ(math_after, CUBLAS_TF32_TENSOR_OP_MATH);
  }
  cublasSetStream(gpu.cublas(), nullptr);
  cudaStreamDestroy(other_stream);
}

// ---- regulariser ----------------------------------------------------------------------

void CheckRegularizer(const DeformationConfig& config, const char* name) {
  const DeformationField field = RandomField(config, 77, 0.2, 1.8);
  const DeformationField base = RandomFieldLike(field, 0.001, 78);
  RegularizerWeights weights;
  weights.plane_tv = 0.3f;
  weights.time_smoothness = 0.7f;
  weights.time_l1 = 0.2f;
  DeformationField cpu_grad = base;
  const float cpu_value = DeformRegularizer(field, weights, &cpu_grad);
  ASSERT_TRUE(std::isfinite(cpu_value));

  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  DeviceField d_field, d_grad;
  ATEX_ASSERT_OK(d_field.Upload(field, gpu.stream()));
  ATEX_ASSERT_OK(d_grad.Upload(base, gpu.stream()));
  DeviceBuffer<float> loss;
  ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.25f}, &loss));  // the engine ADDS to it
  DeformEngine engine(gpu.cublas(), gpu.stream());
  ATEX_ASSERT_OK(engine.Regularizer(d_field.layout, d_field.grid.data(), weights.plane_tv, weights.time_smoothness,
                                    weights.time_l1, d_grad.grid.data(), loss.data()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  const double gpu_value = static_cast<double>(ToHost(loss)[0]) - 0.25;
  const double value_error = std::abs(gpu_value - cpu_value) / std::abs(static_cast<double>(cpu_value));
  const StatusOr<DeformationField> gpu_grad = d_grad.Download(gpu.stream());
  ATEX_ASSERT_OK(gpu_grad.status());
  const double grad_error = RelativeError(FlattenPlanes(*gpu_grad), FlattenPlanes(cpu_grad), FlattenPlanes(base));
  std::printf("[deform parity] regulariser %s: value %.9g (cpu %.9g) relative error %.3g, gradient %.3g\n", name,
              gpu_value, static_cast<double>(cpu_value), value_error, grad_error);
  EXPECT_LE(value_error, 1e-5);
  EXPECT_LE(grad_error, 1e-5);
  EXPECT_EQ(FirstNonFinite(FlattenPlanes(*gpu_grad)), -1);
  // The MLP part of the gradient buffer is not touched.
  EXPECT_EQ(FlattenMlp(*gpu_grad), FlattenMlp(base));

  // Value only (no gradient buffer) gives the same value.
  ATEX_ASSERT_OK(ToDevice(std::vector<float>{0.0f}, &loss));
  ATEX_ASSERT_OK(engine.Regularizer(d_field.layout, d_field.grid.data(), weights.plane_tv, weights.time_smoothness,
                                    weights.time_l1, nullptr, loss.data()));
  ATEX_ASSERT_CUDA(cudaStreamSynchronize(gpu.stream()));
  EXPECT_NEAR(ToHost(loss)[0], gpu_value, 1e-6 * std::abs(gpu_value));
}

TEST(DeformRegularizerParityTest, MatchesCpu) {
  ATEX_REQUIRE_CUDA_DEVICE();
  CheckRegularizer(BaseConfig(8, {12, 10, 14, 9}, {1, 2}, 16, 1, {true, true, true, false, false}, 0), "two scales");
}

TEST(DeformRegularizerParityTest, PlanesWithFewerThanThreeRowsSkipSmoothness) {
  ATEX_REQUIRE_CUDA_DEVICE();
  // y resolution 2 (xy plane has 2 rows) and time resolution 2 (every time plane has 2 rows).
  CheckRegularizer(BaseConfig(5, {6, 2, 5, 2}, {1, 3}, 16, 1, {true, false, false, false, false}, 0), "short planes");
}

// ---- transfers and layout ---------------------------------------------------------------

TEST(DeformTransferTest, UploadDownloadRoundTripIsExact) {
  ATEX_REQUIRE_CUDA_DEVICE();
  DeformationConfig config =
      BaseConfig(5, {7, 6, 9, 4}, {1, 2, 3}, 24, 2, {true, false, true, true, true}, 2);
  std::swap(config.aabb_lo, config.aabb_hi);
  const DeformationField field = RandomField(config, 99);
  GpuContext gpu;
  ASSERT_TRUE(gpu.ok());
  DeviceField d_field;
  ATEX_ASSERT_OK(d_field.Upload(field, gpu.stream()));
  const StatusOr<DeformationField> back = d_field.Download(gpu.stream());
  ATEX_ASSERT_OK(back.status());
  ASSERT_EQ(back->planes.size(), field.planes.size());
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) EXPECT_EQ(back->planes[s][p], field.planes[s][p]) << s << "," << p;
  }
  ASSERT_EQ(back->trunk.size(), field.trunk.size());
  for (size_t l = 0; l < field.trunk.size(); ++l) {
    EXPECT_EQ(back->trunk[l].weight, field.trunk[l].weight);
    EXPECT_EQ(back->trunk[l].bias, field.trunk[l].bias);
    EXPECT_EQ(back->trunk[l].in, field.trunk[l].in);
    EXPECT_EQ(back->trunk[l].out, field.trunk[l].out);
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(back->heads[h][j].weight, field.heads[h][j].weight) << h;
      EXPECT_EQ(back->heads[h][j].bias, field.heads[h][j].bias) << h;
      EXPECT_EQ(back->heads[h][j].in, field.heads[h][j].in) << h;
      EXPECT_EQ(back->heads[h][j].out, field.heads[h][j].out) << h;
    }
  }
  EXPECT_EQ(back->config.aabb_lo, field.config.aabb_lo);
  EXPECT_EQ(back->config.aabb_hi, field.config.aabb_hi);
  EXPECT_EQ(back->config.grid.multires, field.config.grid.multires);
  EXPECT_EQ(back->config.heads, field.config.heads);
  EXPECT_EQ(back->config.sh_coeffs, field.config.sh_coeffs);
  EXPECT_TRUE(CheckDeformationField(*back).ok());

  // The device grid is channel-last: value (c, b, a) of plane (s, p) sits at ((b * res_a) + a) * C + c.
  const std::vector<float> grid = ToHost(d_field.grid);
  const int s = 1, p = 4;  // yt plane of the second scale
  const int res_a = config.grid.resolution(s, kHexPlaneAxes[p][0]);
  const int res_b = config.grid.resolution(s, kHexPlaneAxes[p][1]);
  const int c = 3, b = 2, a = 5;
  ASSERT_LT(a, res_a);
  ASSERT_LT(b, res_b);
  EXPECT_EQ(grid[d_field.layout.plane_offset[s * 6 + p] + (static_cast<size_t>(b) * res_a + a) * 5 + c],
            field.planes[s][p][(static_cast<size_t>(c) * res_b + b) * res_a + a]);
}

// These run without a device: the checks happen before anything touches the GPU.
TEST(DeformLayoutTest, SizesMatchTheFieldsParameterCount) {
  DeformationConfig config = BaseConfig(7, {5, 6, 7, 8}, {1, 2, 4}, 20, 3, {true, false, true, false, true}, 3);
  const DeformationField field = RandomField(config, 5);
  const DeformLayout layout = DeformLayout::Make(config);
  EXPECT_EQ(layout.grid_size + layout.mlp_size, ParameterCount(field));
  EXPECT_EQ(layout.grid_size, FlattenPlanes(field).size());
  EXPECT_EQ(layout.mlp_size, FlattenMlp(field).size());
  // Layers are packed back to back in the documented order.
  EXPECT_EQ(layout.trunk[0].weight, 0u);
  EXPECT_EQ(layout.trunk[0].bias, static_cast<size_t>(config.grid.feature_dim() * 20));
  EXPECT_EQ(layout.head_hidden[kHeadPosition].weight, layout.trunk[2].bias + 20);
  EXPECT_EQ(layout.head_output[kHeadPosition].weight, layout.head_hidden[kHeadPosition].bias + 20);
  EXPECT_EQ(layout.head_hidden[kHeadRotation].weight, layout.head_output[kHeadPosition].bias + 3);
  EXPECT_EQ(layout.head_hidden[kHeadScale].in, 0);  // disabled
  EXPECT_EQ(layout.head_output[kHeadSH].out, 48);
  EXPECT_EQ(layout.mlp_size, layout.head_output[kHeadSH].bias + 48);
  EXPECT_EQ(layout.plane_offset.size(), 18u);
  EXPECT_EQ(layout.plane_offset[1], static_cast<size_t>(7 * 6 * 5));  // after the xy plane [C][y][x]
}

TEST(DeformEngineValidationTest, RejectsBadCallsBeforeTouchingTheDevice) {
  DeformationConfig config = BaseConfig(4, {5, 5, 5, 5}, {1}, 8, 1, {true, true, true, false, true}, 1);
  const DeformLayout layout = DeformLayout::Make(config);
  // A fake, never dereferenced, non-null pointer: validation must fail before any access.
  float* fake = reinterpret_cast<float*>(uintptr_t{256});
  GaussianTensors tensors{fake, fake, fake, fake, fake};
  DeformEngine engine(nullptr, nullptr);
  // SH head configured for K = 4, Gaussians with K = 1.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 1, 0.5f, tensors, {}).code(), StatusCode::kInvalidArgument);
  // Backward with no Forward before it.
  EXPECT_EQ(engine.Backward(layout, fake, fake, 10, 4, 0.5f, tensors, tensors, fake, fake, {}).code(),
            StatusCode::kInvalidArgument);
  // Deformed aliasing canonical.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 4, 0.5f, tensors, tensors).code(), StatusCode::kInvalidArgument);
  // A layout edited after Make.
  DeformLayout edited = layout;
  edited.mlp_size += 1;
  EXPECT_EQ(engine.Forward(edited, fake, fake, 10, 4, 0.5f, tensors, {}).code(), StatusCode::kInvalidArgument);
  // More scales than any valid config has.
  DeformationConfig many = config;
  many.grid.multires.assign(17, 1);
  EXPECT_EQ(engine.Forward(DeformLayout::Make(many), fake, fake, 10, 4, 0.5f, tensors, {}).code(),
            StatusCode::kInvalidArgument);
  // Non-finite time.
  EXPECT_EQ(engine.Forward(layout, fake, fake, 10, 4, std::nanf(""), tensors, {}).code(),
            StatusCode::kInvalidArgument);
  // Upload of a field whose plane has the wrong size.
  DeformationField field = RandomField(config, 3);
  field.planes[0][2].pop_back();
  EXPECT_EQ(UploadDeformation(field, layout, fake, fake, nullptr).code(), StatusCode::kInvalidArgument);
  // Download into nothing.
  EXPECT_EQ(DownloadDeformation(fake, fake, layout, nullptr, nullptr).code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::cuda
