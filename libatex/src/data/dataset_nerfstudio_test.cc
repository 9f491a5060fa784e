// The nerfstudio / instant-ngp kind (transforms.json): synthetic scenes written here with
// cameras whose OpenCV form is known independently, the real lego .npz rewritten as a
// transforms.json (the same cameras and pixels must come back), and hostile inputs (every
// truncation, garbage, absurd sizes, refused camera models): errors, never crashes.
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
// camera right = +x, up = +z, back = -y.
json LookAlongY(double d, double z) {
  return json::parse(StrCat("[[1,0,0,0],[0,0,-1,", -d, "],[0,1,0,", z, "],[0,0,0,1]]"));
}

// --- transforms.json ---------------------------------------------------------------
// Ten frames frame_00..frame_09 (8x6), global intrinsics, per-frame time.
json TenFrames() {
  json doc = {{"fl_x", 10.0}, {"fl_y", 12.0}, {"cx", 4.5}, {"cy", 2.5}, {"w", 8}, {"h", 6},
              {"camera_model", "OPENCV"}, {"k1", 0}, {"k2", 0}, {"p1", 0}, {"p2", 0},
              {"applied_transform", json::parse("[[1,0,0,0],[0,1,0,0],[0,0,1,0]]")}, {"frames", json::array()}};
  for (int i = 9; i >= 0; --i) {  // written in reverse: the loader sorts by file_path
    doc["frames"].push_back({{"file_path", StrCat("images/frame_0", i, ".png")},
                             {"time", i / 9.0},
                             {"transform_matrix", LookAlongY(4 + i, 0)}});
  }
  return doc;
}

void WriteFrames(const fs::path& root, const json& doc, int width = 8, int height = 6) {
  for (const json& f : doc["frames"]) {
    fs::path p = root / f["file_path"].get<std::string>();
    if (!p.has_extension()) p += ".png";
    fs::create_directories(p.parent_path());
    ASSERT_TRUE(WriteImage(p.string(), Frame(width, height, int(p.string().size()))).ok());
  }
}

TEST(Nerfstudio, PosesIntrinsicsTimesSplitAndPointCloud) {
  testing::TempDir dir;
  json doc = TenFrames();
  doc["ply_file_path"] = "sparse_pc.ply";
  doc["frames"][0]["mask_path"] = "masks/frame_09.png";  // frame_09 is frames[0]
  WriteText(dir / "transforms.json", doc.dump());
  WriteFrames(dir.path(), doc);
  Image mask(8, 6, 1);
  for (int x = 0; x < 8; ++x) mask.at(x, 0, 0) = 1.0f;
  fs::create_directories(dir / "masks");
  ASSERT_TRUE(WriteImage((dir / "masks/frame_09.png").string(), mask).ok());
  PointCloud cloud;
  cloud.positions = {0, 0, 0, 0.5f, 0, 0};
  cloud.colours = {1, 0, 0, 0, 1, 0};
  ASSERT_TRUE(WritePlyPoints((dir / "sparse_pc.ply").string(), cloud).ok());

  for (const fs::path& path : {dir.path(), dir / "transforms.json"}) {  // folder or file
    auto dataset = OpenDataset(path.string());
    ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
    const Dataset& d = **dataset;
    EXPECT_EQ(d.kind(), DatasetKind::kNerfstudio);
    // Sorted by file path: ranks 0 and 8 (frame_00, frame_08) are the test split.
    ASSERT_EQ(d.test_views().size(), 2u);
    ASSERT_EQ(d.train_views().size(), 8u);
    EXPECT_EQ(d.test_views()[0].camera.name, "images/frame_00.png");
    EXPECT_EQ(d.test_views()[1].camera.name, "images/frame_08.png");
    EXPECT_EQ(d.timestep_count(), 8);
    EXPECT_FLOAT_EQ(d.time_min(), 0.0f);
    EXPECT_FLOAT_EQ(d.time_max(), 1.0f);
    const View& v = d.train_views()[2];  // frame_03
    EXPECT_EQ(v.camera.name, "images/frame_03.png");
    EXPECT_NEAR(v.camera.time, 3 / 9.0, 1e-12);
    EXPECT_EQ(v.timestep, -1);  // no camera_id: each frame its own camera, as D-NeRF
    EXPECT_EQ(v.camera.fx, 10.0);
    EXPECT_EQ(v.camera.fy, 12.0);
    EXPECT_EQ(v.camera.cx, 4.5);
    EXPECT_EQ(v.camera.cy, 2.5);
    // Camera at (0, -7, 0) looking along +y: the origin at depth 7 on the principal point,
    // world +x to the right, world +z (up) upwards in the image.
    const auto o = Project(v.camera, 0, 0, 0);
    EXPECT_NEAR(o[0], 4.5, 1e-9);
    EXPECT_NEAR(o[1], 2.5, 1e-9);
    EXPECT_NEAR(o[2], 7.0, 1e-9);
    EXPECT_GT(Project(v.camera, 0.3, 0, 0)[0], 4.5);
    EXPECT_LT(Project(v.camera, 0, 0, 0.3)[1], 2.5);
    EXPECT_EQ(d.point_cloud(), (dir / "sparse_pc.ply").lexically_normal().string());
    EXPECT_TRUE(d.has_masks());
    const View& masked = d.train_views().back();  // frame_09
    auto m = d.LoadMask(masked);
    ASSERT_TRUE(m.ok()) << m.status().ToString();
    EXPECT_EQ((*m)->at(3, 0, 0), 1.0f);
    EXPECT_EQ((*m)->at(3, 1, 0), 0.0f);
    EXPECT_EQ(d.LoadMask(v).status().code(), StatusCode::kNotFound);
    auto image = d.LoadImage(v);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    const Image expected = Frame(8, 6, int((dir / "images/frame_03.png").string().size()));
    for (size_t k = 0; k < expected.pixels.size(); ++k) ASSERT_NEAR((*image)->pixels[k], expected.pixels[k], 1e-6);
  }
  // The dataset's points are the default initialisation.
  auto dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok());
  InitReport report;
  auto gaussians = InitializeGaussians(**dataset, {}, &report);
  ASSERT_TRUE(gaussians.ok()) << gaussians.status().ToString();
  EXPECT_EQ(report.method, InitMethod::kFile);
  EXPECT_EQ(gaussians->size(), 2u);
}

