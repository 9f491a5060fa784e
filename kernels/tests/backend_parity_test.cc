// The whole CUDA backend against the CPU backend: the same model (deformation field,
// adaptive textures, SH 1), the same views and requests. The first step's gradients of
// every parameter group must agree; later steps are compared by their losses only
// loosely, because Adam with eps = 1e-15 turns any tiny gradient difference into a
// full-size step (sign(g)·lr) and the trajectories drift apart by design. Statistics,
// a densification edit, a texture growth and the final renders must agree. Skips
// without a GPU.
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "atex/cuda/cuda_backend.h"
#include "atex/deform.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "atex/train/texture_growth.h"
#include "gpu_test_support.h"
#include "render/render_test_util.h"

namespace atex::cuda {
namespace {

using testing::RelativeError;

struct Scene {
  std::vector<Camera> cameras;  // one pose, four times
  std::vector<Image> targets;
  train::ModelState state;
};

Scene MakeScene(uint32_t seed) {
  std::mt19937 rng(seed);
  Scene s;
  const Camera base = render_testing::RandomCamera(96, 72, rng);
  render_testing::SceneOptions options;
  options.count = 300;
  options.sh_degree = 1;
  options.extras = false;
  options.textures = render_testing::TextureKind::kAdaptiveMixed;
  Gaussians g = render_testing::RandomGaussians<float>(base, options, rng);
  TexturePool pool = render_testing::RandomTextures<float>(g, options.textures, 0.5, rng);

  DeformationConfig dc;
  dc.grid.channels = 4;
  dc.grid.base_resolution = {8, 8, 8, 4};
  dc.grid.multires = {1, 2};
  dc.mlp_width = 16;
  dc.heads = {true, true, true, true, true};
  dc.sh_coeffs = g.sh_coeffs();
  for (int k = 0; k < 3; ++k) {
    float lo = 1e30f, hi = -1e30f;
    for (size_t i = 0; i < g.size(); ++i) {
      lo = std::min(lo, g.positions[3 * i + k]);
      hi = std::max(hi, g.positions[3 * i + k]);
    }
    dc.aabb_lo[k] = lo;
    dc.aabb_hi[k] = hi;
  }
  auto field = InitDeformationField(dc, seed);
  EXPECT_TRUE(field.ok());
  // Make the residuals visible: scale up the heads' output layers.
  for (auto& head : field->heads) {
    for (float& w : head[1].weight) w *= 30.0f;
  }
  s.state.gaussians = g;
  s.state.textures = pool;
  s.state.deformation = *field;
  train::ResetMoments(&s.state);

  // Targets: the scene with shifted colours and positions, rendered by the reference.
  Gaussians shifted = g;
  std::normal_distribution<float> noise(0.0f, 0.05f);
  for (float& v : shifted.sh) v += noise(rng);
  for (float& v : shifted.positions) v += 0.2f * noise(rng);
  for (int k = 0; k < 4; ++k) {
    Camera c = base;
    c.time = 0.25 * k;
    Gaussians deformed;
    EXPECT_TRUE(DeformForward(*field, shifted, c.time, &deformed, nullptr).ok());
    RenderSettings settings;
    auto out = RenderForward<float>(c, deformed, &pool, settings);
    EXPECT_TRUE(out.ok());
    s.cameras.push_back(c);
    s.targets.push_back(RenderedImage(*out));
  }
  return s;
}

train::StepRequest Request() {
  train::StepRequest r;
  r.learning_rates = {1e-3, 1e-3, 5e-3, 5e-2, 2.5e-3, 1.25e-4, 2.5e-3, 1.6e-3, 1.6e-4};
  r.active_sh_degree = 1;
  r.apply_deformation = true;
  r.use_textures = true;
  r.plane_tv = 2e-4;
  r.time_smoothness = 1e-3;
  r.time_l1 = 1e-4;
  r.accumulate_densify_stats = true;
  r.accumulate_texture_stats = true;
  r.accumulate_importance = true;
  r.time_bins = 4;
  return r;
}

// Every parameter group's gradient of the last step, GPU against CPU, to 1e-3.
void ExpectSameGradients(train::Backend& cpu, train::Backend& gpu) {
  train::ModelState ga, gb;
  ATEX_ASSERT_OK(cpu.ReadGradients(&ga));
  ATEX_ASSERT_OK(gpu.ReadGradients(&gb));
  auto flatten = [](const DeformationField& f, bool planes) {
    std::vector<float> out;
    if (planes) {
      for (const auto& scale : f.planes) {
        for (const auto& p : scale) out.insert(out.end(), p.begin(), p.end());
      }
    } else {
      for (const auto& l : f.trunk) {
        out.insert(out.end(), l.weight.begin(), l.weight.end());
        out.insert(out.end(), l.bias.begin(), l.bias.end());
      }
      for (const auto& head : f.heads) {
        for (const auto& l : head) {
          out.insert(out.end(), l.weight.begin(), l.weight.end());
          out.insert(out.end(), l.bias.begin(), l.bias.end());
        }
      }
    }
    return out;
  };
  ASSERT_TRUE(ga.textures && gb.textures && ga.deformation && gb.deformation);
  const std::vector<std::tuple<const char*, std::vector<float>, std::vector<float>>> groups = {
      {"positions", gb.gaussians.positions, ga.gaussians.positions},
      {"rotations", gb.gaussians.rotations, ga.gaussians.rotations},
      {"log_scales", gb.gaussians.log_scales, ga.gaussians.log_scales},
      {"opacity", gb.gaussians.opacity_logits, ga.gaussians.opacity_logits},
      {"sh", gb.gaussians.sh, ga.gaussians.sh},
      {"texels", gb.textures->texels, ga.textures->texels},
      {"grid", flatten(*gb.deformation, true), flatten(*ga.deformation, true)},
      {"mlp", flatten(*gb.deformation, false), flatten(*ga.deformation, false)},
  };
  std::printf("[backend parity] step-0 gradients (GPU vs CPU):");
  for (const auto& [name, got, want] : groups) {
    const double e = RelativeError(got, want);
    std::printf(" %s %.2e", name, e);
    EXPECT_LE(e, 1e-3) << name;
  }
  std::printf("\n");
}

// The CPU backend and a CUDA backend (FP32, as parity is measured), both loaded with `state`.
void LoadBoth(const train::ModelState& state, bool profile, std::unique_ptr<train::Backend>* cpu,
              std::unique_ptr<train::Backend>* gpu) {
  CudaBackendOptions options;
  options.tf32 = false;
  options.profile = profile;
  auto gpu_or = MakeCudaBackend(options);
  ASSERT_TRUE(gpu_or.ok()) << gpu_or.status().ToString();
  *gpu = std::move(*gpu_or);
  *cpu = train::MakeCpuBackend();
  ATEX_ASSERT_OK((*cpu)->Load(state));
  ATEX_ASSERT_OK((*gpu)->Load(state));
}

// One step of `batch` on both; both must succeed with finite numbers.
void StepBoth(train::Backend& cpu, train::Backend& gpu, std::span<const train::TrainView> batch,
              train::StepResult* a, train::StepResult* b) {
  const train::StepRequest request = Request();
  auto on_cpu = cpu.Step(request, batch);
  auto on_gpu = gpu.Step(request, batch);
  ASSERT_TRUE(on_cpu.ok()) << on_cpu.status().ToString();
  ASSERT_TRUE(on_gpu.ok()) << on_gpu.status().ToString();
  ASSERT_TRUE(on_cpu->finite && on_gpu->finite);
  *a = std::move(*on_cpu);
  *b = std::move(*on_gpu);
}

TEST(BackendParity, StepsStatisticsEditsAndGrowthMatchTheCpuBackend) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(7);
  std::unique_ptr<train::Backend> cpu, gpu;
  ASSERT_NO_FATAL_FAILURE(LoadBoth(scene.state, /*profile=*/false, &cpu, &gpu));

