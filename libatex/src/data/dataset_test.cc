// Datasets: the real Panoptic and lego data, synthetic D-NeRF and N3DV folders
// written here (with poses whose OpenCV form is known independently), the
// bounded image cache, and malformed inputs.
#include <cmath>
#include <atomic>
#include <fstream>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "atex/dataset.h"
#include "atex/file_io.h"
#include "atex/npy.h"
#include "core/test_support.h"
#include "dataset_test_util.h"

namespace atex {
namespace {


using dataset_testing::WriteText;
const auto ProjectPoint = dataset_testing::Project;

// --- Panoptic (real data) --------------------------------------------------------
TEST(Panoptic, OpensTheRealSubsetWithItsSplitAndDroppedTimesteps) {
  ATEX_REQUIRE_DATA_FILE(root, "panoptic_basketball/train_meta.json");
  auto dataset = OpenDataset(root.parent_path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.kind(), DatasetKind::kPanoptic);
  EXPECT_EQ(d.timestep_count(), 30);
  EXPECT_EQ(d.train_views().size(), 27u * 30);
  EXPECT_EQ(d.test_views().size(), 4u * 30);
  ASSERT_EQ(d.warnings().size(), 1u);
  EXPECT_NE(d.warnings()[0].find("120 of 150"), std::string::npos) << d.warnings()[0];
  std::set<int> test_ids, train_ids;
  for (const View& v : d.test_views()) test_ids.insert(v.camera_id);
  for (const View& v : d.train_views()) train_ids.insert(v.camera_id);
  EXPECT_EQ(test_ids, (std::set<int>{0, 10, 15, 30}));
  EXPECT_EQ(train_ids.size(), 27u);
  EXPECT_FLOAT_EQ(d.time_min(), 0.0f);
  EXPECT_FLOAT_EQ(d.time_max(), 1.0f);
  EXPECT_TRUE(d.has_masks());
  const View& last = d.train_views().back();
  EXPECT_EQ(last.timestep, 29);
  EXPECT_DOUBLE_EQ(last.camera.time, 1.0);
  EXPECT_DOUBLE_EQ(d.train_views()[27].camera.time, 1.0 / 29);  // timestep 1, first camera

  // Every camera looks at the middle of the capture: the mean of the camera
  // centres (inside the dome, a little above the floor) is in front of every
  // camera and projects into (or just beside) every image.
  double mean[3] = {0, 0, 0};
  std::vector<const View*> first;
  for (const auto* views : {&d.train_views(), &d.test_views()}) {
    for (const View& v : *views) {
      if (v.timestep != 0) continue;
      const auto c = v.camera.Center();
      for (int a = 0; a < 3; ++a) mean[a] += c[a];
      first.push_back(&v);
    }
  }
  ASSERT_EQ(first.size(), 31u);
  for (double& m : mean) m /= first.size();
  for (const View* v : first) {
    const auto p = ProjectPoint(v->camera, mean[0], mean[1], mean[2]);
    EXPECT_GT(p[2], 0) << v->camera.name;
    EXPECT_GT(p[0], -0.25 * 640) << v->camera.name;
    EXPECT_LT(p[0], 1.25 * 640) << v->camera.name;
    EXPECT_GT(p[1], -0.25 * 360) << v->camera.name;
    EXPECT_LT(p[1], 1.25 * 360) << v->camera.name;
  }

  // Images and masks.
  auto image = d.LoadImage(d.test_views()[0]);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ((*image)->width, 640);
  EXPECT_EQ((*image)->channels, 3);
  auto mask = d.LoadMask(d.train_views()[0]);
  ASSERT_TRUE(mask.ok()) << mask.status().ToString();
  EXPECT_EQ((*mask)->channels, 1);
  for (float v : (*mask)->pixels) ASSERT_TRUE(v == 0.0f || v == 1.0f);
  EXPECT_EQ(d.LoadMask(d.test_views()[0]).status().code(), StatusCode::kNotFound);
}

TEST(Panoptic, OptionsDownscaleTimestepsAndTestCameras) {
  ATEX_REQUIRE_DATA_FILE(root, "panoptic_basketball/train_meta.json");
  DatasetOptions options;
  options.downscale = 2;
  options.max_timesteps = 5;
  options.test_cameras = {1, 2};
  auto dataset = OpenDataset(root.parent_path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.timestep_count(), 5);
  EXPECT_EQ(d.test_views().size(), 2u * 5);
  EXPECT_EQ(d.train_views().size(), 29u * 5);
  EXPECT_DOUBLE_EQ(d.test_views().back().camera.time, 1.0);
  auto full = OpenDataset(root.parent_path().string());
  ASSERT_TRUE(full.ok());
  const View& small = d.test_views()[0];
  const View* big = nullptr;
  for (const View& v : (*full)->train_views()) {
    if (v.camera_id == small.camera_id && v.timestep == small.timestep) big = &v;
  }
  ASSERT_NE(big, nullptr);
  EXPECT_EQ(small.camera.width, 320);
  EXPECT_EQ(small.camera.height, 180);
  EXPECT_DOUBLE_EQ(small.camera.fx, big->camera.fx / 2);
  EXPECT_DOUBLE_EQ(small.camera.cy, big->camera.cy / 2);
  // A world point lands on the same spot in both, at half the pixel coordinates.
  const auto p_big = ProjectPoint(big->camera, 0.1, 0.5, 0.2);
  const auto p_small = ProjectPoint(small.camera, 0.1, 0.5, 0.2);
  EXPECT_NEAR(p_small[0], p_big[0] / 2, 1e-9);
  EXPECT_NEAR(p_small[1], p_big[1] / 2, 1e-9);
  auto a = d.LoadImage(small);
  auto b = (*full)->LoadImage(*big);
  ASSERT_TRUE(a.ok() && b.ok());
  auto expected = DownscaleImage(**b, 2);
  ASSERT_TRUE(expected.ok());
  EXPECT_EQ((*a)->pixels, expected->pixels);
  auto mask = d.LoadMask(d.train_views()[3]);
  ASSERT_TRUE(mask.ok());
  EXPECT_EQ((*mask)->width, 320);
  for (float v : (*mask)->pixels) ASSERT_TRUE(v == 0.0f || v == 1.0f);

  options.test_cameras = {99};
  EXPECT_EQ(OpenDataset(root.parent_path().string(), options).status().code(), StatusCode::kNotFound);
}

TEST(Panoptic, MalformedMetasAreErrors) {
  testing::TempDir dir;
  const std::string good_entry =
      R"("k": [[[[100,0,8],[0,100,6],[0,0,1]]]], "w2c": [[[[1,0,0,0],[0,1,0,0],[0,0,1,2],[0,0,0,1]]]])";
  WriteText(dir / "test_meta.json",
            "{\"w\": 16, \"h\": 12, " + good_entry + R"(, "fn": [["0/000000.jpg"]], "cam_id": [[0]]})");
  WriteText(dir / "train_meta.json",
            "{\"w\": 16, \"h\": 12, " + good_entry + R"(, "fn": [["../../etc/passwd"]], "cam_id": [[1]]})");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kCorrupt);
  WriteText(dir / "train_meta.json", R"({"w": 16, "h": 12, "k": [], "w2c": [[]], "fn": [], "cam_id": []})");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kCorrupt);
  WriteText(dir / "train_meta.json", R"({"w": 16, "h": )");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kCorrupt);
  // Well-formed but no images at all.
  WriteText(dir / "train_meta.json",
            "{\"w\": 16, \"h\": 12, " + good_entry + R"(, "fn": [["1/000000.jpg"]], "cam_id": [[1]]})");
  EXPECT_EQ(OpenDataset(dir.path().string()).status().code(), StatusCode::kNotFound);
}

