// D-NeRF folders (Blender transforms, RGBA frames): poses, backgrounds, refusals.
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
using dataset_testing::WriteText;
const auto ProjectPoint = dataset_testing::Project;

// --- synthetic D-NeRF folder ---------------------------------------------------------
TEST(DNerf, BlenderPosesRgbaFramesAndMissingFiles) {
  testing::TempDir dir;
  // A camera at (0, -4, 0) in Blender's z-up world, looking along +y at the origin:
  // camera axes in world: right = +x, up = +z, back = -y.
  const std::string pose = "[[1,0,0,0],[0,0,-1,-4],[0,1,0,0],[0,0,0,1]]";
  nlohmann::json train = nlohmann::json::parse(R"({"camera_angle_x": 0.6911112070083618, "frames": []})");
  for (int i = 0; i < 3; ++i) {
    train["frames"].push_back({{"file_path", "./train/r_00" + std::to_string(i)},
                               {"time", i / 2.0},
                               {"transform_matrix", nlohmann::json::parse(pose)}});
  }
  WriteText(dir / "transforms_train.json", train.dump());
  nlohmann::json test = train;
  test["frames"] = nlohmann::json::array({train["frames"][1]});
  test["frames"][0]["file_path"] = "./test/r_000.png";
  WriteText(dir / "transforms_test.json", test.dump());
  fs::create_directories(dir / "train");
  fs::create_directories(dir / "test");
  Image rgba(8, 6, 4);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) {
      rgba.at(x, y, 0) = 1.0f;
      rgba.at(x, y, 1) = 0.4f;
      rgba.at(x, y, 2) = 0.2f;
      rgba.at(x, y, 3) = x < 4 ? 1.0f : 0.0f;  // left half opaque
    }
  }
  ASSERT_TRUE(WriteImage((dir / "train/r_000.png").string(), rgba).ok());
  ASSERT_TRUE(WriteImage((dir / "train/r_002.png").string(), rgba).ok());  // r_001 is missing
  ASSERT_TRUE(WriteImage((dir / "test/r_000.png").string(), rgba).ok());
  DatasetOptions options;
  options.background = std::array<float, 3>{0.0f, 0.0f, 1.0f};
  auto dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.kind(), DatasetKind::kDNerf);
  ASSERT_EQ(d.train_views().size(), 2u);
  ASSERT_EQ(d.test_views().size(), 1u);
  ASSERT_EQ(d.warnings().size(), 1u);
  EXPECT_NE(d.warnings()[0].find("1 of 3"), std::string::npos);
  EXPECT_DOUBLE_EQ(d.train_views()[1].camera.time, 1.0);
  const Camera& cam = d.train_views()[0].camera;
  EXPECT_NEAR(cam.fx, 4.0 / std::tan(0.5 * 0.6911112070083618), 1e-9);
  EXPECT_DOUBLE_EQ(cam.cx, 4.0);
  EXPECT_DOUBLE_EQ(cam.cy, 3.0);
  const auto centre = cam.Center();
  EXPECT_NEAR(centre[1], -4.0, 1e-12);
  const auto origin = ProjectPoint(cam, 0, 0, 0);
  EXPECT_NEAR(origin[0], 4.0, 1e-9);
  EXPECT_NEAR(origin[1], 3.0, 1e-9);
  EXPECT_NEAR(origin[2], 4.0, 1e-12);
  EXPECT_GT(ProjectPoint(cam, 0.3, 0, 0)[0], 4.0);  // world +x is image right
  EXPECT_LT(ProjectPoint(cam, 0, 0, 0.3)[1], 3.0);  // world +z (up) is image up
  auto image = d.LoadImage(d.train_views()[0]);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ((*image)->channels, 3);
  EXPECT_FLOAT_EQ((*image)->at(1, 1, 0), 1.0f);  // opaque: the frame's colour
  EXPECT_FLOAT_EQ((*image)->at(6, 1, 2), 1.0f);  // transparent: the background
  EXPECT_FLOAT_EQ((*image)->at(6, 1, 0), 0.0f);
  ASSERT_TRUE(d.has_masks());
  auto mask = d.LoadMask(d.test_views()[0]);
  ASSERT_TRUE(mask.ok()) << mask.status().ToString();
  EXPECT_FLOAT_EQ((*mask)->at(1, 1, 0), 1.0f);
  EXPECT_FLOAT_EQ((*mask)->at(6, 1, 0), 0.0f);
  options.test_cameras = {0};
  EXPECT_EQ(OpenDataset(dir.path().string(), options).status().code(), StatusCode::kInvalidArgument);
}