  std::vector<train::TrainView> views;
  for (size_t k = 0; k < scene.cameras.size(); ++k) {
    views.push_back({&scene.cameras[k], &scene.targets[k], k + 1});
  }
  // Step 0: every gradient.
  {
    train::StepResult a, b;
    ASSERT_NO_FATAL_FAILURE(StepBoth(*cpu, *gpu, std::span<const train::TrainView>(views.data(), 2), &a, &b));
    std::printf("[backend parity] step 0: loss cpu %.8f gpu %.8f\n", a.loss, b.loss);
    EXPECT_LE(std::abs(a.loss - b.loss), 1e-5 * std::abs(a.loss));
    ExpectSameGradients(*cpu, *gpu);
  }
  for (int step = 1; step < 6; ++step) {
    train::StepResult a, b;
    ASSERT_NO_FATAL_FAILURE(
        StepBoth(*cpu, *gpu, std::span<const train::TrainView>(views.data() + (step % 2) * 2, 2), &a, &b));
    const double rel = std::abs(a.loss - b.loss) / std::abs(a.loss);
    std::printf("[backend parity] step %d: loss cpu %.7f gpu %.7f (rel %.2e)\n", step, a.loss, b.loss, rel);
    EXPECT_LE(rel, step <= 2 ? 1e-4 : 5e-2);  // drift after a few Adam steps, see the top of the file
  }

