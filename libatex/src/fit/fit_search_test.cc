// The fitter's search speed-ups: the count search of ApplyPlan and the refill
// (count_search.h), proposals prepared in parallel, and growing steps (PlanOptions).
#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "atex/fit.h"
#include "atex/train/backend.h"
#include "fit/count_search.h"
#include "fit/fit_test_util.h"
#include "fit/proposals.h"
#include "train/forwarding_backend.h"

namespace atex::fit {
namespace {

using internal::HalvingsToSave;
using internal::SmallestFittingCount;
using testing::SmallAsset;

// The smallest count in (lo, hi] whose size fits, by trying every one from hi down (the
// search's answer on sizes that do not rise with the count).
uint64_t Exhaustive(const std::vector<uint64_t>& sizes, uint64_t lo, uint64_t hi, uint64_t budget) {
  uint64_t best = hi;
  for (uint64_t c = hi; c > lo && sizes[c] <= budget; --c) best = c;
  return best;
}

TEST(CountSearch, FindsTheBoundaryOfMonotoneSizesInFewTrials) {
  std::mt19937_64 random(7);
  int worst_trials = 0;
  for (int round = 0; round < 300; ++round) {
    // Sizes that fall with the count, nearly linearly (a prune or texture move), with steps
    // of compression noise; some rounds far from linear (a kink: a stream changes codec).
    const uint64_t hi = 2 + random() % 40000;
    std::vector<uint64_t> sizes(hi + 1);
    const bool kinked = round % 3 == 0;
    uint64_t size = 10'000'000;
    for (uint64_t c = 0; c <= hi; ++c) {
      sizes[c] = size;
      const uint64_t step = (kinked && c > hi / 5) ? 1 + random() % 3 : 20 + random() % 17;
      size -= std::min<uint64_t>(size - 1, step);
    }
    const uint64_t budget = sizes[hi] + random() % (sizes[0] - sizes[hi]);
    int calls = 0, trials = 0;
    auto got = SmallestFittingCount(0, sizes[0], hi, sizes[hi], budget, [&](uint64_t c) -> StatusOr<uint64_t> {
      ++calls;
      EXPECT_GT(c, 0u);
      EXPECT_LT(c, hi) << "the ends are never tried";
      return sizes[c];
    }, &trials);
    ASSERT_TRUE(got.ok()) << got.status().ToString();
    EXPECT_EQ(*got, Exhaustive(sizes, 0, hi, budget)) << "round " << round;
    EXPECT_EQ(trials, calls);
    // Never much worse than a bisection's ceil(log2(hi)) trials.
    EXPECT_LE(trials, 2 * static_cast<int>(std::ceil(std::log2(static_cast<double>(hi)))) + 2) << round;
    if (!kinked) worst_trials = std::max(worst_trials, trials);
  }
  // Near-linear sizes (the common case) take a handful of trials, not a bisection's 16.
  EXPECT_LE(worst_trials, 8);
}

TEST(CountSearch, AStepInTheSizesTakesAtMostTwiceABisection) {
  // Far from linear: a huge size at count 0, one byte over the budget below t, one under from t
  // on. Interpolation alone would creep towards t from above (found by review: 43 trials for
  // t = 2 with a rule that bisected only after two guesses on one side).
  const uint64_t hi = 65536, budget = 1'000'000;
  for (uint64_t t : {1ull, 2ull, 100ull, 30000ull, 65535ull}) {
    const auto bytes_at = [&](uint64_t c) -> StatusOr<uint64_t> {
      return c == 0 ? uint64_t{1} << 40 : (c < t ? budget + 1 : budget - 1);
    };
    int trials = 0;
    auto got = SmallestFittingCount(0, uint64_t{1} << 40, hi, budget - 1, budget, bytes_at, &trials);
    ASSERT_TRUE(got.ok());
    EXPECT_EQ(*got, t);
    EXPECT_LE(trials, 2 * 16 + 1) << "t = " << t;
  }
}

TEST(CountSearch, SizesThatRiseLocallyStillGiveAFittingCountWhosePredecessorDoesNot) {
  // A compressed size can grow by a few bytes when one more unit is removed.
  std::vector<uint64_t> sizes = {1000, 990, 995, 960, 970, 930, 900, 905, 880};
  for (uint64_t budget = 880; budget < 1000; ++budget) {
    auto got = SmallestFittingCount(0, sizes[0], 8, sizes[8], budget,
                                    [&](uint64_t c) -> StatusOr<uint64_t> { return sizes[c]; });
    ASSERT_TRUE(got.ok());
    EXPECT_LE(sizes[*got], budget) << budget;
    EXPECT_GT(sizes[*got - 1], budget) << budget;
  }
}

TEST(CountSearch, StopsOnceTheSlackLeftIsBelowEnough) {
  // Near-linear sizes with compression noise, as in FindsTheBoundary...: with enough_slack the
  // answer fits and leaves less than that unused (or is the exact answer), in fewer trials.
  std::mt19937_64 random(11);
  int exact_trials = 0, early_trials = 0, stopped_early = 0;
  for (int round = 0; round < 200; ++round) {
    const uint64_t hi = 1000 + random() % 40000;
    std::vector<uint64_t> sizes(hi + 1);
    uint64_t size = 40'000'000;
    for (uint64_t c = 0; c <= hi; ++c) {
      sizes[c] = size - std::min<uint64_t>(size, 55 * c) + random() % 600;  // 55 bytes a unit, noisy
    }
    const uint64_t budget = sizes[hi] + random() % (sizes[0] - sizes[hi] - 600);
    const auto bytes_at = [&](uint64_t c) -> StatusOr<uint64_t> { return sizes[c]; };
    const uint64_t enough = budget / 1024;
    int trials = 0;
    auto exact = SmallestFittingCount(0, sizes[0], hi, sizes[hi], budget, bytes_at, &trials);
    ASSERT_TRUE(exact.ok());
    exact_trials += trials;
    auto early = SmallestFittingCount(0, sizes[0], hi, sizes[hi], budget, bytes_at, &trials, enough);
    ASSERT_TRUE(early.ok());
    early_trials += trials;
    ASSERT_LE(sizes[*early], budget) << round;
    if (*early != *exact) {
      ++stopped_early;
      EXPECT_LT(budget - sizes[*early], enough) << round;
    }
  }
  EXPECT_GT(stopped_early, 0) << "no round stopped early: the test tests nothing";
  EXPECT_LT(early_trials, exact_trials);
  // Aimed at the middle of the accepted sizes, the first guess mostly lands there: 177 trials in
  // these 200 rounds (some need none), against 324 when the guesses aimed at the budget itself.
  EXPECT_LE(early_trials, 250);
  // hi itself within enough of the budget: nothing is tried.
  const auto never = [](uint64_t) -> StatusOr<uint64_t> {
    ADD_FAILURE() << "tried a count";
    return uint64_t{0};
  };
  auto at_hi = SmallestFittingCount(0, 2000, 100, 1000, 1005, never, nullptr, 6);
  ASSERT_TRUE(at_hi.ok());
  EXPECT_EQ(*at_hi, 100u);
}

TEST(CountSearch, EndsThatDoNotBracketTheBudgetAreABugNotAFit) {
  const auto never = [](uint64_t) -> StatusOr<uint64_t> { return uint64_t{0}; };
  EXPECT_EQ(SmallestFittingCount(0, 100, 10, 90, 80, never).status().code(), StatusCode::kInternal);
  EXPECT_EQ(SmallestFittingCount(0, 100, 10, 90, 100, never).status().code(), StatusCode::kInternal);
  EXPECT_EQ(SmallestFittingCount(5, 100, 5, 90, 95, never).status().code(), StatusCode::kInternal);
  // A failing trial's error comes back as it is.
  auto failing = SmallestFittingCount(0, 100, 10, 50, 75, [](uint64_t) -> StatusOr<uint64_t> {
    return MakeError(StatusCode::kOutOfRange, "f16 overflow");
  });
  EXPECT_EQ(failing.status().code(), StatusCode::kOutOfRange);
}

struct Planned {
  Plan plan;
  uint64_t minimum = 0;
};

// `gpu_path`: the probes rendered as on a GPU backend (whole render states, preparations beside
// the renders), by the CPU backend behind a ForwardingBackend, which the renderer does not take
// for the CPU.
// `texture_fraction` and `min_texture_step` as PlanOptions.
Planned PlanWith(int parallel, double growth, LeverSet levers = kDefaultLevers, bool gpu_path = false,
                 double texture_fraction = 0.05, double min_texture_step = PlanOptions{}.min_texture_step) {
  const Asset asset = SmallAsset(container::SyntheticTextures::kMixed, 5);
  std::unique_ptr<train::Backend> backend =
      gpu_path ? std::make_unique<train::ForwardingBackend>() : train::MakeCpuBackend();
  ProbeRenderer renderer(backend.get(), OrbitProbes(asset, 4, 40, 30));
  EXPECT_EQ(renderer.cpu_renderer() == nullptr, gpu_path);
  PlanOptions o;
  o.write.write_stats = false;
  auto minimum = MinimumBytes(asset, o.write, 4, levers);
  EXPECT_TRUE(minimum.ok());
  o.floor_bytes = *minimum;
  o.levers = levers;
  o.prune_fraction = 0.05;
  o.texture_fraction = texture_fraction;
  o.min_texture_step = min_texture_step;
  o.parallel_candidates = parallel;
  o.step_growth = growth;
  auto plan = BuildPlan(asset, &renderer, o);
  EXPECT_TRUE(plan.ok()) << plan.status().ToString();
  return {std::move(*plan), *minimum};
}

// The same moves, move for move: kind, count, size and distortion after each.
void ExpectSameMoves(const Plan& expected, const Plan& actual) {
  ASSERT_EQ(expected.moves.size(), actual.moves.size());
  for (size_t i = 0; i < expected.moves.size(); ++i) {
    const Move &a = expected.moves[i], &b = actual.moves[i];
    EXPECT_EQ(DescribeMove(a), DescribeMove(b)) << i;
    EXPECT_EQ(a.bytes_after, b.bytes_after) << i;
    EXPECT_EQ(a.distortion_after, b.distortion_after) << i;
  }
}

TEST(Plan, TheSamePlanWhateverTheCandidatesPreparedAtOnce) {
  const Planned serial = PlanWith(1, 2.0), parallel = PlanWith(5, 2.0);
  ExpectSameMoves(serial.plan, parallel.plan);
  EXPECT_EQ(serial.plan.timing.measurements, parallel.plan.timing.measurements);
  EXPECT_EQ(serial.plan.timing.overlap_seconds, 0.0);
  EXPECT_EQ(serial.plan.timing.render_load_seconds, 0.0);  // the CPU renders assets, loads nothing
  // The parallel plan prepared stale proposals ahead of their refresh and used some of them.
  EXPECT_EQ(serial.plan.timing.prepared_ahead, 0);
  EXPECT_GT(parallel.plan.timing.prepared_ahead, parallel.plan.timing.prepared_unused);
}

// On a GPU backend a candidate is scored while the next ones are prepared, and speculative
// preparations left unused are cancelled or finish in the background: the plan is still the
// serial one, move for move.
TEST(Plan, ScoringBesidePreparationsGivesTheSamePlan) {
  const Planned serial = PlanWith(1, 2.0, kDefaultLevers, true), parallel = PlanWith(4, 2.0, kDefaultLevers, true);
  ASSERT_GE(serial.plan.moves.size(), 3u);
  ExpectSameMoves(serial.plan, parallel.plan);
  EXPECT_EQ(serial.plan.timing.measurements, parallel.plan.timing.measurements);
  EXPECT_GT(serial.plan.timing.render_state_seconds, 0.0);  // the GPU path's render states
  EXPECT_GT(serial.plan.timing.render_load_seconds, 0.0);   // and their loads onto the backend
  EXPECT_LT(serial.plan.timing.render_load_seconds,
            serial.plan.timing.render_seconds + serial.plan.timing.reference_seconds);
  EXPECT_EQ(serial.plan.timing.prepared_ahead, 0);
  EXPECT_GT(parallel.plan.timing.prepared_ahead, parallel.plan.timing.prepared_unused);
  // Next steps were prepared at candidates' states, and the plan took some of them.
  EXPECT_EQ(serial.plan.timing.next_steps_prepared, 0);
  EXPECT_GT(parallel.plan.timing.next_steps_used, 0);
  EXPECT_LE(parallel.plan.timing.next_steps_used, parallel.plan.timing.next_steps_prepared);
}

// The plan of `levers` on the GPU path with four candidates at once (next steps prepared
// ahead), checked against the serial plan move for move.
Plan AheadMatchingTheSerialPlan(LeverSet levers) {
  const Planned serial = PlanWith(1, 2.0, levers, true);
  Planned ahead = PlanWith(4, 2.0, levers, true);
  EXPECT_GE(serial.plan.moves.size(), 4u);
  ExpectSameMoves(serial.plan, ahead.plan);
  EXPECT_EQ(serial.plan.timing.measurements, ahead.plan.timing.measurements);
  EXPECT_EQ(serial.plan.timing.next_steps_prepared, 0);
  return std::move(ahead.plan);
}

TEST(Plan, NextStepsPreparedAheadFollowALeverThatKeepsWinning) {
  // Textures alone: after the first move every move is the texture lever's next step, prepared
  // at the state of the candidate before it (its own next step started once the plan took it),
  // with the step scale the plan has then. Every proposal after the second move was such a next
  // step, but a proposal that the state no longer has (nothing left to halve) prepares nothing.
  const Plan ahead = AheadMatchingTheSerialPlan(LeverBit(Lever::kTextures));
  EXPECT_GE(ahead.timing.next_steps_used, static_cast<int>(ahead.moves.size()) - 2);
}

TEST(Plan, NextStepsPreparedAheadKeepTheTextureFloor) {
  // Textures alone, steps of 1 % of the growable textures but at least a twentieth of the bytes
  // to shed: the floor sets every step, and the next steps prepared ahead carry it (the step
  // scale they copy), so they are the serial plan's moves and the plan takes them.
  const LeverSet textures = LeverBit(Lever::kTextures);
  const Planned serial = PlanWith(1, 2.0, textures, true, 0.01, 0.05);
  const Planned ahead = PlanWith(4, 2.0, textures, true, 0.01, 0.05);
  const Planned unfloored = PlanWith(1, 2.0, textures, true, 0.01, 0);
  ASSERT_GE(serial.plan.moves.size(), 4u);
  ASSERT_FALSE(unfloored.plan.moves.empty());
  EXPECT_GT(serial.plan.moves[0].count, unfloored.plan.moves[0].count * 4) << "the floor binds";
  ExpectSameMoves(serial.plan, ahead.plan);
  EXPECT_GT(ahead.plan.timing.next_steps_used, 0);
}

TEST(Plan, NextStepsOfEncodingMovesArePreparedAtTheStateTheyWerePreparedAt) {
  // Encodings alone: an encoding candidate's state is the state it was prepared at with other
  // write options, copied only once it is taken; its stream's next encoding is prepared at that
  // state with those options and moves to the copy.
  EXPECT_GT(AheadMatchingTheSerialPlan(LeverBit(Lever::kEncoding)).timing.next_steps_used, 0);
}

TEST(Plan, ALeverThatKeepsWinningTakesGrowingSteps) {
  // Textures alone: every move is a texture move, so from the third on each step doubles
  // (up to every growable texture) with growth 2, and stays at its fraction with growth 1.
  const Planned fixed = PlanWith(1, 1.0, LeverBit(Lever::kTextures));
  const Planned growing = PlanWith(1, 2.0, LeverBit(Lever::kTextures));
  ASSERT_GE(fixed.plan.moves.size(), 4u);
  ASSERT_GE(growing.plan.moves.size(), 4u);
  // The same first two steps; then each is about twice the one before (the growable
  // textures shrink a little in between).
  EXPECT_EQ(growing.plan.moves[0].count, fixed.plan.moves[0].count);
  EXPECT_EQ(growing.plan.moves[1].count, fixed.plan.moves[1].count);
  EXPECT_GT(growing.plan.moves[2].count, growing.plan.moves[1].count * 3 / 2);
  EXPECT_GT(growing.plan.moves[3].count, growing.plan.moves[2].count * 3 / 2);
  for (size_t i = 1; i < fixed.plan.moves.size(); ++i) {
    EXPECT_LE(fixed.plan.moves[i].count, fixed.plan.moves[i - 1].count) << "fixed fractions of fewer textures";
  }
  // Growing steps reach at least as far. (Here further: the fixed plan stops where a step of
  // a few textures no longer shrinks the compressed file.)
  EXPECT_LE(growing.plan.moves.back().bytes_after, fixed.plan.moves.back().bytes_after);
}

// Ten 4×4 textures (four halvings and 15 removable texels each) and ten 1×1 ones (none).
TexturePool TenByFourAndTenByOne() {
  TexturePool pool;
  for (int i = 0; i < 20; ++i) {
    const uint8_t side = i < 10 ? 4 : 1;
    pool.heights.push_back(side);
    pool.widths.push_back(side);
    pool.axis_u.push_back(0);
    pool.axis_v.push_back(1);
  }
  pool.RebuildOffsets();
  pool.texels.assign(pool.texel_count() * kTexelChannels, 0.0f);
  return pool;
}

TEST(Proposals, HalvingsToSaveCountsRawTexelBytesAtThePoolsAverageHalving) {
  const TexturePool pool = TenByFourAndTenByOne();
  // 150 texels × 4 channels over 40 halvings: 15 bytes a halving in q8, 60 in f32.
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, 100), 7u);
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, 105), 7u);
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, 106), 8u);
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kFloat32, 100), 2u);
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, 1e9), 40u);  // every halving there is
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, 0), 0u);
  EXPECT_EQ(HalvingsToSave(pool, ScalarEncoding::kQuant8, std::nan("")), 0u);
  TexturePool flat = pool;
  for (uint8_t& h : flat.heights) h = 1;
  for (uint8_t& w : flat.widths) w = 1;
  flat.RebuildOffsets();
  EXPECT_EQ(HalvingsToSave(flat, ScalarEncoding::kQuant8, 100), 0u);  // nothing to halve
}

