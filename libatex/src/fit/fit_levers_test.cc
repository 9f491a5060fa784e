// The budget fitter's levers, the fixed-count protocol, importance and byte sizes.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <random>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "container/synthetic_asset.h"
#include "fit/fit_test_util.h"
#include "fit/levers.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

using testing::SmallAsset;

TEST(Levers, ParsedByNameAndRefusedWhenUnknown) {
  EXPECT_EQ(*ParseLevers("default"), kDefaultLevers);
  EXPECT_EQ(*ParseLevers("prune"), LeverBit(Lever::kPrune));
  EXPECT_EQ(*ParseLevers("prune,all-textures"), LeverBit(Lever::kPrune) | LeverBit(Lever::kAllTextures));
  EXPECT_EQ(LeverSetNames(kDefaultLevers), "prune,textures,sh,encoding,grid");
  EXPECT_EQ(*ParseLevers(LeverSetNames(kDefaultLevers)), kDefaultLevers);
  const auto unknown = ParseLevers("prune,quantise");
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("'quantise'"), std::string::npos) << unknown.status().ToString();
  EXPECT_NE(unknown.status().message().find("all-textures"), std::string::npos) << "lists the known levers";
  EXPECT_FALSE(ParseLevers("").ok());
  EXPECT_FALSE(ParseLevers(",").ok());
}

// The paper's fixed-memory protocol (docs/fit.md): only the Gaussian count and whole-pool
// texture scale may change, never the precision, the SH degree, the grids or the
// allocation of texels between Gaussians.
TEST(Plan, RestrictedLeversKeepEverythingElse) {
  Asset a = SmallAsset(container::SyntheticTextures::kUniform, 17);
  a.metadata.texture_mode = "uniform";
  WriteOptions w;
  w.write_stats = false;
  auto backend = train::MakeCpuBackend();
  ProbeRenderer renderer(backend.get(), OrbitProbes(a, 3, 32, 24));
  for (const LeverSet levers : {LeverBit(Lever::kPrune), LeverBit(Lever::kPrune) | LeverBit(Lever::kAllTextures)}) {
    SCOPED_TRACE(LeverSetNames(levers));
    auto minimum = MinimumBytes(a, w, 4, levers);
    ASSERT_TRUE(minimum.ok());
    EXPECT_GT(*minimum, *MinimumBytes(a, w)) << "fewer levers reach less far";
    const Status below = CheckBudget(a, w, *minimum - 1, 4, levers);
    EXPECT_EQ(below.code(), StatusCode::kBudgetTooSmall);
    EXPECT_NE(below.message().find(std::to_string(*minimum)), std::string::npos) << below.ToString();
    EXPECT_NE(below.message().find(LeverSetNames(levers)), std::string::npos) << below.ToString();
    auto full = EncodeAsset(a, w);
    ASSERT_TRUE(full.ok());
    PlanOptions o;
    o.write = w;
    o.levers = levers;
    o.prune_fraction = 0.2;
    o.floor_bytes = full->size() / 3;
    auto plan = BuildPlan(a, &renderer, o);
    ASSERT_TRUE(plan.ok()) << plan.status().ToString();
    ASSERT_FALSE(plan->moves.empty());
    std::set<Lever> used;
    for (const Move& m : plan->moves) {
      EXPECT_TRUE(HasLever(levers, m.lever)) << DescribeMove(m);
      used.insert(m.lever);
    }
    EXPECT_EQ(used.size(), static_cast<size_t>(std::popcount(levers))) << "every allowed lever is used";
    auto fitted = ApplyPlan(a, *plan, w, full->size() / 3);
    ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
    EXPECT_LE(fitted->bytes.size(), full->size() / 3);
    const Asset& out = fitted->asset;
    EXPECT_LT(out.gaussians.size(), a.gaussians.size());
    EXPECT_EQ(out.gaussians.sh_degree, a.gaussians.sh_degree);
    EXPECT_EQ(out.deformation->config.grid.base_resolution, a.deformation->config.grid.base_resolution);
    for (int s = 0; s < static_cast<int>(Stream::kCount); ++s) {
      EXPECT_EQ(GetEncoding(fitted->write, static_cast<Stream>(s)), GetEncoding(w, static_cast<Stream>(s)));
    }
    EXPECT_EQ(out.metadata.texture_mode, "uniform");
    for (size_t i = 1; i < out.textures->size(); ++i) {
      ASSERT_EQ(out.textures->heights[i], out.textures->heights[0]);
      ASSERT_EQ(out.textures->widths[i], out.textures->widths[0]);
    }
    if (levers == LeverBit(Lever::kPrune)) {
      EXPECT_EQ(out.textures->heights[0] * out.textures->widths[0], 16);
    }
    EXPECT_TRUE(ValidateAsset(out).ok());
  }
  PlanOptions none;
  none.levers = 0;
  EXPECT_EQ(BuildPlan(a, &renderer, none).status().code(), StatusCode::kInvalidArgument);
}

