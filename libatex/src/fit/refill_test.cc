// The refill after an indivisible last move (refill.cc) takes shortcuts: an encoding move is
// undone without a replay (encoding moves change only the write options), its prefixes start
// from ApplyPlan's checkpoint instead of the input, and its last replay starts from the prefix
// it built last. None may change what a fit gives: every output must be its own moves
// replayed from the input, with each move's recorded size the size of that replay's prefix.
#include <algorithm>
#include <random>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit.h"
#include "atex/train/backend.h"
#include "fit/fit_test_util.h"
#include "fit/plan_state.h"

namespace atex::fit {
namespace {

TEST(Refill, EveryOutputIsItsMovesReplayedFromTheInput) {
  int refilled = 0, undone_encodings = 0;
  for (const uint64_t seed : {7u, 19u}) {
    const Asset asset = testing::SmallAsset(container::SyntheticTextures::kMixed, seed);
    auto backend = train::MakeCpuBackend();
    ProbeRenderer renderer(backend.get(), OrbitProbes(asset, 4, 40, 30));
    WriteOptions write;
    write.write_stats = false;
    auto minimum = MinimumBytes(asset, write);
    ASSERT_TRUE(minimum.ok()) << minimum.status().ToString();
    PlanOptions o;
    o.write = write;
    o.floor_bytes = *minimum;
    o.prune_fraction = 0.2;
    o.texture_fraction = 0.3;
    auto plan = BuildPlan(asset, &renderer, o);
    ASSERT_TRUE(plan.ok()) << plan.status().ToString();
    const uint64_t lo = plan->moves.back().bytes_after, hi = plan->initial_bytes;
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 30; ++trial) {
      const uint64_t budget = lo + rng() % (hi - lo + 1);
      auto fitted = ApplyPlan(asset, *plan, write, budget);
      ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
      ASSERT_LE(fitted->bytes.size(), budget);
      refilled += fitted->refill_seconds > 0;
      // The plan's moves up to the first that fits (ApplyPlan's), against the output's: an
      // encoding move fewer is one the refill undid.
      size_t j = 0;
      while (j < plan->moves.size() && plan->moves[j].bytes_after > budget) ++j;
      const auto encodings = [](auto begin, auto end) {
        return std::count_if(begin, end, [](const Move& m) { return m.lever == Lever::kEncoding; });
      };
      if (j < plan->moves.size() &&
          encodings(fitted->moves.begin(), fitted->moves.end()) <
              encodings(plan->moves.begin(), plan->moves.begin() + static_cast<std::ptrdiff_t>(j + 1))) {
        ++undone_encodings;
      }
      internal::State replay = internal::InitialState(asset, write);
      for (size_t i = 0; i < fitted->moves.size(); ++i) {
        const Move& m = fitted->moves[i];
        ASSERT_TRUE(ApplyMove(m, plan->prune_order, &replay.asset, &replay.write, &replay.kept,
                              plan->min_grid_resolution, replay.memo.get())
                        .ok());
        auto bytes = EncodeAsset(replay.asset, replay.write);
        ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
        EXPECT_EQ(bytes->size(), m.bytes_after) << "budget " << budget << ", move " << i << ": " << DescribeMove(m);
        if (i + 1 == fitted->moves.size()) {
          EXPECT_EQ(*bytes, fitted->bytes) << "budget " << budget;
        }
      }
      EXPECT_EQ(replay.kept, fitted->kept) << "budget " << budget;
    }
  }
  EXPECT_GT(refilled, 0);
  EXPECT_GT(undone_encodings, 0);  // the shortcut of encoding moves was taken, not only tried
}

}  // namespace
}  // namespace atex::fit
