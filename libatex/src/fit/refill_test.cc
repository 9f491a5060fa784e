// The refill after an indivisible last move (refill.cc) takes shortcuts: an encoding move is
// undone without a replay (encoding moves change only the write options), its prefixes start
// from ApplyPlan's checkpoint instead of the input, and its last replay starts from the prefix
// it built last; ApplyPlan itself starts from the plan's kept states. None may change what a
// fit gives: every output must be its own moves replayed from the input, with each move's
// recorded size the size of that replay's prefix.
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
  int refilled = 0, undone_encodings = 0, refill_encoded = 0;
  for (const uint64_t seed : {7u, 19u}) {
    const testing::PlanFixture f = testing::MakePlan(container::SyntheticTextures::kMixed, seed);
    const Asset& asset = f.asset;
    const WriteOptions& write = f.write;
    const Plan* plan = &f.plan;
    const uint64_t lo = plan->moves.back().bytes_after, hi = plan->initial_bytes;
    std::mt19937_64 rng(seed);
    for (int trial = 0; trial < 30; ++trial) {
      const uint64_t budget = lo + rng() % (hi - lo + 1);
      auto fitted = ApplyPlan(asset, *plan, write, budget);
      ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
      ASSERT_LE(fitted->bytes.size(), budget);
      refilled += fitted->refill_seconds > 0;
      // The report's encode counts: the refill's are part of ApplyPlan's (some refills skip
      // every trial by arithmetic; no refill, no refill encodes).
      EXPECT_LE(fitted->refill_encodes, fitted->trial_encodes);
      EXPECT_LE(fitted->refill_encode_seconds, fitted->trial_encode_seconds);
      // Its state builds and encodes are parts of the refill's time, apart from each other.
      EXPECT_LE(fitted->refill_state_seconds + fitted->refill_encode_seconds, fitted->refill_seconds + 1e-9);
      if (fitted->refill_seconds == 0) {
        EXPECT_EQ(fitted->refill_encodes, 0) << "budget " << budget;
      }
      refill_encoded += fitted->refill_encodes > 0;
      // Its log holds every refill encode, and before each move's trials (the first of which is
      // count 0, the move undone) the move's whole count, noted without an encode.
      const auto& log = fitted->refill_trials;
      size_t noted = 0;
      for (size_t i = 0; i < log.size(); ++i) {
        if (log[i][0] >= 0) EXPECT_LT(static_cast<size_t>(log[i][0]), plan->moves.size());
        if (log[i][0] < 0 || log[i][1] != 0) continue;
        ++noted;
        ASSERT_GT(i, 0u) << "a move's trials start without its whole count";
        EXPECT_EQ(log[i - 1][0], log[i][0]);
        EXPECT_GT(log[i - 1][1], 0);
      }
      EXPECT_EQ(log.size(), static_cast<size_t>(fitted->refill_encodes) + noted);
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
  EXPECT_GT(refill_encoded, 0);
  EXPECT_GT(undone_encodings, 0);  // the shortcut of encoding moves was taken, not only tried
}

// The refill skips undoing an encoding move that would land far over the budget by arithmetic:
// while no content move follows it, undoing it adds back exactly what it saved (a file's size
// is the sum of its chunks', and an encoding move changes one chunk). Checked here on every
// such move of a few plans, replayed without it from the input.
TEST(Refill, UndoingALateEncodingMoveAddsBackWhatItSaved) {
  int checked = 0;
  for (const uint64_t seed : {3u, 7u, 19u}) {
    const testing::PlanFixture f = testing::MakePlan(container::SyntheticTextures::kMixed, seed, [](PlanOptions* o) {
      o->floor_bytes = 1;
      o->levers = LeverBit(Lever::kEncoding);
    });
    const Asset& asset = f.asset;
    const WriteOptions& write = f.write;
    const Plan* plan = &f.plan;
    const std::vector<Move>& moves = plan->moves;
    size_t first = moves.size();  // the encoding moves after the last content move
    while (first > 0 && moves[first - 1].lever == Lever::kEncoding) --first;
    for (size_t k = first; k + 1 < moves.size(); ++k) {
      bool overridden = false;  // a later move sets the same stream: undoing k changes nothing
      for (size_t i = k + 1; i < moves.size(); ++i) overridden |= moves[i].stream == moves[k].stream;
      if (overridden) continue;
      internal::State s = internal::InitialState(asset, write);
      auto without = internal::ApplyRange(s, *plan, moves, 0, moves.size(), k, 0);
      ASSERT_TRUE(without.ok()) << without.status().ToString();
      auto bytes = EncodeAsset(without->asset, without->write);
      ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
      const uint64_t before = k == 0 ? plan->initial_bytes : moves[k - 1].bytes_after;
      EXPECT_EQ(bytes->size(), moves.back().bytes_after + (before - moves[k].bytes_after))
          << "seed " << seed << ", move " << k << ": " << DescribeMove(moves[k]);
      ++checked;
    }
  }
  EXPECT_GE(checked, 3);
}

// ApplyPlan starts from the plan's kept states (Plan::tail) when it is given the plan's own
// asset object and write options; a plan without them, or another asset object, replays the
// moves from the input. Every budget must give the same file and moves either way.
TEST(Refill, ThePlansKeptStatesGiveTheSameFits) {
  const testing::PlanFixture f = testing::MakePlan(container::SyntheticTextures::kMixed, 13);
  const Asset& asset = f.asset;
  const WriteOptions& write = f.write;
  const Plan* plan = &f.plan;
  ASSERT_NE(plan->tail, nullptr);
  ASSERT_TRUE(plan->tail->Serves(asset, write)) << "the fixture's asset moved since its plan was built";
  ASSERT_GE(plan->moves.size(), 3u);
  // Several states before content moves besides the last two states, so that refills start
  // from kept states at several depths.
  EXPECT_GE(plan->tail->indices.size(), 5u);
  Plan without = *plan;
  without.tail = nullptr;
  const Asset copy = asset;  // equal content, another object: not served by the tail
  const uint64_t lo = plan->moves.back().bytes_after, hi = plan->initial_bytes;
  std::mt19937_64 rng(5);
  std::vector<uint64_t> budgets = {plan->moves.back().bytes_after, plan->moves[plan->moves.size() - 2].bytes_after,
                                   hi, hi + 1};
  for (int trial = 0; trial < 30; ++trial) budgets.push_back(lo + rng() % (hi - lo + 1));
  for (const uint64_t budget : budgets) {
    auto served = ApplyPlan(asset, *plan, write, budget);
    auto replayed = ApplyPlan(asset, without, write, budget);
    auto other_object = ApplyPlan(copy, *plan, write, budget);
    ASSERT_TRUE(served.ok()) << served.status().ToString();
    ASSERT_TRUE(replayed.ok()) << replayed.status().ToString();
    ASSERT_TRUE(other_object.ok()) << other_object.status().ToString();
    EXPECT_EQ(served->bytes, replayed->bytes) << "budget " << budget;
    EXPECT_EQ(other_object->bytes, replayed->bytes) << "budget " << budget;
    EXPECT_EQ(served->kept, replayed->kept) << "budget " << budget;
    ASSERT_EQ(served->moves.size(), replayed->moves.size()) << "budget " << budget;
    for (size_t i = 0; i < served->moves.size(); ++i) {
      EXPECT_EQ(served->moves[i].count, replayed->moves[i].count) << "budget " << budget << ", move " << i;
      EXPECT_EQ(served->moves[i].bytes_after, replayed->moves[i].bytes_after) << "budget " << budget << ", move " << i;
    }
  }
}

}  // namespace
}  // namespace atex::fit