// A D-NeRF folder of one train and one test RGBA frame (left half opaque red, right half transparent).
void WriteRgbaDNerfFolder(const fs::path& dir) {
  nlohmann::json meta = nlohmann::json::parse(R"({"camera_angle_x": 0.69, "frames": [{"file_path": "./r_000",
      "time": 0.0, "transform_matrix": [[1,0,0,0],[0,0,-1,-4],[0,1,0,0],[0,0,0,1]]}]})");
  WriteText(dir / "transforms_train.json", meta.dump());
  WriteText(dir / "transforms_test.json", meta.dump());
  Image rgba(8, 6, 4);
  for (int y = 0; y < 6; ++y) {
    for (int x = 0; x < 8; ++x) {
      rgba.at(x, y, 0) = 1.0f;
      rgba.at(x, y, 3) = x < 4 ? 1.0f : 0.0f;
    }
  }
  ASSERT_TRUE(WriteImage((dir / "r_000.png").string(), rgba).ok());
}

// Issue 24: D-NeRF's published convention composites its RGBA frames on white; a dataset
// opened without a background follows it, and says so. The tiny lego .npz (alpha dropped on
// black when it was packed) keeps black.
TEST(DNerf, DefaultBackgroundIsTheDatasetsConvention) {
  testing::TempDir dir;
  WriteRgbaDNerfFolder(dir.path());
  auto dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_TRUE(d.background_is_default());
  EXPECT_EQ(d.background(), (std::array<float, 3>{1.0f, 1.0f, 1.0f}));
  EXPECT_TRUE(d.frames_have_alpha());
  auto image = d.LoadImage(d.train_views()[0]);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_FLOAT_EQ((*image)->at(6, 1, 1), 1.0f);  // transparent: white
  EXPECT_FLOAT_EQ((*image)->at(1, 1, 1), 0.0f);  // opaque red
  EXPECT_NE(DefaultBackgroundReason(DatasetKind::kDNerf).find("white"), std::string::npos);
  DatasetOptions black;
  black.background = std::array<float, 3>{0.0f, 0.0f, 0.0f};
  auto explicit_black = OpenDataset(dir.path().string(), black);
  ASSERT_TRUE(explicit_black.ok());
  EXPECT_FALSE((*explicit_black)->background_is_default());
  EXPECT_FLOAT_EQ((*(*explicit_black)->LoadImage((*explicit_black)->train_views()[0]))->at(6, 1, 1), 0.0f);
  EXPECT_EQ(DefaultBackground(DatasetKind::kDNerfNpz), (std::array<float, 3>{0.0f, 0.0f, 0.0f}));
  EXPECT_EQ(DefaultBackground(DatasetKind::kPanoptic), (std::array<float, 3>{0.0f, 0.0f, 0.0f}));
}

TEST(DNerf, NonRigidPoseIsRefused) {
  testing::TempDir dir;
  WriteText(dir / "transforms_train.json",
            R"({"camera_angle_x": 0.7, "frames": [{"file_path": "a", "time": 0,
                "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
  ASSERT_TRUE(WriteImage((dir / "a.png").string(), Image(4, 4, 3)).ok());
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kCorrupt);
}

}  // namespace
}  // namespace atex
