// The web viewers' static formats (.splat, .ksplat, PlayCanvas SOG and compressed
// PLY), read from files that third-party tools wrote (needs node and
// tests/splat_transform/install.sh; the hostile-input tests are websplat_test.cc):
//   * tests/splat_transform/make_fixtures.mjs converts the shared INRIA PLY with
//     unmodified npm packages (splat-transform: compressed PLY and SOG; gsplat.js:
//     .splat; GaussianSplats3D: .ksplat levels 0-2) and has splat-transform decode
//     each file back to a plain PLY;
//   * our reader must agree with that reference decoding (same order, float
//     rounding) and with the source values within the format's quantisation;
//   * the shared PlayCanvas SOG (playbot LOD 6) agrees with splat-transform's decoding.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <set>
#include <unordered_map>

#include "atex/converters/convert.h"
#include "atex/converters/ply.h"
#include "atex/converters/gltf.h"
#include "atex/converters/web_splats.h"
#include "atex/file_io.h"
#include "atex/zip.h"
#include "atex/container.h"
#include "convert/bytes.h"
#include "convert/upright_test_util.h"
#include "core/test_support.h"

namespace atex {
namespace {

namespace fs = std::filesystem;
constexpr double kShC0 = 0.28209479177387814;

fs::path WritersDir() { return testing::SourceDir() / "tests" / "splat_transform"; }

std::string Quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Why the third-party writers cannot run here, or "" when they can.
std::string MissingWriters() {
  if (std::system("node --version > /dev/null 2>&1") != 0) return "`node` is not on PATH";
  for (const char* pkg : {"@playcanvas/splat-transform", "gsplat", "@mkkellogg/gaussian-splats-3d"}) {
    if (!fs::exists(WritersDir() / "node_modules" / pkg / "package.json")) {
      return std::string("npm package ") + pkg + " is not installed (run tests/splat_transform/install.sh)";
    }
  }
  return "";
}

// The fixtures, written once per test binary into a folder of the build tree.
const fs::path* Fixtures(std::string* why) {
  static std::unique_ptr<testing::TempDir> dir;
  static std::string failure;
  static bool tried = false;
  if (!tried) {
    tried = true;
    failure = MissingWriters();
    const fs::path source = testing::DataDir() / "splats" / "kacytran1122_try_iter7000_point_cloud.ply";
    const fs::path sog = testing::DataDir() / "splats" / "playbot_lod6" / "meta.json";
    if (failure.empty() && (!fs::exists(source) || !fs::exists(sog))) failure = "real test data missing";
    if (failure.empty()) {
      dir = std::make_unique<testing::TempDir>();
      const std::string command = "node " + Quote((WritersDir() / "make_fixtures.mjs").string()) + " " +
                                  Quote(source.string()) + " " + Quote(dir->path().string()) + " " +
                                  Quote(sog.string());
      if (std::system(command.c_str()) != 0) failure = "make_fixtures.mjs failed: " + command;
    }
  }
  *why = failure;
  return failure.empty() ? &dir->path() : nullptr;
}

#define ATEX_REQUIRE_FIXTURES(var)                                                          \
  std::string why_##var;                                                                    \
  const fs::path* var = Fixtures(&why_##var);                                               \
  if (var == nullptr) {                                                                     \
    if (testing::DataRequired()) FAIL() << "third-party splat writers unavailable: " << why_##var; \
    GTEST_SKIP() << "third-party splat writers unavailable: " << why_##var;                 \
  }

double Sigmoid(double x) { return 1 / (1 + std::exp(-x)); }

// Errors of `got` against `want` per attribute, for the Gaussian pairs (i, match[i]):
// the `quantile` of the per-Gaussian absolute errors (1 = the largest). Rotations are
// compared as unit quaternions up to sign (1 - |cos|). Lossy formats whose writers
// reorder are checked at the 0.99 quantile: matching by position can pair a Gaussian
// with a near-coincident neighbour.
struct Errors {
  double position = 0, log_scale = 0, rotation = 0, opacity = 0, dc = 0, rest = 0;
};
Errors Compare(const Gaussians& got, const Gaussians& want, const std::vector<size_t>& match, int sh_degree,
               double dc_clamp = 1e30, double rest_clamp = 1e30, double quantile = 1.0) {
  std::vector<double> position, log_scale, rotation, opacity, dc, rest;
  const size_t kg = size_t(got.sh_coeffs()), kw = size_t(want.sh_coeffs());
  for (size_t i = 0; i < got.size(); ++i) {
    const size_t j = match[i];
    double ep = 0, es = 0, ed = 0, er = 0;
    for (int k = 0; k < 3; ++k) {
      ep = std::max(ep, double(std::fabs(got.positions[i * 3 + k] - want.positions[j * 3 + k])));
      es = std::max(es, double(std::fabs(got.log_scales[i * 3 + k] - want.log_scales[j * 3 + k])));
      // Colours are clamped to what the format can hold ([0, 1] for 8-bit RGB).
      const double want_dc = std::clamp(double(want.sh[j * kw * 3 + k]), -dc_clamp, dc_clamp);
      ed = std::max(ed, std::fabs(got.sh[i * kg * 3 + k] - want_dc));
    }
    double ng = 0, nw = 0, dot = 0;
    for (int k = 0; k < 4; ++k) {
      ng += double(got.rotations[i * 4 + k]) * got.rotations[i * 4 + k];
      nw += double(want.rotations[j * 4 + k]) * want.rotations[j * 4 + k];
      dot += double(got.rotations[i * 4 + k]) * want.rotations[j * 4 + k];
    }
    for (int c = 1; c < ShCoeffCount(sh_degree); ++c) {
      for (int ch = 0; ch < 3; ++ch) {
        const double w = std::clamp(double(want.sh[(j * kw + size_t(c)) * 3 + size_t(ch)]), -rest_clamp, rest_clamp);
        er = std::max(er, std::fabs(got.sh[(i * kg + size_t(c)) * 3 + size_t(ch)] - w));
      }
    }
    position.push_back(ep), log_scale.push_back(es), dc.push_back(ed), rest.push_back(er);
    rotation.push_back(1 - std::fabs(dot) / std::sqrt(ng * nw));
    opacity.push_back(std::fabs(Sigmoid(got.opacity_logits[i]) - Sigmoid(want.opacity_logits[j])));
  }
  auto at = [&](std::vector<double>& v) {
    if (v.empty()) return 0.0;
    const size_t k = std::min(v.size() - 1, size_t(quantile * double(v.size() - 1) + 0.5));
    std::nth_element(v.begin(), v.begin() + long(k), v.end());
    return v[k];
  };
  return {at(position), at(log_scale), at(rotation), at(opacity), at(dc), at(rest)};
}

std::vector<size_t> Identity(size_t n) {
  std::vector<size_t> m(n);
  for (size_t i = 0; i < n; ++i) m[i] = i;
  return m;
}

// For each Gaussian of `got`, the Gaussian of `want` it came from (writers may
// reorder): among those within `cell` of its position, the one closest in position,
// colour and opacity together (the source has Gaussians sharing a position). Counts
// how many distinct Gaussians were matched.
std::vector<size_t> MatchByPosition(const Gaussians& got, const Gaussians& want, double cell, size_t* distinct) {
  auto key = [&](const float* p) {
    return (int64_t(std::floor(p[0] / cell)) * 73856093) ^ (int64_t(std::floor(p[1] / cell)) * 19349663) ^
           (int64_t(std::floor(p[2] / cell)) * 83492791);
  };
  std::unordered_multimap<int64_t, size_t> grid;
  for (size_t j = 0; j < want.size(); ++j) grid.emplace(key(&want.positions[j * 3]), j);
  std::vector<size_t> match(got.size(), 0);
  std::vector<bool> used(want.size(), false);
  const size_t kg = size_t(got.sh_coeffs()) * 3, kw = size_t(want.sh_coeffs()) * 3;
  for (size_t i = 0; i < got.size(); ++i) {
    const float* p = &got.positions[i * 3];
    double best = 1e300;
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const float q[3] = {float(p[0] + dx * cell), float(p[1] + dy * cell), float(p[2] + dz * cell)};
          auto range = grid.equal_range(key(q));
          for (auto it = range.first; it != range.second; ++it) {
            const size_t j = it->second;
            const float* w = &want.positions[j * 3];
            double score = std::hypot(p[0] - w[0], p[1] - w[1], p[2] - w[2]) / cell;
            if (score > 1) continue;
            // Ties of position (repeated Gaussians) are broken by displayed colour and opacity.
            double attributes = std::fabs(Sigmoid(got.opacity_logits[i]) - Sigmoid(want.opacity_logits[j]));
            for (int c = 0; c < 3; ++c) {
              auto shown = [](double dc) { return std::clamp(0.5 + kShC0 * dc, 0.0, 1.0); };
              attributes += std::fabs(shown(got.sh[i * kg + size_t(c)]) - shown(want.sh[j * kw + size_t(c)]));
            }
            score += 1e-3 * attributes;
            if (score < best) best = score, match[i] = j;
          }
        }
      }
    }
    used[match[i]] = true;
  }
  *distinct = size_t(std::count(used.begin(), used.end(), true));
  return match;
}

