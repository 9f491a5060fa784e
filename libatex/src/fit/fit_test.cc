// The budget fitter: plans, budgets and the refill below an indivisible move.
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
#include "fit/count_search.h"
#include "fit/fit_test_util.h"
#include "fit/levers.h"
#include "fit/texture_shrink.h"

namespace atex::fit {
namespace {

using testing::MakePlan;
using testing::PlanFixture;
using testing::SmallAsset;

TEST(Plan, UsesEveryLeverAndShrinksMonotonically) {
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 5);
  ASSERT_FALSE(f.plan.moves.empty());
  std::set<Lever> used;
  uint64_t previous = f.plan.initial_bytes;
  for (const Move& m : f.plan.moves) {
    used.insert(m.lever);
    EXPECT_LT(m.bytes_after, previous) << DescribeMove(m);
    previous = m.bytes_after;
  }
  for (Lever l : {Lever::kPrune, Lever::kTextures, Lever::kShDegree, Lever::kEncoding, Lever::kGrid}) {
    EXPECT_TRUE(used.count(l)) << "lever " << LeverName(l) << " never chosen";
  }
  // The plan reaches within a few percent of the smallest valid asset.
  EXPECT_LE(f.plan.moves.back().bytes_after, f.minimum * 11 / 10 + 512);
  // Every accepted move was measured (plus the initial state), and the measured parts took time.
  const MeasureTiming& t = f.plan.timing;
  EXPECT_GE(t.measurements, static_cast<int>(f.plan.moves.size()) + 1);
  EXPECT_GT(t.render_seconds, 0.0);
  EXPECT_GT(t.encode_seconds, 0.0);
  const nlohmann::json j = TimingToJson(t);
  EXPECT_EQ(j["measurements"], t.measurements);
  EXPECT_DOUBLE_EQ(j["seconds_per_measurement"]["render"].get<double>(), t.render_seconds / t.measurements);
  // The whole plan's time covers its measured parts; "other" is the rest, never negative.
  EXPECT_GT(t.reference_seconds, 0.0);
  EXPECT_GT(t.propose_seconds, 0.0);
  EXPECT_GE(t.total_seconds, t.apply_seconds + t.encode_seconds + t.decode_seconds + t.render_seconds +
                                 t.distortion_seconds + t.reference_seconds + t.propose_seconds -
                                 t.overlap_seconds);
  EXPECT_GE(j["seconds"]["other"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(j["seconds"]["total"].get<double>(), t.total_seconds);
}

TEST(Plan, ThousandRandomBudgetsNeverOver) {
  for (auto textures : {container::SyntheticTextures::kMixed, container::SyntheticTextures::kNone}) {
    PlanFixture f = MakePlan(textures, 11);
    const uint64_t lo = f.plan.moves.back().bytes_after, hi = f.plan.initial_bytes + 100;
    std::mt19937_64 rng(textures == container::SyntheticTextures::kNone ? 1 : 2);
    for (int trial = 0; trial < 500; ++trial) {
      const uint64_t budget = lo + rng() % (hi - lo + 1);
      auto fitted = ApplyPlan(f.asset, f.plan, f.write, budget);
      ASSERT_TRUE(fitted.ok()) << budget << ": " << fitted.status().ToString();
      ASSERT_LE(fitted->bytes.size(), budget);
      // Valid: it decodes (a full reader pass) and validates.
      auto decoded = DecodeAsset(fitted->bytes.data(), fitted->bytes.size());
      ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
      ASSERT_TRUE(ValidateAsset(*decoded).ok());
      ASSERT_EQ(fitted->kept.size(), decoded->gaussians.size());
    }
    // Below what the plan reaches but not below the minimum: the levers' smallest asset.
    if (f.minimum < lo) {
      auto smallest = ApplyPlan(f.asset, f.plan, f.write, lo - 1);
      ASSERT_TRUE(smallest.ok()) << smallest.status().ToString();
      EXPECT_TRUE(smallest->smallest_fallback);
      EXPECT_EQ(smallest->bytes.size(), f.minimum);
    }
    // Below both: a clear error naming both sizes, never an oversized file.
    auto too_small = ApplyPlan(f.asset, f.plan, f.write, std::min(lo, f.minimum) - 1);
    EXPECT_FALSE(too_small.ok());
    EXPECT_NE(too_small.status().message().find(std::to_string(lo)), std::string::npos);
    EXPECT_NE(too_small.status().message().find(std::to_string(f.minimum)), std::string::npos);
  }
}

// ApplyPlan reuses the plan's texture residuals (Plan::texture_memo) for its replays; the
// memo only saves time: without it (null, or a fresh one) every budget gets the same file.
TEST(Plan, ThePlansTextureMemoGivesTheSameFits) {
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 11);
  ASSERT_NE(f.plan.texture_memo, nullptr);
  Plan without = f.plan;
  without.texture_memo = nullptr;
  const uint64_t lo = f.plan.moves.back().bytes_after, hi = f.plan.initial_bytes;
  std::mt19937_64 rng(3);
  int refilled = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const uint64_t budget = lo + rng() % (hi - lo + 1);
    auto with_memo = ApplyPlan(f.asset, f.plan, f.write, budget);
    auto plain = ApplyPlan(f.asset, without, f.write, budget);
    ASSERT_TRUE(with_memo.ok()) << with_memo.status().ToString();
    ASSERT_TRUE(plain.ok()) << plain.status().ToString();
    EXPECT_EQ(with_memo->bytes, plain->bytes) << budget;
    refilled += with_memo->refill_seconds > 0;
  }
  EXPECT_GT(refilled, 0);  // the refill's replays used the memo too
}

// A greedy plan can stop above MinimumBytes: near the end, removing one more Gaussian may not
// shrink the compressed file, so no move saves bytes (the sample asset's plan stopped at 7,672
// bytes against a minimum of 7,616, and a 7,665-byte budget that CheckBudget accepted was
// refused). Every budget from the minimum up must still be met. A plan cut in half stands in
// for a search that stopped early.
TEST(Plan, BudgetsBetweenTheMinimumAndThePlansEndGetTheSmallestAsset) {
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 29);
  ASSERT_GE(f.plan.moves.size(), 4u);
  Plan short_plan = f.plan;
  short_plan.moves.resize(short_plan.moves.size() / 2);
  const uint64_t end = short_plan.moves.back().bytes_after;
  ASSERT_GT(end, f.minimum + 64);
  for (const uint64_t budget : {f.minimum, f.minimum + 1, (f.minimum + end) / 2, end - 1}) {
    auto fitted = ApplyPlan(f.asset, short_plan, f.write, budget);
    ASSERT_TRUE(fitted.ok()) << budget << ": " << fitted.status().ToString();
    EXPECT_TRUE(fitted->smallest_fallback);
    EXPECT_EQ(fitted->plan_end_bytes, end);
    EXPECT_TRUE(fitted->moves.empty());
    EXPECT_EQ(fitted->bytes.size(), f.minimum);
    ASSERT_EQ(fitted->kept.size(), 1u) << "one Gaussian, the most important";
    EXPECT_EQ(fitted->asset.gaussians.size(), 1u);
    EXPECT_EQ(fitted->asset.gaussians.sh_degree, 0);
    auto decoded = DecodeAsset(fitted->bytes.data(), fitted->bytes.size());
    ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
    EXPECT_TRUE(ValidateAsset(*decoded).ok());
  }
  // At the plan's end the plan itself is applied, not the fallback.
  auto at_end = ApplyPlan(f.asset, short_plan, f.write, end);
  ASSERT_TRUE(at_end.ok()) << at_end.status().ToString();
  EXPECT_FALSE(at_end->smallest_fallback);
  EXPECT_FALSE(at_end->moves.empty());
}