  train::TrainingStats sa, sb;
  ATEX_ASSERT_OK(cpu->ReadStats(train::kStatsAll, &sa));
  ATEX_ASSERT_OK(gpu->ReadStats(train::kStatsAll, &sb));
  EXPECT_EQ(sa.densify.visible_count, sb.densify.visible_count);
  EXPECT_EQ(sa.texture.visible_count, sb.texture.visible_count);
  const double e_demand = RelativeError(sb.texture.demand_sum, sa.texture.demand_sum);
  const double e_grad = RelativeError(sb.densify.grad_norm_sum, sa.densify.grad_norm_sum);
  const double e_scale = RelativeError(sb.texture.scale_u_sum, sa.texture.scale_u_sum);
  const double e_importance = RelativeError(sb.importance, sa.importance);
  std::printf("[backend parity] stats: demand %.2e densify %.2e scale_u %.2e importance %.2e\n", e_demand, e_grad,
              e_scale, e_importance);
  // Statistics summed over six steps of slightly different trajectories.
  EXPECT_LE(e_demand, 2e-2);
  EXPECT_LE(e_grad, 2e-2);
  EXPECT_LE(e_scale, 1e-3);
  EXPECT_LE(e_importance, 1e-2);

  // The same texture growth on both (planned from the CPU statistics), then the same edit.
  train::ModelState before;
  ATEX_ASSERT_OK(cpu->Save(&before));
  const train::GrowthEvidence evidence = train::ComputeGrowthEvidence(sa.texture, {});
  train::Stage2Config growth;
  growth.growth_threshold = 0;
  auto resize = train::PlanTextureGrowth(*before.textures, evidence, growth, 16 * before.gaussians.size(), nullptr);
  ASSERT_TRUE(resize.ok());
  ATEX_ASSERT_OK(cpu->ResizeTextures(*resize));
  ATEX_ASSERT_OK(gpu->ResizeTextures(*resize));
  // A second growth with rescaled moments (Stage2Config::rescale_grown_moments).
  train::ModelState once;
  ATEX_ASSERT_OK(cpu->Save(&once));
  growth.rescale_grown_moments = true;
  auto again = train::PlanTextureGrowth(*once.textures, evidence, growth, 16 * before.gaussians.size(), nullptr);
  ASSERT_TRUE(again.ok());
  ASSERT_TRUE(again->rescale_moments);
  ASSERT_TRUE(again->heights != once.textures->heights || again->widths != once.textures->widths)
      << "the second growth must grow textures for the rescaled moments to be compared";
  ATEX_ASSERT_OK(cpu->ResizeTextures(*again));
  ATEX_ASSERT_OK(gpu->ResizeTextures(*again));
  train::GaussianEdit edit;
  for (uint32_t i = 0; i < before.gaussians.size(); i += 2) edit.source.push_back(i);  // drop every other
  edit.source.push_back(5);                                                            // and clone one
  edit.reset_moments.assign(edit.source.size(), 0);
  edit.reset_moments.back() = 1;
  ATEX_ASSERT_OK(cpu->ApplyEdit(edit));
  ATEX_ASSERT_OK(gpu->ApplyEdit(edit));

