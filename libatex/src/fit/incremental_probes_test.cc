// The fitter's incremental probe renders (incremental_probes.h) against full renders of
// the asset each candidate stands for, across the moves of a plan; the candidate maps;
// and the range-stable prune measurements (measure.h) against exact ones.
#include <cmath>
#include <numeric>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "atex/render.h"
#include "atex/train/trainer.h"
#include "container/synthetic_asset.h"
#include "fit/cpu_probes.h"
#include "fit/incremental_probes.h"
#include "fit/levers.h"
#include "fit/incremental_test_util.h"
#include "fit/measure.h"
#include "fit/probe_test_util.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

using internal::CandidateMap;
using internal::CpuProbeRenderer;
using internal::IncrementalProbes;
using internal::kNoBase;

// Largest difference of a pixel channel between an incremental and a full render: the
// deformation's summation order for residuals computed in another block of Gaussians
// (cpu_probes.h); everything else is the same arithmetic in the same order.
constexpr float kTolerance = 2e-5f;

using testing::AllNew;
using testing::Cameras;
using testing::DynamicAsset;
using testing::Iota;
using testing::PruneEvery;
using testing::MaxDifference;
using testing::MeanValue;

// Renders `next` (kept: its input indices) against the base `current` (current_kept)
// incrementally, commits it, and checks it against a full render of `next`.
class Chain {
 public:
  Chain(const Asset& first, const std::vector<Camera>& cameras)
      : cameras_(cameras),
        probes_(&deformer_, cameras),
        current_(first),
        kept_(Iota(first.gaussians.size())) {
    std::shared_ptr<const IncrementalProbes::Pending> pending;
    auto images = probes_.Render(first, AllNew(first.gaussians.size()), &pending);
    EXPECT_TRUE(images.ok()) << images.status().ToString();
    EXPECT_TRUE(probes_.Commit(*pending).ok());
    EXPECT_LE(MaxDifference(*images, Full(first)), kTolerance);
    EXPECT_GT(MeanValue(*images), 1e-3) << "the probes must see the asset";
  }

  std::vector<Image> Full(const Asset& a) {
    CpuProbeRenderer fresh;
    auto images = fresh.Render(a, cameras_, train::RenderRequestFor(a));
    EXPECT_TRUE(images.ok()) << images.status().ToString();
    return *images;
  }

  // Returns the tiles composited by the step.
  uint64_t Step(const Asset& next, const std::vector<uint32_t>& kept, const char* what) {
    CandidateMap map;
    map.base_of = internal::BaseIndices(kept_, kept);
    map.changed = internal::ChangedGaussians(current_, next, map.base_of);
    const uint64_t before = probes_.tiles_drawn();
    std::shared_ptr<const IncrementalProbes::Pending> pending;
    auto images = probes_.Render(next, map, &pending);
    EXPECT_TRUE(images.ok()) << what << ": " << images.status().ToString();
    if (!images.ok()) return 0;
    EXPECT_LE(MaxDifference(*images, Full(next)), kTolerance) << what;
    EXPECT_TRUE(probes_.Commit(*pending).ok()) << what;
    current_ = next;
    kept_ = kept;
    return probes_.tiles_drawn() - before;
  }

  IncrementalProbes& probes() { return probes_; }
  const Asset& current() const { return current_; }
  const std::vector<uint32_t>& kept() const { return kept_; }

 private:
  std::vector<Camera> cameras_;
  CpuProbeRenderer deformer_;
  IncrementalProbes probes_;
  Asset current_;
  std::vector<uint32_t> kept_;
};