// --- the tiny lego .npz (real data) ------------------------------------------------
TEST(LegoNpz, SplitsIntrinsicsAndCameras) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  DatasetOptions options;
  options.load_val_split = true;
  auto dataset = OpenDataset(npz.string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.kind(), DatasetKind::kDNerfNpz);
  EXPECT_EQ(d.background(), (std::array<float, 3>{0.0f, 0.0f, 0.0f}));  // its frames are on black
  EXPECT_FALSE(d.frames_have_alpha());
  EXPECT_EQ(d.train_views().size(), 50u);
  EXPECT_EQ(d.val_views().size(), 11u);
  EXPECT_EQ(d.test_views().size(), 20u);
  EXPECT_GE(d.time_min(), 0.0f);
  EXPECT_LE(d.time_max(), 1.0f);
  EXPECT_GT(d.time_max() - d.time_min(), 0.9f);
  EXPECT_NEAR(d.val_views()[0].camera.time, 0.0, 1e-6);
  EXPECT_NEAR(d.val_views()[10].camera.time, 1.0, 1e-6);
  for (const auto* views : {&d.train_views(), &d.test_views()}) {
    for (const View& v : *views) {
      EXPECT_NEAR(v.camera.fx, 138.8888, 1e-3);
      EXPECT_DOUBLE_EQ(v.camera.cx, 50.0);
      // The D-NeRF cameras orbit the origin and look at it: it projects near the
      // image centre, in front of the camera.
      const auto p = ProjectPoint(v.camera, 0, 0, 0);
      EXPECT_GT(p[2], 1.0) << v.camera.name;
      EXPECT_NEAR(p[0], 50.0, 3.0) << v.camera.name;
      EXPECT_NEAR(p[1], 50.0, 3.0) << v.camera.name;
    }
  }
  // Blender's world z is up: in every OpenCV camera the world +z axis points up the image (negative v).
  const View& v = d.test_views()[3];
  const auto base = ProjectPoint(v.camera, 0, 0, 0);
  const auto up = ProjectPoint(v.camera, 0, 0, 0.5);
  EXPECT_LT(up[1], base[1]);
  auto image = d.LoadImage(d.train_views()[7]);
  ASSERT_TRUE(image.ok());
  EXPECT_EQ((*image)->width, 100);
  auto arrays = ReadNpzFile(npz.string());
  ASSERT_TRUE(arrays.ok());
  const std::vector<float> all = arrays->at("images").ToFloat();
  EXPECT_TRUE(std::equal((*image)->pixels.begin(), (*image)->pixels.end(), all.begin() + 7 * 30000));
  EXPECT_EQ(d.LoadMask(d.train_views()[0]).status().code(), StatusCode::kNotFound);
}