TEST(Plan, SmallerBudgetsNeverReduceDistortion) {
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 17);
  // Distortion measured independently of the plan's own bookkeeping.
  auto reference = f.renderer->Render(f.asset);
  ASSERT_TRUE(reference.ok());
  double previous = -1;
  const uint64_t lo = f.plan.moves.back().bytes_after;
  for (int k = 10; k >= 0; --k) {
    const uint64_t budget = lo + (f.plan.initial_bytes - lo) * k / 10;
    auto fitted = ApplyPlan(f.asset, f.plan, f.write, budget);
    ASSERT_TRUE(fitted.ok());
    auto renders = f.renderer->Render(fitted->asset);
    ASSERT_TRUE(renders.ok());
    const double mse = *MeanSquaredError(*renders, *reference);
    // Greedy prefixes: a move may rarely help by chance; allow 2% slack on the way down.
    EXPECT_GE(mse, previous * 0.98 - 1e-9) << "budget " << budget;
    previous = std::max(previous, mse);
  }
}

TEST(Plan, ALastMoveCutToTheBudgetReportsAnInterpolatedDistortion) {
  // Prune alone: every move divisible, so a budget inside a move's bytes cuts that move.
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 17,
                           [](PlanOptions* o) { o->levers = LeverBit(Lever::kPrune); });
  ASSERT_GE(f.plan.moves.size(), 3u);
  int cut = 0;
  for (size_t j = 1; j < f.plan.moves.size(); ++j) {
    const Move& whole = f.plan.moves[j];
    const Move& before = f.plan.moves[j - 1];
    const uint64_t budget = (before.bytes_after + whole.bytes_after) / 2;
    auto fitted = ApplyPlan(f.asset, f.plan, f.write, budget);
    ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
    ASSERT_EQ(fitted->moves.size(), j + 1);
    const Move& last = fitted->moves.back();
    for (size_t k = 0; k < j; ++k) EXPECT_EQ(fitted->moves[k].distortion_after, f.plan.moves[k].distortion_after);
    if (last.count == whole.count) {
      EXPECT_EQ(last.distortion_after, whole.distortion_after) << j;
      continue;
    }
    ++cut;
    EXPECT_LT(last.count, whole.count);
    const double expected = before.distortion_after + (whole.distortion_after - before.distortion_after) *
                                                          static_cast<double>(last.count) /
                                                          static_cast<double>(whole.count);
    EXPECT_DOUBLE_EQ(last.distortion_after, expected) << j;
    EXPECT_LT(last.distortion_after, whole.distortion_after) << "the whole move's distortion, not the cut one's";
  }
  EXPECT_GT(cut, 0);
}

