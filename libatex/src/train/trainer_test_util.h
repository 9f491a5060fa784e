// For the trainer's tests: shared checks of the training loop.
#pragma once

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "atex/dataset.h"
#include "atex/train/checkpoint.h"
#include "atex/train/trainer.h"

namespace atex::train {

// A few dozen steps of every phase on a small model.
inline TrainConfig TinyConfig() {
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

// A red ball (radius 0.4) moving along x over 4 timesteps, seen by 8 cameras on a ring at
// distance 3 looking at the origin, on a blue background; camera 0 is held out for testing.
// 24×24 pixels: a CPU step takes milliseconds.
inline std::unique_ptr<Dataset> MovingBall() {
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
  EXPECT_EQ(resumed->asset.gaussians.time_windows, straight->asset.gaussians.time_windows);
  ASSERT_TRUE(resumed->asset.deformation && straight->asset.deformation);
  EXPECT_EQ(resumed->asset.deformation->trunk[0].weight, straight->asset.deformation->trunk[0].weight);
}

}  // namespace atex::train
