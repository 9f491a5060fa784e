// The COLMAP kind: text and binary models written here with cameras whose OpenCV form is
// known independently (the same views from both), points3D as the default initialisation,
// and hostile models (every truncation of the binary files, absurd counts, refused camera
// models, missing files): errors naming the file and position, never crashes.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "atex/dataset.h"
#include "atex/dataset_formats.h"
#include "atex/file_io.h"
#include "atex/init.h"
#include "atex/npy.h"
#include "atex/point_cloud.h"
#include "core/test_support.h"
#include "data/dataset_test_util.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using dataset_testing::Frame;
using dataset_testing::Project;
using dataset_testing::WriteText;

// Blender/OpenGL camera-to-world of a camera at (0, -d, z) looking along +y (world z up):
// --- COLMAP ------------------------------------------------------------------------
void PutU32(std::string* s, uint32_t v) { s->append(reinterpret_cast<const char*>(&v), 4); }
void PutU64(std::string* s, uint64_t v) { s->append(reinterpret_cast<const char*>(&v), 8); }
void PutF64(std::string* s, double v) { s->append(reinterpret_cast<const char*>(&v), 8); }

struct SyntheticModel {
  // Camera 1: PINHOLE 16x12 (fx 20, fy 22, cx 8, cy 6); camera 2: SIMPLE_RADIAL with k = 0.
  // Image i (9 of them): rotation of 90° about y (q = (cos 45°, 0, sin 45°, 0)) for odd i,
  // identity for even i, translation (0, 0, 3 + i).
  std::string cameras_txt, images_txt, cameras_bin, images_bin;
  SyntheticModel() {
    cameras_txt = "# Camera list\n1 PINHOLE 16 12 20 22 8 6\n2 SIMPLE_RADIAL 16 12 21 8 6 0\n";
    PutU64(&cameras_bin, 2);
    PutU32(&cameras_bin, 1);
    PutU32(&cameras_bin, 1);
    PutU64(&cameras_bin, 16);
    PutU64(&cameras_bin, 12);
    for (double v : {20.0, 22.0, 8.0, 6.0}) PutF64(&cameras_bin, v);
    PutU32(&cameras_bin, 2);
    PutU32(&cameras_bin, 2);
    PutU64(&cameras_bin, 16);
    PutU64(&cameras_bin, 12);
    for (double v : {21.0, 8.0, 6.0, 0.0}) PutF64(&cameras_bin, v);
    images_txt = "# Image list\n";
    PutU64(&images_bin, 9);
    const double h = std::sqrt(0.5);
    for (int i = 8; i >= 0; --i) {  // reverse order: the loader sorts by name
      const std::array<double, 7> pose = {i % 2 ? h : 1.0, 0, i % 2 ? h : 0.0, 0, 0, 0, 3.0 + i};
      const uint32_t camera = i < 4 ? 1 : 2;
      const std::string name = StrCat("img_", i, ".png");
      images_txt += StrCat(10 + i, " ");
      for (double v : pose) {
        char text[32];
        std::snprintf(text, sizeof(text), "%.17g ", v);  // exact, as the binary file
        images_txt += text;
      }
      images_txt += StrCat(camera, " ", name, "\n");
      images_txt += i == 3 ? "\n" : "1.5 2.5 -1 3.5 4.5 7\n";  // an image without 2D points
      PutU32(&images_bin, 10 + i);
      for (double v : pose) PutF64(&images_bin, v);
      PutU32(&images_bin, camera);
      images_bin += name;
      images_bin.push_back('\0');
      const int points = i == 3 ? 0 : 2;
      PutU64(&images_bin, points);
      for (int p = 0; p < points; ++p) {
        PutF64(&images_bin, 1.5);
        PutF64(&images_bin, 2.5);
        PutU64(&images_bin, uint64_t(-1));
      }
    }
  }
  void Write(const fs::path& root, bool binary) const {
    fs::create_directories(root / "sparse/0");
    WriteText(root / "sparse/0" / (binary ? "cameras.bin" : "cameras.txt"), binary ? cameras_bin : cameras_txt);
    WriteText(root / "sparse/0" / (binary ? "images.bin" : "images.txt"), binary ? images_bin : images_txt);
    WriteText(root / "sparse/0" / (binary ? "points3D.bin" : "points3D.txt"),
              binary ? PointsBin() : "1 0 0 0 255 0 0 0.1 10 0\n2 0.1 0.2 0.3 0 255 0 0.2\n3 -0.1 0 0.1 0 0 255 0.3\n");
    fs::create_directories(root / "images");
    for (int i = 0; i < 9; ++i) {
      EXPECT_TRUE(WriteImage((root / "images" / StrCat("img_", i, ".png")).string(), Frame(16, 12, i)).ok());
    }
  }
  static std::string PointsBin() {
    std::string s;
    PutU64(&s, 3);
    for (int i = 0; i < 3; ++i) {
      PutU64(&s, i + 1);
      for (double v : {0.1 * i, 0.0, 0.1}) PutF64(&s, v);
      s += std::string("\x10\x20\x30", 3);
      PutF64(&s, 0.5);
      PutU64(&s, 0);
    }
    return s;
  }
};