TEST(IncrementalProbes, EqualFullRendersAcrossMoves) {
  const Asset asset = DynamicAsset(7);
  ASSERT_TRUE(asset.deformation.has_value() && asset.textures.has_value());
  Chain chain(asset, Cameras(asset));
  const uint64_t full_tiles = chain.probes().tiles_drawn();

  // Prune every third Gaussian.
  const auto [keep, kept] = PruneEvery(asset.gaussians.size(), 3, 0);
  chain.Step(SubsetGaussians(asset, keep), kept, "pruned");

  // A texture move changes a few Gaussians: fewer tiles than a full render.
  Asset shrunk = chain.current();
  ASSERT_TRUE(ShrinkTextures(&shrunk, 3).ok());
  const uint64_t texture_tiles = chain.Step(shrunk, kept, "three texture axes halved");
  EXPECT_GT(texture_tiles, 0u);
  EXPECT_LT(texture_tiles, full_tiles / 2);

  // Nothing changed: nothing composited.
  EXPECT_EQ(chain.Step(chain.current(), kept, "unchanged"), 0u);

  // Requantised positions (every Gaussian changed), a coarser field, a lower SH degree
  // and a static asset: full renders through the same path.
  WriteOptions q8;
  q8.positions = ScalarEncoding::kQuant8;
  auto bytes = EncodeAsset(chain.current(), q8);
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  chain.Step(*decoded, kept, "q8 positions");
  Asset coarse = chain.current();
  ASSERT_TRUE(CoarsenGrid(&coarse, 2).ok());
  chain.Step(coarse, kept, "coarser grid");
  Asset lower = coarse;
  ASSERT_TRUE(LowerShDegree(&lower).ok());
  chain.Step(lower, kept, "SH degree lowered");

  // A second prune after all that, then an opacity change of one Gaussian.
  const auto [keep2, kept2] = PruneEvery(lower.gaussians.size(), 5, 2, kept);
  Asset pruned2 = SubsetGaussians(lower, keep2);
  chain.Step(pruned2, kept2, "pruned again");
  Asset one = pruned2;
  one.gaussians.opacity_logits[one.gaussians.size() / 2] += 2.0f;
  chain.Step(one, kept2, "one opacity raised");
  Asset still = one;
  still.deformation.reset();
  chain.Step(still, kept2, "static");
}

// Time-local Gaussians (model.h time_windows): the subsets the incremental renders deform carry
// the windows, and a changed window counts as a changed Gaussian.
TEST(IncrementalProbes, EqualFullRendersWithTimeWindows) {
  Asset asset = DynamicAsset(9, 400);
  Gaussians& g = asset.gaussians;
  g.time_windows.assign(2 * g.size(), 0.0f);
  for (size_t i = 0; i < g.size(); i += 2) {  // half of them time-local, around times across [0, 1]
    g.time_windows[2 * i] = float(i % 10) / 9.0f;
    g.time_windows[2 * i + 1] = 3.0f;
  }
  ASSERT_TRUE(ValidateAsset(asset).ok());
  Chain chain(asset, Cameras(asset));
  const auto [keep, kept] = PruneEvery(g.size(), 4, 1);
  chain.Step(SubsetGaussians(asset, keep), kept, "pruned, with windows");
  Asset narrower = chain.current();
  narrower.gaussians.time_windows[1] = 40.0f;  // one window narrowed: that Gaussian changes
  EXPECT_GT(chain.Step(narrower, kept, "one window narrowed"), 0u);
}

TEST(IncrementalProbes, RangeStablePruneRendersTheBaseLessTheRemoved) {
  const Asset asset = DynamicAsset(11);
  Chain chain(asset, Cameras(asset));
  // A candidate whose values all moved (as after a range change), rendered with no
  // Gaussian marked changed: the base's values less the removed ones.
  const auto [keep, kept] = PruneEvery(asset.gaussians.size(), 4, 1);
  const Asset survivors = SubsetGaussians(asset, keep);
  Asset moved = survivors;
  for (float& x : moved.gaussians.log_scales) x += 0.05f;
  CandidateMap map;
  map.base_of = internal::BaseIndices(chain.kept(), kept);
  auto images = chain.probes().Render(moved, map);
  ASSERT_TRUE(images.ok()) << images.status().ToString();
  EXPECT_LE(MaxDifference(*images, chain.Full(survivors)), kTolerance);
  EXPECT_GT(MaxDifference(*images, chain.Full(moved)), 1e-3f) << "the moved values must not be rendered";
}

