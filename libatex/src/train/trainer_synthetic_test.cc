// The training loop on a synthetic dynamic scene that every machine has (no ../shared/data):
// resume after an interrupted run, rollback of a non-finite step, the time limit, the
// order of the phases and texture growth. The real-data tests are trainer_test.cc.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/dataset.h"
#include "atex/train/backend.h"
#include "atex/train/checkpoint.h"
#include "atex/train/trainer.h"
#include "core/test_support.h"
#include "train/forwarding_backend.h"
#include "train/trainer_test_util.h"

namespace atex::train {
namespace {

// A progress callback that appends each phase's name once, in the order they run.
ProgressCallback RecordPhases(std::vector<std::string>* phases) {
  return [phases](const TrainProgress& p) {
    if (p.event.empty() && (phases->empty() || phases->back() != p.phase)) phases->push_back(p.phase);
    return true;
  };
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

// Fast-object seeds (stage1.fast_objects): added once where the fine stage starts, they keep
// their time windows through densification (clones inherit them) into the asset, and a run
// resumed from a checkpoint after that point ends where the uninterrupted one does.
TrainConfig FastObjectsConfig() {
  TrainConfig config = TinyConfig();
  config.stage1.fast_objects.enabled = true;
  config.stage1.fast_objects.points = 150;
  config.stage1.fast_objects.hull_resolution = 24;
  config.stage1.fast_objects.max_presence = 0.3;  // 4 timesteps: voxels held at one time only
  return config;
}

TEST(TrainerSynthetic, FastObjectSeedsJoinAtTheFineStageWithTheirWindows) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = FastObjectsConfig();
  options.stages = kStage1;
  auto backend = MakeCpuBackend();
  auto trained = Train(*data, *backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  const auto added = std::find_if(trained->events.begin(), trained->events.end(), [](const std::string& e) {
    return e.find("fast-object seeds") != std::string::npos;
  });
  ASSERT_NE(added, trained->events.end());
  const Gaussians& g = trained->asset.gaussians;
  ASSERT_EQ(g.time_windows.size(), 2 * g.size());
  size_t local = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    if (g.time_windows[2 * i + 1] == 0) continue;
    ++local;
    EXPECT_NEAR(g.time_windows[2 * i + 1], 1.0 / (0.5 / 3.0), 1e-3);  // 4 timesteps over [0, 1]
    const double step = g.time_windows[2 * i] * 3.0;
    EXPECT_NEAR(step, std::round(step), 1e-5);
  }
  EXPECT_GT(local, 0u);
  EXPECT_LT(local, g.size());
  EXPECT_TRUE(ValidateAsset(trained->asset).ok());
  auto bytes = EncodeAsset(trained->asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  auto back = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->gaussians.time_windows, g.time_windows);
}

TEST(TrainerSynthetic, ResumeAfterTheFastObjectSeedsReproducesTheUninterruptedRun) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  testing::TempDir dir;
  TrainConfig config = FastObjectsConfig();
  config.checkpoint_every = 5;
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
