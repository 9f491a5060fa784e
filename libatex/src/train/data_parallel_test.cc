// Data-parallel training on the CPU backend (issue 25's acceptance test): ranks as threads
// through the in-process communicator, each with its share of every step's views, must train
// the model that one rank trains with all the views, densification and texture growth included.
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "atex/train/backend.h"
#include "atex/train/checkpoint.h"
#include "atex/train/communicator.h"
#include "atex/train/schedule.h"
#include "atex/train/trainer.h"
#include "core/test_support.h"
#include "train/data_parallel.h"
#include "train/forwarding_backend.h"
#include "train/trainer_test_util.h"

namespace atex::train {
namespace {

// Both stages on the moving ball, batches of 4 views, with densification at stage-1 steps 10
// and 20 of each phase and growth at stage-2 steps 4 and 8: a few seconds on one core.
TrainConfig SmallConfig() {
  TrainConfig c = TinyConfig();
  c.stage1.batch_size = 4;
  c.stage2.batch_size = 4;
  c.eval_every = 10;  // the replicas' checksums are compared at every evaluation
  return c;
}

// Trains on `ranks` threads (each with its own CPU backend, made by `make_backend(rank)`);
// returns each rank's result.
std::vector<StatusOr<TrainSummary>> TrainRanks(
    const Dataset& data, const TrainerOptions& options, int ranks,
    const std::function<std::unique_ptr<Backend>(int)>& make_backend = [](int) { return MakeCpuBackend(); }) {
  auto group = MakeInProcessGroup(ranks, std::chrono::seconds(120));
  EXPECT_TRUE(group.ok()) << group.status().ToString();
  std::vector<StatusOr<TrainSummary>> results(ranks, MakeError(StatusCode::kInternal, "did not run"));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) {
    threads.emplace_back([&, r] {
      TrainerOptions mine = options;
      mine.communicator = (*group)[r].get();
      auto backend = make_backend(r);
      results[r] = Train(data, *backend, mine);
    });
  }
  for (std::thread& t : threads) t.join();
  return results;
}

float MaxAbsDifference(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  float worst = 0;
  for (size_t k = 0; k < std::min(a.size(), b.size()); ++k) worst = std::max(worst, std::abs(a[k] - b[k]));
  return worst;
}

// Texel sides (h, w) -> how many Gaussians have them.
std::map<std::pair<int, int>, int> TexelHistogram(const TexturePool& pool) {
  std::map<std::pair<int, int>, int> histogram;
  for (size_t i = 0; i < pool.size(); ++i) ++histogram[{pool.heights[i], pool.widths[i]}];
  return histogram;
}

TEST(DataParallel, TwoRanksWithHalfTheViewsTrainTheModelOfOneRankWithAll) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  auto one_backend = MakeCpuBackend();
  auto one = Train(*data, *one_backend, options);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  auto two = TrainRanks(*data, options, 2);
  for (const auto& r : two) ASSERT_TRUE(r.ok()) << r.status().ToString();

  // The test can fail: the schedule must densify, prune or clone, and grow textures.
  size_t edited = 0;
  for (const DensifyReport& d : one->densifications) edited += d.cloned + d.split + d.pruned;
  ASSERT_GT(edited, 0u) << "densification must change the topology for the test to mean something";
  size_t grown = 0;
  for (const GrowthReport& g : one->growths) grown += g.grown;
  ASSERT_GT(grown, 0u) << "textures must grow for the test to mean something";

  // The replicas of the two ranks are bit-identical.
  const Asset& a0 = two[0]->asset;
  const Asset& a1 = two[1]->asset;
  EXPECT_EQ(a0.gaussians.positions, a1.gaussians.positions);
  EXPECT_EQ(a0.gaussians.sh, a1.gaussians.sh);
  ASSERT_TRUE(a0.textures && a1.textures);
  EXPECT_EQ(a0.textures->texels, a1.textures->texels);