TEST(Nerfstudio, AnglesPerFrameIntrinsicsCamerasAndSplitRules) {
  testing::TempDir dir;
  // camera_angle_x and no w/h: the size comes from the image; a frame overrides fl_x.
  json doc = {{"camera_angle_x", 2 * std::atan(0.5)}, {"frames", json::array()}};
  for (int t = 0; t < 3; ++t) {
    for (int cam = 0; cam < 3; ++cam) {
      doc["frames"].push_back({{"file_path", StrCat("c", cam, "/", t)},  // ".png" added
                               {"timestep", t * 5},
                               {"camera_id", cam},
                               {"transform_matrix", LookAlongY(4, cam)}});
    }
  }
  doc["frames"][4]["fl_x"] = 3.0;  // c1/1
  WriteText(dir / "transforms.json", doc.dump());
  WriteFrames(dir.path(), doc, 8, 4);
  DatasetOptions options;
  options.test_cameras = {2};
  auto dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  ASSERT_EQ(d.train_views().size(), 6u);
  ASSERT_EQ(d.test_views().size(), 3u);
  for (const View& v : d.test_views()) EXPECT_EQ(v.camera_id, 2);
  EXPECT_EQ(d.timestep_count(), 3);
  for (const View& v : d.train_views()) {
    EXPECT_EQ(v.camera.width, 8);
    EXPECT_EQ(v.camera.height, 4);
    EXPECT_NEAR(v.camera.time, v.timestep / 2.0, 1e-12);  // timestep / the largest (10)
    const bool overridden = v.camera.name == "c1/1";
    EXPECT_NEAR(v.camera.fx, overridden ? 3.0 : 8.0, 1e-9) << v.camera.name;  // 0.5 W / tan(angle/2) = 8
    EXPECT_NEAR(v.camera.fy, v.camera.fx, 1e-12);
    EXPECT_EQ(v.camera.cx, 4.0);
  }
  EXPECT_EQ(FirstTimestepViews(d.train_views()).size(), 2u);  // one per training camera

  // nerfstudio's split lists.
  doc.erase("camera_angle_x");
  doc["fl_x"] = 5.0;
  doc["test_filenames"] = {"c0/0.png", "./c1/2.png"};
  doc["train_filenames"] = {"c0/1.png", "c2/2.png", "c2/0.png"};
  WriteText(dir / "transforms.json", doc.dump());
  dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->test_views().size(), 2u);
  EXPECT_EQ((*dataset)->train_views().size(), 3u);

  // transforms_test.json beside it takes precedence over the lists.
  json test = {{"fl_x", 5.0}, {"frames", json::array({doc["frames"][0]})}};
  WriteText(dir / "transforms_test.json", test.dump());
  dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->kind(), DatasetKind::kNerfstudio);
  EXPECT_EQ((*dataset)->test_views().size(), 1u);
  EXPECT_EQ((*dataset)->train_views().size(), 9u);

  // Downscale scales the intrinsics.
  options = {};
  options.downscale = 2;
  dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->train_views()[0].camera.width, 4);
  EXPECT_EQ((*dataset)->train_views()[0].camera.fx, 2.5);
}