TEST(CameraConversions, BlenderIdentityLooksDownNegativeZ) {
  // Blender camera at (0, 0, 5) with identity rotation looks along −z (its back is +z).
  std::array<double, 16> c2w = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 5, 0, 0, 0, 1};
  auto w2c = BlenderCameraToWorldToOpenCv(c2w);
  ASSERT_TRUE(w2c.ok());
  Camera cam;
  cam.fx = cam.fy = 10;
  cam.world_to_camera = *w2c;
  const auto p = ProjectPoint(cam, 0, 0, 0);
  EXPECT_NEAR(p[2], 5.0, 1e-12);
  EXPECT_LT(ProjectPoint(cam, 0, 1, 0)[1], 0.0);  // world +y (camera up) is image up
  EXPECT_GT(ProjectPoint(cam, 1, 0, 0)[0], 0.0);  // world +x is image right
}

TEST(InMemoryDataset, ViewsImagesAndValidation) {
  std::vector<InMemoryFrame> frames(2);
  for (int i = 0; i < 2; ++i) {
    frames[i].view.camera.width = 4;
    frames[i].view.camera.height = 2;
    frames[i].view.camera.fx = frames[i].view.camera.fy = 3;
    frames[i].view.camera.time = i;
    frames[i].view.timestep = i;
    frames[i].image = Image(4, 2, 3, 0.25f * (i + 1));
    frames[i].test = i == 1;
  }
  frames[0].mask = Image(4, 2, 1, 1.0f);
  auto dataset = MakeInMemoryDataset("synthetic", frames);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->timestep_count(), 2);
  EXPECT_EQ((*dataset)->time_max(), 1.0f);
  auto image = (*dataset)->LoadImage((*dataset)->test_views()[0]);
  ASSERT_TRUE(image.ok());
  EXPECT_FLOAT_EQ((*image)->pixels[0], 0.5f);
  EXPECT_TRUE((*dataset)->LoadMask((*dataset)->train_views()[0]).ok());
  EXPECT_EQ((*dataset)->LoadMask((*dataset)->test_views()[0]).status().code(), StatusCode::kNotFound);
  frames[1].image = Image(5, 2, 3);
  EXPECT_EQ(MakeInMemoryDataset("bad", frames).status().code(), StatusCode::kInvalidArgument);
  DatasetOptions bad;
  bad.downscale = 0;
  EXPECT_EQ(MakeInMemoryDataset("bad", {}, bad).status().code(), StatusCode::kInvalidArgument);
}


