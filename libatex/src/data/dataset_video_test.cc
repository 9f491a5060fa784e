// N3DV straight from its camNN.mp4 videos: lossless videos made here with the ffmpeg command
// from PNG frames whose pixels are known, decoded through libavcodec; the decoded pixels must
// be the encoded ones. Builds without FFmpeg must refuse with advice instead.
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include <gtest/gtest.h>

#include "atex/dataset.h"
#include "atex/npy.h"
#include "core/test_support.h"
#include "data/video_frames.h"

namespace atex {
namespace {

namespace fs = std::filesystem;

// Frame f of camera c: a gradient whose values identify both.
Image VideoFrame(int c, int f) {
  Image image(32, 16, 3);
  for (int y = 0; y < 16; ++y) {
    for (int x = 0; x < 32; ++x) {
      image.at(x, y, 0) = float((x * 8 + c * 40) % 256) / 255.0f;
      image.at(x, y, 1) = float((y * 16 + f * 20) % 256) / 255.0f;
      image.at(x, y, 2) = float((x * y + f * 3 + c) % 256) / 255.0f;
    }
  }
  return image;
}

// poses_bounds.npy for `cameras` cameras looking along -z (LLFF rotation columns down = -y,
// right = +x, back = +z), at x = c, with (H, W, focal) = (16, 32, 30).
void WritePoses(const fs::path& root, int cameras) {
  std::vector<double> rows;
  for (int c = 0; c < cameras; ++c) {
    const double row[17] = {0, 1, 0, double(c), 16, -1, 0, 0, 0, 32, 0, 0, 1, 0, 30, 0.5, 20};
    rows.insert(rows.end(), row, row + 17);
  }
  ASSERT_TRUE(WriteNpyFile((root / "poses_bounds.npy").string(), NpyArray::FromDoubles({cameras, 17}, rows)).ok());
}

// camNN.mp4 of `frames` frames, H.264 lossless RGB (libx264rgb -qp 0), made by the ffmpeg command.
void WriteVideos(const fs::path& root, int cameras, int frames) {
  const std::string ffmpeg = ATEX_FFMPEG_EXECUTABLE;
  ASSERT_FALSE(ffmpeg.empty()) << "the ffmpeg command (Debian package ffmpeg) encodes this test's videos";
  for (int c = 0; c < cameras; ++c) {
    const fs::path pngs = root / "png" / std::to_string(c);
    fs::create_directories(pngs);
    for (int f = 0; f < frames; ++f) {
      char name[32];
      std::snprintf(name, sizeof(name), "%03d.png", f);
      ASSERT_TRUE(WriteImage((pngs / name).string(), VideoFrame(c, f)).ok());
    }
    char video[32];
    std::snprintf(video, sizeof(video), "cam%02d.mp4", c);
    const std::string command = "'" + ffmpeg + "' -nostdin -v error -y -framerate 30 -i '" +
                                (pngs / "%03d.png").string() + "' -c:v libx264rgb -qp 0 -pix_fmt rgb24 '" +
                                (root / video).string() + "'";
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
  }
  fs::remove_all(root / "png");
}

TEST(N3dvVideo, DecodedFramesAreTheEncodedPixels) {
  testing::TempDir dir;
  WritePoses(dir.path(), 3);
  if (!data_detail::VideoDecodingAvailable()) {
    std::ofstream(dir / "cam00.mp4") << "x";
    std::ofstream(dir / "cam01.mp4") << "x";
    std::ofstream(dir / "cam02.mp4") << "x";
    auto d = OpenDataset(dir.path().string());
    EXPECT_EQ(d.status().code(), StatusCode::kUnsupported);
    EXPECT_NE(d.status().ToString().find("extract the frames"), std::string::npos) << d.status().ToString();
    return;
  }
  WriteVideos(dir.path(), 3, 6);
  auto dataset = OpenDataset(dir.path().string());
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  const Dataset& d = **dataset;
  EXPECT_EQ(d.kind(), DatasetKind::kN3dv);
  EXPECT_EQ(d.timestep_count(), 6);
  ASSERT_EQ(d.test_views().size(), 6u);   // cam00
  ASSERT_EQ(d.train_views().size(), 12u);
  const View& v = d.train_views()[9];  // cam02, frame 3
  EXPECT_EQ(v.camera_id, 2);
  EXPECT_EQ(v.timestep, 3);
  EXPECT_DOUBLE_EQ(v.camera.time, 3 / 5.0);
  EXPECT_EQ(v.camera.width, 32);
  EXPECT_DOUBLE_EQ(v.camera.fx, 30.0);
  EXPECT_NEAR(v.camera.Center()[0], 2.0, 1e-12);
  for (const View* view : {&d.test_views()[0], &d.train_views()[9], &d.train_views()[11]}) {
    auto image = d.LoadImage(*view);
    ASSERT_TRUE(image.ok()) << image.status().ToString();
    const Image expected = VideoFrame(view->camera_id, view->timestep);
    ASSERT_EQ((*image)->pixels.size(), expected.pixels.size());
    for (size_t k = 0; k < expected.pixels.size(); ++k) {
      ASSERT_NEAR((*image)->pixels[k], expected.pixels[k], 1e-6) << view->camera.name << " value " << k;
    }
  }

  // --timesteps stops the decoding early; --downscale keeps small frames.
  DatasetOptions options;
  options.max_timesteps = 2;
  options.downscale = 2;
  dataset = OpenDataset(dir.path().string(), options);
  ASSERT_TRUE(dataset.ok()) << dataset.status().ToString();
  EXPECT_EQ((*dataset)->timestep_count(), 2);
  EXPECT_EQ((*dataset)->train_views().size(), 4u);
  const View& small = (*dataset)->train_views()[3];  // cam02, frame 1
  auto image = (*dataset)->LoadImage(small);
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ((*image)->width, 16);
  auto expected = DownscaleImage(VideoFrame(2, 1), 2);
  ASSERT_TRUE(expected.ok());
  for (size_t k = 0; k < expected->pixels.size(); ++k)
    ASSERT_NEAR((*image)->pixels[k], expected->pixels[k], 0.5 / 255 + 1e-6);
  int seen = 0;
  auto count = data_detail::DecodeVideoFrames((dir / "cam01.mp4").string(), 4, [&](int64_t index, Image frame) {
    EXPECT_EQ(index, seen++);
    EXPECT_EQ(frame.width, 32);
    return Status::Ok();
  });
  ASSERT_TRUE(count.ok()) << count.status().ToString();
  EXPECT_EQ(*count, 4);
  EXPECT_EQ(seen, 4);

  // The decoded frames are bounded by the image cache.
  options = {};
  options.image_cache_bytes = 32 * 16 * 3 * 5;  // five frames
  auto limited = OpenDataset(dir.path().string(), options);
  EXPECT_EQ(limited.status().code(), StatusCode::kLimitExceeded) << limited.status().ToString();
  EXPECT_NE(limited.status().ToString().find("--timesteps"), std::string::npos);

  // Hostile videos: garbage and a truncated file are errors naming the file.
  std::ofstream(dir / "cam01.mp4", std::ios::binary | std::ios::trunc) << std::string(3000, '\x17');
  auto garbage = OpenDataset(dir.path().string());
  ASSERT_FALSE(garbage.ok());
  EXPECT_NE(garbage.status().ToString().find("cam01.mp4"), std::string::npos) << garbage.status().ToString();
  const auto size = fs::file_size(dir / "cam02.mp4");
  fs::resize_file(dir / "cam02.mp4", size / 2);
  fs::copy_file(dir / "cam00.mp4", dir / "cam01.mp4", fs::copy_options::overwrite_existing);
  auto truncated = OpenDataset(dir.path().string());
  if (truncated.ok()) {  // a cut may still leave decodable frames; those must be the encoded ones
    for (const View& view : (*truncated)->train_views()) EXPECT_TRUE((*truncated)->LoadImage(view).ok());
  } else {
    EXPECT_NE(truncated.status().ToString().find("cam02.mp4"), std::string::npos) << truncated.status().ToString();
  }

  // Extracted frames beside the videos take precedence (4DGaussians keeps both).
  for (int c = 0; c < 3; ++c) {
    const fs::path folder = dir / ("cam0" + std::to_string(c)) / "images";
    fs::create_directories(folder);
    ASSERT_TRUE(WriteImage((folder / "0000.png").string(), VideoFrame(c, 9)).ok());
  }
  auto extracted = OpenDataset(dir.path().string());
  ASSERT_TRUE(extracted.ok()) << extracted.status().ToString();
  EXPECT_EQ((*extracted)->timestep_count(), 1);
  EXPECT_EQ(fs::path((*extracted)->train_views()[0].image).extension(), ".png");
}

}  // namespace
}  // namespace atex
