// The training loop on a synthetic dynamic scene that every machine has (no ../shared/data):
// resume after an interrupted run, rollback of a non-finite step, the time limit, the
// order of the phases and texture growth. The real-data tests are trainer_test.cc.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "atex/dataset.h"
#include "atex/train/backend.h"
#include "atex/train/checkpoint.h"
#include "atex/train/trainer.h"
#include "core/test_support.h"
#include "train/forwarding_backend.h"
#include "train/trainer_test_util.h"

namespace atex::train {
namespace {

// A red ball (radius 0.4) moving along x over 4 timesteps, seen by 8 cameras on a ring at
// distance 3 looking at the origin, on a blue background; camera 0 is held out for testing.
// 24×24 pixels: a CPU step takes milliseconds.
std::unique_ptr<Dataset> MovingBall() {
  constexpr int kSize = 24, kCameras = 8, kTimesteps = 4;
  constexpr double kRadius = 0.4;
  std::vector<InMemoryFrame> frames;
  for (int t = 0; t < kTimesteps; ++t) {
    const double centre_x = -0.3 + 0.2 * t;
    for (int i = 0; i < kCameras; ++i) {
      const double azimuth = 2 * M_PI * i / kCameras;
      const double o[3] = {3 * std::cos(azimuth), 0.8, 3 * std::sin(azimuth)};
      const double on = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
      const double z[3] = {-o[0] / on, -o[1] / on, -o[2] / on};
      double x[3] = {-z[2], 0, z[0]};  // z × (0, 1, 0)… any horizontal vector ⟂ z
      const double xn = std::sqrt(x[0] * x[0] + x[2] * x[2]);
      x[0] /= xn;
      x[2] /= xn;
      const double y[3] = {z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]};
      InMemoryFrame f;
      Camera& cam = f.view.camera;
      cam.width = cam.height = kSize;
      cam.fx = cam.fy = kSize * 1.2;
      cam.cx = cam.cy = kSize / 2.0;
      cam.time = kTimesteps > 1 ? double(t) / (kTimesteps - 1) : 0.0;
      const double* rows[3] = {x, y, z};
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) cam.world_to_camera[r * 4 + c] = rows[r][c];
        cam.world_to_camera[r * 4 + 3] = -(rows[r][0] * o[0] + rows[r][1] * o[1] + rows[r][2] * o[2]);
      }
      f.view.camera_id = i;
      f.view.timestep = t;
      f.test = i == 0;
      f.image = Image(kSize, kSize, 3);
      f.mask = Image(kSize, kSize, 1);
      const double c[3] = {centre_x, 0, 0};
      const double oc[3] = {o[0] - c[0], o[1] - c[1], o[2] - c[2]};
      for (int py = 0; py < kSize; ++py) {
        for (int px = 0; px < kSize; ++px) {
          const double u[3] = {(px + 0.5 - cam.cx) / cam.fx, (py + 0.5 - cam.cy) / cam.fy, 1};
          double d[3];
          for (int a = 0; a < 3; ++a) d[a] = x[a] * u[0] + y[a] * u[1] + z[a] * u[2];
          const double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
          const double od = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
          const double oo = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2];
          const bool hit = od * od - dd * (oo - kRadius * kRadius) >= 0;
          f.mask.at(px, py, 0) = hit ? 1.0f : 0.0f;
          f.image.at(px, py, 0) = hit ? 0.9f : 0.1f;
          f.image.at(px, py, 1) = hit ? 0.2f : 0.1f;
          f.image.at(px, py, 2) = hit ? 0.1f : 0.8f;
        }
      }
      frames.push_back(std::move(f));
    }
  }
  auto dataset = MakeInMemoryDataset("moving ball", std::move(frames));
  EXPECT_TRUE(dataset.ok()) << dataset.status().ToString();
  return dataset.ok() ? std::move(*dataset) : nullptr;
}

// A progress callback that appends each phase's name once, in the order they run.
ProgressCallback RecordPhases(std::vector<std::string>* phases) {
  return [phases](const TrainProgress& p) {
    if (p.event.empty() && (phases->empty() || phases->back() != p.phase)) phases->push_back(p.phase);
    return true;
  };
}

