#include "atex/world_up.h"

#include <gtest/gtest.h>

#include <cmath>

#include "atex/dataset.h"
#include "core/test_support.h"

namespace atex {
namespace {

// A camera at `center` looking at the origin with world direction `up` up.
Camera LookAt(std::array<double, 3> center, std::array<double, 3> up) {
  auto normalise = [](std::array<double, 3> v) {
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return std::array<double, 3>{v[0] / l, v[1] / l, v[2] / l};
  };
  auto cross = [](std::array<double, 3> a, std::array<double, 3> b) {
    return std::array<double, 3>{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  const auto forward = normalise({-center[0], -center[1], -center[2]});
  const auto right = normalise(cross(forward, up));
  const auto down = cross(forward, right);
  Camera c;
  const std::array<std::array<double, 3>, 3> rows{right, down, forward};
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) c.world_to_camera[4 * r + k] = rows[r][k];
    c.world_to_camera[4 * r + 3] = -(rows[r][0] * center[0] + rows[r][1] * center[1] + rows[r][2] * center[2]);
  }
  return c;
}

TEST(WorldUp, MetadataUpWinsOverTheLegacyRule) {
  Metadata m;
  m.axes = "opencv";
  EXPECT_EQ(*WorldUpAxis(m), "-y");  // older files: from axes
  m.up = "+z";
  EXPECT_EQ(*WorldUpAxis(m), "+z");
  m.up = "";
  m.axes = "blender";
  EXPECT_EQ(*WorldUpAxis(m), "+z");
  m.axes = "something";
  EXPECT_EQ(WorldUpAxis(m).status().code(), StatusCode::kInvalidArgument);
  m.up = "up";
  EXPECT_EQ(WorldUpAxis(m).status().code(), StatusCode::kInvalidArgument);
}

TEST(WorldUp, MetadataJsonKeepsUpAndRefusesOtherNames) {
  Metadata m;
  EXPECT_FALSE(MetadataToJson(m).contains("up"));  // unrecorded: not written (older readers, golden files)
  m.up = "-x";
  auto back = MetadataFromJson(MetadataToJson(m));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->up, "-x");
  nlohmann::json j = MetadataToJson(m);
  j["up"] = "Y";
  EXPECT_EQ(MetadataFromJson(j).status().code(), StatusCode::kCorrupt);
  j["up"] = 3;
  EXPECT_EQ(MetadataFromJson(j).status().code(), StatusCode::kCorrupt);
}

TEST(WorldUp, CamerasAroundAnAxisAgreeOnIt) {
  for (const auto& [up, name] : std::vector<std::pair<std::array<double, 3>, std::string>>{
           {{0, 0, 1}, "+z"}, {{0, -1, 0}, "-y"}, {{1, 0, 0}, "+x"}, {{0, 0, -1}, "-z"}}) {
    std::vector<Camera> cameras;
    for (int i = 0; i < 12; ++i) {
      const double a = 0.5 * i;
      // Cameras on a ring around `up`, slightly above it, all upright.
      std::array<double, 3> side1 = up[0] != 0 ? std::array<double, 3>{0, 1, 0} : std::array<double, 3>{1, 0, 0};
      std::array<double, 3> side2{up[1] * side1[2] - up[2] * side1[1], up[2] * side1[0] - up[0] * side1[2],
                                  up[0] * side1[1] - up[1] * side1[0]};
      std::array<double, 3> c;
      for (int k = 0; k < 3; ++k) c[k] = 4 * std::cos(a) * side1[k] + 4 * std::sin(a) * side2[k] + 1.5 * up[k];
      cameras.push_back(LookAt(c, up));
    }
    EXPECT_EQ(UpAxisFromCameras(cameras).value_or("none"), name);
  }
  EXPECT_FALSE(UpAxisFromCameras({}).has_value());
  // Two cameras upside down to each other: no agreement.
  EXPECT_FALSE(UpAxisFromCameras({LookAt({4, 0, 0}, {0, 0, 1}), LookAt({-4, 0, 0}, {0, 0, -1})}).has_value());
}

// The real datasets: the D-NeRF lego (Blender, Z up) and CMU Panoptic (a dome whose
// floor normal is the world's -y).
TEST(WorldUp, RealDatasetsGiveTheirUpAxis) {
  ATEX_REQUIRE_DATA_FILE(lego, "dnerf_lego_tiny/tiny_dnerf_data.npz");
  ATEX_REQUIRE_DATA_FILE(panoptic, "panoptic_basketball/train_meta.json");
  for (const auto& [path, expected] : std::vector<std::pair<std::filesystem::path, std::string>>{
           {lego, "+z"}, {panoptic.parent_path(), "-y"}}) {
    DatasetOptions options;
    auto data = OpenDataset(path.string(), options);
    ASSERT_TRUE(data.ok()) << data.status().ToString();
    std::vector<Camera> cameras;
    for (const auto& view : (*data)->train_views()) cameras.push_back(view.camera);
    EXPECT_EQ(UpAxisFromCameras(cameras).value_or("none"), expected) << path;
  }
}

}  // namespace
}  // namespace atex