// The importance from the incremental renderer is the reference rasteriser's, bitwise
// (the prune order depends on it), and leaves that render as the plan's first base.
TEST(IncrementalProbes, ImportanceIsTheReferenceRasterisersBitwise) {
  const Asset asset = DynamicAsset(23);
  const std::vector<Camera> cameras = Cameras(asset);
  const train::RenderRequest request = train::RenderRequestFor(asset);
  CpuProbeRenderer renderer;
  auto importance = renderer.Importance(asset, cameras, request);
  ASSERT_TRUE(importance.ok()) << importance.status().ToString();
  ASSERT_NE(renderer.ImportanceBase(), nullptr);
  // The reference: RenderForward of the same deformed Gaussians, summed over the probes.
  std::vector<double> times;
  for (const Camera& c : cameras) times.push_back(c.time);
  std::vector<Gaussians> deformed;
  ASSERT_TRUE(
      renderer.DeformCached(*asset.deformation, asset.gaussians, times, asset.gaussians.size(), &deformed).ok());
  RenderSettings settings;
  settings.background = request.background;
  settings.near_plane = request.near_plane;
  settings.active_sh_degree = request.active_sh_degree;
  std::vector<float> expected(asset.gaussians.size(), 0.0f);
  for (size_t k = 0; k < cameras.size(); ++k) {
    auto out = RenderForward<float>(cameras[k], deformed[k], &*asset.textures, settings);
    ASSERT_TRUE(out.ok()) << out.status().ToString();
    for (size_t i = 0; i < expected.size(); ++i) expected[i] += out->importance[i];
  }
  ASSERT_EQ(importance->size(), expected.size());
  size_t positive = 0;
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ((*importance)[i], expected[i]) << "Gaussian " << i;
    positive += expected[i] > 0;
  }
  EXPECT_GT(positive, expected.size() / 4) << "the probes must see the asset";
  // A later commit retires the importance render as the base.
  IncrementalProbes* probes = renderer.Incremental(cameras);
  CandidateMap same;
  same.base_of = Iota(asset.gaussians.size());
  std::shared_ptr<const IncrementalProbes::Pending> pending;
  const uint64_t drawn = probes->tiles_drawn();
  auto images = probes->Render(asset, same, &pending);
  ASSERT_TRUE(images.ok());
  EXPECT_EQ(probes->tiles_drawn(), drawn) << "the importance render is the base: nothing to draw";
  ASSERT_TRUE(probes->Commit(*pending).ok());
  EXPECT_EQ(renderer.ImportanceBase(), nullptr);
}

TEST(IncrementalProbes, RefusesMapsThatDoNotFit) {
  const Asset asset = DynamicAsset(3, 200);
  Chain chain(asset, Cameras(asset));
  const size_t n = asset.gaussians.size();
  CandidateMap wrong_size;
  wrong_size.base_of = Iota(n - 1);
  EXPECT_EQ(chain.probes().Render(asset, wrong_size).status().code(), StatusCode::kInvalidArgument);
  CandidateMap descending;
  descending.base_of = Iota(n);
  std::swap(descending.base_of[3], descending.base_of[4]);
  EXPECT_EQ(chain.probes().Render(asset, descending).status().code(), StatusCode::kInvalidArgument);
  CandidateMap unlisted_new;
  unlisted_new.base_of = Iota(n);
  unlisted_new.base_of[5] = kNoBase;
  EXPECT_EQ(chain.probes().Render(asset, unlisted_new).status().code(), StatusCode::kInvalidArgument);
  CandidateMap beyond;
  beyond.base_of = Iota(n);
  beyond.changed = {static_cast<uint32_t>(n)};
  EXPECT_EQ(chain.probes().Render(asset, beyond).status().code(), StatusCode::kInvalidArgument);
  // A pending render from before a commit cannot be committed.
  CandidateMap same;
  same.base_of = Iota(n);
  std::shared_ptr<const IncrementalProbes::Pending> first, second;
  ASSERT_TRUE(chain.probes().Render(asset, same, &first).ok());
  ASSERT_TRUE(chain.probes().Render(asset, same, &second).ok());
  ASSERT_TRUE(chain.probes().Commit(*first).ok());
  EXPECT_FALSE(chain.probes().Commit(*second).ok());
}