// A few dozen steps of every phase on a small model.
TrainConfig TinyConfig() {
  TrainConfig c = DefaultConfig("dnerf");
  c.stage1.coarse_iterations = 20;
  c.stage1.fine_iterations = 20;
  c.stage1.init_points = 600;
  c.stage1.densify.from_step = 5;
  c.stage1.densify.interval = 10;
  c.stage1.deformation.grid.channels = 4;
  c.stage1.deformation.grid.base_resolution = {8, 8, 8, 4};
  c.stage1.deformation.mlp_width = 16;
  c.stage2.iterations = 12;
  c.stage2.batch_size = 2;
  c.stage2.growth_steps = {4, 8};
  c.eval_every = 0;
  c.checkpoint_every = 0;
  return c;
}

TEST(TrainerSynthetic, PhasesRunInOrderAndTexturesGrow) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = TinyConfig();
  options.log_every = 1;
  std::vector<std::string> phases;
  options.progress = RecordPhases(&phases);
  auto backend = MakeCpuBackend();
  auto trained = Train(*data, *backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  EXPECT_EQ(phases, (std::vector<std::string>{"coarse", "fine", "textures"}));
  EXPECT_EQ(trained->coarse_steps, 20);
  EXPECT_EQ(trained->fine_steps, 20);
  EXPECT_EQ(trained->texture_steps, 12);
  ASSERT_TRUE(trained->asset.textures.has_value());
  ASSERT_TRUE(trained->asset.deformation.has_value());
  // Growth at steps 4 and 8: two reports, and the pool grew (or the texel budget said why not).
  ASSERT_EQ(trained->growths.size(), 2u);
  uint64_t grown = 0;
  for (const GrowthReport& g : trained->growths) {
    EXPECT_GE(g.texels_after, g.texels_before);
    grown += g.grown;
  }
  EXPECT_GT(grown, 0u) << "the moving ball's edges must ask for texture detail";
  EXPECT_EQ(trained->asset.textures->texel_count(), trained->growths.back().texels_after);
  EXPECT_TRUE(ValidateAsset(trained->asset).ok());
}

TEST(TrainerSynthetic, ResumeAfterAnInterruptedRunReproducesTheUninterruptedOne) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  testing::TempDir dir;
  TrainConfig config = TinyConfig();
  config.checkpoint_every = 5;
  // Killed at fine step 10 (the last checkpoint written), then a new process resumes.
  ExpectResumeReproducesTheStraightRun(*data, config, 10, dir.path());
}

// The CPU backend, except that one step reports a non-finite loss (and applies nothing).
using OneBadStep = NonFiniteAtStep;

TEST(TrainerSynthetic, NonFiniteStepRollsBackAndTrainingContinues) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = TinyConfig();
  options.config.stage1.densify.enabled = false;
  options.stages = kStage1;
  OneBadStep backend(25);  // a fine step
  auto trained = Train(*data, backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  bool rolled_back = false;
  for (const std::string& e : trained->events) rolled_back |= e.find("rolled back") != std::string::npos;
  EXPECT_TRUE(rolled_back);
  EXPECT_EQ(backend.loads(), 2);  // the initial load and the rollback
  EXPECT_EQ(trained->coarse_steps + trained->fine_steps, 40) << "the phase still runs to its end";
  EXPECT_TRUE(ValidateAsset(trained->asset).ok());
}

TEST(TrainerSynthetic, TimeLimitEndsThePhaseAndSkipsTheLaterOnes) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = TinyConfig();
  options.config.stage1.coarse_iterations = 100000;  // far more than the limit allows
  options.time_limit_seconds = 0.5;
  std::vector<std::string> phases;
  options.progress = RecordPhases(&phases);
  auto backend = MakeCpuBackend();
  auto trained = Train(*data, *backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  EXPECT_TRUE(trained->stopped_by_time_limit);
  EXPECT_LT(trained->coarse_steps, 100000);
  EXPECT_GT(trained->coarse_steps, 0);
  EXPECT_EQ(trained->fine_steps, 0);
  EXPECT_EQ(trained->texture_steps, 0);
  bool said = false;
  for (const std::string& e : trained->events) said |= e.find("time limit") != std::string::npos;
  EXPECT_TRUE(said);
  // The asset is still written as usual (a valid, if undertrained, model).
  EXPECT_TRUE(ValidateAsset(trained->asset).ok());
}

}  // namespace
}  // namespace atex::train
