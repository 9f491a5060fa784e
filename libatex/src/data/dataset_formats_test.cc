// The nerfstudio (transforms.json) and COLMAP dataset kinds: synthetic scenes written here
// with cameras whose OpenCV form is known independently, the real lego .npz rewritten as a
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

namespace atex {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::array<double, 3> Project(const Camera& c, double x, double y, double z) {
  const auto& m = c.world_to_camera;
  const double px = m[0] * x + m[1] * y + m[2] * z + m[3];
  const double py = m[4] * x + m[5] * y + m[6] * z + m[7];
  const double pz = m[8] * x + m[9] * y + m[10] * z + m[11];
  return {c.fx * px / pz + c.cx, c.fy * py / pz + c.cy, pz};
}

void WriteText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// A small RGB frame whose pixels identify it.
Image Frame(int width, int height, int seed) {
  Image image(width, height, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = float((x * 7 + y * 3 + seed * 11 + c * 5) % 256) / 255.0f;
    }
  }
  return image;
}

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
      {"1 PINHOLE 16 12 20 20 8 6\n", "1 1 0 0 0 0 0 3 1\n\n", StatusCode::kCorrupt, "images.txt: COLMAP images line 1"},
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