TEST(KeepCount, SubsetsAreIdenticalAcrossTextureModes) {
  // One stage-1 model, three stage-2 variants with different statistics: the shared order
  // from the stage-1 model selects the same Gaussians in each.
  Asset stage1 = SmallAsset(container::SyntheticTextures::kNone, 31);
  const std::vector<uint32_t> order = ImportanceOrder(stage1, 6666);
  for (double fraction : {0.25, 0.5}) {
    std::vector<std::vector<uint32_t>> kept_sets;
    for (auto textures : {container::SyntheticTextures::kNone, container::SyntheticTextures::kUniform,
                          container::SyntheticTextures::kMixed}) {
      Asset variant = SmallAsset(textures, 31);
      for (float& v : variant.stats->importance) v = 1.0f - v;  // a different order of its own
      std::vector<uint32_t> kept;
      auto subset = KeepMostImportant(variant, order, fraction, &kept);
      ASSERT_TRUE(subset.ok());
      EXPECT_EQ(subset->gaussians.size(), static_cast<size_t>(std::ceil(fraction * stage1.gaussians.size())));
      EXPECT_TRUE(ValidateAsset(*subset).ok());
      kept_sets.push_back(kept);
    }
    EXPECT_EQ(kept_sets[0], kept_sets[1]);
    EXPECT_EQ(kept_sets[0], kept_sets[2]);
  }
  // The kept ones are the most important of the shared order.
  std::vector<uint32_t> kept;
  ASSERT_TRUE(KeepMostImportant(stage1, order, 0.25, &kept).ok());
  float min_kept = 1e30f, max_dropped = -1e30f;
  std::vector<uint8_t> is_kept(stage1.gaussians.size(), 0);
  for (uint32_t i : kept) is_kept[i] = 1;
  for (size_t i = 0; i < is_kept.size(); ++i) {
    const float imp = stage1.stats->importance[i];
    if (is_kept[i]) min_kept = std::min(min_kept, imp);
    else max_dropped = std::max(max_dropped, imp);
  }
  EXPECT_GE(min_kept, max_dropped);
  EXPECT_FALSE(KeepMostImportant(stage1, order, 0.0).ok());
  EXPECT_FALSE(KeepMostImportant(stage1, std::vector<uint32_t>(3, 0), 0.5).ok());
}

TEST(Importance, MeasuredWhenMissing) {
  Asset a = SmallAsset(container::SyntheticTextures::kMixed, 41);
  a.stats.reset();
  ASSERT_TRUE(EnsureImportance(&a, OrbitProbes(a, 3, 24, 18)).ok());
  ASSERT_TRUE(a.stats);
  EXPECT_TRUE(ValidateAsset(a).ok()) << ValidateAsset(a).ToString();
  double total = 0;
  for (float v : a.stats->importance) total += v;
  EXPECT_GT(total, 0.0);
}

}  // namespace
}  // namespace atex::fit

namespace atex::fit {
namespace {

TEST(ByteSize, ParsesUnitsAndRefusesNonsense) {
  EXPECT_EQ(*ParseByteSize("123456"), 123456u);
  EXPECT_EQ(*ParseByteSize("80MiB"), 80u * 1048576u);
  EXPECT_EQ(*ParseByteSize("80 MB"), 80000000u);
  EXPECT_EQ(*ParseByteSize("1.5GiB"), 1610612736u);
  EXPECT_EQ(*ParseByteSize("2k"), 2048u);
  for (const char* bad : {"", "MiB", "12XB", "1.2.3MB", "-5MB", "0", "0.2"}) {
    EXPECT_FALSE(ParseByteSize(bad).ok()) << bad;
  }
}

}  // namespace
}  // namespace atex::fit
