// The training loop on the CPU backend with the real tiny D-NeRF lego: learning,
// texture growth, checkpoints and resume, NaN rollback.
#include "atex/train/trainer.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/render.h"
#include "atex/train/checkpoint.h"
#include "core/test_support.h"
#include "train/forwarding_backend.h"
#include "train/trainer_test_util.h"

namespace atex::train {
namespace {

// A small config: a few hundred CPU steps on 100x100 images.
TrainConfig SmallConfig() {
  TrainConfig c = DefaultConfig("dnerf");
  c.stage1.coarse_iterations = 150;
  c.stage1.fine_iterations = 100;
  c.stage1.init_points = 4000;
  c.stage1.densify.from_step = 50;
  c.stage1.densify.interval = 50;
  c.stage1.deformation.grid.channels = 8;
  c.stage1.deformation.grid.base_resolution = {16, 16, 16, 8};
  c.stage1.deformation.mlp_width = 32;
  c.stage2.iterations = 30;
  c.stage2.batch_size = 2;
  c.stage2.growth_steps = {10, 20};
  c.eval_every = 0;
  c.checkpoint_every = 0;
  return c;
}

std::unique_ptr<Dataset> OpenLego(const std::filesystem::path& path) {
  auto dataset = OpenDataset(path.string());
  EXPECT_TRUE(dataset.ok()) << dataset.status().ToString();
  return dataset.ok() ? std::move(*dataset) : nullptr;
}

// SmallConfig with a shorter stage 1: the base model of the stage-2 tests.
TrainConfig ShortStageOneConfig() {
  TrainConfig c = SmallConfig();
  c.stage1.coarse_iterations = 60;
  c.stage1.fine_iterations = 20;
  return c;
}

// Trains `stages` of `config` on a fresh CPU backend (from `init` when given).
StatusOr<TrainSummary> TrainOnCpu(const Dataset& data, const TrainConfig& config, int stages,
                                  const Asset* init = nullptr) {
  TrainerOptions options;
  options.config = config;
  options.stages = stages;
  auto backend = MakeCpuBackend();
  return Train(data, *backend, options, init);
}

TEST(TrainerLego, CpuStageOneRaisesTestPsnrClearly) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.stages = kStage1;
  options.log_every = 25;
  std::vector<std::pair<int, double>> curve;
  options.progress = [&](const TrainProgress& p) {
    if (p.event.empty()) curve.emplace_back(p.step + (p.phase == "fine" ? 150 : 0), p.psnr);
    return true;
  };
  // The initial model's test PSNR: stage 1 with zero steps.
  TrainerOptions initial_options = options;
  initial_options.config.stage1.coarse_iterations = 0;
  initial_options.config.stage1.fine_iterations = 0;
  auto backend0 = MakeCpuBackend();
  auto initial = Train(*data, *backend0, initial_options);
  ASSERT_TRUE(initial.ok()) << initial.status().ToString();

  auto backend = MakeCpuBackend();
  auto trained = Train(*data, *backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  std::printf("[lego] test PSNR initial %.2f dB -> after %d steps %.2f dB (SSIM %.4f)\n", initial->test.mean.psnr,
              trained->coarse_steps + trained->fine_steps, trained->test.mean.psnr, trained->test.mean.ssim);
  for (const auto& [step, psnr] : curve) std::printf("[lego] step %d train PSNR %.2f\n", step, psnr);
  EXPECT_GT(trained->test.mean.psnr, initial->test.mean.psnr + 5.0);
  EXPECT_EQ(trained->test.views.size(), data->test_views().size());
  ASSERT_TRUE(trained->asset.deformation.has_value());
  EXPECT_TRUE(ValidateAsset(trained->asset).ok());
}

// Stage 2 on a short stage-1 model: growth happens, never beyond the budget, adaptive
// uses fewer texels than uniform, and the stored statistics are complete.
TEST(TrainerLego, CpuStageTwoGrowsWithinTheBudget) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  const TrainConfig config = ShortStageOneConfig();
  auto stage1 = TrainOnCpu(*data, config, kStage1);
  ASSERT_TRUE(stage1.ok()) << stage1.status().ToString();
  const size_t n = stage1->asset.gaussians.size();