TEST(Proposals, OnlyTheOtherDivisibleLeverEndsAStreak) {
  internal::StepScale scale;
  scale.Taken(Lever::kTextures, 2);
  scale.Taken(Lever::kTextures, 2);
  EXPECT_EQ(scale.textures, 2);  // won twice in a row: the next step is twice as large
  // Moves taken once, between texture steps, leave the streak as it was.
  for (Lever once : {Lever::kEncoding, Lever::kShDegree, Lever::kGrid, Lever::kAllTextures}) {
    scale.Taken(once, 2);
    EXPECT_EQ(scale.textures, 2) << static_cast<int>(once);
  }
  scale.Taken(Lever::kTextures, 2);
  EXPECT_EQ(scale.textures, 4);
  EXPECT_EQ(scale.prune, 1);
  // The other divisible lever ends it, and starts its own.
  scale.Taken(Lever::kPrune, 2);
  EXPECT_EQ(scale.textures, 1);
  EXPECT_EQ(scale.prune, 1);
  scale.Taken(Lever::kEncoding, 2);
  scale.Taken(Lever::kPrune, 3);
  EXPECT_EQ(scale.prune, 3);
  scale.Taken(Lever::kTextures, 2);
  EXPECT_EQ(scale.prune, 1);
  EXPECT_EQ(scale.textures, 1);
}

