// Checkpoints as hostile input: fields of trainer.json with the wrong type are refused
// with a message, never an exception.
#include "atex/train/checkpoint.h"

#include <fstream>

#include <gtest/gtest.h>

#include "atex/train/trainer.h"
#include "container/synthetic_asset.h"
#include "core/test_support.h"

namespace atex::train {
namespace {

TEST(Checkpoint, WrongFieldTypesAreCorruptNotExceptions) {
  container::SyntheticAssetOptions o;
  o.gaussians = 20;
  o.stats = false;
  const Asset asset = container::MakeSyntheticAsset(o);
  const ModelState state = StateFromAsset(asset);
  for (const char* bad : {R"({"phase": 3})", R"({"step": "ten"})", R"({"lr_scale": [1]})",
                          R"({"total_steps": 1.5})", R"({"adam_steps": "x"})", R"({"adam_steps": [1, 2]})"}) {
    testing::TempDir dir;
    const std::string path = (dir / "ckpt").string();
    ASSERT_TRUE(WriteCheckpoint(path, state, asset.metadata, {{"phase", "fine"}, {"step", 10}}).ok());
    auto good = ReadCheckpoint(path);
    ASSERT_TRUE(good.ok()) << good.status().ToString();
    std::ofstream(path + "/trainer.json", std::ios::trunc) << bad;
    auto read = ReadCheckpoint(path);
    ASSERT_FALSE(read.ok()) << bad;
    EXPECT_EQ(read.status().code(), StatusCode::kCorrupt) << bad;
    EXPECT_NE(read.status().message().find("trainer.json"), std::string::npos) << read.status().ToString();
  }
}

}  // namespace
}  // namespace atex::train
