// Per-frame export (`atex convert --frames`, see atex/converters/convert.h), and the command
// line of `atex convert`. The 4DGaussians input is tested in fourdgs_convert_test.cc.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <random>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/converters/ply.h"
#include "atex/converters/spz.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "convert/convert_test_util.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"

namespace atex {
namespace {

using converters::testing::ExpectBitEqual;
using converters::testing::FourDgsFixtureDir;
using converters::testing::HasText;
using converters::testing::MaxAbsDiff;
using converters::testing::RandomGaussians;
namespace fs = std::filesystem;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
}

// A dynamic asset whose every head (opacity and SH included) moves its
// Gaussians visibly and differently at different times: the heads' last layers
// are scaled up (native initialisation starts near identity) and the time
// planes are randomised (initialised to 1, they would make the field constant
// in time).
Asset DeformingAsset(int sh_degree) {
  Asset asset;
  asset.gaussians = RandomGaussians(48, sh_degree, 11, 0.9f);
  DeformationConfig config;
  config.grid.channels = 4;
  config.grid.base_resolution = {6, 6, 6, 5};
  config.mlp_width = 16;
  config.heads = {true, true, true, true, true};
  config.sh_coeffs = ShCoeffCount(sh_degree);
  auto field = InitDeformationField(config, 5);
  EXPECT_TRUE(field.ok()) << field.status().ToString();
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> around_one(0.3f, 1.7f);
  for (auto& scale : field->planes) {
    for (int p : {2, 4, 5}) {  // xt, yt, zt
      for (float& v : scale[p]) v = around_one(rng);
    }
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    for (float& w : field->heads[h][1].weight) w *= h == kHeadOpacity ? 300.0f : 30.0f;
  }
  asset.deformation = std::move(field).value();
  asset.metadata.time_min = 0;
  asset.metadata.time_max = 1;
  return asset;
}

// ---------------------------------------------------------------------------
// FrameRange

TEST(FrameRange, ParsesAndIncludesTheEnd) {
  auto r = ParseFrameRange("0:1:0.1");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const std::vector<double> times = r->Times();
  ASSERT_EQ(times.size(), 11u);
  EXPECT_EQ(times.front(), 0.0);
  EXPECT_EQ(times.back(), 1.0);                                                        // snapped to END
  for (size_t i = 0; i < times.size(); ++i) EXPECT_EQ(times[i], double(i) / 10) << i;  // decimal, not i * 0.1
  EXPECT_EQ(ParseFrameRange("0.02:0.1:0.04")->Times(), (std::vector<double>{0.02, 0.06, 0.1}));
  // Steps that are no short decimal: start + i * step.
  const double third = 1.0 / 3;
  EXPECT_EQ(FrameRange({0, 1, third}).Times(), (std::vector<double>{0, third, 2 * third, 1}));
  EXPECT_EQ(ParseFrameRange("0:1:0.25")->Times().size(), 5u);
  const std::vector<double> not_reaching = ParseFrameRange("0:1:0.3")->Times();  // 1 is not a time of this range
  EXPECT_EQ(not_reaching, (std::vector<double>{0, 0.3, 0.6, 0.9}));
  EXPECT_EQ(ParseFrameRange("0.5:0.5:1")->Times(), std::vector<double>{0.5});
  EXPECT_EQ(ParseFrameRange("-1:1:2")->Times(), (std::vector<double>{-1.0, 1.0}));
}

TEST(FrameRange, MalformedStringsNameTheProblem) {
  struct Case {
    const char* text;
    const char* message;
  };
  for (const Case& c :
       {Case{"0:1", "is not START:END:STEP"}, Case{"0:1:0.1:2", "is not START:END:STEP"},
        Case{"", "is not START:END:STEP"}, Case{"0,1,0.1", "is not START:END:STEP"},
        Case{"a:1:0.1", "START 'a' is not a finite number"}, Case{"0:1x:0.1", "END '1x' is not a finite number"},
        Case{"0::0.1", "END is empty"}, Case{"0:1:", "STEP is empty"},
        Case{"0:inf:0.1", "END 'inf' is not a finite number"}, Case{"0:1:nan", "STEP 'nan' is not a finite number"},
        Case{"0:1:-0.1", "STEP -0.1 is not positive"}, Case{"0:1:0", "STEP 0 is not positive"},
        Case{"1:0:0.1", "END 0 is before START 1"},
        Case{"0:1:1e-6", "gives 1000001 frames, more than the limit of 100000"},
        Case{"0:1e300:1e-300", "frames, more than the limit of 100000"}}) {
    auto r = ParseFrameRange(c.text);
    ASSERT_FALSE(r.ok()) << "'" << c.text << "' parsed";
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << c.text;
    EXPECT_TRUE(HasText(r.status().message(), c.message)) << c.text;
  }
  // Exactly the limit is allowed.
  auto limit = ParseFrameRange("0:99999:1");
  ASSERT_TRUE(limit.ok()) << limit.status().ToString();
  EXPECT_EQ(limit->Times().size(), kMaxFrames);
}

// ---------------------------------------------------------------------------
// Per-frame export

class FramesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    source_ = DeformingAsset(1);
    atex_ = (dir_ / "d.atex").string();
    ASSERT_TRUE(WriteAssetFile(atex_, source_).ok());
    // What ConvertFile reads: the asset as stored (f32 streams, but compare
    // against the file's content rather than assume it).
    auto stored = ReadAssetFile(atex_);
    ASSERT_TRUE(stored.ok()) << stored.status().ToString();
    stored_ = std::move(stored).value();
  }

  Gaussians Expected(double time) const {
    Gaussians out;
    EXPECT_TRUE(DeformForward(*stored_.deformation, stored_.gaussians, time, &out, nullptr).ok());
    return out;
  }

  testing::TempDir dir_;
  Asset source_, stored_;
  std::string atex_;
};

