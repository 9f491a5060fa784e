// The texture-shrinking lever (fit/texture_shrink.h) and the SH-degree and grid levers
// (fit/levers.h): exact where the coarser form can represent the field, least squares otherwise,
// and valid assets throughout.
#include <cmath>
#include <optional>
#include <queue>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "container/synthetic_asset.h"
#include "fit/fit_test_util.h"
#include "fit/levers.h"
#include "fit/plan_state.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

using testing::SmallAsset;

TEST(TextureShrink, RepresentableFieldsShrinkExactly) {
  // A raw field linear along u is exactly representable on 2 samples: shrinking 4 → 2 loses nothing.
  float src[1 * 4 * 4];
  for (int x = 0; x < 4; ++x)
    for (int c = 0; c < 4; ++c) src[x * 4 + c] = 0.3f * c - 0.5f + 0.9f * x / 3.0f;
  EXPECT_LT(ShrinkResidual(src, 1, 4, 1, 2), 1e-14);
  EXPECT_GT(ShrinkResidual(src, 1, 4, 1, 1), 1e-6) << "a constant cannot hold a ramp";
  float constant[2 * 2 * 4];
  for (float& v : constant) v = 0.3f;
  EXPECT_LT(ShrinkResidual(constant, 2, 2, 1, 1), 1e-14);
  float out[4];
  ShrinkTexture(constant, 2, 2, out, 1, 1);
  for (float v : out) EXPECT_NEAR(v, 0.3f, 1e-6);
}

TEST(TextureShrink, LeastSquaresBeatsCornerSampling) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-2, 2);
  for (int trial = 0; trial < 20; ++trial) {
    float src[16 * 4];
    for (float& v : src) v = u(rng);
    const double ls = ShrinkResidual(src, 4, 4, 2, 2);
    // Corner sampling: what plain resampling (detail::UpsampleTexture to a smaller grid) keeps.
    float corners[2 * 2 * 4], back[16 * 4];
    detail::UpsampleTexture(src, 4, 4, corners, 2, 2, 4);
    detail::UpsampleTexture(corners, 2, 2, back, 4, 4, 4);
    double naive = 0;
    for (int k = 0; k < 64; ++k) {
      const double d = 0.1 * (std::tanh(back[k]) - std::tanh(src[k]));
      naive += d * d;
    }
    EXPECT_LE(ls, naive / 64 + 1e-12);
  }
}

TEST(TextureShrink, GreedyOrderAndLimits) {
  Asset a = SmallAsset(container::SyntheticTextures::kMixed);
  const uint64_t before = a.textures->texel_count();
  const uint64_t shrinkable = ShrinkableTexels(*a.textures);
  ASSERT_GT(shrinkable, 0u);
  ASSERT_TRUE(ShrinkTextures(&a, 10).ok());
  EXPECT_LT(a.textures->texel_count(), before);
  EXPECT_TRUE(ValidateAsset(a).ok());
  auto done = ShrinkTextures(&a, ~uint64_t{0});
  ASSERT_TRUE(done.ok());
  EXPECT_EQ(a.textures->texel_count(), a.textures->size()) << "everything ends 1x1";
  EXPECT_TRUE(ValidateAsset(a).ok());
}

// The memo of residuals changes nothing: the same pool with and without it, also when
// the memo already holds the textures (a second state sharing them) and after some changed.
TEST(TextureShrink, TheResidualMemoGivesTheSamePools) {
  TextureShrinkMemo memo;
  for (int round = 0; round < 3; ++round) {
    Asset plain = SmallAsset(container::SyntheticTextures::kMixed, 5);
    if (round == 2) plain.textures->texels[7] += 0.5f;  // one texture's content changed
    Asset memoised = plain;
    const uint64_t count = 40 + 30 * round;
    const uint64_t done = ShrinkTextures(&plain, count).value();
    EXPECT_GT(done, 0u);
    ASSERT_EQ(ShrinkTextures(&memoised, count, &memo).value(), done);
    EXPECT_EQ(plain.textures->heights, memoised.textures->heights) << round;
    EXPECT_EQ(plain.textures->widths, memoised.textures->widths) << round;
    EXPECT_EQ(plain.textures->texels, memoised.textures->texels) << round;
  }
  const Asset a = SmallAsset(container::SyntheticTextures::kUniform, 6);
  const float* texels = a.textures->texels.data();
  const HalvingResiduals direct = HalvingResidualsOf(texels, 4, 4);
  const HalvingResiduals remembered = memo.Residuals(texels, 4, 4), again = memo.Residuals(texels, 4, 4);
  EXPECT_EQ(direct.width, remembered.width);
  EXPECT_EQ(direct.height, again.height);
  EXPECT_EQ(direct.width, ShrinkResidual(texels, 4, 4, 4, 2));
  EXPECT_EQ(direct.height, ShrinkResidual(texels, 4, 4, 2, 4));
}

