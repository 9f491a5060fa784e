// The importer + DeformForward against PyTorch: fixtures written by
// tests/fixtures/fourdgs/make_fixture.py (a 4DGaussians deform_network with
// its exact state_dict keys, evaluated with F.grid_sample in PyTorch).
//
//   tests/fixtures/fourdgs/            written by the lead with PyTorch 2.11
//   tests/fixtures/fourdgs/torch1.13/  written with Debian's PyTorch 1.13
//
// A fixture folder that does not exist yet is skipped with a message.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "atex/converters/fourdgs.h"
#include "atex/deform.h"
#include "atex/file_io.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;

struct Expected {
  nlohmann::json meta;
  size_t count = 0;
  int sh_coeffs = 0;
  std::vector<Gaussians> blocks;  // [0] canonical, [1 + i] deformed at times[i]
};

StatusOr<Expected> LoadExpected(const fs::path& dir) {
  Expected e;
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> json_bytes, ReadFileBytes((dir / "expected.json").string()));
  e.meta = nlohmann::json::parse(json_bytes.begin(), json_bytes.end(), nullptr, false);
  if (e.meta.is_discarded()) return MakeError(StatusCode::kCorrupt, "expected.json does not parse");
  e.count = e.meta["count"].get<size_t>();
  const int degree = e.meta["sh_degree"].get<int>();
  e.sh_coeffs = ShCoeffCount(degree);
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, ReadFileBytes((dir / "expected.bin").string()));
  const size_t per_block = e.count * (3 + 3 + 4 + 1 + 3 * static_cast<size_t>(e.sh_coeffs));
  const size_t blocks = 1 + e.meta["times"].size();
  if (raw.size() != blocks * per_block * 4) {
    return MakeError(StatusCode::kCorrupt, "expected.bin has ", raw.size(), " bytes, expected ",
                     blocks * per_block * 4);
  }
  size_t at = 0;
  auto take = [&](std::vector<float>& v, size_t n) {
    v.resize(n);
    for (size_t i = 0; i < n; ++i, at += 4) {
      v[i] = std::bit_cast<float>(static_cast<uint32_t>(raw[at]) | static_cast<uint32_t>(raw[at + 1]) << 8 |
                                  static_cast<uint32_t>(raw[at + 2]) << 16 | static_cast<uint32_t>(raw[at + 3]) << 24);
    }
  };
  for (size_t b = 0; b < blocks; ++b) {
    Gaussians g;
    g.sh_degree = degree;
    take(g.positions, 3 * e.count);
    take(g.log_scales, 3 * e.count);
    take(g.rotations, 4 * e.count);
    take(g.opacity_logits, e.count);
    take(g.sh, 3 * e.count * e.sh_coeffs);
    e.blocks.push_back(std::move(g));
  }
  return e;
}

// Worst |ours - torch| over an array, with a mixed tolerance check.
double Compare(const std::vector<float>& ours, const std::vector<float>& torch, const std::string& what,
               double atol, double rtol) {
  EXPECT_EQ(ours.size(), torch.size()) << what;
  double worst = 0;
  for (size_t i = 0; i < std::min(ours.size(), torch.size()); ++i) {
    const double diff = std::fabs(double(ours[i]) - double(torch[i]));
    worst = std::max(worst, diff);
    EXPECT_LE(diff, atol + rtol * std::fabs(double(torch[i]))) << what << "[" << i << "]: ours " << ours[i]
                                                               << ", PyTorch " << torch[i];
  }
  return worst;
}