  // The same decisions as one rank: every densification and growth, the same texel layout.
  ASSERT_EQ(two[0]->densifications.size(), one->densifications.size());
  for (size_t k = 0; k < one->densifications.size(); ++k) {
    const DensifyReport& d1 = one->densifications[k];
    const DensifyReport& d2 = two[0]->densifications[k];
    EXPECT_EQ(std::tie(d2.before, d2.cloned, d2.split, d2.pruned, d2.after),
              std::tie(d1.before, d1.cloned, d1.split, d1.pruned, d1.after))
        << "densification " << k;
  }
  ASSERT_EQ(two[0]->growths.size(), one->growths.size());
  for (size_t k = 0; k < one->growths.size(); ++k) {
    EXPECT_EQ(two[0]->growths[k].grown, one->growths[k].grown) << "growth " << k;
    EXPECT_EQ(two[0]->growths[k].texels_after, one->growths[k].texels_after) << "growth " << k;
  }
  const Asset& reference = one->asset;
  ASSERT_EQ(a0.gaussians.size(), reference.gaussians.size());
  ASSERT_TRUE(reference.textures.has_value());
  EXPECT_EQ(TexelHistogram(*a0.textures), TexelHistogram(*reference.textures));
  EXPECT_EQ(a0.textures->heights, reference.textures->heights);
  EXPECT_EQ(a0.textures->widths, reference.textures->widths);

  // The same parameters up to the order of float sums. (The CPU backend sums a batch's views as a
  // tree, so two ranks' gradients equal one rank's bit for bit; the statistics, accumulated over
  // steps per rank, differ in their last bits, which these tolerances also allow for.)
  EXPECT_LT(MaxAbsDifference(a0.gaussians.positions, reference.gaussians.positions), 1e-3f);
  EXPECT_LT(MaxAbsDifference(a0.gaussians.log_scales, reference.gaussians.log_scales), 1e-2f);
  EXPECT_LT(MaxAbsDifference(a0.gaussians.opacity_logits, reference.gaussians.opacity_logits), 1e-2f);
  EXPECT_LT(MaxAbsDifference(a0.gaussians.sh, reference.gaussians.sh), 1e-2f);
  EXPECT_LT(MaxAbsDifference(a0.textures->texels, reference.textures->texels), 1e-2f);
  ASSERT_TRUE(a0.deformation && reference.deformation);
  EXPECT_LT(MaxAbsDifference(a0.deformation->trunk[0].weight, reference.deformation->trunk[0].weight), 1e-3f);
  // Rank 0 evaluates; the test PSNR matches one rank's.
  ASSERT_FALSE(two[0]->test.views.empty());
  EXPECT_TRUE(two[1]->test.views.empty());
  EXPECT_NEAR(two[0]->test.mean.psnr, one->test.mean.psnr, 0.05);
}

// Per-camera colour corrections are fitted on rank 0 and sent to the others as JSON (which a
// 2-GPU Panoptic run once failed to read back): every rank must hold the same corrections, and
// those of one rank with all the views.
TEST(DataParallel, CameraColoursReachEveryRankAsOneRankFitsThem) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.config.camera_colour.enabled = true;
  options.config.camera_colour.first_step = 10;
  options.config.camera_colour.interval = 10;
  auto one_backend = MakeCpuBackend();
  auto one = Train(*data, *one_backend, options);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  auto two = TrainRanks(*data, options, 2);
  for (const auto& r : two) ASSERT_TRUE(r.ok()) << r.status().ToString();
  const nlohmann::json& reference = one->asset.metadata.extra["camera_colour"];
  ASSERT_TRUE(reference.is_object());
  ASSERT_GT(reference.size(), 0u) << "the test needs fitted cameras";
  EXPECT_EQ(two[0]->asset.metadata.extra["camera_colour"], two[1]->asset.metadata.extra["camera_colour"]);
  const nlohmann::json& fitted = two[0]->asset.metadata.extra["camera_colour"];
  ASSERT_EQ(fitted.size(), reference.size());
  for (auto it = reference.begin(); it != reference.end(); ++it) {
    ASSERT_TRUE(fitted.contains(it.key())) << "camera " << it.key();
    for (const char* part : {"gain", "offset"}) {
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(fitted[it.key()][part][c].get<double>(), it.value()[part][c].get<double>(), 1e-3)
            << "camera " << it.key() << " " << part << " " << c;
      }
    }
  }
}