// The real lego .npz rewritten as nerfstudio files: the same cameras, times and pixels.
TEST(Nerfstudio, TheLegoRewrittenAsTransformsJsonMatchesTheNpz) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto lego = OpenDataset(npz.string());
  ASSERT_TRUE(lego.ok()) << lego.status().ToString();
  auto arrays = ReadNpzFile(npz.string());
  ASSERT_TRUE(arrays.ok());
  const std::vector<double> poses = (*arrays)["poses"].ToDouble();
  const double focal = *(*arrays)["focal"].Scalar("focal");
  testing::TempDir dir;
  json train = {{"fl_x", focal}, {"fl_y", focal}, {"w", 100}, {"h", 100}, {"frames", json::array()}};
  json test = train;
  for (const auto* views : {&(*lego)->train_views(), &(*lego)->test_views()}) {
    for (const View& v : *views) {
      auto image = (*lego)->LoadImage(v);
      ASSERT_TRUE(image.ok());
      const std::string name = StrCat("r_", 100 + v.frame_index, ".png");
      ASSERT_TRUE(WriteImage((dir / name).string(), **image).ok());
      json m = json::array();
      for (int r = 0; r < 4; ++r) {
        m.push_back(json::array());
        for (int c = 0; c < 4; ++c) m[r].push_back(poses[v.frame_index * 16 + r * 4 + c]);
      }
      (views == &(*lego)->train_views() ? train : test)["frames"].push_back(
          {{"file_path", name}, {"time", v.camera.time}, {"transform_matrix", m}});
    }
  }
  WriteText(dir / "transforms.json", train.dump());
  WriteText(dir / "transforms_test.json", test.dump());
  DatasetOptions options;
  options.image_cache_bytes = 64 << 20;
  auto ns = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(ns.ok()) << ns.status().ToString();
  ASSERT_EQ((*ns)->train_views().size(), (*lego)->train_views().size());
  ASSERT_EQ((*ns)->test_views().size(), (*lego)->test_views().size());
  EXPECT_EQ((*ns)->timestep_count(), (*lego)->timestep_count());
  for (int split = 0; split < 2; ++split) {
    const auto& a = split ? (*ns)->test_views() : (*ns)->train_views();
    const auto& b = split ? (*lego)->test_views() : (*lego)->train_views();
    for (size_t i = 0; i < a.size(); ++i) {  // names r_1NN sort in the npz's order
      EXPECT_EQ(a[i].camera.time, b[i].camera.time);
      EXPECT_EQ(a[i].camera.fx, b[i].camera.fx);
      EXPECT_EQ(a[i].camera.cx, b[i].camera.cx);
      for (int k = 0; k < 16; ++k) ASSERT_NEAR(a[i].camera.world_to_camera[k], b[i].camera.world_to_camera[k], 1e-12);
      if (i % 10 == 0) {
        auto pa = (*ns)->LoadImage(a[i]);
        auto pb = (*lego)->LoadImage(b[i]);
        ASSERT_TRUE(pa.ok() && pb.ok());
        for (size_t k = 0; k < (*pa)->pixels.size(); ++k) {
          ASSERT_NEAR((*pa)->pixels[k], (*pb)->pixels[k], 0.5 / 255 + 1e-6);  // 8-bit PNG
        }
      }
    }
  }
}