// The greedy of ShrinkTextures one op at a time, as its contract states it: pop the cheapest
// halving (damage per removed texel, then demand, then index), apply it, offer the texture's
// next halving. The library computes the chains of halvings ahead in parallel.
TexturePool SequentialShrink(const Asset& asset, uint64_t count) {
  const TexturePool& pool = *asset.textures;
  const size_t n = pool.size();
  const GaussianStats* stats = asset.stats ? &*asset.stats : nullptr;
  const auto stat = [&](const std::vector<float>* v, size_t i, float fallback) {
    return v != nullptr && v->size() == n ? (*v)[i] : fallback;
  };
  std::vector<std::vector<float>> texels(n);
  std::vector<uint8_t> heights = pool.heights, widths = pool.widths;
  for (size_t i = 0; i < n; ++i) {
    const float* src = pool.texels.data() + pool.offsets[i] * kTexelChannels;
    texels[i].assign(src, src + pool.heights[i] * pool.widths[i] * kTexelChannels);
  }
  using Op = std::tuple<double, double, uint32_t, int, int>;  // cost, demand, index, new h, new w
  const auto best = [&](uint32_t i) -> std::optional<Op> {
    const int h = heights[i], w = widths[i];
    if (h * w == 1) return std::nullopt;
    const double importance = std::max(0.0f, stat(stats ? &stats->importance : nullptr, i, 1.0f));
    const double demand = stat(stats ? &stats->texture_demand : nullptr, i, 0.0f);
    const HalvingResiduals r = HalvingResidualsOf(texels[i].data(), h, w);
    std::optional<Op> by_width, by_height;
    if (w > 1) by_width = Op{importance * r.width * h * w / (h * (w - w / 2)), demand, i, h, w / 2};
    if (h > 1) by_height = Op{importance * r.height * h * w / (w * (h - h / 2)), demand, i, h / 2, w};
    if (!by_width) return by_height;
    if (!by_height) return by_width;
    const double cost_w = std::get<0>(*by_width), cost_h = std::get<0>(*by_height);
    if (cost_h < cost_w) return by_height;
    if (cost_h == cost_w &&
        stat(stats ? &stats->peak_scale_v : nullptr, i, 0.0f) < stat(stats ? &stats->peak_scale_u : nullptr, i, 0.0f)) {
      return by_height;
    }
    return by_width;
  };
  std::priority_queue<Op, std::vector<Op>, std::greater<Op>> queue;
  for (uint32_t i = 0; i < n; ++i)
    if (auto op = best(i)) queue.push(*op);
  for (uint64_t done = 0; done < count && !queue.empty(); ++done) {
    const auto [cost, demand, i, new_h, new_w] = queue.top();
    queue.pop();
    std::vector<float> shrunk(new_h * new_w * kTexelChannels);
    ShrinkTexture(texels[i].data(), heights[i], widths[i], shrunk.data(), new_h, new_w);
    texels[i] = std::move(shrunk);
    heights[i] = static_cast<uint8_t>(new_h);
    widths[i] = static_cast<uint8_t>(new_w);
    if (auto next = best(i)) queue.push(*next);
  }
  TexturePool out;
  out.heights = heights;
  out.widths = widths;
  out.axis_u = pool.axis_u;
  out.axis_v = pool.axis_v;
  out.RebuildOffsets();
  for (const auto& t : texels) out.texels.insert(out.texels.end(), t.begin(), t.end());
  return out;
}

// ShrinkTextures (its chains of halvings computed ahead, in parallel) pools what the plain
// greedy does, bit for bit: over counts from one op to all of them, with and without the
// trainer's statistics, and with ties in cost (zero importance) and in the axis choice
// (equal residuals: the peak scales decide).
TEST(TextureShrink, ChainsComputedAheadGiveTheSequentialGreedysPool) {
  for (int variant = 0; variant < 3; ++variant) {
    Asset a = SmallAsset(variant == 1 ? container::SyntheticTextures::kUniform : container::SyntheticTextures::kMixed,
                         11 + variant, 3000);
    if (variant == 0) a.stats.reset();
    if (variant == 2) {
      ASSERT_TRUE(a.stats.has_value());
      for (size_t i = 0; i < a.stats->size(); i += 7) a.stats->importance[i] = 0;  // ties at cost 0
      // Constant textures: both halvings are exact, so the peak scales choose the axis.
      for (size_t i = 0; i < a.textures->size(); i += 5) {
        float* t = a.textures->texels.data() + a.textures->offsets[i] * kTexelChannels;
        std::fill(t, t + a.textures->heights[i] * a.textures->widths[i] * kTexelChannels, 0.25f);
      }
    }
    const uint64_t all = ShrinkableTexels(*a.textures);
    for (uint64_t count : {uint64_t{1}, uint64_t{17}, uint64_t{900}, uint64_t{4000}, all, all + 5}) {
      TextureShrinkMemo memo;
      Asset shrunk = a;
      ASSERT_TRUE(ShrinkTextures(&shrunk, count, variant == 2 ? &memo : nullptr).ok());
      const TexturePool expected = SequentialShrink(a, count);
      EXPECT_EQ(shrunk.textures->heights, expected.heights) << variant << " " << count;
      EXPECT_EQ(shrunk.textures->widths, expected.widths) << variant << " " << count;
      EXPECT_EQ(shrunk.textures->texels, expected.texels) << variant << " " << count;
    }
  }
}