  train::ModelState ca, cb;
  ATEX_ASSERT_OK(cpu->Save(&ca));
  ATEX_ASSERT_OK(gpu->Save(&cb));
  ASSERT_EQ(ca.gaussians.size(), cb.gaussians.size());
  ASSERT_TRUE(ca.textures && cb.textures);
  EXPECT_EQ(ca.textures->heights, cb.textures->heights);
  EXPECT_EQ(ca.textures->widths, cb.textures->widths);
  const double e_texels = RelativeError(cb.textures->texels, ca.textures->texels);
  const double e_positions = RelativeError(cb.gaussians.positions, ca.gaussians.positions);
  const double e_m = RelativeError(cb.m_texels, ca.m_texels);
  const double e_v = RelativeError(cb.v_texels, ca.v_texels);
  std::printf("[backend parity] after growth + edit: texels %.2e positions %.2e texel moments %.2e / %.2e\n",
              e_texels, e_positions, e_m, e_v);
  EXPECT_LE(e_texels, 1e-2);
  EXPECT_LE(e_positions, 1e-3);
  EXPECT_LE(e_m, 5e-2);
  EXPECT_LE(e_v, 5e-2);

  train::RenderRequest render;
  render.active_sh_degree = 1;
  auto ia = cpu->Render(scene.cameras[1], render);
  auto ib = gpu->Render(scene.cameras[1], render);
  ASSERT_TRUE(ia.ok() && ib.ok());
  const double e_image = RelativeError(ib->pixels, ia->pixels);
  std::printf("[backend parity] final render: %.2e\n", e_image);
  EXPECT_LE(e_image, 1e-2);
}

// A batch of two times, two views each, listed interleaved: the CUDA backend deforms
// once per time and runs one deformation backward for the sum of the two views' render
// gradients; the gradients must still be the CPU backend's, which deforms per view.
TEST(BackendParity, ViewsOfOneTimeShareOneDeformationPass) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(11);
  std::unique_ptr<train::Backend> cpu, gpu;
  ASSERT_NO_FATAL_FAILURE(LoadBoth(scene.state, /*profile=*/true, &cpu, &gpu));  // profile: counts the passes

  // A second pose at the times of cameras 0 and 1: the base pose moved sideways.
  std::vector<Camera> moved = {scene.cameras[0], scene.cameras[1]};
  for (Camera& c : moved) c.world_to_camera[3] += 0.05;  // camera-space x translation
  const std::vector<train::TrainView> batch = {{&scene.cameras[0], &scene.targets[0], 1},
                                               {&scene.cameras[1], &scene.targets[1], 2},
                                               {&moved[0], &scene.targets[0], 3},
                                               {&moved[1], &scene.targets[1], 4}};
  train::StepResult a, b;
  ASSERT_NO_FATAL_FAILURE(StepBoth(*cpu, *gpu, batch, &a, &b));
  std::printf("[backend parity] shared deformation: loss cpu %.8f gpu %.8f\n", a.loss, b.loss);
  EXPECT_LE(std::abs(a.loss - b.loss), 1e-5 * std::abs(a.loss));
  for (size_t k = 0; k < batch.size(); ++k) EXPECT_NEAR(a.view_psnr[k], b.view_psnr[k], 1e-3) << "view " << k;
  ExpectSameGradients(*cpu, *gpu);
  EXPECT_EQ(gpu->Profile().value("deformation_passes", -1), 2);
}

