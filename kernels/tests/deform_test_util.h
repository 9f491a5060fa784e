// Helpers of the deformation engine's GPU tests (deform_parity_test.cc,
// deform_engine_parity_test.cc): random fields and Gaussians built from a config independently
// of the CPU module, the Gaussians that stay clear of the function's kinks, and device-side
// copies of Gaussians and fields.
#pragma once

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

namespace atex::cuda::deform_testing {

using ::atex::cuda::testing::CudaDeviceCount;
using ::atex::cuda::testing::FirstNonFinite;
using ::atex::cuda::testing::PoisonedDevice;
using ::atex::cuda::testing::RelativeError;
using ::atex::cuda::testing::ToDevice;
using ::atex::cuda::testing::ToHost;

constexpr double kForwardTolerance = 1e-4;
constexpr double kGradientTolerance = 1e-3;

// ---- random inputs ------------------------------------------------------------------

inline std::vector<float> Uniform(size_t n, double lo, double hi, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = static_cast<float>(u(rng));
  return v;
}

inline Linear RandomLinear(int in, int out, std::mt19937_64& rng) {
  Linear l;
  l.in = in;
  l.out = out;
  const double a = std::sqrt(3.0 / in);  // unit-variance outputs for unit-variance inputs
  l.weight = Uniform(static_cast<size_t>(in) * out, -a, a, rng);
  l.bias = Uniform(static_cast<size_t>(out), -0.2, 0.2, rng);
  return l;
}

// Shapes built here from the config (independently of the CPU module); values random.
inline DeformationField RandomField(const DeformationConfig& config, uint64_t seed, double plane_lo = 0.6,
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
inline Gaussians RandomGaussians(const DeformationConfig& config, size_t n, int sh_degree, double outside_fraction,
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

inline Gaussians RandomLike(const Gaussians& like, double scale, uint64_t seed) {
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

inline DeformationField RandomFieldLike(const DeformationField& like, double scale, uint64_t seed) {
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

inline Gaussians Subset(const Gaussians& g, const std::vector<size_t>& keep) {
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
inline bool NearKnot(double g, int res, double margin) {
  if (g < -margin || g > (res - 1) + margin) return false;  // clamped either way
  return std::abs(g - std::round(g)) < margin;
}

inline double ContinuousIndex(double normalised, int res) { return (normalised + 1.0) / 2.0 * (res - 1); }

inline double NormalisedTime(const DeformationConfig& config, float time) {
  return static_cast<double>(config.time_scale) * time + static_cast<double>(config.time_offset);
}

// Indices of the Gaussians whose every sampling coordinate is at least 1e-3 (index units)
// from a knot and whose every ReLU input is at least 1e-4 x the layer's RMS from 0.
inline std::vector<size_t> SafeGaussians(const DeformationField& field, const Gaussians& gaussians, float time) {
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

inline std::vector<float> FlattenPlanes(const DeformationField& f) {
  std::vector<float> out;
  for (const auto& scale_planes : f.planes) {
    for (const auto& plane : scale_planes) out.insert(out.end(), plane.begin(), plane.end());
  }
  return out;
}

inline std::vector<float> FlattenMlp(const DeformationField& f) {
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

// A config of the given sizes over a fixed, off-centre box.
inline DeformationConfig BaseConfig(int channels, std::array<int, 4> resolution, std::vector<int> multires, int width,
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

}  // namespace atex::cuda::deform_testing