float MaxAbs(const std::vector<float>& a) {
  float worst = 0;
  for (float x : a) worst = std::max(worst, std::abs(x));
  return worst;
}

TEST(DataParallel, OneStepsGradientsSummedOverTheRanksAreThoseOfAllTheViews) {
  // A fine-phase Step (deformation, regularisers counted once) on 4 views against two ranks
  // with 2 views each, from the same model.
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.config.stage1.densify.enabled = false;
  options.config.stage1.coarse_iterations = 2;
  options.config.stage1.fine_iterations = 2;
  options.config.eval_every = 0;
  options.stages = kStage1;
  auto trainer_backend = MakeCpuBackend();
  auto trained = Train(*data, *trainer_backend, options);
  ASSERT_TRUE(trained.ok()) << trained.status().ToString();
  const ModelState start = StateFromAsset(trained->asset);

  StepRequest request;
  request.learning_rates.fill(1e-3);
  request.apply_deformation = true;
  request.plane_tv = 1e-2;
  request.time_smoothness = 1e-2;
  request.time_l1 = 1e-3;
  request.background = options.config.background;
  std::vector<std::shared_ptr<const Image>> images;
  std::vector<TrainView> views;
  for (size_t i = 0; i < 4; ++i) {
    const View& v = data->train_views()[i * 5];  // different times and cameras
    auto image = data->LoadImage(v);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    images.push_back(*image);
    views.push_back({&v.camera, images.back().get(), i + 1, {}});
  }
  auto one = MakeCpuBackend();
  ASSERT_TRUE(one->Load(start).ok());
  auto one_step = one->Step(request, views);
  ASSERT_TRUE(one_step.ok() && one_step->finite) << one_step.status().ToString();
  ModelState one_grad;
  ASSERT_TRUE(one->ReadGradients(&one_grad).ok());

  auto group = MakeInProcessGroup(2, std::chrono::seconds(60));
  ASSERT_TRUE(group.ok());
  std::vector<ModelState> grads(2);
  std::vector<double> losses(2);
  std::vector<Status> status(2);
  std::vector<std::thread> threads;
  for (int r = 0; r < 2; ++r) {
    threads.emplace_back([&, r] {
      auto backend = MakeCpuBackend();
      status[r] = backend->Load(start);
      if (status[r].ok()) status[r] = backend->SetCommunicator((*group)[r].get());
      if (!status[r].ok()) return;
      auto step = backend->Step(request, std::span<const TrainView>(views).subspan(2 * r, 2));
      if (!step.ok()) {
        status[r] = step.status();
        return;
      }
      losses[r] = step->loss;
      status[r] = backend->ReadGradients(&grads[r]);
    });
  }
  for (std::thread& t : threads) t.join();
  for (const Status& s : status) ASSERT_TRUE(s.ok()) << s.ToString();
  EXPECT_EQ(losses[0], losses[1]);
  EXPECT_NEAR(losses[0], one_step->loss, 1e-6 * std::abs(one_step->loss));
  EXPECT_EQ(grads[0].gaussians.positions, grads[1].gaussians.positions) << "every rank gets the same sum";
  const auto expect_close = [](const std::vector<float>& got, const std::vector<float>& want, const char* what) {
    ASSERT_GT(MaxAbs(want), 0.0f) << what;
    EXPECT_LE(MaxAbsDifference(got, want), 1e-4f * MaxAbs(want)) << what;
  };
  expect_close(grads[0].gaussians.positions, one_grad.gaussians.positions, "positions");
  expect_close(grads[0].gaussians.sh, one_grad.gaussians.sh, "sh");
  expect_close(grads[0].gaussians.opacity_logits, one_grad.gaussians.opacity_logits, "opacity");
  ASSERT_TRUE(grads[0].deformation && one_grad.deformation);
  expect_close(grads[0].deformation->planes[0][0], one_grad.deformation->planes[0][0], "grid plane (with TV)");
  expect_close(grads[0].deformation->trunk[0].weight, one_grad.deformation->trunk[0].weight, "MLP trunk");
}

