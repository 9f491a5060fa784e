// Issue 24: training configs that would train garbage are refused before training, with
// an error naming the key and the value (or both settings of a contradiction).
#include "atex/train/config_check.h"

#include <gtest/gtest.h>

#include "atex/train/trainer.h"

namespace atex::train {
namespace {

// An in-memory dataset of two RGBA frames (one train, one test), composited on `background`.
std::unique_ptr<Dataset> TinyRgbaDataset(std::optional<std::array<float, 3>> background) {
  std::vector<InMemoryFrame> frames;
  for (int k = 0; k < 2; ++k) {
    InMemoryFrame f;
    f.view.camera.width = 8;
    f.view.camera.height = 8;
    f.view.camera.fx = f.view.camera.fy = 8;
    f.view.camera.cx = f.view.camera.cy = 4;
    f.view.camera.world_to_camera = {1, 0, 0, 0.1 * k, 0, 1, 0, 0, 0, 0, 1, 4, 0, 0, 0, 1};
    f.view.camera.time = 0.5 * k;
    f.view.camera_id = k;
    f.view.timestep = k;
    f.image = Image(8, 8, 4);
    f.test = k == 1;
    frames.push_back(std::move(f));
  }
  DatasetOptions options;
  options.background = background;
  auto d = MakeInMemoryDataset("tiny", std::move(frames), options);
  EXPECT_TRUE(d.ok()) << d.status().ToString();
  return std::move(*d);
}

Status Override(TrainConfig* config, const std::string& assignment) {
  auto changed = ApplyOverride(*config, assignment);
  if (!changed.ok()) return changed.status();
  *config = *changed;
  return ValidateConfig(*config);
}

TEST(ConfigCheck, DefaultsAreValid) {
  for (const char* kind : {"panoptic", "dnerf", "n3dv", "generic"}) {
    EXPECT_TRUE(ValidateConfig(DefaultConfig(kind)).ok())
        << kind << ": " << ValidateConfig(DefaultConfig(kind)).ToString();
  }
}

// Each probe value of the issue: refused, with the key in the message.
TEST(ConfigCheck, OutOfRangeValuesNameTheKey) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"stage2.time_bins=0", "stage2.time_bins"},
      {"stage2.time_bins=-1", "stage2.time_bins"},
      {"stage2.time_bins=100000000", "stage2.time_bins"},
      {"stage1.densify.interval=0", "stage1.densify.interval"},
      {"stage1.densify.interval=-1", "stage1.densify.interval"},
      {"background=[2,2,2]", "background[0]"},
      {"stage1.lr.opacity=-0.05", "stage1.lr.opacity"},
      {"stage1.lr.position.initial=-1", "stage1.lr.position.initial"},
      {"stage1.lr.grid.final=0", "stage1.lr.grid"},
      {"stage1.lambda_dssim=5", "stage1.lambda_dssim"},
      {"stage2.lambda_dssim=-0.1", "stage2.lambda_dssim"},
      {"stage1.batch_size=0", "stage1.batch_size"},
      {"stage1.sh_degree=4", "stage1.sh_degree"},
      {"near_plane=0", "near_plane"},
      {"stage1.deformation.grid.channels=0", "stage1.deformation.grid.channels"},
      {"stage1.deformation.grid.multires=[]", "multires"},
      {"stage2.texel_budget_fraction=2", "stage2.texel_budget_fraction"},
      {"stage1.init_method=\"magic\"", "stage1.init_method"},
      {"stage1.init_method=\"file\"", "stage1.init_point_cloud"},
      {"stage1.init_mvs.window_radius=0", "stage1.init_mvs.window_radius"},
      {"stage1.init_mvs.far=0.1", "stage1.init_mvs.far"},
      {"stage1.init_mvs.best_neighbors=7", "stage1.init_mvs.best_neighbors"},
      {"camera_colour.keep=0", "camera_colour.keep"},
      {"camera_colour.views_per_camera=0", "camera_colour.views_per_camera"},
      {"camera_colour.first_step=0", "camera_colour.first_step"},
      {"stage1.fast_objects.max_presence=1", "stage1.fast_objects.max_presence"},
      {"stage1.fast_objects.window_frames=0", "stage1.fast_objects.window_frames"},
      {"stage1.fast_objects.points=-5", "stage1.fast_objects.points"},
  };
  for (const auto& [assignment, key] : cases) {
    TrainConfig config = DefaultConfig("dnerf");
    const Status s = Override(&config, assignment);
    EXPECT_FALSE(s.ok()) << assignment;
    EXPECT_NE(s.message().find(key), std::string::npos) << assignment << ": " << s.ToString();
  }
}

// A value of the wrong JSON type is never converted silently (1.5 -> 1, true -> 1, a fourth
// background channel dropped, -1 -> 2^64 - 1).
TEST(ConfigCheck, WrongTypesAreRefusedNotConverted) {
  TrainConfig config = DefaultConfig("dnerf");
  for (const char* bad : {"stage1.batch_size=1.5", "stage1.batch_size=true", "stage1.batch_size=\"2\"",
                          "background=[1,1,1,1]", "background=[1,1]", "stage1.densify.max_gaussians=-1",
                          "stage1.densify.enabled=1", "stage2.time_bins=1e8", "stage2.growth_steps=[1.5]",
                          "stage1.coarse_iterations=4294967297", "seed=-3"}) {
    auto r = ApplyOverride(config, bad);
    EXPECT_FALSE(r.ok()) << bad;
    const std::string key(bad, std::string_view(bad).find('='));
    EXPECT_NE(r.status().message().find(key), std::string::npos) << bad << ": " << r.status().ToString();
  }
  EXPECT_TRUE(ApplyOverride(config, "stage1.lambda_dssim=0").ok());  // an integer is a fine real
  EXPECT_TRUE(ApplyOverride(config, "background=[1,1,1]").ok());
}