TEST(CandidateMaps, BaseIndicesAndChanges) {
  EXPECT_EQ(internal::BaseIndices({2, 5, 7, 9}, {2, 7, 8, 9}), (std::vector<uint32_t>{0, 2, kNoBase, 3}));
  const Asset asset = DynamicAsset(5, 50);
  EXPECT_TRUE(internal::ChangedGaussians(asset, asset, Iota(50)).empty());
  Asset shrunk = asset;
  ASSERT_TRUE(ShrinkTextures(&shrunk, 2).ok());
  const std::vector<uint32_t> changed = internal::ChangedGaussians(asset, shrunk, Iota(50));
  EXPECT_GE(changed.size(), 1u);
  EXPECT_LE(changed.size(), 2u);
  Asset moved = asset;
  moved.gaussians.sh[7 * 3 * size_t(moved.gaussians.sh_coeffs())] += 0.5f;  // Gaussian 7's DC red
  EXPECT_EQ(internal::ChangedGaussians(asset, moved, Iota(50)), (std::vector<uint32_t>{7}));
  Asset lower = asset;
  ASSERT_TRUE(LowerShDegree(&lower).ok());
  EXPECT_EQ(internal::ChangedGaussians(asset, lower, Iota(50)).size(), 50u) << "another SH degree changes all";
}

// The range-stable measurement of prune candidates ranks them as the exact measurement
// does, on an asset whose q8 streams change range with every prune; the bytes are exact.
TEST(Measurer, RangeStablePrunesRankAsExactOnes) {
  Asset asset = DynamicAsset(13, 900);
  const std::vector<Probe> probes = OrbitProbes(asset, 4, 64, 48);
  ProbeRenderer renderer(nullptr, probes);
  ASSERT_TRUE(renderer.EnsureImportance(&asset).ok());
  const std::vector<uint32_t> order = ImportanceOrder(asset, 1);
  WriteOptions write;
  write.positions = ScalarEncoding::kQuant16;
  write.rotations = write.log_scales = write.opacities = write.sh_dc = write.sh_rest = write.texels =
      ScalarEncoding::kQuant8;
  std::vector<double> stable, exact;
  for (internal::PruneMeasure mode : {internal::PruneMeasure::kRangeStable, internal::PruneMeasure::kExact}) {
    EncodeCache chunks;
    MeasureTiming timing;
    ProbeRenderer own(nullptr, probes);
    internal::Measurer measurer(&own, &chunks, &timing, mode);
    const internal::State start = internal::InitialState(asset, write);
    ASSERT_TRUE(measurer.Start(asset, start).ok());
    for (uint64_t count : {40u, 90u, 200u, 400u}) {
      internal::State next = start;
      Move m;
      m.lever = Lever::kPrune;
      m.count = count;
      ASSERT_TRUE(ApplyMove(m, order, &next.asset, &next.write, &next.kept).ok());
      auto c = measurer.Measure(next, m);
      ASSERT_TRUE(c.ok()) << c.status().ToString();
      auto bytes = EncodeAsset(next.asset, next.write);
      ASSERT_TRUE(bytes.ok());
      EXPECT_EQ(c->measured.bytes, bytes->size()) << "bytes are always exact";
      (mode == internal::PruneMeasure::kExact ? exact : stable).push_back(c->measured.distortion);
    }
  }
  ASSERT_EQ(stable.size(), exact.size());
  for (size_t k = 1; k < stable.size(); ++k) {
    EXPECT_GT(stable[k], stable[k - 1]);
    EXPECT_GT(exact[k], exact[k - 1]);
  }
  for (size_t k = 0; k < stable.size(); ++k) {
    EXPECT_NEAR(stable[k], exact[k], 0.5 * exact[k]) << "prune " << k << ": removal dominates re-rounding";
  }
}