TEST_F(FramesTest, PlyFramesAreTheDeformedGaussiansBitForBit) {
  ConvertOptions options;
  options.frames = *ParseFrameRange("0:1:0.5");
  std::vector<std::pair<size_t, size_t>> progress;
  options.frame_progress = [&](size_t done, size_t total) {
    progress.emplace_back(done, total);
    return true;
  };
  const fs::path out = dir_ / "frames";
  auto report = ConvertFile(atex_, out.string(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->to, FileFormat::kPly);
  EXPECT_EQ(report->frame_times, (std::vector<double>{0.0, 0.5, 1.0}));
  ASSERT_EQ(report->outputs.size(), 4u);  // 3 frames + frames.json
  EXPECT_EQ(report->outputs.back(), (out / "frames.json").string());
  EXPECT_EQ(progress, (std::vector<std::pair<size_t, size_t>>{{1, 3}, {2, 3}, {3, 3}}));
  EXPECT_TRUE(report->dropped.empty());  // the deformation is baked, not dropped
  EXPECT_TRUE(report->warnings.empty());
  uint64_t bytes = 0;
  for (const auto& p : report->outputs) bytes += fs::file_size(p);
  EXPECT_EQ(report->output_bytes, bytes);

  std::vector<Gaussians> frames;
  for (size_t i = 0; i < 3; ++i) {
    const double t = report->frame_times[i];
    const std::string name = "frame_000" + std::to_string(i) + ".ply";
    ASSERT_EQ(report->outputs[i], (out / name).string());
    auto read = ReadPlyGaussians((out / name).string());
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    const Gaussians expected = Expected(t);
    const std::string at = " at t = " + std::to_string(t);
    ExpectBitEqual(read->positions, expected.positions, "positions" + at);
    ExpectBitEqual(read->log_scales, expected.log_scales, "log_scales" + at);
    ExpectBitEqual(read->rotations, expected.rotations, "rotations" + at);
    ExpectBitEqual(read->opacity_logits, expected.opacity_logits, "opacity_logits" + at);
    ExpectBitEqual(read->sh, expected.sh, "sh" + at);
    // The heads did something (else the comparison above proves nothing):
    // opacity and SH (which 4DGaussians' own exporter leaves out) included.
    EXPECT_GT(MaxAbsDiff(read->opacity_logits, stored_.gaussians.opacity_logits), 0.05) << at;
    EXPECT_GT(MaxAbsDiff(read->sh, stored_.gaussians.sh), 1e-3) << at;
    EXPECT_GT(MaxAbsDiff(read->positions, stored_.gaussians.positions), 1e-3) << at;
    frames.push_back(std::move(read).value());
  }
  // ... and differently at different times.
  EXPECT_GT(MaxAbsDiff(frames[0].opacity_logits, frames[2].opacity_logits), 0.01);
  EXPECT_GT(MaxAbsDiff(frames[0].positions, frames[2].positions), 1e-4);

  const nlohmann::json manifest = ReadJson(out / "frames.json");
  ASSERT_FALSE(manifest.is_discarded());
  EXPECT_EQ(manifest["format"], "ply");
  EXPECT_EQ(manifest["count"], 3);
  EXPECT_EQ(manifest["deformed"], true);
  ASSERT_EQ(manifest["frames"].size(), 3u);
  EXPECT_EQ(manifest["frames"][1]["file"], "frame_0001.ply");
  EXPECT_EQ(manifest["frames"][1]["time"].get<double>(), 0.5);
  EXPECT_EQ(report->ToJson()["frames"]["count"], 3);
}

// Time-local Gaussians (model.h time_windows): a static file of such an asset needs a time (the
// canonical set would show every one at every time); at a time, and per frame, the window is applied.
TEST(ConvertTimeWindows, NeedATimeAndApplyTheWindowWhenGivenOne) {
  testing::TempDir dir;
  Asset asset = DeformingAsset(0);
  asset.gaussians.time_windows.assign(2 * asset.gaussians.size(), 0.0f);
  asset.gaussians.time_windows[0] = 0.0f;  // Gaussian 0 lives around t = 0 only
  asset.gaussians.time_windows[1] = 10.0f;
  const std::string atex = (dir / "w.atex").string();
  ASSERT_TRUE(WriteAssetFile(atex, asset).ok());
  auto refused = ConvertFile(atex, (dir / "w.ply").string());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("--time"), std::string::npos) << refused.status().message();
  for (double t : {0.0, 1.0}) {
    ConvertOptions at;
    at.time = t;
    const std::string ply = (dir / ("w" + std::to_string(int(t)) + ".ply")).string();
    auto r = ConvertFile(atex, ply, at);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    auto g = ReadPlyGaussians(ply);
    ASSERT_TRUE(g.ok()) << g.status().ToString();
    Gaussians deformed;
    ASSERT_TRUE(DeformForward(*asset.deformation, asset.gaussians, t, &deformed, nullptr).ok());
    EXPECT_EQ(g->opacity_logits[0], deformed.opacity_logits[0]) << "t = " << t;
  }
}

