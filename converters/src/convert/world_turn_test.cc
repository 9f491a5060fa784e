// The PLY and SPZ writers turn an asset's world so that its up axis is the file's
// up (-y for 3DGS PLY, +y in SPZ's RUB axes): positions, orientations and
// view-dependent colour turn together; assets whose up is -y (or unknown) are
// written as before.
#include "convert/world_turn.h"

#include <gtest/gtest.h>

#include <cmath>

#include "atex/converters/convert.h"
#include "atex/converters/ply.h"
#include "atex/converters/spz.h"
#include "convert/test_gaussians.h"
#include "core/test_support.h"
#include "gltf/sh_rotation.h"

namespace atex {
namespace {

using converters::testing::RandomGaussians;

Asset AssetWithUp(const std::string& up, int sh_degree = 2) {
  Asset a;
  a.gaussians = RandomGaussians(50, sh_degree, 11);
  a.metadata.axes = "opencv";
  a.metadata.up = up;
  return a;
}

// Colour of Gaussian i seen from direction d (SH evaluated, DC included).
double Colour(const Gaussians& g, size_t i, const double d[3], int channel) {
  double basis[16];
  gltf::EvaluateShBasis(d[0], d[1], d[2], g.sh_degree, basis);
  double c = 0;
  for (int k = 0; k < g.sh_coeffs(); ++k)
    c += basis[k] * g.sh[(i * size_t(g.sh_coeffs()) + size_t(k)) * 3 + size_t(channel)];
  return c;
}

TEST(WorldTurn, PlyOfAZUpAssetHasUpAlongMinusY) {
  const Asset asset = AssetWithUp("+z");
  testing::TempDir dir;
  ConvertOptions options;
  ConvertReport report;
  ASSERT_TRUE(WriteAssetAs((dir / "out.ply").string(), asset, FileFormat::kPly, options, &report).ok());
  auto g = ReadPlyGaussians((dir / "out.ply").string());
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  ASSERT_FALSE(report.notes.empty());
  const auto& src = asset.gaussians;
  for (size_t i = 0; i < src.size(); ++i) {
    // The world's +z (up) becomes -y; x stays; y becomes z (a proper rotation).
    EXPECT_FLOAT_EQ(g->positions[i * 3 + 0], src.positions[i * 3 + 0]);
    EXPECT_FLOAT_EQ(g->positions[i * 3 + 1], -src.positions[i * 3 + 2]);
    EXPECT_FLOAT_EQ(g->positions[i * 3 + 2], src.positions[i * 3 + 1]);
    EXPECT_EQ(g->log_scales[i * 3], src.log_scales[i * 3]);
    // A direction d in the old world is R d in the new one; colours seen along them agree.
    const double d[3] = {0.6, 0.0, 0.8}, rd[3] = {0.6, -0.8, 0.0};
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(Colour(*g, i, rd, c), Colour(src, i, d, c), 1e-5);
    // The Gaussian's first local axis turns the same way: R (q x q*) = (q' x q'*).
    auto axis = [](const float* q) {
      const double n = std::sqrt(double(q[0]) * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
      return std::array<double, 3>{1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)};
    };
    const auto before = axis(&src.rotations[i * 4]), after = axis(&g->rotations[i * 4]);
    EXPECT_NEAR(after[0], before[0], 1e-5);
    EXPECT_NEAR(after[1], -before[2], 1e-5);
    EXPECT_NEAR(after[2], before[1], 1e-5);
  }
}

TEST(WorldTurn, DownYAndUnknownAssetsAreWrittenUnchanged) {
  for (const char* up : {"-y", ""}) {
    Asset asset = AssetWithUp(up);
    if (std::string(up).empty()) asset.metadata.axes = "unrecorded";
    Gaussians g = asset.gaussians;
    EXPECT_EQ(convert::TurnWorldDownY(asset.metadata, &g), "");
    EXPECT_EQ(g.positions, asset.gaussians.positions);
    EXPECT_EQ(g.sh, asset.gaussians.sh);
  }
}

TEST(WorldTurn, EveryUpAxisEndsAtMinusY) {
  for (UpAxis up : {UpAxis::kPosX, UpAxis::kNegX, UpAxis::kPosY, UpAxis::kNegY, UpAxis::kPosZ, UpAxis::kNegZ}) {
    const auto r = convert::RotationToDownY(up);
    double v[3] = {0, 0, 0};
    const std::string name = UpAxisName(up);
    v[name[1] - 'x'] = name[0] == '+' ? 1 : -1;
    const double out[3] = {r[0] * v[0] + r[1] * v[1] + r[2] * v[2], r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
                           r[6] * v[0] + r[7] * v[1] + r[8] * v[2]};
    EXPECT_EQ(out[0], 0) << name;
    EXPECT_EQ(out[1], -1) << name;
    EXPECT_EQ(out[2], 0) << name;
    // The glTF node rotation takes the same axis to +y.
    const auto q = GltfRootRotation(up);
    const double x = q[0], y = q[1], z = q[2], w = q[3];
    const double up_y = 2 * (x * y + w * z) * v[0] + (1 - 2 * (x * x + z * z)) * v[1] + 2 * (y * z - w * x) * v[2];
    EXPECT_NEAR(up_y, 1, 1e-12) << name;
  }
}

TEST(WorldTurn, SpzOfAZUpAssetStoresUpAlongPlusYOfRub) {
  const Asset asset = AssetWithUp("+z", 0);
  testing::TempDir dir;
  ConvertOptions options;
  ASSERT_TRUE(WriteAssetAs((dir / "out.spz").string(), asset, FileFormat::kSpz, options).ok());
  SpzReadOptions stored;
  stored.axes = SpzAxes::kStored;  // what the file holds, in RUB
  auto g = ReadSpzGaussians((dir / "out.spz").string(), stored);
  ASSERT_TRUE(g.ok()) << g.status().ToString();
  for (size_t i = 0; i < asset.gaussians.size(); ++i) {
    EXPECT_NEAR(g->positions[i * 3 + 1], asset.gaussians.positions[i * 3 + 2], 1e-3);  // up is +y
  }
}

}  // namespace
}  // namespace atex