  uint64_t adaptive_texels = 0;
  for (double fraction : {0.5, 1.0}) {
    TrainConfig budgeted = config;
    budgeted.stage2.texel_budget_fraction = fraction;
    auto stage2 = TrainOnCpu(*data, budgeted, kStage2, &stage1->asset);
    ASSERT_TRUE(stage2.ok()) << stage2.status().ToString();
    ASSERT_TRUE(stage2->asset.textures.has_value());
    const TextureHistogram h = ComputeTextureHistogram(*stage2->asset.textures);
    const uint64_t budget = static_cast<uint64_t>(std::llround(fraction * 16.0 * n));
    EXPECT_LE(h.texels, budget);
    int sizes_used = 0;
    for (const auto& row : h.counts) {
      for (uint64_t c : row) sizes_used += c > 0 ? 1 : 0;
    }
    std::printf("[lego stage 2] budget %.2f: %llu texels (uniform %llu), %d texture sizes in use, growths %zu\n",
                fraction, static_cast<unsigned long long>(h.texels),
                static_cast<unsigned long long>(h.uniform_texels()), sizes_used, stage2->growths.size());
    EXPECT_GE(sizes_used, 2) << "growth left every texture the same size";
    ASSERT_EQ(stage2->growths.size(), 2u);
    EXPECT_GT(stage2->growths[0].grown, 0u);
    for (const auto& g : stage2->growths) EXPECT_LE(g.texels_after, budget);
    ASSERT_TRUE(stage2->asset.stats.has_value());
    EXPECT_EQ(stage2->asset.stats->texture_demand.size(), n);
    EXPECT_TRUE(ValidateAsset(stage2->asset).ok());
    if (fraction == 1.0) adaptive_texels = h.texels;
    // Growth at 10 and 20 of 30 steps: the report notes the late growth (NoteLateGrowth).
    bool noted = false;
    for (const auto& e : stage2->events) {
      noted |= e.find("the last growth (step 20) leaves 10 of 30") != std::string::npos;
    }
    EXPECT_TRUE(noted);
    if (fraction == 0.5) {
      EXPECT_GT(stage2->growths[1].rejected_budget + stage2->growths[0].rejected_budget, 0u);
    }
  }
  EXPECT_LT(adaptive_texels, 16u * n) << "adaptive should use fewer texels than uniform 4x4";
}

TEST(TrainerLego, ObserverCountPruningReachesTheDensificationStep) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  TrainConfig config = SmallConfig();
  config.stage1.coarse_iterations = 10;
  config.stage1.fine_iterations = 0;
  config.stage1.densify.from_step = 0;
  config.stage1.densify.interval = 10;  // one densification, after step 10
  // More cameras than the dataset has: every Gaussian is under-observed, and the trainer
  // stops with the cause instead of training an empty model.
  config.stage1.densify.min_observing_cameras = 100000;
  auto all_pruned = TrainOnCpu(*data, config, kStage1);
  ASSERT_FALSE(all_pruned.ok());
  EXPECT_EQ(all_pruned.status().code(), StatusCode::kNumericalError);
  EXPECT_NE(all_pruned.status().message().find("pruning would remove all"), std::string::npos)
      << all_pruned.status().ToString();
  // One camera: the Gaussians in the training views survive.
  config.stage1.densify.min_observing_cameras = 1;
  auto trained = TrainOnCpu(*data, config, kStage1);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  ASSERT_EQ(trained->densifications.size(), 1u);
  EXPECT_GT(trained->densifications[0].after, 0u);
}