TEST_F(FramesTest, SpzFramesMatchWithinQuantisation) {
  ConvertOptions options;
  options.frames = *ParseFrameRange("0:1:0.5");
  options.to = FileFormat::kSpz;
  const fs::path out = dir_ / "spz";
  auto report = ConvertFile(atex_, out.string(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->to, FileFormat::kSpz);
  ASSERT_EQ(report->frame_times.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const double t = report->frame_times[i];
    const fs::path path = out / ("frame_000" + std::to_string(i) + ".spz");
    auto read = ReadSpzGaussians(path.string());
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    const Gaussians expected = Expected(t);
    ASSERT_EQ(read->size(), expected.size());
    // Positions: 24-bit fixed point with 12 fraction bits, rounded to nearest.
    for (size_t k = 0; k < expected.positions.size(); ++k) {
      ASSERT_NEAR(read->positions[k], expected.positions[k], 0.5 / 4096 + 1e-6) << "position " << k << " at " << t;
    }
    // Opacity: alpha as u8 (rounded), decoded within [1/255, 254/255].
    size_t moved = 0;
    for (size_t k = 0; k < expected.size(); ++k) {
      const double alpha = std::clamp(Sigmoid(expected.opacity_logits[k]), 1.0 / 255, 254.0 / 255);
      ASSERT_NEAR(Sigmoid(read->opacity_logits[k]), alpha, 0.5 / 255 + 1e-6) << "opacity " << k << " at " << t;
      const double canonical = std::clamp(Sigmoid(stored_.gaussians.opacity_logits[k]), 1.0 / 255, 254.0 / 255);
      if (std::fabs(alpha - canonical) > 2.0 / 255) ++moved;
    }
    EXPECT_GT(moved, 0u) << "the opacity deformation is visible in the SPZ frame at " << t;
    // Log-scales: u8 with step 1/16.
    for (size_t k = 0; k < expected.log_scales.size(); ++k) {
      ASSERT_NEAR(read->log_scales[k], expected.log_scales[k], 0.5 / 16 + 1e-5) << "log-scale " << k << " at " << t;
    }
  }
  const nlohmann::json manifest = ReadJson(out / "frames.json");
  EXPECT_EQ(manifest["format"], "spz");
  EXPECT_EQ(manifest["frames"][2]["file"], "frame_0002.spz");
}

TEST_F(FramesTest, ErrorsAndCancellation) {
  const std::string out = (dir_ / "out").string();
  ConvertOptions options;
  options.frames = *ParseFrameRange("0:1:0.5");

  ConvertOptions to_atex = options;
  to_atex.to = FileFormat::kAtex;
  auto r = ConvertFile(atex_, out, to_atex);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasText(r.status().message(), "--frames writes .ply or .spz files"));

  ConvertOptions with_time = options;
  with_time.time = 0.5;
  r = ConvertFile(atex_, out, with_time);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasText(r.status().message(), "exclude each other"));

  ConvertOptions bad_range = options;
  bad_range.frames->step = -0.5;
  r = ConvertFile(atex_, out, bad_range);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasText(r.status().message(), "STEP -0.5 is not positive"));

  // An output that names a file rather than a folder.
  r = ConvertFile(atex_, (dir_ / "frames.ply").string(), options);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_TRUE(HasText(r.status().message(), "looks like a file name"));
  EXPECT_FALSE(fs::exists(dir_ / "frames.ply"));
  r = ConvertFile(atex_, atex_ + ".x", options);  // does not exist, no known extension: becomes a folder
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  r = ConvertFile(atex_, atex_, options);
  EXPECT_FALSE(r.ok());

  // Cancelled after the first frame: the manifest is not written.
  ConvertOptions cancel = options;
  cancel.frame_progress = [](size_t done, size_t) { return done < 1; };
  r = ConvertFile(atex_, out, cancel);
  EXPECT_EQ(r.status().code(), StatusCode::kCancelled);
  EXPECT_TRUE(fs::exists(fs::path(out) / "frame_0000.ply"));
  EXPECT_FALSE(fs::exists(fs::path(out) / "frame_0001.ply"));
  EXPECT_FALSE(fs::exists(fs::path(out) / "frames.json"));

  // A complete export, then a shorter one into the same folder: the old
  // manifest is replaced and the left-over files are pointed out.
  ASSERT_TRUE(ConvertFile(atex_, out, options).ok());
  ConvertOptions shorter = options;
  shorter.frames = *ParseFrameRange("0:0.5:0.5");
  auto second = ConvertFile(atex_, out, shorter);
  ASSERT_TRUE(second.ok()) << second.status().ToString();
  EXPECT_EQ(ReadJson(fs::path(out) / "frames.json")["count"], 2);
  bool pointed_out = false;
  for (const auto& n : second->notes) pointed_out |= n.find("earlier, longer export") != std::string::npos;
  EXPECT_TRUE(pointed_out);
}