// Every texture's residuals as HalvingResidualsOf computes them from the pool.
PoolResiduals ResidualsOf(const TexturePool& pool) {
  PoolResiduals r;
  for (size_t i = 0; i < pool.size(); ++i) {
    r.push_back(
        HalvingResidualsOf(pool.texels.data() + pool.offsets[i] * kTexelChannels, pool.heights[i], pool.widths[i]));
  }
  return r;
}

void ExpectSameResiduals(const PoolResiduals& expected, const PoolResiduals& actual, const std::string& where) {
  ASSERT_EQ(expected.size(), actual.size()) << where;
  for (size_t i = 0; i < expected.size(); ++i) {
    ASSERT_EQ(expected[i].width, actual[i].width) << where << " texture " << i;
    ASSERT_EQ(expected[i].height, actual[i].height) << where << " texture " << i;
  }
}

TEST(TextureShrink, ResidualsCarriedFromPoolToPoolAreThePoolsOwn) {
  // A chain of texture moves, each given the residuals the one before wrote: the same pools
  // as without them, and the residuals written are those of each new pool's textures.
  Asset a = SmallAsset(container::SyntheticTextures::kMixed, 21, 3000);
  std::optional<PoolResiduals> known;
  for (uint64_t count : {uint64_t{700}, uint64_t{1}, uint64_t{2500}, ShrinkableTexels(*a.textures)}) {
    TexturePool plain, carried;
    PoolResiduals written;
    const uint64_t done = ShrinkTexturePool(a, count, nullptr, &plain).value();
    ASSERT_EQ(ShrinkTexturePool(a, count, nullptr, &carried, known ? &*known : nullptr, &written).value(), done);
    EXPECT_EQ(plain.heights, carried.heights) << count;
    EXPECT_EQ(plain.widths, carried.widths) << count;
    EXPECT_EQ(plain.texels, carried.texels) << count;
    ExpectSameResiduals(ResidualsOf(carried), written, "after " + std::to_string(count));
    a.textures = std::move(carried);
    known = std::move(written);
  }
  PoolResiduals wrong(a.textures->size() + 1);
  TexturePool out;
  EXPECT_EQ(ShrinkTexturePool(a, 1, nullptr, &out, &wrong).status().code(), StatusCode::kInvalidArgument);
}

TEST(TextureShrink, FitStatesCarryTheirTexturesResiduals) {
  // The fitter's states: a texture move writes the residuals of its pool, a prune gathers the
  // kept textures', an SH move keeps them, and halving every texture forgets them.
  const Asset asset = SmallAsset(container::SyntheticTextures::kMixed, 22, 2000);
  internal::State state = internal::InitialState(asset, WriteOptions{});
  const std::vector<uint32_t> order = ImportanceOrder(asset, 3);
  Move textures, prune, sh, all;
  textures.lever = Lever::kTextures;
  textures.count = 900;
  prune.lever = Lever::kPrune;
  prune.count = 600;
  sh.lever = Lever::kShDegree;
  all.lever = Lever::kAllTextures;
  for (const Move& m : {textures, prune, textures, sh, prune, textures}) {
    auto next = internal::AppliedTo(state, m, order, 4);
    ASSERT_TRUE(next.ok()) << next.status().ToString();
    state = std::move(*next);
    ASSERT_NE(state.texture_residuals, nullptr) << DescribeMove(m);
    ExpectSameResiduals(ResidualsOf(*state.asset.textures), *state.texture_residuals, DescribeMove(m));
  }
  auto halved = internal::AppliedTo(state, all, order, 4);
  ASSERT_TRUE(halved.ok());
  EXPECT_EQ(halved->texture_residuals, nullptr);
  ASSERT_TRUE(internal::ApplyInPlace(textures, order, 4, &state).ok());
  EXPECT_EQ(state.texture_residuals, nullptr) << "a move applied in place forgets them";
}

