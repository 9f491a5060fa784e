// N3DV folders of frames (LLFF poses_bounds.npy): cameras, layouts, downscaling, the image cache.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/npy.h"
#include "core/test_support.h"
#include "dataset_test_util.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
const auto ProjectPoint = dataset_testing::Project;

// --- synthetic N3DV folders ---------------------------------------------------------
// The OpenCV frame of camera c: centre (c, 2, 3), looking along world +x, image
// down = world −z, image right = world −y (a right-handed camera frame).
constexpr double kForward[3] = {1, 0, 0}, kDown[3] = {0, 0, -1}, kRight[3] = {0, -1, 0};

// LLFF row: 3x5 [R | t | hwf] with rotation columns (down, right, back), then near, far.
std::vector<double> LlffRow(double cx, double h, double w, double focal) {
  std::vector<double> row(17);
  const double centre[3] = {cx, 2, 3};
  for (int i = 0; i < 3; ++i) {
    row[i * 5 + 0] = kDown[i];
    row[i * 5 + 1] = kRight[i];
    row[i * 5 + 2] = -kForward[i];
    row[i * 5 + 3] = centre[i];
  }
  row[4] = h;
  row[9] = w;
  row[14] = focal;
  row[15] = 0.5;
  row[16] = 20;
  return row;
}

// Writes a scene of `cameras` x `frames` PNGs of 16x12 whose pixel (0, 0) encodes (camera, frame).
void WriteN3dv(const fs::path& root, int cameras, int frames, bool images_subfolder, const std::string& ext = ".png") {
  std::vector<double> rows;
  for (int c = 0; c < cameras; ++c) {
    const std::vector<double> row = LlffRow(c, 24, 32, 40);  // poses at twice the frames' resolution
    rows.insert(rows.end(), row.begin(), row.end());
  }
  ASSERT_TRUE(WriteNpyFile((root / "poses_bounds.npy").string(), NpyArray::FromDoubles({cameras, 17}, rows)).ok());
  for (int c = 0; c < cameras; ++c) {
    char name[16];
    std::snprintf(name, sizeof(name), "cam%02d", c);
    const fs::path dir = images_subfolder ? root / name / "images" : root / name;
    fs::create_directories(dir);
    for (int f = 0; f < frames; ++f) {
      Image image(16, 12, 3, 0.5f);
      image.at(0, 0, 0) = c / 255.0f;
      image.at(0, 0, 1) = (f % 256) / 255.0f;
      image.at(0, 0, 2) = (f / 256) / 255.0f;
      char file[16];
      std::snprintf(file, sizeof(file), "%04d", f);
      // Plain (non-atomic) writes: thousands of fsyncs would dominate the test's time.
      auto bytes = EncodeImage(image, ext == ".png" ? ImageFormat::kPng : ImageFormat::kJpeg);
      ASSERT_TRUE(bytes.ok());
      std::ofstream(dir / (file + ext), std::ios::binary)
          .write(reinterpret_cast<const char*>(bytes->data()), static_cast<std::streamsize>(bytes->size()));
    }
  }
}