// Gaussians of `g` that differ in something (the shared PLY repeats some exactly).
size_t DistinctGaussians(const Gaussians& g) {
  std::set<std::vector<float>> rows;
  const size_t k = size_t(g.sh_coeffs()) * 3;
  for (size_t i = 0; i < g.size(); ++i) {
    std::vector<float> row(g.positions.begin() + long(i * 3), g.positions.begin() + long(i * 3 + 3));
    row.insert(row.end(), g.sh.begin() + long(i * k), g.sh.begin() + long(i * k + k));
    row.push_back(g.opacity_logits[i]);
    rows.insert(std::move(row));
  }
  return rows.size();
}

Gaussians MustRead(const std::function<StatusOr<Gaussians>()>& read) {
  auto g = read();
  EXPECT_TRUE(g.ok()) << g.status().ToString();
  return g.ok() ? *g : Gaussians();
}

// Our reader against splat-transform's decoding of the same file: same order and
// the same formulas, so agreement to float rounding.
void ExpectMatchesReference(const Gaussians& ours, const fs::path& reference_ply, int sh_degree,
                            double rotation_tolerance = 1e-6) {
  const Gaussians ref = MustRead([&] { return ReadPlyGaussians(reference_ply.string()); });
  ASSERT_EQ(ours.size(), ref.size()) << reference_ply;
  ASSERT_EQ(ours.sh_degree, sh_degree);
  const Errors e = Compare(ours, ref, Identity(ours.size()), sh_degree);
  double extent = 0;
  for (float v : ref.positions) extent = std::max(extent, double(std::fabs(v)));
  EXPECT_LE(e.position, 1e-6 * std::max(1.0, extent)) << reference_ply;
  EXPECT_LE(e.log_scale, 1e-4) << reference_ply;
  EXPECT_LE(e.rotation, rotation_tolerance) << reference_ply;
  EXPECT_LE(e.opacity, 1e-4) << reference_ply;
  EXPECT_LE(e.dc, 1e-4) << reference_ply;
  EXPECT_LE(e.rest, 1e-4) << reference_ply;
}