TEST(Nerfstudio, HostileTransformsAreErrorsNamingTheElement) {
  const std::string valid = TenFrames().dump();
  // Every truncation of a valid file: an error, never a crash.
  for (size_t n = 0; n < valid.size(); ++n) {
    EXPECT_FALSE(ParseTransformsJson(std::string_view(valid).substr(0, n), "t.json").ok()) << n;
  }
  EXPECT_TRUE(ParseTransformsJson(valid, "t.json").ok());
  struct Case {
    std::string edit;  // JSON merge patch applied to frames[2] (or the file when it starts with "file:")
    StatusCode code;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {R"({"transform_matrix": [[1,0,0],[0,1,0],[0,0,1]]})", StatusCode::kCorrupt, "frames[2].transform_matrix[0]"},
      {R"({"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,"x"],[0,0,0,1]]})", StatusCode::kCorrupt,
       "frames[2].transform_matrix[2][3]"},
      {R"({"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,1,1]]})", StatusCode::kCorrupt, "last row"},
      {R"({"transform_matrix": null})", StatusCode::kCorrupt, "frames[2].transform_matrix is missing"},
      {R"({"time": "soon"})", StatusCode::kCorrupt, "frames[2].time"},
      {R"({"timestep": -3})", StatusCode::kCorrupt, "frames[2].timestep"},
      {R"({"camera_id": 1.5})", StatusCode::kCorrupt, "frames[2].camera_id"},
      {R"({"file_path": 7})", StatusCode::kCorrupt, "frames[2].file_path"},
      {R"({"w": 1e12})", StatusCode::kCorrupt, "frames[2].w"},
      {R"({"h": 0})", StatusCode::kCorrupt, "frames[2].h"},
      {R"({"fl_x": -1})", StatusCode::kCorrupt, "frames[2].fl_x"},
      {R"({"k1": 0.01})", StatusCode::kUnsupported, "frames[2].k1"},
      {R"({"camera_model": "OPENCV_FISHEYE"})", StatusCode::kUnsupported, "OPENCV_FISHEYE"},
      {R"(file:{"p2": -0.2})", StatusCode::kUnsupported, "p2"},
      {R"(file:{"fl_x": null})", StatusCode::kCorrupt, "no focal length"},
      {R"(file:{"frames": {"a": 1}})", StatusCode::kCorrupt, "'frames'"},
      {R"(file:{"applied_transform": [[1,0,0,0]]})", StatusCode::kCorrupt, "applied_transform"},
      {R"(file:{"test_filenames": [1]})", StatusCode::kCorrupt, "test_filenames[0]"},
  };
  for (const Case& c : cases) {
    json doc = TenFrames();
    const bool file = c.edit.rfind("file:", 0) == 0;
    (file ? doc : doc["frames"][2]).merge_patch(json::parse(file ? c.edit.substr(5) : c.edit));
    auto parsed = ParseTransformsJson(doc.dump(), "t.json");
    ASSERT_FALSE(parsed.ok()) << c.edit;
    EXPECT_EQ(parsed.status().code(), c.code) << c.edit << ": " << parsed.status().ToString();
    EXPECT_NE(parsed.status().ToString().find(c.needle), std::string::npos) << parsed.status().ToString();
  }
  // A number beyond double's range (nlohmann throws out_of_range, not parse_error, for it).
  auto overflow = ParseTransformsJson(
      R"({"fl_x": 1, "frames": [{"file_path": "a.png", "time": 1e999, "transform_matrix": [[1,0,0,0]]}]})", "t.json");
  EXPECT_EQ(overflow.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(overflow.status().ToString().find("1e999"), std::string::npos) << overflow.status().ToString();
  auto garbage = ParseTransformsJson("{\"frames\": [\x01\x02", "t.json");
  EXPECT_EQ(garbage.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(garbage.status().ToString().find("byte"), std::string::npos);
  EXPECT_FALSE(ParseTransformsJson("[1, 2]", "t.json").ok());

  // Folder-level errors: a missing image, mixed times, a missing mask, empty frames.
  testing::TempDir dir;
  json doc = TenFrames();
  WriteFrames(dir.path(), doc);
  fs::remove(dir / "images/frame_04.png");
  WriteText(dir / "transforms.json", doc.dump());
  auto d = OpenDataset(dir.path().string());
  EXPECT_EQ(d.status().code(), StatusCode::kNotFound);
  EXPECT_NE(d.status().ToString().find("frame_04.png"), std::string::npos) << d.status().ToString();
  WriteFrames(dir.path(), doc);
  doc["frames"][3].erase("time");
  WriteText(dir / "transforms.json", doc.dump());
  d = OpenDataset(dir.path().string());
  EXPECT_EQ(d.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(d.status().ToString().find("has no 'time'"), std::string::npos) << d.status().ToString();
  doc = TenFrames();
  doc["frames"][1]["mask_path"] = "nowhere.png";
  WriteText(dir / "transforms.json", doc.dump());
  d = OpenDataset(dir.path().string());
  EXPECT_EQ(d.status().code(), StatusCode::kNotFound);
  EXPECT_NE(d.status().ToString().find("mask_path"), std::string::npos) << d.status().ToString();
  WriteText(dir / "transforms.json", R"({"fl_x": 3, "frames": []})");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kNotFound);
  // Images of another size than w/h: the image load says so.
  doc = TenFrames();
  doc["w"] = 16;
  WriteText(dir / "transforms.json", doc.dump());
  d = OpenDataset(dir.path().string());
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  EXPECT_EQ((*d)->LoadImage((*d)->train_views()[0]).status().code(), StatusCode::kCorrupt);
  // The D-NeRF reader shares the JSON reading: an out-of-range number is an error there too
  // (it escaped as an exception before).
  testing::TempDir dnerf;
  WriteText(dnerf / "transforms_train.json", R"({"camera_angle_x": 1e999, "frames": []})");
  d = OpenDataset(dnerf.path().string());
  EXPECT_EQ(d.status().code(), StatusCode::kCorrupt) << d.status().ToString();
}

}  // namespace
}  // namespace atex