// The CPU backend, except that after step `step` rank `rank`'s first position moves a little:
// a replica drifting apart, as an unreduced gradient would make it.
class DriftAfterStep final : public ForwardingBackend {
 public:
  explicit DriftAfterStep(int step) : step_(step) {}
  StatusOr<StepResult> Step(const StepRequest& r, std::span<const TrainView> v) override {
    auto result = ForwardingBackend::Step(r, v);
    if (result.ok() && steps_++ == step_) {
      ModelState state;
      ATEX_RETURN_IF_ERROR(Save(&state));
      state.gaussians.positions[0] += 1e-3f;
      ATEX_RETURN_IF_ERROR(Load(state));
    }
    return result;
  }

 private:
  int step_, steps_ = 0;
};

TEST(DataParallel, ReplicasThatDriftApartFailLoudly) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.stages = kStage1;
  auto results = TrainRanks(*data, options, 2, [](int rank) -> std::unique_ptr<Backend> {
    if (rank == 1) return std::make_unique<DriftAfterStep>(3);
    return MakeCpuBackend();
  });
  for (const auto& r : results) {
    ASSERT_EQ(r.status().code(), StatusCode::kInternal) << r.status().ToString();
    EXPECT_NE(r.status().message().find("coarse step 10"), std::string::npos) << r.status().ToString();
    EXPECT_NE(r.status().message().find("rank(s) 1 (checksum "), std::string::npos) << r.status().ToString();
  }
}

// The CPU backend, except that step `step` fails (a device error on one rank).
class FailAtStep final : public ForwardingBackend {
 public:
  explicit FailAtStep(int step) : step_(step) {}
  StatusOr<StepResult> Step(const StepRequest& r, std::span<const TrainView> v) override {
    if (steps_++ == step_) return MakeError(StatusCode::kNoDevice, "the device went away");
    return ForwardingBackend::Step(r, v);
  }

 private:
  int step_, steps_ = 0;
};

TEST(DataParallel, ARankThatFailsStopsTheOthersAtOnce) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.stages = kStage1;
  const auto start = std::chrono::steady_clock::now();
  auto results = TrainRanks(*data, options, 2, [](int rank) -> std::unique_ptr<Backend> {
    if (rank == 1) return std::make_unique<FailAtStep>(3);
    return MakeCpuBackend();
  });
  EXPECT_EQ(results[1].status().code(), StatusCode::kNoDevice) << results[1].status().ToString();
  EXPECT_EQ(results[0].status().code(), StatusCode::kCancelled) << results[0].status().ToString();
  EXPECT_NE(results[0].status().message().find("the device went away"), std::string::npos);
  // Not the group's 120 s timeout (a hang would show as that).
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(100));
}

TEST(DataParallel, BatchNotAMultipleOfTheRanksIsRefusedByEveryRank) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  TrainerOptions options;
  options.config = SmallConfig();
  options.config.stage1.batch_size = 3;
  options.stages = kStage1;
  for (const auto& r : TrainRanks(*data, options, 2)) {
    ASSERT_EQ(r.status().code(), StatusCode::kInvalidArgument) << r.status().ToString();
    EXPECT_NE(r.status().message().find("not a positive multiple of 2 ranks"), std::string::npos);
  }
}