TEST(Plan, TextureStepsSaveAtLeastTheirShareOfTheBytesToShed) {
  // Textures alone, at fixed fractions of 1 % of the growable textures. Without a floor each
  // step halves one or two axes, and the plan stops after a few moves, far above its floor,
  // where such a step no longer shrinks the compressed file. With a floor each step halves
  // at least what saves an estimated `share` of the bytes between the input and the floor,
  // and the plan reaches it.
  const Asset asset = SmallAsset(container::SyntheticTextures::kMixed, 5);
  auto backend = train::MakeCpuBackend();
  const auto plan_with = [&](double share) {
    ProbeRenderer renderer(backend.get(), OrbitProbes(asset, 4, 40, 30));
    PlanOptions o;
    o.write.write_stats = false;
    o.floor_bytes = *MinimumBytes(asset, o.write, 4, LeverBit(Lever::kTextures));
    o.levers = LeverBit(Lever::kTextures);
    o.texture_fraction = 0.01;
    o.step_growth = 1;
    o.min_texture_step = share;
    auto plan = BuildPlan(asset, &renderer, o);
    EXPECT_TRUE(plan.ok()) << plan.status().ToString();
    return std::make_pair(std::move(*plan), o.floor_bytes);
  };
  const auto [none, floor_bytes] = plan_with(0);
  const Plan floored = plan_with(0.05).first;
  ASSERT_FALSE(none.moves.empty());
  ASSERT_GE(floored.moves.size(), 10u);
  EXPECT_LE(none.moves[0].count, 2u);
  EXPECT_GT(none.moves.back().bytes_after, floor_bytes + (none.initial_bytes - floor_bytes) / 2);
  const double share = 0.05 * static_cast<double>(floored.initial_bytes - floor_bytes);
  EXPECT_EQ(floored.moves[0].count, HalvingsToSave(*asset.textures, ScalarEncoding::kFloat32, share))
      << "the floor sets the first step (the input's texels are f32)";
  uint64_t before = floored.initial_bytes;
  for (const Move& m : floored.moves) {
    EXPECT_LT(m.bytes_after, before);
    before = m.bytes_after;
  }
  EXPECT_LE(floored.moves.back().bytes_after, floor_bytes);
}

TEST(Plan, StepOptionsOutOfRangeAreRefused) {
  const Asset asset = SmallAsset(container::SyntheticTextures::kMixed, 5);
  auto backend = train::MakeCpuBackend();
  ProbeRenderer renderer(backend.get(), OrbitProbes(asset, 2, 20, 20));
  for (double growth : {0.5, 0.0, -2.0, 17.0, std::nan("")}) {
    PlanOptions o;
    o.step_growth = growth;
    EXPECT_EQ(BuildPlan(asset, &renderer, o).status().code(), StatusCode::kInvalidArgument) << growth;
  }
  for (int parallel : {-1, 65}) {
    PlanOptions o;
    o.parallel_candidates = parallel;
    EXPECT_EQ(BuildPlan(asset, &renderer, o).status().code(), StatusCode::kInvalidArgument) << parallel;
  }
  for (double share : {-0.01, 1.5, std::nan("")}) {
    PlanOptions o;
    o.min_texture_step = share;
    EXPECT_EQ(BuildPlan(asset, &renderer, o).status().code(), StatusCode::kInvalidArgument) << share;
  }
}

}  // namespace
}  // namespace atex::fit