// Confirming a taken range-stable prune renders its exact decode: the distortion the
// confirmed measurer returns is the exact measurer's, and after the confirmed take the
// next measurements are exact ones too.
TEST(Measurer, ConfirmedPrunesAreExact) {
  Asset asset = DynamicAsset(19, 800);
  const std::vector<Probe> probes = OrbitProbes(asset, 4, 64, 48);
  ProbeRenderer renderer(nullptr, probes);
  ASSERT_TRUE(renderer.EnsureImportance(&asset).ok());
  const std::vector<uint32_t> order = ImportanceOrder(asset, 1);
  WriteOptions write;
  write.positions = ScalarEncoding::kQuant16;
  write.rotations = write.log_scales = write.opacities = write.sh_dc = write.texels = ScalarEncoding::kQuant8;
  const internal::State start = internal::InitialState(asset, write);
  Move prune;
  prune.lever = Lever::kPrune;
  prune.count = 300;
  internal::State pruned = start;
  ASSERT_TRUE(ApplyMove(prune, order, &pruned.asset, &pruned.write, &pruned.kept).ok());
  Move texture;
  texture.lever = Lever::kTextures;
  texture.count = 5;
  internal::State shrunk = pruned;
  ASSERT_TRUE(ApplyMove(texture, order, &shrunk.asset, &shrunk.write, &shrunk.kept).ok());
  std::vector<double> taken, after;
  for (internal::PruneMeasure mode : {internal::PruneMeasure::kExact, internal::PruneMeasure::kRangeStableConfirmed,
                                      internal::PruneMeasure::kRangeStable}) {
    EncodeCache chunks;
    MeasureTiming timing;
    ProbeRenderer own(nullptr, probes);
    internal::Measurer measurer(&own, &chunks, &timing, mode);
    ASSERT_TRUE(measurer.Start(asset, start).ok());
    auto c = measurer.Measure(pruned, prune);
    ASSERT_TRUE(c.ok()) << c.status().ToString();
    auto measured = measurer.Take(pruned, *c);
    ASSERT_TRUE(measured.ok()) << measured.status().ToString();
    taken.push_back(measured->distortion);
    auto next = measurer.Measure(shrunk, texture);
    ASSERT_TRUE(next.ok()) << next.status().ToString();
    after.push_back(next->measured.distortion);
  }
  EXPECT_NEAR(taken[1], taken[0], 1e-5 * taken[0]);
  EXPECT_NEAR(after[1], after[0], 1e-5 * after[0]);
  EXPECT_NE(taken[2], taken[0]) << "the unconfirmed take leaves out the survivors' re-rounding";
}

// A plan built with range-stable prunes replays to exactly the bytes it recorded (each
// move's bytes are the exact encoding's), so no budget is ever exceeded.
TEST(Measurer, PlansReplayToTheirBytes) {
  Asset asset = DynamicAsset(17, 500);
  const std::vector<Probe> probes = OrbitProbes(asset, 3, 48, 36);
  ProbeRenderer renderer(nullptr, probes);
  ASSERT_TRUE(renderer.EnsureImportance(&asset).ok());
  WriteOptions write;
  auto full = EncodeAsset(asset, write);
  ASSERT_TRUE(full.ok());
  PlanOptions options;
  options.write = write;
  options.floor_bytes = full->size() / 4;
  auto plan = BuildPlan(asset, &renderer, options);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_GT(plan->moves.size(), 2u);
  internal::State state = internal::InitialState(asset, write);
  for (const Move& m : plan->moves) {
    ASSERT_TRUE(ApplyMove(m, plan->prune_order, &state.asset, &state.write, &state.kept).ok());
    auto bytes = EncodeAsset(state.asset, state.write);
    ASSERT_TRUE(bytes.ok());
    EXPECT_EQ(bytes->size(), m.bytes_after) << DescribeMove(m);
  }
  for (uint64_t budget = full->size() / 4; budget < full->size(); budget += full->size() / 7) {
    auto fitted = ApplyPlan(asset, *plan, write, budget);
    ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
    EXPECT_LE(fitted->bytes.size(), budget);
  }
}

}  // namespace
}  // namespace atex::fit
