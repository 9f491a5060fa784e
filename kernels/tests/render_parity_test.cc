// The CUDA rasteriser against the CPU reference (libatex RenderForward/Backward)
// on random scenes: colour, every parameter gradient, texel gradients and the
// demand statistic, for every texture mode. Skips without a GPU.
//
// The reference is the CPU engine in DOUBLE precision. A float engine can take a
// different branch than the exact function where a sample sits on a threshold
// (α̃ = 1/255, the 0.99 clamp, u/v clamps): the CPU float engine is measured against
// the same reference, and a quantity passes when the GPU is within the tolerance or
// no further from the exact function than twice the CPU float engine is.
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "atex/deform.h"
#include "atex/render.h"
#include "gpu_test_support.h"
#include "render/render_cuda.h"
#include "render/render_test_util.h"

namespace atex::cuda {
namespace {

using render_testing::TextureKind;
using testing::RelativeError;

struct Case {
  TextureKind textures;
  int width, height, count;
  const char* name;
};

// One random scene through the float and double CPU references and the GPU engine, forward and
// backward, every output compared. Over 120 lines on purpose: a parity case reads top to bottom
// (references, upload, forward, backward, the table of compared quantities), and its gtest
// assertions must stay in one function to stop the case at the first fatal failure.
void RunCase(const Case& c, uint32_t seed) {
  std::mt19937 rng(seed);
  const Camera camera = render_testing::RandomCamera(c.width, c.height, rng);
  render_testing::SceneOptions options;
  options.count = c.count;
  options.textures = c.textures;
  const Gaussians g = render_testing::RandomGaussians<float>(camera, options, rng);
  TexturePool pool;
  const bool textured = c.textures != TextureKind::kNone;
  if (textured) pool = render_testing::RandomTextures<float>(g, c.textures, options.texel_range, rng);
  RenderSettings settings;
  settings.background = {0.2f, 0.4f, 0.6f};

  // CPU references: double (the function) and float (what a float engine achieves).
  auto cpu = RenderForward<float>(camera, g, textured ? &pool : nullptr, settings);
  ASSERT_TRUE(cpu.ok()) << cpu.status().ToString();
  std::vector<float> grad_color(cpu->color.size());
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (float& v : grad_color) v = unit(rng);
  atex::RenderGradients cpu_grads;
  ASSERT_TRUE(RenderBackward<float>(camera, g, textured ? &pool : nullptr, settings, *cpu, grad_color.data(), nullptr,
                                    &cpu_grads)
                  .ok());
  const BasicGaussians<double> gd = Cast<double>(g);
  BasicTexturePool<double> pd;
  pd.heights = pool.heights;
  pd.widths = pool.widths;
  pd.axis_u = pool.axis_u;
  pd.axis_v = pool.axis_v;
  pd.offsets = pool.offsets;
  pd.texels.assign(pool.texels.begin(), pool.texels.end());
  auto exact = RenderForward<double>(camera, gd, textured ? &pd : nullptr, settings);
  ASSERT_TRUE(exact.ok()) << exact.status().ToString();
  const std::vector<double> grad_color_d(grad_color.begin(), grad_color.end());
  BasicRenderGradients<double> exact_grads;
  ASSERT_TRUE(RenderBackward<double>(camera, gd, textured ? &pd : nullptr, settings, *exact, grad_color_d.data(),
                                     nullptr, &exact_grads)
                  .ok());

  // GPU.
  DeviceBuffer<float> positions, rotations, log_scales, opacity, sh, texels;
  DeviceBuffer<uint32_t> offsets;
  DeviceBuffer<uint8_t> layout;
  ATEX_ASSERT_OK(testing::ToDevice(g.positions, &positions));
  ATEX_ASSERT_OK(testing::ToDevice(g.rotations, &rotations));
  ATEX_ASSERT_OK(testing::ToDevice(g.log_scales, &log_scales));
  ATEX_ASSERT_OK(testing::ToDevice(g.opacity_logits, &opacity));
  ATEX_ASSERT_OK(testing::ToDevice(g.sh, &sh));
  RenderInputs in;
  in.count = static_cast<int>(g.size());
  in.sh_coeffs = g.sh_coeffs();
  in.active_sh_degree = std::min(settings.active_sh_degree, g.sh_degree);
  in.positions = positions.data();
  in.rotations = rotations.data();
  in.log_scales = log_scales.data();
  in.opacity = opacity.data();
  in.sh = sh.data();
  for (int k = 0; k < 3; ++k) in.background[k] = settings.background[k];
  if (textured) {
    std::vector<uint8_t> packed;
    for (size_t i = 0; i < pool.size(); ++i) {
      packed.insert(packed.end(), {pool.heights[i], pool.widths[i], pool.axis_u[i], pool.axis_v[i]});
    }
    ATEX_ASSERT_OK(testing::ToDevice(packed, &layout));
    ATEX_ASSERT_OK(testing::ToDevice(std::vector<uint32_t>(pool.offsets.begin(), pool.offsets.end()), &offsets));
    ATEX_ASSERT_OK(testing::ToDevice(pool.texels, &texels));
    in.texels = texels.data();
    in.texel_offsets = offsets.data();
    in.texture_layout = layout.data();
  }
  cudaStream_t stream = nullptr;
  RenderEngine engine(stream);
  const detail::CameraModel<float> cam = detail::MakeCameraModel<float>(camera, settings.near_plane);
  const size_t pixels = size_t(c.width) * c.height;
  DeviceBuffer<float> color, alpha, importance;
  ATEX_ASSERT_OK(testing::PoisonedDevice(pixels * 3, &color));
  ATEX_ASSERT_OK(testing::PoisonedDevice(pixels, &alpha));
  ATEX_ASSERT_OK(importance.Resize(g.size()));
  ATEX_ASSERT_OK(importance.Zero());
  ATEX_ASSERT_OK(engine.Forward(cam, in, color.data(), alpha.data(), importance.data()));
  ATEX_ASSERT_CUDA(cudaDeviceSynchronize());
  const std::vector<float> gpu_color = testing::ToHost(color);
  const std::vector<float> gpu_alpha = testing::ToHost(alpha);
  ASSERT_EQ(testing::FirstNonFinite(gpu_color), -1) << "unwritten or non-finite colour";

  DeviceBuffer<float> d_grad_color, g_positions, g_rotations, g_log_scales, g_opacity, g_sh, g_texels;
  DeviceBuffer<float> norm_sum, visible, max_radius;
  ATEX_ASSERT_OK(testing::ToDevice(grad_color, &d_grad_color));
  for (auto [buffer, n] : {std::pair{&g_positions, g.positions.size()}, std::pair{&g_rotations, g.rotations.size()},
                           std::pair{&g_log_scales, g.log_scales.size()}, std::pair{&g_opacity, g.size()},
                           std::pair{&g_sh, g.sh.size()}, std::pair{&g_texels, std::max<size_t>(1, pool.texels.size())},
                           std::pair{&norm_sum, g.size()}, std::pair{&visible, g.size()},
                           std::pair{&max_radius, g.size()}}) {
    ATEX_ASSERT_OK(buffer->Resize(n));
    ATEX_ASSERT_OK(buffer->Zero());
  }
  RenderGradients grads{g_positions.data(), g_rotations.data(), g_log_scales.data(), g_opacity.data(),
                        g_sh.data(),       textured ? g_texels.data() : nullptr};
  RenderStats stats;
  stats.grad_norm_sum = norm_sum.data();
  stats.visible_count = visible.data();
  stats.max_radius = max_radius.data();
  ATEX_ASSERT_OK(engine.Backward(cam, in, d_grad_color.data(), nullptr, grads, &stats));
  ATEX_ASSERT_CUDA(cudaDeviceSynchronize());

  // Demand statistic of the exact function: |dL/dm| in NDC units for each visible Gaussian.
  auto demand = [&](const auto& mean2d_grad, const std::vector<int32_t>& radius) {
    std::vector<double> out(g.size(), 0.0);
    for (size_t i = 0; i < g.size(); ++i) {
      if (radius[i] <= 0) continue;
      const double gx = mean2d_grad[2 * i] * 0.5 * c.width, gy = mean2d_grad[2 * i + 1] * 0.5 * c.height;
      out[i] = std::sqrt(gx * gx + gy * gy);
    }
    return out;
  };
  std::vector<float> want_visible(g.size(), 0.0f);
  for (size_t i = 0; i < g.size(); ++i) want_visible[i] = exact->radius[i] > 0 ? 1.0f : 0.0f;
  EXPECT_EQ(testing::ToHost(visible), want_visible) << "visibility (positive radius) differs";

  std::vector<float> gpu_texels = testing::ToHost(g_texels);
  gpu_texels.resize(pool.texels.size());
  struct Quantity {
    const char* name;
    std::vector<float> gpu, cpu;
    std::vector<double> exact;
    double tolerance;
  };
  std::vector<float> cpu_demand_f;
  for (double v : demand(cpu_grads.mean2d, cpu->radius)) cpu_demand_f.push_back(static_cast<float>(v));
  std::vector<Quantity> quantities = {
      {"color", gpu_color, cpu->color, exact->color, 1e-4},
      {"alpha", gpu_alpha, cpu->alpha, exact->alpha, 1e-4},
      {"importance", testing::ToHost(importance), cpu->importance, exact->importance, 1e-4},
      {"d_positions", testing::ToHost(g_positions), cpu_grads.gaussians.positions, exact_grads.gaussians.positions,
       1e-3},
      {"d_rotations", testing::ToHost(g_rotations), cpu_grads.gaussians.rotations, exact_grads.gaussians.rotations,
       1e-3},
      {"d_log_scales", testing::ToHost(g_log_scales), cpu_grads.gaussians.log_scales, exact_grads.gaussians.log_scales,
       1e-3},
      {"d_opacity", testing::ToHost(g_opacity), cpu_grads.gaussians.opacity_logits,
       exact_grads.gaussians.opacity_logits, 1e-3},
      {"d_sh", testing::ToHost(g_sh), cpu_grads.gaussians.sh, exact_grads.gaussians.sh, 1e-3},
      {"d_texels", gpu_texels, cpu_grads.texels, exact_grads.texels, 1e-3},
      {"demand", testing::ToHost(norm_sum), cpu_demand_f, demand(exact_grads.mean2d, exact->radius), 1e-3},
  };
  std::printf("[parity] %-9s %4dx%-4d N=%-5d seed %u (GPU vs exact | CPU float vs exact):", c.name, c.width,
              c.height, c.count, seed);
  for (const Quantity& q : quantities) {
    if (q.exact.empty()) continue;
    const double e_gpu = RelativeError(q.gpu, q.exact);
    const double e_cpu = RelativeError(q.cpu, q.exact);
    std::printf(" %s %.1e|%.1e", q.name, e_gpu, e_cpu);
    EXPECT_TRUE(e_gpu <= q.tolerance || e_gpu <= 2.0 * e_cpu)
        << q.name << ": GPU error " << e_gpu << " vs tolerance " << q.tolerance << " (CPU float engine: " << e_cpu
        << ")";
  }
  std::printf("\n");
}

class RenderParity : public ::testing::TestWithParam<Case> {};

TEST_P(RenderParity, MatchesTheCpuReference) {
  ATEX_REQUIRE_CUDA_DEVICE();
  for (uint32_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    RunCase(GetParam(), seed);
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllTextureModes, RenderParity,
    ::testing::Values(Case{TextureKind::kNone, 64, 48, 60, "none"}, Case{TextureKind::kUniform, 64, 48, 60, "uniform"},
                      Case{TextureKind::kAdaptiveMixed, 64, 48, 60, "adaptive"},
                      Case{TextureKind::kNone, 333, 250, 1500, "none"},
                      Case{TextureKind::kAdaptiveMixed, 333, 250, 1500, "adaptive"}));

}  // namespace
}  // namespace atex::cuda
