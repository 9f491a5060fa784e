#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "atex/model.h"
#include "container/synthetic_asset.h"

namespace atex {
namespace {

Asset Valid() {
  container::SyntheticAssetOptions o;
  o.gaussians = 20;
  o.sh_degree = 2;
  o.sh_head = true;
  return container::MakeSyntheticAsset(o);
}

TEST(ValidateAsset, SyntheticAssetsAreValid) {
  EXPECT_TRUE(ValidateAsset(Valid()).ok()) << ValidateAsset(Valid()).ToString();
  Asset empty;
  EXPECT_TRUE(ValidateAsset(empty).ok()) << ValidateAsset(empty).ToString();
}

struct Case {
  const char* name;
  std::function<void(Asset&)> mutate;
  StatusCode code;
  const char* message_part;  // what the message must name
};

TEST(ValidateAsset, RefusesEachViolationWithItsCodeAndPosition) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const Case cases[] = {
      {"sh degree", [](Asset& a) { a.gaussians.sh_degree = 4; }, StatusCode::kOutOfRange, "SH degree"},
      {"positions size", [](Asset& a) { a.gaussians.positions.pop_back(); }, StatusCode::kInvalidArgument, "positions"},
      {"rotations size", [](Asset& a) { a.gaussians.rotations.push_back(1); }, StatusCode::kInvalidArgument,
       "rotations"},
      {"sh size", [](Asset& a) { a.gaussians.sh.resize(a.gaussians.sh.size() - 3); }, StatusCode::kInvalidArgument,
       "sh"},
      {"nan position", [=](Asset& a) { a.gaussians.positions[3 * 7 + 1] = nan; }, StatusCode::kOutOfRange,
       "positions element 7 component 1"},
      {"inf opacity", [=](Asset& a) { a.gaussians.opacity_logits[5] = -inf; }, StatusCode::kOutOfRange,
       "opacity_logits element 5"},
      {"nan sh", [=](Asset& a) { a.gaussians.sh[9 * 27 + 4] = nan; }, StatusCode::kOutOfRange,
       "sh element 9 component 4"},
      {"texture side 3",
       [](Asset& a) {
         a.textures->heights[4] = 3;
         a.textures->RebuildOffsets();
       },
       StatusCode::kOutOfRange, "Gaussian 4"},
      {"texture side 8",
       [](Asset& a) {
         a.textures->widths[2] = 8;
         a.textures->RebuildOffsets();
       },
       StatusCode::kOutOfRange, "Gaussian 2"},
      {"axis 3", [](Asset& a) { a.textures->axis_u[6] = 3; }, StatusCode::kOutOfRange, "Gaussian 6"},
      {"equal axes", [](Asset& a) { a.textures->axis_v[6] = a.textures->axis_u[6]; }, StatusCode::kOutOfRange,
       "Gaussian 6"},
      {"stale offsets", [](Asset& a) { a.textures->offsets[3] += 1; }, StatusCode::kInvalidArgument, "offsets[3]"},
      {"texel count", [](Asset& a) { a.textures->texels.resize(a.textures->texels.size() + 4); },
       StatusCode::kInvalidArgument, "texels"},
      {"nan texel", [=](Asset& a) { a.textures->texels[8] = nan; }, StatusCode::kOutOfRange,
       "texels element 2 component 0"},
      {"texture arrays", [](Asset& a) { a.textures->axis_v.pop_back(); }, StatusCode::kInvalidArgument, "axis_v"},
      {"uniform mode", [](Asset& a) { a.metadata.texture_mode = "uniform"; }, StatusCode::kInvalidArgument, "uniform"},
      {"mode none with textures", [](Asset& a) { a.metadata.texture_mode = "none"; }, StatusCode::kInvalidArgument,
       "texture_mode"},
      {"bad mode", [](Asset& a) { a.metadata.texture_mode = "fancy"; }, StatusCode::kInvalidArgument, "fancy"},
      {"textures absent but mode", [](Asset& a) { a.textures.reset(); }, StatusCode::kInvalidArgument, "texture_mode"},
      {"channels", [](Asset& a) { a.deformation->config.grid.channels = 0; }, StatusCode::kOutOfRange, "channels"},
      {"multires", [](Asset& a) { a.deformation->config.grid.multires = {}; }, StatusCode::kOutOfRange, "scales"},
      {"plane size", [](Asset& a) { a.deformation->planes[1][4].pop_back(); }, StatusCode::kInvalidArgument,
       "scale 1, plane 4"},
      {"nan grid", [=](Asset& a) { a.deformation->planes[0][2][3] = nan; }, StatusCode::kOutOfRange,
       "scale 0, plane 2"},
      // Issue 24: finite values `render` cannot use were called valid by `verify`.
      {"huge grid", [](Asset& a) { a.deformation->planes[0][1][2] = 1e38f; }, StatusCode::kOutOfRange,
       "scale 0, plane 1"},
      {"huge mlp weight", [](Asset& a) { a.deformation->trunk[0].weight[5] = 2.7e37f; }, StatusCode::kOutOfRange,
       "largest magnitude"},
      {"huge head bias", [](Asset& a) { a.deformation->heads[0][0].bias[0] = -1e7f; }, StatusCode::kOutOfRange,
       "head 0"},
      {"huge rotation", [](Asset& a) { a.gaussians.rotations[4 * 3 + 2] = 1e30f; }, StatusCode::kOutOfRange,
       "rotations element 3 component 2"},
      {"trunk shape", [](Asset& a) { a.deformation->trunk[1].in = 3; }, StatusCode::kInvalidArgument, "trunk layer 1"},
      {"head weight", [](Asset& a) { a.deformation->heads[2][1].weight.pop_back(); }, StatusCode::kInvalidArgument,
       "head 2 layer 1"},
      {"disabled head not empty", [](Asset& a) { a.deformation->config.heads[kHeadOpacity] = false; },
       StatusCode::kInvalidArgument, "head 3"},
      {"sh head mismatch", [](Asset& a) { a.deformation->config.sh_coeffs = 4; }, StatusCode::kInvalidArgument,
       "sh_coeffs"},
      {"sh coeffs value", [](Asset& a) { a.deformation->config.sh_coeffs = 5; }, StatusCode::kOutOfRange, "sh_coeffs"},
      {"aabb empty", [](Asset& a) { a.deformation->config.aabb_hi[1] = a.deformation->config.aabb_lo[1]; },
       StatusCode::kOutOfRange, "axis 1"},
      {"time scale", [=](Asset& a) { a.deformation->config.time_scale = inf; }, StatusCode::kOutOfRange, "time_scale"},
      {"stats size", [](Asset& a) { a.stats->importance.pop_back(); }, StatusCode::kInvalidArgument, "importance"},
      {"stats nan", [=](Asset& a) { a.stats->peak_scale_v[3] = nan; }, StatusCode::kOutOfRange,
       "peak_scale_v element 3"},
      {"bounds order", [](Asset& a) { a.metadata.bounds_min[2] = a.metadata.bounds_max[2] + 1; },
       StatusCode::kOutOfRange, "bounds axis 2"},
      {"background", [](Asset& a) { a.metadata.background[1] = 1.5f; }, StatusCode::kOutOfRange, "background[1]"},
      {"time range",
       [](Asset& a) {
         a.metadata.time_min = 2;
         a.metadata.time_max = 1;
       },
       StatusCode::kOutOfRange, "time range"},
      {"extra not object", [](Asset& a) { a.metadata.extra = 3; }, StatusCode::kInvalidArgument, "extra"},
      {"extra nan",
       [=](Asset& a) {
         a.metadata.extra["x"] = {1.0, std::nan("")};
       },
       StatusCode::kOutOfRange, "extra.x[1]"},
      {"extra utf8", [](Asset& a) { a.metadata.extra["s"] = std::string("\xC3\x28"); }, StatusCode::kInvalidArgument,
       "UTF-8"},
      {"units utf8", [](Asset& a) { a.metadata.units = std::string("\xED\xA0\x80"); }, StatusCode::kInvalidArgument,
       "UTF-8"},
  };
  for (const Case& c : cases) {
    Asset a = Valid();
    c.mutate(a);
    const Status s = ValidateAsset(a);
    EXPECT_EQ(s.code(), c.code) << c.name << ": " << s.ToString();
    EXPECT_NE(s.message().find(c.message_part), std::string::npos) << c.name << ": " << s.ToString();
  }
}

TEST(ValidateAsset, DeepExtraIsRefused) {
  Asset a = Valid();
  nlohmann::json deep = 1;
  for (int i = 0; i < 80; ++i) deep = nlohmann::json::array({deep});
  a.metadata.extra["deep"] = deep;
  EXPECT_EQ(ValidateAsset(a).code(), StatusCode::kLimitExceeded);
}

}  // namespace
}  // namespace atex
