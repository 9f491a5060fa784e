// The 4DGaussians input of `atex convert` (see atex/converters/convert.h): the committed fixture
// (tests/fixtures/fourdgs, see converters/src/fourdgs/fourdgs_fixture_test.cc) through ConvertFile,
// against PyTorch's own deformation of it.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/converters/convert.h"
#include "atex/converters/ply.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "convert/convert_test_util.h"
#include "core/test_support.h"

namespace atex {
namespace {

using converters::testing::ExpectBitEqual;
using converters::testing::FourDgsFixtureDir;
using converters::testing::HasText;
using converters::testing::MaxAbsDiff;
namespace fs = std::filesystem;

struct FixtureExpected {
  std::vector<double> times;
  std::vector<Gaussians> blocks;  // [0] canonical, [1 + i] deformed by PyTorch at times[i]
};

// expected.json / expected.bin as written by tests/fixtures/fourdgs/make_fixture.py.
StatusOr<FixtureExpected> LoadFixture(const fs::path& dir) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> text, ReadFileBytes((dir / "expected.json").string()));
  const nlohmann::json meta = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
  if (meta.is_discarded()) return MakeError(StatusCode::kCorrupt, "expected.json does not parse");
  FixtureExpected e;
  e.times = meta["times"].get<std::vector<double>>();
  const size_t n = meta["count"].get<size_t>();
  const int degree = meta["sh_degree"].get<int>();
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, ReadFileBytes((dir / "expected.bin").string()));
  const size_t floats = (1 + e.times.size()) * n * (3 + 3 + 4 + 1 + 3 * ShCoeffCount(degree));
  if (raw.size() != floats * 4) return MakeError(StatusCode::kCorrupt, "expected.bin has ", raw.size(), " bytes");
  size_t at = 0;
  auto take = [&](std::vector<float>& v) {
    for (float& x : v) {
      uint32_t bits = 0;
      for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(raw[at++]) << (8 * b);
      x = std::bit_cast<float>(bits);
    }
  };
  for (size_t b = 0; b < 1 + e.times.size(); ++b) {
    Gaussians g;
    g.sh_degree = degree;
    g.Resize(n);
    take(g.positions);  // the file's order: positions, log-scales, rotations, opacities, SH
    take(g.log_scales);
    take(g.rotations);
    take(g.opacity_logits);
    take(g.sh);
    e.blocks.push_back(std::move(g));
  }
  return e;
}

void ExpectNear(const std::vector<float>& ours, const std::vector<float>& torch, const std::string& what) {
  ASSERT_EQ(ours.size(), torch.size()) << what;
  for (size_t i = 0; i < ours.size(); ++i) {
    ASSERT_NEAR(ours[i], torch[i], 2e-5 + 2e-5 * std::fabs(torch[i])) << what << "[" << i << "]";
  }
}

TEST(ConvertFourDgs, FixtureFolderToAtexMatchesPyTorch) {
  const fs::path fixture = FourDgsFixtureDir();
  ASSERT_TRUE(fs::exists(fixture / "deformation.pth")) << fixture;
  auto expected = LoadFixture(fixture);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();
  testing::TempDir dir;
  const std::string atex = (dir / "imported.atex").string();
  auto report = ConvertFile(fixture.string(), atex);  // a folder: read as 4dgs
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->from, FileFormat::kFourDgs);
  EXPECT_EQ(report->to, FileFormat::kAtex);
  EXPECT_TRUE(report->deformation);
  EXPECT_EQ(report->gaussians, expected->blocks[0].size());
  EXPECT_EQ(report->input_bytes,
            fs::file_size(fixture / "point_cloud.ply") + fs::file_size(fixture / "deformation.pth"));
  ASSERT_FALSE(report->notes.empty());
  EXPECT_TRUE(HasText(report->notes[0], "position, scale, rotation, opacity, SH"));

  auto asset = ReadAssetFile(atex);
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  ASSERT_TRUE(asset->deformation.has_value());
  EXPECT_EQ(asset->metadata.extra["importer"], "4DGaussians");
  const Gaussians& canonical = expected->blocks[0];
  ExpectBitEqual(asset->gaussians.positions, canonical.positions, "canonical positions");
  ExpectBitEqual(asset->gaussians.opacity_logits, canonical.opacity_logits, "canonical opacity");
  ExpectBitEqual(asset->gaussians.sh, canonical.sh, "canonical sh");
  for (size_t i = 0; i < expected->times.size(); ++i) {
    Gaussians ours;
    ASSERT_TRUE(DeformForward(*asset->deformation, asset->gaussians, expected->times[i], &ours, nullptr).ok());
    const Gaussians& torch = expected->blocks[1 + i];
    const std::string at = " at t = " + std::to_string(expected->times[i]);
    ExpectNear(ours.positions, torch.positions, "positions" + at);
    ExpectNear(ours.log_scales, torch.log_scales, "log_scales" + at);
    ExpectNear(ours.rotations, torch.rotations, "rotations" + at);
    ExpectNear(ours.opacity_logits, torch.opacity_logits, "opacity_logits" + at);
    ExpectNear(ours.sh, torch.sh, "sh" + at);
  }
}