// Per-camera colour corrections (TrainConfig::camera_colour): the loss of gain · render + offset
// against the target, the gradient chained through the gain, on both backends; a view without
// one (identity) in the same batch.
TEST(BackendParity, CameraColourCorrectionMatchesTheCpuBackend) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(13);
  std::unique_ptr<train::Backend> cpu, gpu;
  ASSERT_NO_FATAL_FAILURE(LoadBoth(scene.state, /*profile=*/false, &cpu, &gpu));
  const train::ColourAffine warm{{1.12f, 0.97f, 0.88f}, {0.03f, -0.01f, 0.02f}};
  const train::ColourAffine cool{{0.91f, 1.04f, 1.10f}, {-0.02f, 0.01f, 0.04f}};
  const std::vector<train::TrainView> batch = {{&scene.cameras[0], &scene.targets[0], 1, warm},
                                               {&scene.cameras[1], &scene.targets[1], 2, cool},
                                               {&scene.cameras[2], &scene.targets[2], 3}};
  train::StepResult a, b;
  ASSERT_NO_FATAL_FAILURE(StepBoth(*cpu, *gpu, batch, &a, &b));
  std::printf("[backend parity] camera colours: loss cpu %.8f gpu %.8f\n", a.loss, b.loss);
  EXPECT_LE(std::abs(a.loss - b.loss), 1e-5 * std::abs(a.loss));
  for (size_t k = 0; k < batch.size(); ++k) EXPECT_NEAR(a.view_psnr[k], b.view_psnr[k], 1e-3) << "view " << k;
  ExpectSameGradients(*cpu, *gpu);
}

// Time-local Gaussians (model.h time_windows): the window's penalty on the deformed opacity,
// the gradients through it, an edit that gathers the windows with the Gaussians, and a render,
// on both backends. Cameras at times 0, 0.25, 0.5, 0.75; windows centred on those times with
// widths that leave penalties from 0 to the cap.
TEST(BackendParity, TimeWindowsMatchTheCpuBackend) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(17);
  train::ModelState& state = scene.state;
  const size_t n = state.gaussians.size();
  state.gaussians.time_windows.assign(2 * n, 0.0f);
  for (size_t i = 0; i < n; i += 2) {  // every other Gaussian time-local, the rest unchanged (k = 0)
    state.gaussians.time_windows[2 * i] = 0.25f * float(i % 4);
    state.gaussians.time_windows[2 * i + 1] = 2.0f + 3.0f * float(i % 7);
  }
  std::unique_ptr<train::Backend> cpu, gpu;
  ASSERT_NO_FATAL_FAILURE(LoadBoth(state, /*profile=*/false, &cpu, &gpu));
  std::vector<train::TrainView> views;
  for (size_t k = 0; k < scene.cameras.size(); ++k) views.push_back({&scene.cameras[k], &scene.targets[k], k + 1});
  train::StepResult a, b;
  ASSERT_NO_FATAL_FAILURE(StepBoth(*cpu, *gpu, std::span<const train::TrainView>(views.data(), 2), &a, &b));
  std::printf("[backend parity] time windows: loss cpu %.8f gpu %.8f\n", a.loss, b.loss);
  EXPECT_LE(std::abs(a.loss - b.loss), 1e-5 * std::abs(a.loss));
  ExpectSameGradients(*cpu, *gpu);

  train::GaussianEdit edit;
  for (uint32_t i = 1; i < n; i += 3) edit.source.push_back(i);
  edit.source.push_back(2);  // a clone of a time-local one
  ATEX_ASSERT_OK(cpu->ApplyEdit(edit));
  ATEX_ASSERT_OK(gpu->ApplyEdit(edit));
  train::ModelState ca, cb;
  ATEX_ASSERT_OK(cpu->Save(&ca));
  ATEX_ASSERT_OK(gpu->Save(&cb));
  ASSERT_EQ(ca.gaussians.time_windows.size(), 2 * edit.source.size());
  EXPECT_EQ(ca.gaussians.time_windows, cb.gaussians.time_windows);
  for (size_t j = 0; j < edit.source.size(); ++j) {
    EXPECT_EQ(cb.gaussians.time_windows[2 * j + 1], state.gaussians.time_windows[2 * edit.source[j] + 1]);
  }
  train::RenderRequest render;
  render.active_sh_degree = 1;
  for (size_t k : {size_t{0}, size_t{3}}) {
    auto ia = cpu->Render(scene.cameras[k], render);
    auto ib = gpu->Render(scene.cameras[k], render);
    ASSERT_TRUE(ia.ok() && ib.ok());
    const double e_image = RelativeError(ib->pixels, ia->pixels);
    std::printf("[backend parity] time windows, render at time %.2f: %.2e\n", scene.cameras[k].time, e_image);
    EXPECT_LE(e_image, 1e-2);
  }
}

