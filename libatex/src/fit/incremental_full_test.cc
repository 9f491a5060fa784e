// IncrementalProbes' full render of a candidate that changes every Gaussian
// (incremental_probes.h, set_full_when_all_changed) against its incremental path.
#include <cstring>
#include <utility>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "fit/cpu_probes.h"
#include "fit/incremental_probes.h"
#include "fit/incremental_test_util.h"
#include "fit/levers.h"
#include "fit/probe_test_util.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

using internal::CandidateMap;
using internal::CpuProbeRenderer;
using internal::IncrementalProbes;
using testing::AllNew;
using testing::Cameras;
using testing::DynamicAsset;
using testing::Iota;
using testing::PruneEvery;
using testing::MaxDifference;

bool BitwiseEqual(const std::vector<Image>& a, const std::vector<Image>& b) {
  if (a.size() != b.size()) return false;
  for (size_t k = 0; k < a.size(); ++k) {
    if (a[k].pixels.size() != b[k].pixels.size() ||
        std::memcmp(a[k].pixels.data(), b[k].pixels.data(), a[k].pixels.size() * sizeof(float)) != 0) {
      return false;
    }
  }
  return true;
}

// A candidate that changes every Gaussian is rendered in full (set_full_when_all_changed):
// the same images, bitwise, as the incremental path that marks every splat of the base;
// and the bases the two paths commit (tile lists and their depths) render the moves after
// it to the same images too.
TEST(IncrementalProbes, AllChangedFullRenderEqualsTheIncrementalPathBitwise) {
  const Asset asset = DynamicAsset(13);
  const std::vector<Camera> cameras = Cameras(asset);
  CpuProbeRenderer deform_full, deform_incremental;  // each its own residuals, computed alike
  IncrementalProbes full(&deform_full, cameras), incremental(&deform_incremental, cameras);
  incremental.set_full_when_all_changed(false);
  Asset current = asset;
  std::vector<uint32_t> current_kept = Iota(asset.gaussians.size());
  const auto step = [&](const Asset& next, const std::vector<uint32_t>& kept,
                        const char* what) -> std::pair<uint64_t, uint64_t> {
    CandidateMap map = AllNew(next.gaussians.size());
    if (full.base_size() > 0) {
      map.base_of = internal::BaseIndices(current_kept, kept);
      map.changed = internal::ChangedGaussians(current, next, map.base_of);
    }
    std::shared_ptr<const IncrementalProbes::Pending> pending_full, pending_incremental;
    const uint64_t full_before = full.tiles_drawn(), incremental_before = incremental.tiles_drawn();
    auto a = full.Render(next, map, &pending_full);
    auto b = incremental.Render(next, map, &pending_incremental);
    EXPECT_TRUE(a.ok() && b.ok()) << what;
    if (!a.ok() || !b.ok()) return {0, 0};
    EXPECT_TRUE(BitwiseEqual(*a, *b)) << what << ": max difference " << MaxDifference(*a, *b);
    EXPECT_TRUE(full.Commit(*pending_full).ok());
    EXPECT_TRUE(incremental.Commit(*pending_incremental).ok());
    current = next;
    current_kept = kept;
    return std::pair<uint64_t, uint64_t>{full.tiles_drawn() - full_before,
                                         incremental.tiles_drawn() - incremental_before};
  };
  // The first render (every Gaussian new) is a full render on both.
  step(asset, current_kept, "first");
  const uint64_t all_tiles = full.tiles_drawn();
  const auto [keep, kept] = PruneEvery(asset.gaussians.size(), 3, 0);
  step(SubsetGaussians(asset, keep), kept, "pruned");
  WriteOptions q8;
  q8.positions = ScalarEncoding::kQuant8;
  auto bytes = EncodeAsset(current, q8);
  ASSERT_TRUE(bytes.ok());
  auto decoded = DecodeAsset(bytes->data(), bytes->size());
  ASSERT_TRUE(decoded.ok());
  const auto [full_tiles, incremental_tiles] = step(*decoded, kept, "q8 positions (every Gaussian changed)");
  EXPECT_EQ(full_tiles, all_tiles) << "a full render composites every tile";
  EXPECT_LE(incremental_tiles, all_tiles);
  Asset shrunk = current;
  ASSERT_TRUE(ShrinkTextures(&shrunk, 3).ok());
  const auto [a, b] = step(shrunk, kept, "three texture axes halved, after the two bases");
  EXPECT_EQ(a, b) << "the same base: the same tiles";
  EXPECT_GT(a, 0u);
  Asset one = current;
  one.gaussians.opacity_logits[one.gaussians.size() / 3] -= 1.5f;
  step(one, kept, "one opacity lowered");
}

}  // namespace
}  // namespace atex::fit