// The white-background defect: the frames were composited on black while the config
// draws white. Train() trained it to 19 dB before; now it refuses before any step.
TEST(ConfigCheck, BackgroundMustMatchTheDatasetsCompositing) {
  auto dataset = TinyRgbaDataset(std::array<float, 3>{0, 0, 0});
  TrainerOptions options;
  options.config = DefaultConfig("dnerf");
  options.config.background = {1, 1, 1};
  options.config.stage1.coarse_iterations = 1;
  options.config.stage1.fine_iterations = 1;
  options.config.stage1.init_points = 50;
  options.config.stage1.init_method = "cube";
  options.config.stage2.iterations = 2;
  options.config.stage2.growth_steps = {1};
  options.config.eval_every = 0;
  auto backend = MakeCpuBackend();
  auto summary = Train(*dataset, *backend, options);
  ASSERT_FALSE(summary.ok());
  EXPECT_EQ(summary.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(summary.status().message().find("background [1,1,1]"), std::string::npos) << summary.status().ToString();
  // The same dataset opened on the training background is accepted.
  auto white = TinyRgbaDataset(std::array<float, 3>{1, 1, 1});
  std::vector<std::string> warnings;
  EXPECT_TRUE(CrossCheckConfig(options.config, *white, kBothStages, &warnings).ok());
}

TEST(ConfigCheck, ContradictionsNameBothSettings) {
  auto dataset = TinyRgbaDataset(std::nullopt);
  TrainConfig config = DefaultConfig("dnerf");
  config.stage2.iterations = 20;  // default growth steps 500, 1000
  Status s = CrossCheckConfig(config, *dataset, kBothStages, nullptr);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("stage2.growth_steps[0]=500"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("stage2.iterations=20"), std::string::npos) << s.ToString();
  // Stage 1 alone: stage 2's schedule does not matter.
  EXPECT_TRUE(CrossCheckConfig(config, *dataset, kStage1, nullptr).ok());
  config.stage2.growth_steps = {5, 10};
  config.stage2.texel_budget_fraction = 0.05;  // 0.8 texels per Gaussian
  s = CrossCheckConfig(config, *dataset, kBothStages, nullptr);
  EXPECT_NE(s.message().find("stage2.texel_budget_fraction"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("stage2.textures"), std::string::npos) << s.ToString();
  config.stage2.textures = TextureMode::kNone;
  EXPECT_TRUE(CrossCheckConfig(config, *dataset, kBothStages, nullptr).ok());
}

// Fast-object seeds come from per-timestep visual hulls: a dataset without masks (this one, a
// monocular D-NeRF-like set) must be refused before anything trains, naming the key.
TEST(ConfigCheck, FastObjectsNeedMasksAndTimesteps) {
  auto dataset = TinyRgbaDataset(std::nullopt);
  TrainConfig config = DefaultConfig("dnerf");
  config.stage1.fast_objects.enabled = true;
  const Status s = CrossCheckConfig(config, *dataset, kStage1, nullptr);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("stage1.fast_objects.enabled"), std::string::npos) << s.ToString();
  config.stage1.fast_objects.enabled = false;
  EXPECT_TRUE(CrossCheckConfig(config, *dataset, kStage1, nullptr).ok());
}

TEST(ConfigCheck, SuspiciousCombinationsWarn) {
  auto dataset = TinyRgbaDataset(std::nullopt);
  TrainConfig config = DefaultConfig("dnerf");
  config.stage1.densify.from_step = 5000;
  config.stage1.densify.until_step = 100;
  config.near_plane = 50;  // the cameras are 0.1 apart
  std::vector<std::string> warnings;
  ASSERT_TRUE(CrossCheckConfig(config, *dataset, kStage1, &warnings).ok());
  std::string all;
  for (const auto& w : warnings) all += w + "\n";
  EXPECT_NE(all.find("densification never runs"), std::string::npos) << all;
  EXPECT_NE(all.find("near_plane=50"), std::string::npos) << all;
}

TEST(ConfigCheck, ResumeKeepsTheCheckpointsModel) {
  const TrainConfig saved = DefaultConfig("dnerf");
  TrainConfig wider = saved;
  wider.stage1.deformation.grid.channels = 8;
  const Status s = CheckResumeConfig(saved, wider, nullptr);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("stage1.deformation.grid.channels"), std::string::npos) << s.ToString();
  TrainConfig longer = saved;
  longer.stage2.iterations = 50;
  std::vector<std::string> changed;
  ASSERT_TRUE(CheckResumeConfig(saved, longer, &changed).ok());
  ASSERT_EQ(changed.size(), 1u);
  EXPECT_NE(changed[0].find("stage2.iterations: 5000 -> 50"), std::string::npos) << changed[0];
  TrainConfig white = saved;
  white.background = {1, 1, 1};
  EXPECT_FALSE(CheckResumeConfig(saved, white, nullptr).ok());
}

}  // namespace
}  // namespace atex::train