// The fitter and the render commands load parameters without moments (RenderStateFromAsset):
// the backend must start them at zero, also where an earlier Load of the same backend left
// other moments in its buffers (the fitter loads every candidate into one backend).
TEST(BackendParity, ALoadWithoutMomentsStartsThemAtZero) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(29);
  const train::ModelState& zeroed = scene.state;  // MakeScene reset its moments
  train::ModelState noisy = zeroed;
  for (float& x : noisy.m_gaussians.positions) x = 0.5f;
  for (float& x : noisy.v_texels) x = 0.25f;
  train::ModelState bare;
  bare.gaussians = zeroed.gaussians;
  bare.textures = zeroed.textures;
  bare.deformation = zeroed.deformation;
  CudaBackendOptions options;
  options.tf32 = false;
  auto a = MakeCudaBackend(options);
  auto b = MakeCudaBackend(options);
  ASSERT_TRUE(a.ok() && b.ok());
  ATEX_ASSERT_OK((*a)->Load(zeroed));
  ATEX_ASSERT_OK((*b)->Load(noisy));
  ATEX_ASSERT_OK((*b)->Load(bare));
  train::RenderRequest render;
  render.active_sh_degree = 1;
  render.apply_deformation = true;
  render.use_textures = true;
  auto ia = (*a)->Render(scene.cameras[1], render);
  auto ib = (*b)->Render(scene.cameras[1], render);
  ASSERT_TRUE(ia.ok() && ib.ok());
  EXPECT_EQ(ia->pixels, ib->pixels);
  std::vector<train::TrainView> views;
  for (size_t k = 0; k < 2; ++k) views.push_back({&scene.cameras[k], &scene.targets[k], k + 1});
  auto ra = (*a)->Step(Request(), views);
  auto rb = (*b)->Step(Request(), views);
  ASSERT_TRUE(ra.ok() && rb.ok());
  train::ModelState sa, sb;
  ATEX_ASSERT_OK((*a)->Save(&sa));
  ATEX_ASSERT_OK((*b)->Save(&sb));
  // After one step from zero, m = (1 - beta1) g: the inherited 0.5 would dominate it. (The
  // gradients' atomic sums may differ in their last bits between the two backends.)
  EXPECT_LE(RelativeError(sb.m_gaussians.positions, sa.m_gaussians.positions), 1e-3);
  EXPECT_LE(RelativeError(sb.v_texels, sa.v_texels), 1e-3);
}

// Views whose images another rank's device keeps (TrainView::keep_on_device false, data parallel
// training): the step is the CPU backend's, and the device keeps none of those images, while the
// views it keeps stay cached for the next step.
TEST(BackendParity, ViewsKeptOnAnotherDeviceAreUsedOnceAndNotCached) {
  ATEX_REQUIRE_CUDA_DEVICE();
  Scene scene = MakeScene(31);
  std::unique_ptr<train::Backend> cpu, gpu;
  ASSERT_NO_FATAL_FAILURE(LoadBoth(scene.state, /*profile=*/false, &cpu, &gpu));
  std::vector<train::TrainView> batch;
  for (size_t k = 0; k < 3; ++k) {
    train::TrainView view{&scene.cameras[k], &scene.targets[k], k + 1};
    view.keep_on_device = k == 1;  // two transient images around one that stays
    batch.push_back(view);
  }
  train::StepResult a, b;
  ASSERT_NO_FATAL_FAILURE(StepBoth(*cpu, *gpu, batch, &a, &b));
  EXPECT_LE(std::abs(a.loss - b.loss), 1e-5 * std::abs(a.loss));
  for (size_t k = 0; k < batch.size(); ++k) EXPECT_NEAR(a.view_psnr[k], b.view_psnr[k], 1e-3) << "view " << k;
  ExpectSameGradients(*cpu, *gpu);
  EXPECT_FALSE(gpu->HasTarget(1));
  EXPECT_TRUE(gpu->HasTarget(2));
  EXPECT_FALSE(gpu->HasTarget(3));
}

}  // namespace
}  // namespace atex::cuda