Gaussians Source() {
  return MustRead([] {
    return ReadPlyGaussians((testing::DataDir() / "splats" / "kacytran1122_try_iter7000_point_cloud.ply").string());
  });
}

double Extent(const Gaussians& g) {
  float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
  for (size_t i = 0; i < g.size(); ++i) {
    for (int k = 0; k < 3; ++k)
      lo[k] = std::min(lo[k], g.positions[i * 3 + k]), hi[k] = std::max(hi[k], g.positions[i * 3 + k]);
  }
  return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
}

TEST(WebSplatsReal, SplatFromGsplatJs) {
  ATEX_REQUIRE_FIXTURES(dir);
  const Gaussians ours = MustRead([&] { return ReadSplatGaussians((*dir / "src.splat").string()); });
  // splat-transform centres the rotation bytes at 127.5 where antimatter15's viewer (and
  // we) use 128: half a step, 1 - cos(1/256 rad) ~ 3e-5 at most apart.
  ExpectMatchesReference(ours, *dir / "src.splat.ref.ply", 0, 1e-4);
  // Against the source: positions and scales are f32, colour and opacity 8 bits, rotation 8 bits per component.
  const Gaussians source = Source();
  ASSERT_EQ(ours.size(), source.size());
  size_t distinct = 0;
  const auto match = MatchByPosition(ours, source, 1e-3 * Extent(source), &distinct);
  EXPECT_GE(distinct, DistinctGaussians(source) * 99 / 100);
  const Errors e = Compare(ours, source, match, 0, 0.5 / kShC0);
  EXPECT_EQ(e.position, 0);
  EXPECT_LE(e.log_scale, 1e-5);
  EXPECT_LE(e.dc, 1.01 / 255 / kShC0);
  EXPECT_LE(e.opacity, 1.01 / 255);
  EXPECT_LE(e.rotation, 2e-3);  // 1 - cos of the 8-bit rounding angle
}