TEST(Frames, StaticAssetRepeatsTheCanonicalSet) {
  testing::TempDir dir;
  const Gaussians g = RandomGaussians(30, 2, 3);
  const std::string ply = (dir / "s.ply").string();
  ASSERT_TRUE(WritePlyGaussians(ply, g).ok());
  ConvertOptions options;
  options.frames = *ParseFrameRange("0:1:0.5");
  auto report = ConvertFile(ply, (dir / "out").string(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->frame_times.size(), 3u);
  bool noted = false;
  for (const auto& n : report->notes) noted |= n.find("static asset") != std::string::npos;
  EXPECT_TRUE(noted);
  for (size_t i = 0; i < 3; ++i) {
    auto read = ReadPlyGaussians(report->outputs[i]);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    ExpectBitEqual(read->positions, g.positions, "positions");
    ExpectBitEqual(read->opacity_logits, g.opacity_logits, "opacity_logits");
    ExpectBitEqual(read->sh, g.sh, "sh");
  }
  EXPECT_EQ(ReadJson(dir / "out" / "frames.json")["deformed"], false);
}

TEST(Frames, TexturedAssetWarnsThatTexturesAreLeftOut) {
  testing::TempDir dir;
  Asset asset = DeformingAsset(0);
  TexturePool pool;
  for (size_t i = 0; i < asset.gaussians.size(); ++i) {
    pool.heights.push_back(2);
    pool.widths.push_back(2);
    pool.axis_u.push_back(0);
    pool.axis_v.push_back(1);
  }
  pool.RebuildOffsets();
  pool.texels.assign(pool.texel_count() * 4, 0.25f);
  asset.textures = pool;
  asset.metadata.texture_mode = "uniform";
  const std::string atex = (dir / "t.atex").string();
  ASSERT_TRUE(WriteAssetFile(atex, asset).ok());
  ConvertOptions options;
  options.frames = *ParseFrameRange("0:1:0.5");
  auto report = ConvertFile(atex, (dir / "out").string(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->warnings.size(), 1u);
  EXPECT_TRUE(HasText(report->warnings[0], "textures dropped"));
  EXPECT_EQ(report->dropped, std::vector<std::string>{"textures"});
  const nlohmann::json json = report->ToJson();
  ASSERT_EQ(json["warnings"].size(), 1u);
  EXPECT_EQ(ReadJson(dir / "out" / "frames.json")["textures_dropped"], true);
  // A single deformed file warns the same way.
  ConvertOptions single;
  single.time = 0.25;
  auto one = ConvertFile(atex, (dir / "one.spz").string(), single);
  ASSERT_TRUE(one.ok()) << one.status().ToString();
  EXPECT_EQ(one->warnings.size(), 1u);
}

// ---------------------------------------------------------------------------
// The command line.

TEST(ConvertCli, FramesAndFourDgs) {
  const char* bin = std::getenv("ATEX_BINARY_DIR");
  ASSERT_NE(bin, nullptr);
  const fs::path atex_bin = fs::path(bin) / "bin" / "atex";
  ASSERT_TRUE(fs::exists(atex_bin)) << atex_bin;
  testing::TempDir dir;
  const std::string atex = (dir / "d.atex").string();
  ASSERT_TRUE(WriteAssetFile(atex, DeformingAsset(0)).ok());

  const std::string json_path = (dir / "out.json").string();
  std::string command = atex_bin.string() + " convert " + atex + " --frames 0:1:0.5 --to spz " +
                        (dir / "frames").string() + " --json > " + json_path;
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  std::ifstream in(json_path);
  const auto json = nlohmann::json::parse(in);
  EXPECT_EQ(json["to"], "spz");
  EXPECT_EQ(json["frames"]["count"], 3);
  EXPECT_TRUE(fs::exists(dir / "frames" / "frame_0002.spz"));
  EXPECT_TRUE(fs::exists(dir / "frames" / "frames.json"));

  // A malformed range fails before anything is read, naming the problem.
  const std::string err_path = (dir / "err.txt").string();
  command = atex_bin.string() + " convert " + atex + " --frames 0:1:-0.5 " + (dir / "bad").string() + " 2> " + err_path;
  EXPECT_NE(std::system(command.c_str()), 0);
  std::ifstream err(err_path);
  const std::string message((std::istreambuf_iterator<char>(err)), std::istreambuf_iterator<char>());
  EXPECT_TRUE(HasText(message, "STEP -0.5 is not positive"));
  EXPECT_FALSE(fs::exists(dir / "bad"));

  // A 4DGaussians folder in, .atex out.
  command = atex_bin.string() + " convert " + FourDgsFixtureDir().string() + " " + (dir / "i.atex").string() +
            " --from 4dgs > /dev/null";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  EXPECT_TRUE(fs::exists(dir / "i.atex"));
}

}  // namespace
}  // namespace atex