void RunFixture(const fs::path& dir) {
  if (!fs::exists(dir / "deformation.pth")) {
    GTEST_SKIP() << "fixture not generated yet: " << dir
                 << " (run python3 tests/fixtures/fourdgs/make_fixture.py " << dir.string() << ")";
  }
  auto expected = LoadExpected(dir);
  ASSERT_TRUE(expected.ok()) << expected.status().ToString();
  auto asset = ImportFourDGaussians(dir.string());  // reads cfg_args beside the checkpoint
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  ASSERT_TRUE(asset->deformation.has_value());
  const DeformationField& field = *asset->deformation;
  const nlohmann::json& config = expected->meta["config"];

  // Shapes inferred from the tensors agree with the generator's config.
  EXPECT_EQ(field.config.grid.channels, config["channels"].get<int>());
  EXPECT_EQ(field.config.mlp_width, config["net_width"].get<int>());
  EXPECT_EQ(field.config.trunk_layers, config["trunk_layers"].get<int>());
  const auto multires = config["multires"].get<std::vector<int>>();
  const auto resolution = config["resolution"].get<std::vector<int>>();
  ASSERT_EQ(field.config.grid.scales(), static_cast<int>(multires.size()));
  for (int s = 0; s < field.config.grid.scales(); ++s) {
    for (int axis = 0; axis < 4; ++axis) {
      EXPECT_EQ(field.config.grid.resolution(s, axis), axis == 3 ? resolution[3] : resolution[axis] * multires[s]);
    }
  }
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(field.config.aabb_lo[a], config["aabb_max"][a].get<float>());  // (max, min) kept as stored
    EXPECT_EQ(field.config.aabb_hi[a], config["aabb_min"][a].get<float>());
  }
  EXPECT_EQ(field.config.heads, (std::array<bool, 5>{true, true, true, true, true}));

  // The canonical Gaussians read from the PLY are PyTorch's, bit for bit.
  const Gaussians& canonical = expected->blocks[0];
  EXPECT_EQ(asset->gaussians.positions, canonical.positions);
  EXPECT_EQ(asset->gaussians.log_scales, canonical.log_scales);
  EXPECT_EQ(asset->gaussians.rotations, canonical.rotations);
  EXPECT_EQ(asset->gaussians.opacity_logits, canonical.opacity_logits);
  EXPECT_EQ(asset->gaussians.sh, canonical.sh);

  // Our deformation (float and double) against PyTorch's float32 forward pass.
  const auto times = expected->meta["times"].get<std::vector<double>>();
  double worst_float = 0, worst_double = 0;
  for (size_t i = 0; i < times.size(); ++i) {
    const Gaussians& torch_out = expected->blocks[1 + i];
    Gaussians ours;
    ASSERT_TRUE(DeformForward(field, asset->gaussians, times[i], &ours, nullptr).ok());
    BasicGaussians<double> ours_double;
    ASSERT_TRUE(
        DeformForward(Cast<double>(field), Cast<double>(asset->gaussians), times[i], &ours_double, nullptr).ok());
    const Gaussians rounded = Cast<float>(ours_double);
    const std::string at = " at t = " + std::to_string(times[i]);
    for (auto [name, a, b, c] :
         {std::tuple{"positions", &ours.positions, &torch_out.positions, &rounded.positions},
          std::tuple{"log_scales", &ours.log_scales, &torch_out.log_scales, &rounded.log_scales},
          std::tuple{"rotations", &ours.rotations, &torch_out.rotations, &rounded.rotations},
          std::tuple{"opacity_logits", &ours.opacity_logits, &torch_out.opacity_logits, &rounded.opacity_logits},
          std::tuple{"sh", &ours.sh, &torch_out.sh, &rounded.sh}}) {
      worst_float = std::max(worst_float, Compare(*a, *b, std::string(name) + at, 2e-5, 2e-5));
      worst_double = std::max(worst_double, Compare(*c, *b, std::string(name) + " (double)" + at, 2e-5, 2e-5));
    }
  }
  std::printf("fixture %s (PyTorch %s): max |ours - PyTorch| float %.3g, double %.3g\n", dir.string().c_str(),
              expected->meta["torch_version"].get<std::string>().c_str(), worst_float, worst_double);
}

TEST(FourDgsFixture, MatchesPyTorch) { RunFixture(testing::SourceDir() / "tests/fixtures/fourdgs"); }

TEST(FourDgsFixture, MatchesPyTorch113) { RunFixture(testing::SourceDir() / "tests/fixtures/fourdgs/torch1.13"); }

}  // namespace
}  // namespace atex