// The encoded size after replaying `moves` on `asset` in order, as ApplyPlan does.
uint64_t SizeAfter(const Asset& asset, const Plan& plan, const WriteOptions& write, const std::vector<Move>& moves) {
  Asset a = asset;
  WriteOptions w = write;
  std::vector<uint32_t> kept(a.gaussians.size());
  std::iota(kept.begin(), kept.end(), 0u);
  for (const Move& m : moves) {
    const Status applied = ApplyMove(m, plan.prune_order, &a, &w, &kept);
    EXPECT_TRUE(applied.ok()) << DescribeMove(m) << ": " << applied.ToString();
    if (!applied.ok()) return std::numeric_limits<uint64_t>::max();
  }
  auto bytes = EncodeAsset(a, w);
  EXPECT_TRUE(bytes.ok()) << bytes.status().ToString();
  return bytes.ok() ? bytes->size() : std::numeric_limits<uint64_t>::max();
}

// `moves` with the count of the latest divisible one lowered by one unit (the move dropped
// at 0); nullopt when no move is divisible.
std::optional<std::vector<Move>> OneUnitLessOfLatestDivisible(std::vector<Move> moves) {
  for (size_t i = moves.size(); i-- > 0;) {
    if (!moves[i].divisible()) continue;
    if (--moves[i].count == 0) moves.erase(moves.begin() + static_cast<std::ptrdiff_t>(i));
    return moves;
  }
  return std::nullopt;
}