TEST(DataParallel, ACheckpointOfTwoRanksResumesOnOneRank) {
  // Rank 0's callback stops the two-rank run at fine step 10 (every rank stops; rank 0 writes
  // the checkpoint); one rank resumes it and must end where one rank trained straight ends.
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  testing::TempDir dir;
  TrainerOptions options;
  options.config = SmallConfig();
  options.config.checkpoint_every = 5;
  options.stages = kStage1;
  auto straight_backend = MakeCpuBackend();
  auto straight = Train(*data, *straight_backend, options);
  ASSERT_TRUE(straight.ok()) << straight.status().ToString();

  TrainerOptions part = options;
  part.checkpoint_dir = (dir.path() / "ckpt").string();
  part.log_every = 5;
  part.progress = [](const TrainProgress& p) { return !(p.phase == "fine" && p.step == 10); };
  for (const auto& r : TrainRanks(*data, part, 2)) {
    ASSERT_EQ(r.status().code(), StatusCode::kCancelled) << r.status().ToString();
  }
  auto checkpoint = ReadCheckpoint(part.checkpoint_dir);
  ASSERT_TRUE(checkpoint.ok()) << checkpoint.status().ToString();
  EXPECT_EQ(checkpoint->trainer.value("step", -1), 10);

  TrainerOptions resume = options;
  resume.resume_dir = part.checkpoint_dir;
  auto resumed_backend = MakeCpuBackend();
  auto resumed = Train(*data, *resumed_backend, resume);
  ASSERT_TRUE(resumed.ok()) << resumed.status().ToString();
  ASSERT_EQ(resumed->asset.gaussians.size(), straight->asset.gaussians.size());
  EXPECT_LT(MaxAbsDifference(resumed->asset.gaussians.positions, straight->asset.gaussians.positions), 1e-3f);
  EXPECT_NEAR(resumed->test.mean.psnr, straight->test.mean.psnr, 0.05);
}

TEST(DataParallel, ChecksumSeesEveryParameterGroup) {
  ModelState a;
  a.gaussians.Resize(2);
  a.deformation = DeformationField{};
  const uint64_t base = ParameterChecksum(a);
  ModelState b = a;
  b.gaussians.sh[0] = 1e-30f;
  EXPECT_NE(ParameterChecksum(b), base);
  b = a;
  b.gaussians.rotations[7] = -0.0f;  // a different bit pattern of an equal value
  EXPECT_NE(ParameterChecksum(b), base);
  EXPECT_EQ(ParameterChecksum(a), base);
}

// Records, for every view of every step, whether the trainer let the device keep its image.
class KeepRecordingBackend : public ForwardingBackend {
 public:
  explicit KeepRecordingBackend(std::vector<std::pair<size_t, bool>>* seen) : seen_(seen) {}
  StatusOr<StepResult> Step(const StepRequest& r, std::span<const TrainView> views) override {
    for (const TrainView& v : views) seen_->emplace_back(v.image_key - 1, v.keep_on_device);
    return ForwardingBackend::Step(r, views);
  }

 private:
  std::vector<std::pair<size_t, bool>>* seen_;  // (training view index, keep_on_device)
};

// Each rank keeps the images of its home views only (schedule.h, HomeRank), and renders mostly
// those (at least 60 %); with images_on_every_gpu every rank keeps every image it draws.
TEST(DataParallel, EachRankKeepsTheImagesOfItsHomeViewsUnlessToldToKeepAll) {
  auto data = MovingBall();
  ASSERT_NE(data, nullptr);
  for (bool every : {false, true}) {
    TrainerOptions options;
    options.config = SmallConfig();
    options.config.images_on_every_gpu = every;
    options.stages = kStage1;
    std::vector<std::vector<std::pair<size_t, bool>>> seen(2);  // per rank; outlives the backends
    auto results = TrainRanks(*data, options, 2, [&](int rank) {
      return std::unique_ptr<Backend>(std::make_unique<KeepRecordingBackend>(&seen[rank]));
    });
    for (const auto& r : results) ASSERT_TRUE(r.ok()) << r.status().ToString();
    for (int rank = 0; rank < 2; ++rank) {
      size_t home = 0;
      ASSERT_GT(seen[rank].size(), 0u);
      for (const auto& [view, keep] : seen[rank]) {
        const bool at_home = HomeRank(view, 2) == rank;
        home += at_home;
        EXPECT_EQ(keep, every || at_home) << "rank " << rank << " view " << view;
      }
      // A split that ignored homes would render half the views at home (the tiny scene's few views
      // are not evenly split between the homes, so no more is certain here).
      EXPECT_GT(home * 10, seen[rank].size() * 6) << "rank " << rank << ": most views at home";
    }
  }
}

}  // namespace
}  // namespace atex::train