// `--stage 2 --textures none`: the untextured control fine-tunes the Gaussians and the
// deformation for the stage-2 steps (it used to run no step at all), and writes no pool;
// with stage 1 in the same run, "none" stays plain 4DGS (no stage-2 steps).
TEST(TrainerLego, StageTwoWithoutTexturesFineTunesTheModel) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  TrainConfig config = ShortStageOneConfig();
  config.stage2.textures = TextureMode::kNone;
  auto stage1 = TrainOnCpu(*data, config, kStage1 | kStage2);
  ASSERT_TRUE(stage1.ok()) << stage1.status().ToString();
  EXPECT_EQ(stage1->texture_steps, 0);
  EXPECT_FALSE(stage1->asset.textures.has_value());

  auto stage2 = TrainOnCpu(*data, config, kStage2, &stage1->asset);
  ASSERT_TRUE(stage2.ok()) << stage2.status().ToString();
  EXPECT_EQ(stage2->texture_steps, config.stage2.iterations);
  EXPECT_FALSE(stage2->asset.textures.has_value());
  EXPECT_TRUE(stage2->growths.empty());
  ASSERT_EQ(stage2->asset.gaussians.size(), stage1->asset.gaussians.size());
  EXPECT_NE(stage2->asset.gaussians.positions, stage1->asset.gaussians.positions) << "no step changed the model";
  EXPECT_TRUE(ValidateAsset(stage2->asset).ok());
}

// The state after both stages of a short SmallConfig on the CPU backend, with one texture
// growth at stage-2 step 5: after it every texture side is at most 2, so every texture can
// grow again. Trained once per test binary; the growth tests below start from it.
const StatusOr<ModelState>& StateAfterOneGrowth(const Dataset& data) {
  static const StatusOr<ModelState> state = [&]() -> StatusOr<ModelState> {
    TrainConfig config = SmallConfig();
    config.stage1.coarse_iterations = 30;
    config.stage1.fine_iterations = 10;
    config.stage2.iterations = 15;
    config.stage2.growth_steps = {5};
    TrainerOptions options;
    options.config = config;
    auto backend = MakeCpuBackend();
    ATEX_RETURN_IF_ERROR(Train(data, *backend, options).status());
    ModelState saved;
    ATEX_RETURN_IF_ERROR(backend->Save(&saved));
    if (!saved.textures) return MakeError(StatusCode::kInternal, "stage 2 left no texture pool");
    return saved;
  }();
  return state;
}

// Every side doubled, up to 4: every texture that can grow grows, along both axes.
TextureResize GrowEverySide(const TexturePool& pool) {
  TextureResize grow{pool.heights, pool.widths};
  for (size_t i = 0; i < grow.heights.size(); ++i) {
    grow.heights[i] = static_cast<uint8_t>(std::min(4, grow.heights[i] * 2));
    grow.widths[i] = static_cast<uint8_t>(std::min(4, grow.widths[i] * 2));
  }
  return grow;
}

// Growth through the backend leaves the rendered image unchanged (corner-aligned resampling).
TEST(TrainerLego, GrowthThroughTheBackendLeavesRendersUnchanged) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  const StatusOr<ModelState>& state = StateAfterOneGrowth(*data);
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  auto backend = MakeCpuBackend();
  ASSERT_TRUE(backend->Load(*state).ok());
  RenderRequest request;
  request.active_sh_degree = state->gaussians.sh_degree;
  const Camera& camera = data->test_views()[3].camera;
  auto before = backend->Render(camera, request);
  ASSERT_TRUE(before.ok());
  ASSERT_TRUE(backend->ResizeTextures(GrowEverySide(*state->textures)).ok());
  auto after = backend->Render(camera, request);
  ASSERT_TRUE(after.ok());
  double worst = 0;
  for (size_t k = 0; k < before->pixels.size(); ++k) {
    worst = std::max(worst, double(std::abs(before->pixels[k] - after->pixels[k])));
  }
  std::printf("[growth invariance] max |render change| = %.3g\n", worst);
  EXPECT_LE(worst, 1e-5);
}