TEST(TextureShrink, UniformAssetsBecomeAdaptive) {
  Asset a = SmallAsset(container::SyntheticTextures::kUniform);
  a.metadata.texture_mode = "uniform";
  ASSERT_TRUE(ValidateAsset(a).ok());
  ASSERT_TRUE(ShrinkTextures(&a, 5).ok());
  EXPECT_EQ(a.metadata.texture_mode, "adaptive");
  EXPECT_TRUE(ValidateAsset(a).ok()) << ValidateAsset(a).ToString();
}

TEST(TextureShrink, HalvingAllTexturesKeepsAUniformPoolUniform) {
  Asset a = SmallAsset(container::SyntheticTextures::kUniform);
  a.metadata.texture_mode = "uniform";
  ASSERT_TRUE(ValidateAsset(a).ok());
  const int side = a.textures->heights[0];
  ASSERT_EQ(side, 4);
  // 4x4 → 2x4 → 2x2 → 1x2 → 1x1: the longer axis (the height on a tie), every texture alike.
  const std::vector<std::pair<int, int>> sizes = {{2, 4}, {2, 2}, {1, 2}, {1, 1}};
  for (const auto& [h, w] : sizes) {
    ASSERT_TRUE(HalveAllTextures(&a).ok());
    for (size_t i = 0; i < a.textures->size(); ++i) {
      ASSERT_EQ(a.textures->heights[i], h);
      ASSERT_EQ(a.textures->widths[i], w);
    }
    EXPECT_EQ(a.metadata.texture_mode, "uniform");
    EXPECT_TRUE(ValidateAsset(a).ok()) << ValidateAsset(a).ToString();
  }
  EXPECT_EQ(HalveAllTextures(&a).code(), StatusCode::kInvalidArgument) << "nothing left to halve";
}

TEST(TextureShrink, HalvingAllTexturesProjectsEachTextureAsShrinkTextureDoes) {
  Asset a = SmallAsset(container::SyntheticTextures::kMixed, 9);
  const TexturePool before = *a.textures;
  ASSERT_TRUE(HalveAllTextures(&a).ok());
  const TexturePool& after = *a.textures;
  size_t halved = 0;
  for (size_t i = 0; i < before.size(); ++i) {
    const int h = before.heights[i], w = before.widths[i];
    const int nh = after.heights[i], nw = after.widths[i];
    const float* src = before.texels.data() + before.offsets[i] * kTexelChannels;
    const float* dst = after.texels.data() + after.offsets[i] * kTexelChannels;
    if (h == 1 && w == 1) {
      ASSERT_EQ(nh * nw, 1);
      for (int c = 0; c < kTexelChannels; ++c) ASSERT_EQ(dst[c], src[c]);
      continue;
    }
    ++halved;
    ASSERT_EQ(nh * nw * 2, h * w) << "texture " << i << " loses exactly one axis halving";
    ASSERT_EQ(nh < h, h >= w) << "texture " << i << " halves its longer axis";
    std::vector<float> expected(static_cast<size_t>(nh) * nw * kTexelChannels);
    ShrinkTexture(src, h, w, expected.data(), nh, nw);
    for (size_t k = 0; k < expected.size(); ++k) ASSERT_EQ(dst[k], expected[k]) << "texture " << i;
  }
  EXPECT_GT(halved, before.size() / 4);
  EXPECT_TRUE(ValidateAsset(a).ok());
}

TEST(Levers, ShDegreeAndGridKeepAssetsValid) {
  Asset a = SmallAsset(container::SyntheticTextures::kMixed);
  ASSERT_TRUE(a.deformation->config.heads[kHeadSH]);
  while (a.gaussians.sh_degree > 0) {
    ASSERT_TRUE(LowerShDegree(&a).ok());
    ASSERT_TRUE(ValidateAsset(a).ok()) << ValidateAsset(a).ToString();
  }
  EXPECT_FALSE(LowerShDegree(&a).ok());
  int halvings = 0;
  while (CanCoarsenGrid(a, 4)) {
    ASSERT_TRUE(CoarsenGrid(&a, 4).ok());
    ASSERT_TRUE(ValidateAsset(a).ok());
    ++halvings;
  }
  EXPECT_GT(halvings, 0);
  EXPECT_FALSE(CoarsenGrid(&a, 4).ok());
}

TEST(Levers, CoarsenGridKeepsAConstantFieldExactly) {
  Asset a = SmallAsset(container::SyntheticTextures::kNone);
  for (auto& scale : a.deformation->planes)
    for (auto& plane : scale) std::fill(plane.begin(), plane.end(), 0.7f);
  ASSERT_TRUE(CoarsenGrid(&a, 2).ok());
  for (auto& scale : a.deformation->planes)
    for (auto& plane : scale)
      for (float v : plane) ASSERT_NEAR(v, 0.7f, 1e-6);
}

}  // namespace
}  // namespace atex::fit
