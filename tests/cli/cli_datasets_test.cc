// The dataset kinds users hold, end to end through the `atex` binary: a nerfstudio
// transforms.json scene with per-frame time and a COLMAP model (text and binary), written
// here, found by --data alone, trained for a few CPU steps and evaluated; COLMAP's points3D
// is the default initialisation. Broken inputs end in a clean error naming the file.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "atex/image.h"
#include "atex/status.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct Result {
  int exit_code = -1;
  bool signalled = false;
  std::string out, err;
};

std::string Slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void WriteText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

// A 24x24 frame: a soft disc whose position moves with `shift`, on a gradient.
Image Frame(double shift) {
  Image image(24, 24, 3);
  for (int y = 0; y < 24; ++y) {
    for (int x = 0; x < 24; ++x) {
      const double d = std::hypot(x - 12 - shift, y - 12.0);
      const float disc = d < 6 ? 1.0f : 0.0f;
      image.at(x, y, 0) = 0.2f + 0.7f * disc;
      image.at(x, y, 1) = 0.1f + 0.02f * x;
      image.at(x, y, 2) = 0.3f * (1 - disc);
    }
  }
  return image;
}

const char* kTiny =
    "--backend cpu --set stage1.coarse_iterations=2 --set stage1.fine_iterations=2 --set stage1.init_points=200 "
    "--set stage2.iterations=2 --set stage2.growth_steps=[1] --set eval_every=0 --set stage2.batch_size=1";

class CliDatasets : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* cli = std::getenv("ATEX_CLI");
    ASSERT_NE(cli, nullptr) << "ATEX_CLI is not set (CTest sets it)";
    cli_ = cli;
  }

  Result Run(const std::string& args) {
    Result r;
    const auto out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string command = "'" + cli_ + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
    const int status = std::system(command.c_str());
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.signalled = !WIFEXITED(status) || r.exit_code >= 128;
    r.out = Slurp(out);
    r.err = Slurp(err);
    return r;
  }

  // Trains a few steps on `data` and evaluates the result on its test views.
  void TrainAndEvaluate(const fs::path& data, const std::string& expect_in_log) {
    const std::string asset = (dir_ / "model.atex").string();
    fs::remove(asset);
    Result r = Run("train --data '" + data.string() + "' " + kTiny + " --out '" + asset + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find(expect_in_log), std::string::npos) << r.err;
    ASSERT_TRUE(fs::exists(asset));
    r = Run("eval '" + asset + "' --data '" + data.string() + "' --backend cpu --json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const json report = json::parse(r.out);
    EXPECT_GE(report["views"].size(), 1u) << r.out;
    EXPECT_TRUE(std::isfinite(report["mean"]["psnr"].get<double>())) << r.out;
  }

  std::string cli_;
  testing::TempDir dir_;
};

TEST_F(CliDatasets, NerfstudioTransformsWithTimeTrainsAndEvaluates) {
  const fs::path root = dir_ / "ns";
  json doc = {{"fl_x", 30.0}, {"fl_y", 30.0}, {"w", 24}, {"h", 24}, {"frames", json::array()}};
  for (int i = 0; i < 10; ++i) {
    // Cameras at (x, -4, 0) looking along +y (OpenGL axes: right +x, up +z, back -y).
    const double x = 0.2 * (i - 5);
    const std::string name = StrCat("images/f", i, ".png");
    fs::create_directories(root / "images");
    ASSERT_TRUE(WriteImage((root / name).string(), Frame(i * 0.5 - 30 * x / 4)).ok());
    doc["frames"].push_back({{"file_path", name},
                             {"time", i / 9.0},
                             {"transform_matrix", json::parse(StrCat("[[1,0,0,", x, "],[0,0,-1,-4],[0,1,0,0],[0,0,0,1]]"))}});
  }
  WriteText(root / "transforms.json", doc.dump());
  TrainAndEvaluate(root, "initialised");
  // --dataset-kind names it; a broken file is a clean error naming the element.
  doc["frames"][3]["transform_matrix"][1] = "x";
  WriteText(root / "transforms.json", doc.dump());
  const Result r = Run("train --data '" + root.string() + "' --dataset-kind nerfstudio " + kTiny + " --out '" +
                       (dir_ / "bad.atex").string() + "'");
  EXPECT_FALSE(r.signalled) << r.err;
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("frames[3].transform_matrix[1]"), std::string::npos) << r.err;
}