TEST(Plan, SlackBelowAnIndivisibleMoveReachesEarlierDivisibleMoves) {
  // A hand-made plan: a large prune, two small prunes, then sh_rest to q8 (indivisible, and
  // worth far more bytes than both small prunes). With the budget between the sizes after
  // the second small prune and after the encoding, the encoding is the last move replayed;
  // undoing both small prunes entirely still leaves slack that only undoing part of the
  // large prune can spend.
  Asset asset = SmallAsset(container::SyntheticTextures::kNone, 53);
  WriteOptions write;
  write.write_stats = false;
  Plan plan;
  plan.prune_order = ImportanceOrder(asset, 6666);
  const auto prune = [](uint64_t count) {
    Move m;
    m.lever = Lever::kPrune;
    m.count = count;
    return m;
  };
  Move sh_rest_q8;
  sh_rest_q8.lever = Lever::kEncoding;
  sh_rest_q8.stream = Stream::kShRest;
  sh_rest_q8.encoding = ScalarEncoding::kQuant8;
  const Move big = prune(150);
  plan.moves = {big, prune(5), prune(5), sh_rest_q8};
  plan.initial_bytes = SizeAfter(asset, plan, write, {});
  for (size_t i = 0; i < plan.moves.size(); ++i) {
    plan.moves[i].bytes_after = SizeAfter(asset, plan, write, {plan.moves.begin(), plan.moves.begin() + i + 1});
    plan.moves[i].distortion_after = 0.01 * static_cast<double>(i + 1);  // estimates, to be kept as they are
  }
  // What the single-move refill gave: the last small prune undone, and nothing more.
  const uint64_t single_refill = SizeAfter(asset, plan, write, {plan.moves[0], plan.moves[1], plan.moves[3]});
  const uint64_t both_undone = SizeAfter(asset, plan, write, {big, sh_rest_q8});
  const uint64_t all_undone = SizeAfter(asset, plan, write, {sh_rest_q8});
  const uint64_t after_small = plan.moves[2].bytes_after;
  const uint64_t budget = both_undone + (after_small - both_undone) / 2;
  // The case is the one described above.
  ASSERT_LT(plan.moves[3].bytes_after, single_refill);
  ASSERT_LT(single_refill, both_undone);
  ASSERT_LT(both_undone + 2, after_small);
  ASSERT_LT(budget, after_small) << "the encoding is the move that crosses the budget";
  ASSERT_LT(budget, all_undone) << "the budget binds inside the large prune";

  auto fitted = ApplyPlan(asset, plan, write, budget);
  ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
  EXPECT_LE(fitted->bytes.size(), budget);
  EXPECT_GT(fitted->bytes.size(), both_undone) << "the slack left by undoing the small prunes is spent";
  // This fit refilled, inside ApplyPlan's time.
  EXPECT_GT(fitted->refill_seconds, 0.0);
  EXPECT_GE(fitted->apply_seconds, fitted->refill_seconds);
  // Both small prunes are gone and the large one is partly undone.
  ASSERT_EQ(fitted->moves.size(), 2u);
  EXPECT_EQ(fitted->moves[0].lever, Lever::kPrune);
  EXPECT_GT(fitted->moves[0].count, 0u);
  EXPECT_LT(fitted->moves[0].count, big.count);
  EXPECT_EQ(fitted->moves[1].lever, Lever::kEncoding);
  EXPECT_EQ(fitted->asset.gaussians.size(), asset.gaussians.size() - fitted->moves[0].count);
  // No unit of slack left: one Gaussian fewer pruned would not fit.
  auto one_less = OneUnitLessOfLatestDivisible(fitted->moves);
  ASSERT_TRUE(one_less.has_value());
  EXPECT_GT(SizeAfter(asset, plan, write, *one_less), budget);
  // The recorded sizes are the real ones; the distortions stay the plan's estimates.
  for (size_t i = 0; i < fitted->moves.size(); ++i) {
    EXPECT_EQ(fitted->moves[i].bytes_after,
              SizeAfter(asset, plan, write, {fitted->moves.begin(), fitted->moves.begin() + i + 1}))
        << i;
  }
  EXPECT_EQ(fitted->moves.back().bytes_after, fitted->bytes.size());
  EXPECT_EQ(fitted->moves[0].distortion_after, plan.moves[0].distortion_after);
  EXPECT_EQ(fitted->moves[1].distortion_after, plan.moves[3].distortion_after);
  // Valid: it decodes (a full reader pass) and validates.
  auto decoded = DecodeAsset(fitted->bytes.data(), fitted->bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_TRUE(ValidateAsset(*decoded).ok());
  EXPECT_EQ(fitted->kept.size(), decoded->gaussians.size());
}

TEST(Plan, SlackIsSpentOnAnEarlierIndivisibleMoveThatFits) {
  // sh_dc to q8 (A), rotations to q16 (B), then sh_rest to q8 (C, crossing the budget and
  // landing far below it). Without B the output still fits; without A as well it would not:
  // B is undone (the latest first), A is kept.
  Asset asset = SmallAsset(container::SyntheticTextures::kNone, 59);
  WriteOptions write;
  write.write_stats = false;
  const auto encoding = [](Stream stream, ScalarEncoding e) {
    Move m;
    m.lever = Lever::kEncoding;
    m.stream = stream;
    m.encoding = e;
    return m;
  };
  const Move a = encoding(Stream::kShDc, ScalarEncoding::kQuant8);
  const Move b = encoding(Stream::kRotations, ScalarEncoding::kQuant16);
  const Move c = encoding(Stream::kShRest, ScalarEncoding::kQuant8);
  Plan plan;
  plan.prune_order = ImportanceOrder(asset, 6666);
  plan.moves = {a, b, c};
  plan.initial_bytes = SizeAfter(asset, plan, write, {});
  for (size_t i = 0; i < plan.moves.size(); ++i) {
    plan.moves[i].bytes_after = SizeAfter(asset, plan, write, {plan.moves.begin(), plan.moves.begin() + i + 1});
  }
  const uint64_t without_b = SizeAfter(asset, plan, write, {a, c});
  const uint64_t only_c = SizeAfter(asset, plan, write, {c});
  const uint64_t budget = without_b + (only_c - without_b) / 2;
  ASSERT_LT(plan.moves[2].bytes_after, without_b);
  ASSERT_LT(without_b, budget);
  ASSERT_LT(budget, only_c);
  ASSERT_LT(budget, plan.moves[1].bytes_after) << "C is the move that crosses the budget";

  auto fitted = ApplyPlan(asset, plan, write, budget);
  ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
  EXPECT_EQ(fitted->bytes.size(), without_b);
  ASSERT_EQ(fitted->moves.size(), 2u);
  EXPECT_EQ(fitted->moves[0].stream, Stream::kShDc);
  EXPECT_EQ(fitted->moves[1].stream, Stream::kShRest);
  EXPECT_EQ(fitted->write.rotations, write.rotations) << "B undone: rotations keep their starting encoding";
  EXPECT_EQ(fitted->moves.back().bytes_after, fitted->bytes.size());
  auto decoded = DecodeAsset(fitted->bytes.data(), fitted->bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_TRUE(ValidateAsset(*decoded).ok());
}

TEST(Plan, NoUnitOfSlackLeftBelowAnIndivisibleLastMove) {
  // Real plans, random budgets: whenever the fit ends on an indivisible move, either less than
  // EnoughSlack of the budget is left unused (the refill stops there), or one unit less of the
  // latest divisible move applied (one Gaussian, one texture axis) would not fit.
  int refilled = 0;
  for (auto textures : {container::SyntheticTextures::kMixed, container::SyntheticTextures::kNone}) {
    PlanFixture f = MakePlan(textures, 11);
    const uint64_t lo = f.plan.moves.back().bytes_after, hi = f.plan.initial_bytes;
    std::mt19937_64 rng(textures == container::SyntheticTextures::kNone ? 3 : 4);
    for (int trial = 0; trial < 150; ++trial) {
      const uint64_t budget = lo + rng() % (hi - lo);
      auto fitted = ApplyPlan(f.asset, f.plan, f.write, budget);
      ASSERT_TRUE(fitted.ok()) << budget << ": " << fitted.status().ToString();
      ASSERT_LE(fitted->bytes.size(), budget);
      if (fitted->moves.empty() || fitted->moves.back().divisible()) continue;
      auto one_less = OneUnitLessOfLatestDivisible(fitted->moves);
      if (!one_less) continue;
      ++refilled;
      if (budget - fitted->bytes.size() < internal::EnoughSlack(budget)) continue;
      EXPECT_GT(SizeAfter(f.asset, f.plan, f.write, *one_less), budget)
          << "budget " << budget << ": " << fitted->bytes.size() << " bytes";
    }
  }
  EXPECT_GE(refilled, 3) << "too few budgets end on an indivisible move to test anything";
}

// Draco positions are not read back (container/read_back.h): their candidates are encoded and
// decoded, and the plan and its application work as with any other write options.
TEST(Plan, DracoPositionsAreMeasuredThroughTheirFile) {
  if (!HaveDracoCodec()) GTEST_SKIP() << "this build has no Draco";
  PlanFixture f = MakePlan(container::SyntheticTextures::kMixed, 29,
                           [](PlanOptions* o) { o->write.draco_positions = true; });
  ASSERT_FALSE(f.plan.moves.empty());
  WriteOptions draco = f.write;
  draco.draco_positions = true;
  const uint64_t budget = f.plan.moves.back().bytes_after;
  auto fitted = ApplyPlan(f.asset, f.plan, draco, budget);
  ASSERT_TRUE(fitted.ok()) << fitted.status().ToString();
  EXPECT_LE(fitted->bytes.size(), budget);
  EXPECT_TRUE(DecodeAsset(fitted->bytes.data(), fitted->bytes.size(), {}).ok());
}

TEST(Plan, BudgetBelowTheMinimumIsNamed) {
  Asset a = SmallAsset(container::SyntheticTextures::kMixed, 23);
  WriteOptions w;
  auto minimum = MinimumBytes(a, w);
  ASSERT_TRUE(minimum.ok());
  EXPECT_GT(*minimum, 100u);
  // The minimum itself is a valid asset: one Gaussian, degree 0, 1x1 textures, q8.
  auto backend = train::MakeCpuBackend();
  ProbeRenderer renderer(backend.get(), OrbitProbes(a, 2, 16, 12));
  PlanOptions o;
  o.write = w;
  o.floor_bytes = *minimum;
  o.prune_fraction = 0.5;
  o.texture_fraction = 1.0;
  auto plan = BuildPlan(a, &renderer, o);
  ASSERT_TRUE(plan.ok());
  EXPECT_LE(plan->moves.back().bytes_after, *minimum) << "the plan reaches the minimum";
  // Below it: kBudgetTooSmall naming the minimum; at it: fine.
  const Status below = CheckBudget(a, w, *minimum - 1);
  EXPECT_EQ(below.code(), StatusCode::kBudgetTooSmall);
  EXPECT_NE(below.message().find(std::to_string(*minimum)), std::string::npos) << below.ToString();
  EXPECT_TRUE(CheckBudget(a, w, *minimum).ok());
}

}  // namespace
}  // namespace atex::fit