TEST(Colmap, TextAndBinaryModelsGiveTheSameCamerasAndSplit) {
  const SyntheticModel model;
  std::vector<std::vector<View>> views;
  for (bool binary : {false, true}) {
    testing::TempDir dir;
    model.Write(dir.path(), binary);
    auto dataset = OpenDataset(dir.path().string());
    ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
    const Dataset& d = **dataset;
    EXPECT_EQ(d.kind(), DatasetKind::kColmap);
    ASSERT_EQ(d.test_views().size(), 2u);  // img_0 and img_8
    ASSERT_EQ(d.train_views().size(), 7u);
    EXPECT_EQ(d.test_views()[0].camera.name, "img_0.png");
    EXPECT_EQ(d.test_views()[1].camera.name, "img_8.png");
    EXPECT_EQ(d.timestep_count(), 1);
    EXPECT_EQ(d.time_max(), 0.0f);
    EXPECT_EQ(d.point_cloud(), (dir / "sparse/0" / (binary ? "points3D.bin" : "points3D.txt")).string());
    const View& first = d.train_views()[0];  // img_1: PINHOLE, rotated 90° about y, t = (0, 0, 4)
    EXPECT_EQ(first.camera.fx, 20.0);
    EXPECT_EQ(first.camera.fy, 22.0);
    EXPECT_EQ(first.camera.cx, 8.0);
    // R = [[0,0,1],[0,1,0],[-1,0,0]]: world (x, y, z) -> camera (z, y, -x + 4)... plus t.
    const auto p = Project(first.camera, -1.0, 0.5, 0.25);  // camera (0.25, 0.5, 5)
    EXPECT_NEAR(p[2], 5.0, 1e-12);
    EXPECT_NEAR(p[0], 20.0 * 0.25 / 5 + 8, 1e-12);
    EXPECT_NEAR(p[1], 22.0 * 0.5 / 5 + 6, 1e-12);
    const View& radial = d.train_views()[4];  // img_5: SIMPLE_RADIAL with k = 0
    EXPECT_EQ(radial.camera.name, "img_5.png");
    EXPECT_EQ(radial.camera.fx, 21.0);
    EXPECT_EQ(radial.camera.fy, 21.0);
    auto image = d.LoadImage(radial);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    EXPECT_NEAR((*image)->at(3, 2, 1), Frame(16, 12, 5).at(3, 2, 1), 1e-6);
    InitReport report;
    auto gaussians = InitializeGaussians(d, {}, &report);
    ASSERT_TRUE(gaussians.ok()) << gaussians.status().ToString();
    EXPECT_EQ(report.method, InitMethod::kFile);
    EXPECT_EQ(report.file_points, 3u);
    views.push_back(d.train_views());
  }
  for (size_t i = 0; i < views[0].size(); ++i) {
    EXPECT_EQ(views[0][i].camera.world_to_camera, views[1][i].camera.world_to_camera);
    EXPECT_EQ(views[0][i].camera.fx, views[1][i].camera.fx);
  }
  // --test-cameras has no meaning here.
  testing::TempDir dir;
  model.Write(dir.path(), false);
  DatasetOptions options;
  options.test_cameras = {1};
  EXPECT_EQ(OpenDataset(dir.path().string(), options).status().code(), StatusCode::kInvalidArgument);
}