TEST_F(CliDatasets, ColmapModelTrainsFromItsPointsAndEvaluates) {
  for (bool binary : {false, true}) {
    const fs::path root = dir_ / (binary ? "colmap_bin" : "colmap_txt");
    std::string cameras = "1 SIMPLE_PINHOLE 24 24 30 12 12\n", images, points;
    for (int i = 0; i < 9; ++i) {
      const double x = 0.2 * (i - 4);
      const std::string name = StrCat("v", i, ".png");
      fs::create_directories(root / "images");
      ASSERT_TRUE(WriteImage((root / "images" / name).string(), Frame(-30 * x / 4)).ok());
      // Identity rotation, camera at (-x, 0, -4): world origin at depth 4.
      images += StrCat(i + 1, " 1 0 0 0 ", x, " 0 4 1 ", name, "\n\n");
    }
    for (int k = 0; k < 40; ++k) {
      points += StrCat(k + 1, " ", 0.05 * (k % 7 - 3), " ", 0.05 * (k / 7 - 3), " 0 200 80 40 0.5\n");
    }
    WriteText(root / "sparse/0/cameras.txt", cameras);
    WriteText(root / "sparse/0/images.txt", images);
    WriteText(root / "sparse/0/points3D.txt", points);
    if (binary) {
      // The same model through `colmap model_converter`'s binary layout, written by hand.
      std::string cam_bin, img_bin, pts_bin;
      auto u32 = [](std::string* s, uint32_t v) { s->append(reinterpret_cast<const char*>(&v), 4); };
      auto u64 = [](std::string* s, uint64_t v) { s->append(reinterpret_cast<const char*>(&v), 8); };
      auto f64 = [](std::string* s, double v) { s->append(reinterpret_cast<const char*>(&v), 8); };
      u64(&cam_bin, 1), u32(&cam_bin, 1), u32(&cam_bin, 0), u64(&cam_bin, 24), u64(&cam_bin, 24);
      for (double v : {30.0, 12.0, 12.0}) f64(&cam_bin, v);
      u64(&img_bin, 9);
      for (int i = 0; i < 9; ++i) {
        u32(&img_bin, i + 1);
        for (double v : {1.0, 0.0, 0.0, 0.0, 0.2 * (i - 4), 0.0, 4.0}) f64(&img_bin, v);
        u32(&img_bin, 1);
        img_bin += StrCat("v", i, ".png");
        img_bin.push_back('\0');
        u64(&img_bin, 0);
      }
      u64(&pts_bin, 40);
      for (int k = 0; k < 40; ++k) {
        u64(&pts_bin, k + 1);
        for (double v : {0.05 * (k % 7 - 3), 0.05 * (k / 7 - 3), 0.0}) f64(&pts_bin, v);
        pts_bin += std::string("\xc8\x50\x28", 3);
        f64(&pts_bin, 0.5);
        u64(&pts_bin, 0);
      }
      fs::remove_all(root / "sparse/0");
      WriteText(root / "sparse/0/cameras.bin", cam_bin);
      WriteText(root / "sparse/0/images.bin", img_bin);
      WriteText(root / "sparse/0/points3D.bin", pts_bin);
    }
    TrainAndEvaluate(root, "file: 40 points of");
    // The kind's defaults (D-NeRF's) are the same named or detected.
    const Result named = Run("train --print-config --dataset-kind colmap");
    const Result detected = Run("train --print-config --data '" + root.string() + "'");
    ASSERT_EQ(named.exit_code, 0) << named.err;
    ASSERT_EQ(detected.exit_code, 0) << detected.err;
    EXPECT_EQ(json::parse(named.out), json::parse(detected.out));
    EXPECT_EQ(json::parse(named.out)["stage1"]["deformation"]["grid"]["channels"], 32);
  }
  // A distorted camera is refused before training, naming the camera and its model.
  const fs::path root = dir_ / "colmap_txt";
  WriteText(root / "sparse/0/cameras.txt", "1 OPENCV 24 24 30 30 12 12 0.2 0 0 0\n");
  const Result r = Run("train --data '" + root.string() + "' " + kTiny + " --out '" + (dir_ / "bad.atex").string() + "'");
  EXPECT_FALSE(r.signalled) << r.err;
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("camera 1 (OPENCV)"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("cameras.txt"), std::string::npos) << r.err;
}

TEST_F(CliDatasets, N3dvFromItsVideosTrainsAndEvaluates) {
  const fs::path root = dir_ / "n3dv";
  fs::create_directories(root);
  const int cameras = 4, frames = 4;
  std::vector<double> rows;
  for (int c = 0; c < cameras; ++c) {
    // LLFF rotation columns (down, right, back) = (-y, +x, +z): cameras at x = 0.2 c, z = 4,
    // looking along -z at the origin; (H, W, focal) = (24, 24, 30).
    const double row[17] = {0, 1, 0, 0.2 * c, 24, -1, 0, 0, 0, 24, 0, 0, 1, 4, 30, 1, 10};
    rows.insert(rows.end(), row, row + 17);
  }
  // poses_bounds.npy: a version-1 .npy header and float64 rows.
  std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" + std::to_string(cameras) + ", 17), }";
  header.append(64 - (10 + header.size() + 1) % 64, ' ');
  header += '\n';
  std::string npy = std::string("\x93NUMPY\x01\x00", 8);
  npy.push_back(char(header.size() & 0xff));
  npy.push_back(char(header.size() >> 8));
  npy += header;
  npy.append(reinterpret_cast<const char*>(rows.data()), rows.size() * sizeof(double));
  WriteText(root / "poses_bounds.npy", npy);
  const std::string ffmpeg = ATEX_FFMPEG_EXECUTABLE;
  ASSERT_FALSE(ffmpeg.empty()) << "the ffmpeg command (Debian package ffmpeg) encodes this test's videos";
  for (int c = 0; c < cameras; ++c) {
    const fs::path pngs = dir_ / "png" / std::to_string(c);
    fs::create_directories(pngs);
    for (int f = 0; f < frames; ++f) {
      ASSERT_TRUE(WriteImage((pngs / StrCat("00", f, ".png")).string(), Frame(f * 0.7 - 30 * 0.2 * c / 4)).ok());
    }
    const std::string command = "'" + ffmpeg + "' -nostdin -v error -y -framerate 30 -i '" + (pngs / "%03d.png").string() +
                                "' -c:v libx264rgb -qp 0 -pix_fmt rgb24 '" + (root / StrCat("cam0", c, ".mp4")).string() + "'";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
  }
  const Result info = Run("train --data '" + root.string() + "' --print-config");
  if (info.exit_code != 0 && info.err.find("without FFmpeg") != std::string::npos) {
    // A build without FFmpeg: the refusal says how to get frames another way.
    EXPECT_NE(info.err.find("extract the frames"), std::string::npos) << info.err;
    return;
  }
  ASSERT_EQ(info.exit_code, 0) << info.err;
  TrainAndEvaluate(root, "initialised");
}

}  // namespace
}  // namespace atex