TEST(WebSplatsReal, KsplatFromGaussianSplats3D) {
  ATEX_REQUIRE_FIXTURES(dir);
  const Gaussians source = Source();
  for (int level = 0; level <= 2; ++level) {
    SCOPED_TRACE("compression level " + std::to_string(level));
    const fs::path file = *dir / ("src.l" + std::to_string(level) + ".ksplat");
    const Gaussians ours = MustRead([&] { return ReadKsplatGaussians(file.string()); });
    ExpectMatchesReference(ours, file.string() + ".ref.ply", 2);
    ASSERT_EQ(ours.size(), source.size());
    size_t distinct = 0;
    const auto match = MatchByPosition(ours, source, 1e-3 * Extent(source), &distinct);
    EXPECT_GE(distinct, DistinctGaussians(source) * 99 / 100);
    // Level 0 stores f32, levels 1-2 f16 scales/rotations and 16-bit bucket offsets
    // (block 5 / 65534 per step); level 2 SH as 8 bits over [-1.5, 1.5].
    const Errors e = Compare(ours, source, match, 2, 0.5 / kShC0, level == 2 ? 1.5 : 1e30, level == 0 ? 1.0 : 0.99);
    EXPECT_LE(e.position, level == 0 ? 0.0 : 1e-4);
    EXPECT_LE(e.log_scale, level == 0 ? 1e-5 : 1e-3);
    EXPECT_LE(e.rotation, level == 0 ? 1e-7 : 1e-5);
    EXPECT_LE(e.dc, 1.01 / 255 / kShC0);
    EXPECT_LE(e.opacity, 1.01 / 255);
    EXPECT_LE(e.rest, level == 0 ? 1e-6 : level == 1 ? 2e-3 : 3.0 / 255);
  }
}

TEST(WebSplatsReal, CompressedPlyFromSplatTransform) {
  ATEX_REQUIRE_FIXTURES(dir);
  const fs::path file = *dir / "src.compressed.ply";
  const Gaussians ours = MustRead([&] { return ReadPlyGaussians(file.string()); });
  ExpectMatchesReference(ours, file.string() + ".ref.ply", 3);
  const Gaussians source = Source();
  ASSERT_EQ(ours.size(), source.size());
  size_t distinct = 0;
  const auto match = MatchByPosition(ours, source, 2e-3 * Extent(source), &distinct);
  EXPECT_GE(distinct, DistinctGaussians(source) * 95 / 100);
  // 11/10/11-bit positions and log-scales over each 256-Gaussian chunk's range,
  // 10-bit smallest-three rotations, 8-bit colours, SH 8 bits over [-4, 4].
  const Errors e = Compare(ours, source, match, 3, 1e30, 4.0, 0.99);
  EXPECT_LE(e.position, Extent(source) / 1023);
  EXPECT_LE(e.rotation, 1e-4);
  EXPECT_LE(e.opacity, 1.01 / 255);
  EXPECT_LE(e.rest, 8.0 / 256);
}