// Stage2Config::rescale_grown_moments: the same texels, and moments equal to the interpolated
// ones times a (m) and a² (v), a = old texels / new texels of that Gaussian.
TEST(TrainerLego, RescaledGrowthScalesTheInterpolatedMomentsByTheTexelShare) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  const StatusOr<ModelState>& trained = StateAfterOneGrowth(*data);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  const ModelState& state = *trained;
  ASSERT_TRUE(state.textures.has_value());
  TextureResize interpolate = GrowEverySide(*state.textures);
  for (size_t i = 0; i < interpolate.heights.size(); i += 3) interpolate.heights[i] = 4;  // shares of 1/4 too
  TextureResize rescale = interpolate;
  rescale.rescale_moments = true;
  ModelState a, b;
  for (auto [resize, out] : {std::pair{&interpolate, &a}, std::pair{&rescale, &b}}) {
    auto backend = MakeCpuBackend();
    ASSERT_TRUE(backend->Load(state).ok());
    ASSERT_TRUE(backend->ResizeTextures(*resize).ok());
    ASSERT_TRUE(backend->Save(out).ok());
  }
  ASSERT_EQ(a.textures->texels, b.textures->texels);
  ASSERT_EQ(a.m_texels.size(), b.m_texels.size());
  size_t checked = 0;
  for (size_t i = 0; i < a.textures->size(); ++i) {
    const double share = double(state.textures->heights[i] * state.textures->widths[i]) /
                         double(a.textures->heights[i] * a.textures->widths[i]);
    ASSERT_LT(share, 1.0);
    for (uint64_t k = a.textures->offsets[i] * 4; k < a.textures->offsets[i + 1] * 4; ++k) {
      EXPECT_NEAR(b.m_texels[k], share * a.m_texels[k], 1e-6 * std::abs(a.m_texels[k]) + 1e-30);
      EXPECT_NEAR(b.v_texels[k], share * share * a.v_texels[k], 1e-6 * a.v_texels[k] + 1e-30);
      checked += a.v_texels[k] > 0;
    }
  }
  EXPECT_GT(checked, a.v_texels.size() / 2) << "the moments must be non-zero for the check to mean anything";
}

TEST(TrainerLego, ResumeFromACheckpointReproducesTheUninterruptedRun) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  testing::TempDir dir;
  TrainConfig config = SmallConfig();
  config.stage1.coarse_iterations = 20;
  config.stage1.fine_iterations = 20;
  config.stage1.densify.from_step = 5;
  config.stage1.densify.interval = 10;
  config.checkpoint_every = 10;
  // Stop after 30 steps (fine step 10), then resume.
  ExpectResumeReproducesTheStraightRun(*data, config, 10, dir.path());
}

// A backend that reports one non-finite step: the loop must roll back and continue.
using FlakyBackend = NonFiniteAtStep;

TEST(TrainerLego, NonFiniteStepRollsBackAndHalvesTheLearningRate) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto data = OpenLego(path);
  ASSERT_NE(data, nullptr);
  TrainConfig config = SmallConfig();
  config.stage1.coarse_iterations = 12;
  config.stage1.fine_iterations = 0;
  config.stage1.densify.enabled = false;
  TrainerOptions options;
  options.config = config;
  options.stages = kStage1;
  FlakyBackend backend(7);
  auto trained = Train(*data, backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  ASSERT_FALSE(trained->events.empty());
  bool logged = false;
  for (const auto& e : trained->events) logged |= e.find("rolled back") != std::string::npos;
  EXPECT_TRUE(logged);
  EXPECT_EQ(backend.loads(), 2);  // the initial load and the rollback
  const double expected = config.stage1.lr.position.At(11) * CameraExtent(data->train_views()) * 0.5;
  EXPECT_NEAR(backend.last_request().learning_rates[kGroupPositions], expected, expected * 1e-9);
}

}  // namespace
}  // namespace atex::train