TEST(N3dv, LlffPosesBecomeOpenCvCameras) {
  testing::TempDir dir;
  WriteN3dv(dir.path(), 3, 4, true);
  auto dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.kind(), DatasetKind::kN3dv);
  EXPECT_EQ(d.timestep_count(), 4);
  ASSERT_EQ(d.test_views().size(), 4u);  // cam00
  ASSERT_EQ(d.train_views().size(), 8u);
  for (const View& v : d.test_views()) EXPECT_EQ(v.camera_id, 0);
  EXPECT_DOUBLE_EQ(d.test_views()[3].camera.time, 1.0);
  EXPECT_DOUBLE_EQ(d.test_views()[1].camera.time, 1.0 / 3);
  EXPECT_FLOAT_EQ(d.depth_bounds()[0], 0.5f);
  EXPECT_FLOAT_EQ(d.depth_bounds()[1], 20.0f);
  const View& v = d.train_views()[4];  // cam02, frame 0
  ASSERT_EQ(v.camera_id, 2);
  const Camera& cam = v.camera;
  EXPECT_EQ(cam.width, 16);
  EXPECT_DOUBLE_EQ(cam.fx, 20.0);  // focal 40 at 32 px wide, frames 16 px wide
  EXPECT_DOUBLE_EQ(cam.cx, 8.0);
  const auto c = cam.Center();
  EXPECT_NEAR(c[0], 2.0, 1e-12);
  EXPECT_NEAR(c[1], 2.0, 1e-12);
  EXPECT_NEAR(c[2], 3.0, 1e-12);
  // A point 2 units ahead projects to the principal point at depth 2; offsets
  // along the camera's right/down axes move it right/down in the image.
  auto at = [&](double ahead, double right, double down) {
    double p[3];
    for (int i = 0; i < 3; ++i) p[i] = c[i] + ahead * kForward[i] + right * kRight[i] + down * kDown[i];
    return ProjectPoint(cam, p[0], p[1], p[2]);
  };
  const auto centre = at(2, 0, 0);
  EXPECT_NEAR(centre[0], 8.0, 1e-12);
  EXPECT_NEAR(centre[1], 6.0, 1e-12);
  EXPECT_NEAR(centre[2], 2.0, 1e-12);
  EXPECT_NEAR(at(2, 0.5, 0)[0], 8.0 + 20.0 * 0.25, 1e-12);
  EXPECT_NEAR(at(2, 0, 0.5)[1], 6.0 + 20.0 * 0.25, 1e-12);
  auto image = d.LoadImage(v);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_NEAR((*image)->at(0, 0, 0), 2 / 255.0f, 1e-6);
  EXPECT_NEAR((*image)->at(0, 0, 1), 0.0f, 1e-6);
  EXPECT_EQ(d.LoadMask(v).status().code(), StatusCode::kNotFound);
}

TEST(N3dv, FlatLayoutDownscaleAndErrors) {
  testing::TempDir dir;
  WriteN3dv(dir.path(), 2, 3, false, ".jpg");
  DatasetOptions options;
  options.downscale = 2;
  options.test_cameras = {1};
  auto dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->test_views()[0].camera_id, 1);
  EXPECT_EQ((*dataset)->train_views()[0].camera.width, 8);
  EXPECT_DOUBLE_EQ((*dataset)->train_views()[0].camera.fx, 10.0);
  auto image = (*dataset)->LoadImage((*dataset)->train_views()[2]);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ((*image)->width, 8);
  EXPECT_EQ((*image)->height, 6);
  // A camera folder without a pose row.
  fs::create_directories(dir / "cam02");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kCorrupt);
  options.test_cameras = {7};
  fs::remove_all(dir / "cam02");
  EXPECT_EQ(OpenDataset(dir.path().string(), options).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(OpenDataset((dir / "nothing").string()).status().code(), StatusCode::kNotFound);
}

TEST(N3dv, LongVideoStaysWithinTheImageCacheLimit) {
  // 20 cameras x 300 frames: iterating over every view must not keep them all.
  testing::TempDir dir;
  WriteN3dv(dir.path(), 20, 300, true);
  DatasetOptions options;
  options.image_cache_bytes = 40000;  // ~17 decoded 16x12 RGB images
  auto dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  ASSERT_EQ(d.train_views().size(), 19u * 300);
  uint64_t peak = 0;
  for (const View& v : d.train_views()) {
    auto image = d.LoadImage(v);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    ASSERT_NEAR((*image)->at(0, 0, 0), v.camera_id / 255.0f, 1e-6);
    ASSERT_NEAR((*image)->at(0, 0, 1) + 256 * (*image)->at(0, 0, 2), v.timestep / 255.0f, 1e-4);
    peak = std::max(peak, d.cache_bytes());
    ASSERT_LE(d.cache_bytes(), options.image_cache_bytes);
  }
  EXPECT_GT(peak, options.image_cache_bytes / 2);  // the cache is used, not bypassed

  // Concurrent loads from several threads return the right images.
  std::vector<std::thread> threads;
  std::atomic<int> wrong{0};
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (size_t i = t; i < 2000; i += 4) {
        const View& v = d.train_views()[(i * 7919) % d.train_views().size()];
        auto image = d.LoadImage(v);
        if (!image.ok() || std::abs((*image)->at(0, 0, 0) - v.camera_id / 255.0f) > 1e-6) ++wrong;
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
  EXPECT_LE(d.cache_bytes(), options.image_cache_bytes);
}

// --- conversions and the in-memory dataset ---------------------------------------------

}  // namespace
}  // namespace atex
