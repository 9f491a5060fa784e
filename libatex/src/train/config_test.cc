#include "atex/train/config.h"

#include <gtest/gtest.h>

namespace atex::train {
namespace {

TEST(Config, JsonRoundTripAndOverrides) {
  TrainConfig config = DefaultConfig("panoptic");
  auto back = ConfigFromJson(ConfigToJson(config), TrainConfig{});
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(ConfigToJson(*back), ConfigToJson(config));

  auto changed = ApplyOverride(config, "stage1.batch_size=2");
  ASSERT_TRUE(changed.ok()) << changed.status().ToString();
  EXPECT_EQ(changed->stage1.batch_size, 2);
  changed = ApplyOverride(*changed, "stage2.textures=uniform");
  ASSERT_TRUE(changed.ok()) << changed.status().ToString();
  EXPECT_EQ(changed->stage2.textures, TextureMode::kUniform);
  changed = ApplyOverride(*changed, "stage1.deformation.grid.multires=[1,2,4]");
  ASSERT_TRUE(changed.ok()) << changed.status().ToString();
  EXPECT_EQ(changed->stage1.deformation.grid.multires, (std::vector<int>{1, 2, 4}));
}

TEST(Config, UnknownKeysAndBadValuesAreErrors) {
  TrainConfig config;
  auto bad = ApplyOverride(config, "stage1.batchsize=2");
  EXPECT_EQ(bad.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("stage1.batchsize"), std::string::npos);
  EXPECT_FALSE(ApplyOverride(config, "stage2.textures=fancy").ok());
  EXPECT_FALSE(ApplyOverride(config, "stage1.batch_size=\"four\"").ok());
  EXPECT_FALSE(ApplyOverride(config, "no_equals_sign").ok());
}

TEST(Config, PanopticRigsStartFromStereoWithCameraColoursAndFastObjectSeeds) {
  EXPECT_EQ(DefaultConfig("panoptic").stage1.init_method, "mvs+hull");
  EXPECT_TRUE(DefaultConfig("panoptic").camera_colour.enabled);
  EXPECT_TRUE(DefaultConfig("panoptic").stage1.fast_objects.enabled);
  for (const char* kind : {"dnerf", "n3dv", ""}) {
    EXPECT_EQ(DefaultConfig(kind).stage1.init_method, "auto") << kind;
    EXPECT_FALSE(DefaultConfig(kind).camera_colour.enabled) << kind;
    EXPECT_FALSE(DefaultConfig(kind).stage1.fast_objects.enabled) << kind;  // N3DV: no masks
  }
}

TEST(Config, EveryDatasetKindNamesItsDefaults) {
  EXPECT_STREQ(DefaultConfigKind(DatasetKind::kPanoptic), "panoptic");
  EXPECT_STREQ(DefaultConfigKind(DatasetKind::kN3dv), "n3dv");
  for (DatasetKind kind :
       {DatasetKind::kDNerf, DatasetKind::kDNerfNpz, DatasetKind::kNerfstudio, DatasetKind::kColmap}) {
    EXPECT_STREQ(DefaultConfigKind(kind), "dnerf") << DatasetKindName(kind);
  }
  EXPECT_STREQ(DefaultConfigKind(DatasetKind::kInMemory), "generic");
  // The D-NeRF defaults are what those kinds get: C = 32, not the generic 16.
  EXPECT_EQ(DefaultConfig(DefaultConfigKind(DatasetKind::kColmap)).stage1.deformation.grid.channels, 32);
  EXPECT_EQ(DefaultConfig(DefaultConfigKind(DatasetKind::kInMemory)).stage1.deformation.grid.channels, 16);
}

TEST(Config, DatasetDefaultsFollowFourDGaussians) {
  EXPECT_EQ(DefaultConfig("dnerf").stage1.deformation.grid.channels, 32);
  EXPECT_EQ(DefaultConfig("dnerf").stage1.deformation.mlp_width, 64);
  EXPECT_EQ(DefaultConfig("n3dv").stage1.deformation.grid.base_resolution[3], 150);
  EXPECT_EQ(DefaultConfig("n3dv").stage1.batch_size, 4);
  EXPECT_EQ(DefaultConfig("n3dv").stage2.batch_size, 8);
}

TEST(ExpDecay, EndpointsAndMonotone) {
  ExpDecay d{1.6e-4, 1.6e-6, 20000};
  EXPECT_NEAR(d.At(0), 1.6e-4, 1e-12);
  EXPECT_NEAR(d.At(20000), 1.6e-6, 1e-14);
  EXPECT_NEAR(d.At(40000), 1.6e-6, 1e-14);
  EXPECT_NEAR(d.At(10000), 1.6e-5, 1e-12);  // geometric midpoint
  EXPECT_GT(d.At(100), d.At(200));
}

}  // namespace
}  // namespace atex::train
