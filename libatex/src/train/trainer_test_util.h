// For the trainer's tests: shared checks of the training loop.
#pragma once

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "atex/dataset.h"
#include "atex/train/checkpoint.h"
#include "atex/train/trainer.h"

namespace atex::train {

// Stage 1 of `config` (checkpoint_every > 0, densification on or off) trained straight, then
// again interrupted at fine step `stop_at` (the progress callback stops it; the last
// checkpoint is written to `dir`), then resumed from that checkpoint by a fresh backend: the
// resumed run must end with the straight run's parameters, bit for bit.
inline void ExpectResumeReproducesTheStraightRun(const Dataset& data, const TrainConfig& config, int stop_at,
                                                 const std::filesystem::path& dir) {
  TrainerOptions full;
  full.config = config;
  full.stages = kStage1;
  auto b1 = MakeCpuBackend();
  auto straight = Train(data, *b1, full);
  ASSERT_TRUE(straight.ok()) << straight.status().ToString();

  TrainerOptions part = full;
  part.checkpoint_dir = (dir / "ckpt").string();
  part.log_every = config.checkpoint_every;
  part.progress = [stop_at](const TrainProgress& p) { return !(p.phase == "fine" && p.step == stop_at); };
  auto b2 = MakeCpuBackend();
  auto stopped = Train(data, *b2, part);
  ASSERT_EQ(stopped.status().code(), StatusCode::kCancelled) << stopped.status().ToString();
  auto checkpoint = ReadCheckpoint(part.checkpoint_dir);
  ASSERT_TRUE(checkpoint.ok()) << checkpoint.status().ToString();
  EXPECT_EQ(checkpoint->trainer.value("phase", ""), "fine");
  EXPECT_EQ(checkpoint->trainer.value("step", -1), stop_at);

  TrainerOptions resume = full;
  resume.resume_dir = part.checkpoint_dir;
  auto b3 = MakeCpuBackend();
  auto resumed = Train(data, *b3, resume);
  ASSERT_TRUE(resumed.ok()) << resumed.status().ToString();
  EXPECT_EQ(resumed->asset.gaussians.positions, straight->asset.gaussians.positions);
  EXPECT_EQ(resumed->asset.gaussians.sh, straight->asset.gaussians.sh);
  ASSERT_TRUE(resumed->asset.deformation && straight->asset.deformation);
  EXPECT_EQ(resumed->asset.deformation->trunk[0].weight, straight->asset.deformation->trunk[0].weight);
}

}  // namespace atex::train