TEST(Colmap, HostileModelsAreErrorsNamingThePosition) {
  const SyntheticModel model;
  // Every truncation of the binary files: an error, never a crash.
  for (size_t n = 0; n < model.cameras_bin.size(); ++n) {
    EXPECT_FALSE(ParseColmapCamerasBinary(reinterpret_cast<const uint8_t*>(model.cameras_bin.data()), n, "c").ok());
  }
  for (size_t n = 0; n < model.images_bin.size(); ++n) {
    EXPECT_FALSE(ParseColmapImagesBinary(reinterpret_cast<const uint8_t*>(model.images_bin.data()), n, "i").ok());
  }
  // Absurd counts are refused before allocating.
  std::string huge;
  PutU64(&huge, uint64_t{1} << 60);
  huge += std::string(64, '\0');
  auto cams = ParseColmapCamerasBinary(reinterpret_cast<const uint8_t*>(huge.data()), huge.size(), "c.bin");
  EXPECT_EQ(cams.status().code(), StatusCode::kLimitExceeded);
  auto imgs = ParseColmapImagesBinary(reinterpret_cast<const uint8_t*>(huge.data()), huge.size(), "i.bin");
  EXPECT_EQ(imgs.status().code(), StatusCode::kLimitExceeded);
  // A 2D point count beyond the bytes present names the image and its byte offset.
  std::string bad = model.images_bin;
  const size_t count_at = 8 + 4 + 56 + 4 + std::strlen("img_8.png") + 1;
  for (int k = 0; k < 8; ++k) bad[count_at + k] = '\x7f';
  imgs = ParseColmapImagesBinary(reinterpret_cast<const uint8_t*>(bad.data()), bad.size(), "i.bin");
  EXPECT_EQ(imgs.status().code(), StatusCode::kTruncated);
  EXPECT_NE(imgs.status().ToString().find("image 0 at byte 8"), std::string::npos) << imgs.status().ToString();
  // An unknown model id.
  bad = model.cameras_bin;
  bad[12] = 99;
  cams = ParseColmapCamerasBinary(reinterpret_cast<const uint8_t*>(bad.data()), bad.size(), "c.bin");
  EXPECT_EQ(cams.status().code(), StatusCode::kUnsupported);
  EXPECT_NE(cams.status().ToString().find("model id 99"), std::string::npos) << cams.status().ToString();

  struct Case {
    std::string cameras, images;
    StatusCode code;
    std::string needle;
  };
  const std::string one_image = "1 1 0 0 0 0 0 3 1 img_0.png\n\n";
  const std::vector<Case> cases = {
      {"1 OPENCV 16 12 20 20 8 6 0.1 0 0 0\n", one_image, StatusCode::kUnsupported, "distortion parameter 0"},
      {"1 OPENCV_FISHEYE 16 12 20 20 8 6 0 0 0 0\n", one_image, StatusCode::kUnsupported, "OPENCV_FISHEYE"},
      {"1 FOO 16 12 20\n", one_image, StatusCode::kUnsupported, "line 1: unknown camera model 'FOO'"},
      {"1 PINHOLE 16 12 20 20 8\n", one_image, StatusCode::kCorrupt, "has 4 parameters, the line 3"},
      {"1 PINHOLE 16 99999999 20 20 8 6\n", one_image, StatusCode::kCorrupt, "image size"},
      {"1 PINHOLE 16 12 20 nan 8 6\n", one_image, StatusCode::kCorrupt, "parameter 1"},
      {"1 PINHOLE 16 12 0 20 8 6\n", one_image, StatusCode::kCorrupt, "focal length"},
      {"1 PINHOLE 16 12 20 20 8 6\n1 PINHOLE 16 12 20 20 8 6\n", one_image, StatusCode::kCorrupt, "appears twice"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 1 0 0 0 0 0 3 7 img_0.png\n\n", StatusCode::kCorrupt, "camera 7 is not"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 0 0 0 0 0 0 3 1 img_0.png\n\n", StatusCode::kCorrupt, "quaternion is zero"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 1 0 0 0 0 0 3 1\n\n", StatusCode::kCorrupt,
       "images.txt: COLMAP images line 1"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 1 0 0 0 0 0 3 1 img_0.png\n1 2\n", StatusCode::kCorrupt, "line 2: 2D points"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 1 0 0 0 0 0 3 1 gone.png\n\n", StatusCode::kNotFound, "gone.png"},
      {"1 PINHOLE 16 12 20 20 8 6\n", "# nothing\n", StatusCode::kNotFound, "no images"},
  };
  for (const Case& c : cases) {
    testing::TempDir dir;
    model.Write(dir.path(), false);
    WriteText(dir / "sparse/0/cameras.txt", c.cameras);
    WriteText(dir / "sparse/0/images.txt", c.images);
    auto d = OpenDataset(dir.path().string());
    ASSERT_FALSE(d.ok()) << c.cameras << c.images;
    EXPECT_EQ(d.status().code(), c.code) << d.status().ToString();
    EXPECT_NE(d.status().ToString().find(c.needle), std::string::npos) << d.status().ToString();
  }
  // No images folder; no model at all.
  testing::TempDir dir;
  model.Write(dir.path(), true);
  fs::remove_all(dir / "images");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kNotFound);
  fs::remove_all(dir / "sparse");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kNotFound);
  DatasetOptions colmap;
  colmap.kind = DatasetKind::kColmap;
  auto d = OpenDataset(dir.path().string(), colmap);
  EXPECT_NE(d.status().ToString().find("no COLMAP model"), std::string::npos) << d.status().ToString();
}

}  // namespace
}  // namespace atex