TEST(WebSplatsReal, SogFromSplatTransform) {
  ATEX_REQUIRE_FIXTURES(dir);
  if (!SogAvailable()) {
    if (testing::DataRequired()) FAIL() << "this build has no libwebp (SOG)";
    GTEST_SKIP() << "this build has no libwebp (SOG)";
  }
  const Gaussians bundle = MustRead([&] { return ReadSogGaussians((*dir / "src.sog").string()); });
  ExpectMatchesReference(bundle, *dir / "src.sog.ref.ply", 3);
  const Gaussians folder = MustRead([&] { return ReadSogGaussians((*dir / "sog" / "meta.json").string()); });
  // Two runs of the writer: the same positions; the SH palette is a k-means result and varies.
  EXPECT_EQ(folder.positions, bundle.positions);
  EXPECT_EQ(folder.sh.size(), bundle.sh.size());
  const Gaussians source = Source();
  ASSERT_EQ(bundle.size(), source.size());
  size_t distinct = 0;
  const auto match = MatchByPosition(bundle, source, 2e-3 * Extent(source), &distinct);
  EXPECT_GE(distinct, DistinctGaussians(source) * 95 / 100);
  // 16-bit log-transformed positions: step (|p| + 1) x range / 65535 at most.
  const Errors e = Compare(bundle, source, match, 3, 1e30, 1e30, 0.99);
  EXPECT_LE(e.position, (Extent(source) + 1) * 2 * std::log(Extent(source) + 1) / 65535);
  EXPECT_LE(e.rotation, 1e-3);
  EXPECT_LE(e.opacity, 1.01 / 255);
}

TEST(WebSplatsReal, SharedPlayCanvasSog) {
  ATEX_REQUIRE_FIXTURES(dir);
  if (!SogAvailable()) GTEST_SKIP() << "this build has no libwebp (SOG)";
  const fs::path meta = testing::DataDir() / "splats" / "playbot_lod6" / "meta.json";
  const Gaussians ours = MustRead([&] { return ReadSogGaussians(meta.string()); });
  EXPECT_EQ(ours.size(), 1873u);
  ExpectMatchesReference(ours, *dir / "extra_0.ref.ply", 2);
  // The folder reads as a SOG input of `atex convert` too.
  ConvertOptions options;
  auto asset = ReadAssetAs(meta.parent_path().string(), FileFormat::kUnknown, options);
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  EXPECT_EQ(asset->gaussians.positions, ours.positions);
  EXPECT_EQ(asset->metadata.axes, "opencv");
}

// Golden "upright" check of the PLY exporter: the lego sample (Blender Z-up) written
// as PLY and converted by PlayCanvas splat-transform to glTF (+y up), which applies
// PlayCanvas's reading of PLY files (the 3DGS y-down world, turned 180 degrees about
// z): the up direction of the dataset's cameras must come out along +y there.
// (splat-transform's SPZ output is no check: it copies PLY coordinates unchanged
// instead of converting them to SPZ's RUB axes.)
TEST(WebSplatsReal, ExportedPlyIsUprightInSplatTransform) {
  ATEX_REQUIRE_FIXTURES(dir);
  ATEX_REQUIRE_DATA_FILE(lego, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  auto up = converters::testing::CamerasUpVector(lego.string());
  ASSERT_TRUE(up.ok()) << up.status().ToString();
  auto asset = ReadAssetFile((testing::SourceDir() / "samples" / "lego_adaptive_2MiB.atex").string());
  ASSERT_TRUE(asset.ok()) << asset.status().ToString();
  testing::TempDir out;
  ConvertOptions options;
  ASSERT_TRUE(WriteAssetAs((out / "lego.ply").string(), *asset, FileFormat::kPly, options).ok());
  const fs::path cli = WritersDir() / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs";
  const std::string command = "node " + Quote(cli.string()) + " -q -w " + Quote((out / "lego.ply").string()) + " " +
                              Quote((out / "lego.glb").string());
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  auto shown = ReadGltfFile((out / "lego.glb").string());  // node transforms baked: glTF's frame
  ASSERT_TRUE(shown.ok()) << shown.status().ToString();
  ASSERT_EQ(shown->gaussians.size(), asset->gaussians.size());
  const std::vector<double> decoded(shown->gaussians.positions.begin(), shown->gaussians.positions.end());
  const Eigen::Matrix3d map = converters::testing::FitLinearMap(asset->gaussians.positions, decoded);
  const Eigen::Vector3d v = (map * Eigen::Vector3d((*up)[0], (*up)[1], (*up)[2])).normalized();
  EXPECT_GT(v.y(), std::cos(30 * M_PI / 180)) << "the cameras' up direction is (" << v.transpose()
                                               << ") in splat-transform's glTF, not +y";
}

}  // namespace
}  // namespace atex