TEST(ConvertFourDgs, FixtureFramesMatchPyTorch) {
  const fs::path fixture = FourDgsFixtureDir();
  ASSERT_TRUE(fs::exists(fixture / "deformation.pth")) << fixture;
  auto expected = LoadFixture(fixture);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();
  ASSERT_EQ(expected->times, (std::vector<double>{0.0, 0.3, 0.65, 1.0}));
  testing::TempDir dir;
  ConvertOptions options;
  options.from = FileFormat::kFourDgs;
  // 0.3 + 0.35 is 0.6499999999999999 in double: the last time snaps to END.
  options.frames = *ParseFrameRange("0.3:0.65:0.35");
  auto report = ConvertFile(fixture.string(), (dir / "frames").string(), options);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  ASSERT_EQ(report->frame_times, (std::vector<double>{0.3, 0.65}));
  for (size_t i = 0; i < 2; ++i) {
    auto read = ReadPlyGaussians(report->outputs[i]);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    const Gaussians& torch = expected->blocks[2 + i];  // times[1], times[2]
    const std::string at = " at t = " + std::to_string(report->frame_times[i]);
    ExpectNear(read->positions, torch.positions, "positions" + at);
    ExpectNear(read->log_scales, torch.log_scales, "log_scales" + at);
    ExpectNear(read->rotations, torch.rotations, "rotations" + at);
    ExpectNear(read->opacity_logits, torch.opacity_logits, "opacity_logits" + at);  // dropped by 4DGaussians' exporter
    ExpectNear(read->sh, torch.sh, "sh" + at);
    EXPECT_GT(MaxAbsDiff(read->opacity_logits, expected->blocks[0].opacity_logits), 1e-4) << at;
  }
}

// 4DGaussians' own layout: RUN/cfg_args and RUN/point_cloud/iteration_N/.
TEST(ConvertFourDgs, RunFolderPicksTheHighestIteration) {
  const fs::path fixture = FourDgsFixtureDir();
  ASSERT_TRUE(fs::exists(fixture / "deformation.pth")) << fixture;
  testing::TempDir dir;
  const fs::path run = dir / "run";
  for (int iteration : {3000, 14000, 7000}) {
    const fs::path it = run / "point_cloud" / ("iteration_" + std::to_string(iteration));
    fs::create_directories(it);
    fs::copy_file(fixture / "point_cloud.ply", it / "point_cloud.ply");
    fs::copy_file(fixture / "deformation.pth", it / "deformation.pth");
  }
  fs::create_directories(run / "point_cloud" / "iteration_20000");  // incomplete: skipped
  fs::copy_file(fixture / "cfg_args", run / "cfg_args");
  auto report = ConvertFile(run.string(), (dir / "a.atex").string());
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(HasText(report->notes[0], "iteration_14000"));
  EXPECT_TRUE(HasText(report->notes[0], "flags from " + (run / "cfg_args").string()));
  auto asset = ReadAssetFile((dir / "a.atex").string());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  EXPECT_EQ(asset->metadata.extra["iteration"], 14000);
  EXPECT_TRUE(asset->deformation->config.heads[kHeadOpacity]);  // cfg_args: no_do=False

  ConvertOptions chosen;
  chosen.fourdgs.iteration = 7000;
  report = ConvertFile(run.string(), (dir / "b.atex").string(), chosen);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_TRUE(HasText(report->notes[0], "iteration 7000"));

  // A folder that is not a 4DGaussians output says what it looked for.
  fs::create_directories(dir / "empty");
  auto bad = ConvertFile((dir / "empty").string(), (dir / "c.atex").string());
  EXPECT_EQ(bad.status().code(), StatusCode::kNotFound);
  EXPECT_TRUE(HasText(bad.status().message(), "not a 4DGaussians output"));
  // Nothing writes a checkpoint.
  ConvertOptions to_4dgs;
  to_4dgs.to = FileFormat::kFourDgs;
  EXPECT_EQ(ConvertFile(run.string(), (dir / "d").string(), to_4dgs).status().code(), StatusCode::kUnsupported);
  EXPECT_EQ(*ParseFileFormat("4DGS"), FileFormat::kFourDgs);
}

}  // namespace
}  // namespace atex