// DatasetOptions::timestep_stride and train_cameras on a synthetic 3-camera x 7-timestep video
// (cameras 2, 5, 9, 11 train; 20 test).
TEST(InMemoryDataset, TimestepStrideAndTrainCameraSubset) {
  std::vector<InMemoryFrame> frames;
  for (int t = 0; t < 7; ++t) {
    for (int cam : {2, 5, 9, 11, 20}) {
      InMemoryFrame f;
      f.view.camera.width = 4;
      f.view.camera.height = 2;
      f.view.camera.fx = f.view.camera.fy = 3;
      f.view.camera.time = t / 6.0;
      f.view.camera_id = cam;
      f.view.timestep = t;
      f.image = Image(4, 2, 3, 0.1f * t);
      f.test = cam == 20;
      frames.push_back(std::move(f));
    }
  }
  DatasetOptions options;
  options.timestep_stride = 3;
  auto strided = MakeInMemoryDataset("video", frames, options);
  ASSERT_TRUE(strided.ok()) << strided.status().ToString();
  EXPECT_EQ((*strided)->timestep_count(), 3);  // timesteps 0, 3, 6
  EXPECT_EQ((*strided)->train_views().size(), 4u * 3);
  EXPECT_EQ((*strided)->test_views().size(), 3u);
  std::set<int> steps;
  for (const View& v : (*strided)->train_views()) steps.insert(v.timestep);
  EXPECT_EQ(steps, (std::set<int>{0, 1, 2}));
  EXPECT_DOUBLE_EQ((*strided)->test_views()[1].camera.time, 0.5);  // original time of timestep 3
  auto image = (*strided)->LoadImage((*strided)->test_views()[2]);
  ASSERT_TRUE(image.ok());
  EXPECT_FLOAT_EQ((*image)->pixels[0], 0.6f);  // timestep 6's frame
  EXPECT_FALSE((*strided)->warnings().empty());

  options = {};
  options.train_cameras = 2;
  auto sparse = MakeInMemoryDataset("video", frames, options);
  ASSERT_TRUE(sparse.ok()) << sparse.status().ToString();
  std::set<int> cams;
  for (const View& v : (*sparse)->train_views()) cams.insert(v.camera_id);
  EXPECT_EQ(cams, (std::set<int>{2, 9}));  // ids[0], ids[2] of {2, 5, 9, 11}
  EXPECT_EQ((*sparse)->train_views().size(), 2u * 7);
  EXPECT_EQ((*sparse)->test_views().size(), 7u);
  EXPECT_EQ((*sparse)->timestep_count(), 7);
  options.train_cameras = 4;
  EXPECT_EQ(MakeInMemoryDataset("video", frames, options).value()->train_views().size(), 4u * 7);
  options.train_cameras = 5;
  auto too_many = MakeInMemoryDataset("video", frames, options);
  EXPECT_EQ(too_many.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(too_many.status().message().find("4"), std::string::npos) << too_many.status().ToString();
  options = {};
  options.timestep_stride = 0;
  EXPECT_EQ(MakeInMemoryDataset("video", frames, options).status().code(), StatusCode::kInvalidArgument);
  options.timestep_stride = 1;
  options.train_cameras = -1;
  EXPECT_EQ(MakeInMemoryDataset("video", frames, options).status().code(), StatusCode::kInvalidArgument);
}

TEST(Panoptic, TimestepStrideAndSparseTrainCameras) {
  ATEX_REQUIRE_DATA_FILE(root, "panoptic_basketball/train_meta.json");
  DatasetOptions options;
  options.max_timesteps = 9;
  options.timestep_stride = 4;
  options.train_cameras = 6;
  auto dataset = OpenDataset(root.parent_path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.timestep_count(), 3);  // timesteps 0, 4, 8
  EXPECT_EQ(d.train_views().size(), 6u * 3);
  EXPECT_EQ(d.test_views().size(), 4u * 3);
  std::set<int> cams;
  for (const View& v : d.train_views()) cams.insert(v.camera_id);
  // The 27 training cameras 1-9, 11-14, 16-29: ids[floor(i * 27 / 6)] = ids[0, 4, 9, 13, 18, 22].
  EXPECT_EQ(cams, (std::set<int>{1, 5, 11, 16, 21, 25}));
  EXPECT_DOUBLE_EQ(d.test_views().back().camera.time, 1.0);  // t = 8 of 0..8
  EXPECT_EQ(d.test_views().back().timestep, 2);
}

// Issue 24: the packed lego layout with the wrong dtype, values outside [0, 1], or images
// larger than the image cache is refused when opened, naming the problem.
TEST(LegoNpz, ImagesAreFloatInRangeAndFitTheCache) {
  testing::TempDir dir;
  const int64_t n = 81, side = 4;
  std::vector<float> pixels(n * side * side * 3, 0.5f);
  std::vector<double> poses;
  for (int64_t i = 0; i < n; ++i) {
    for (double v : {1, 0, 0, 0, 0, 0, -1, -4, 0, 1, 0, 0, 0, 0, 0, 1}) poses.push_back(v);
  }
  std::vector<double> times(n);
  for (int64_t i = 0; i < n; ++i) times[i] = double(i % 10) / 9.0;
  const auto write = [&](const NpyArray& images, const std::string& name) {
    std::map<std::string, NpyArray> arrays = {{"images", images},
                                              {"poses", NpyArray::FromDoubles({n, 4, 4}, poses)},
                                              {"times", NpyArray::FromDoubles({n}, times)},
                                              {"focal", NpyArray::FromDoubles({}, {5.0})}};
    const std::string path = (dir / name).string();
    EXPECT_TRUE(WriteNpzFile(path, arrays, true).ok());
    return path;
  };
  const std::string good = write(NpyArray::FromFloats({n, side, side, 3}, pixels), "good.npz");
  ASSERT_TRUE(OpenDataset(good).ok()) << OpenDataset(good).status().ToString();
  NpyArray bytes;
  bytes.dtype = NpyDtype::kUint8;
  bytes.shape = {n, side, side, 3};
  bytes.data.assign(pixels.size(), 128);
  auto u8 = OpenDataset(write(bytes, "u8.npz"));
  EXPECT_EQ(u8.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(u8.status().message().find("|u1"), std::string::npos) << u8.status().ToString();
  pixels[3 * side * side * 3 + 7] = 1.5f;
  auto bright = OpenDataset(write(NpyArray::FromFloats({n, side, side, 3}, pixels), "bright.npz"));
  EXPECT_EQ(bright.status().code(), StatusCode::kCorrupt);
  EXPECT_NE(bright.status().message().find("frame 3"), std::string::npos) << bright.status().ToString();
  DatasetOptions small;
  small.image_cache_bytes = 1000;  // the 81 frames need 15,552 bytes
  auto big = OpenDataset(good, small);
  EXPECT_EQ(big.status().code(), StatusCode::kLimitExceeded);
  EXPECT_NE(big.status().message().find("image cache"), std::string::npos) << big.status().ToString();
}

// A cache larger than the machine degrades to half its RAM, with a warning.
TEST(ImageCache, LargerThanRamDegradesWithAWarning) {
  ATEX_REQUIRE_DATA_FILE(npz, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  DatasetOptions options;
  options.image_cache_bytes = uint64_t{1} << 62;
  auto d = OpenDataset(npz.string(), options);
  ASSERT_TRUE(d.ok()) << d.status().ToString();
  if (PhysicalMemoryBytes() == 0) GTEST_SKIP() << "physical memory unknown";
  EXPECT_LE((*d)->cache_limit(), PhysicalMemoryBytes() / 2);
  ASSERT_FALSE((*d)->warnings().empty());
  EXPECT_NE((*d)->warnings().back().find("half the machine's RAM"), std::string::npos);
}

TEST(LegoNpz, TimestepStrideIsRefusedTrainCamerasSelectFrames) {
  ATEX_REQUIRE_DATA_FILE(path, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  DatasetOptions options;
  options.timestep_stride = 2;
  auto strided = OpenDataset(path.string(), options);
  EXPECT_EQ(strided.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(strided.status().message().find("stride"), std::string::npos) << strided.status().ToString();
  options.timestep_stride = 1;
  options.train_cameras = 10;
  auto sparse = OpenDataset(path.string(), options);
  ASSERT_TRUE(sparse.ok()) << sparse.status().ToString();
  EXPECT_EQ((*sparse)->train_views().size(), 10u);
  EXPECT_EQ((*sparse)->train_views()[1].camera_id, 5);
  EXPECT_EQ((*sparse)->timestep_count(), 10);
  EXPECT_EQ((*sparse)->test_views().size(), 20u);
}

TEST(Views, FirstTimestepViewsAreOnePerCamera) {
  std::vector<View> views(5);
  const int steps[5] = {3, 2, 2, 5, 2};
  for (int i = 0; i < 5; ++i) {
    views[i].timestep = steps[i];
    views[i].camera_id = i;
  }
  const std::vector<const View*> first = FirstTimestepViews(views);
  ASSERT_EQ(first.size(), 3u);
  EXPECT_EQ(first[0], &views[1]);
  EXPECT_EQ(first[1], &views[2]);
  EXPECT_EQ(first[2], &views[4]);
  // Without timesteps (one frame per view, as D-NeRF): every view.
  for (View& v : views) v.timestep = -1;
  EXPECT_EQ(FirstTimestepViews(views).size(), 5u);
  EXPECT_TRUE(FirstTimestepViews({}).empty());
}

}  // namespace
}  // namespace atex
