// RunFit (fit_run.h) as the CLI and Python use it: what each output of a run reports.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit_run.h"
#include "container/synthetic_asset.h"
#include "fit/fit_test_util.h"
#include "train/trainer_test_util.h"

namespace atex::fit {
namespace {

// With --keep-count, the plan works on the subset; every output's `kept` must still name input
// Gaussians, the outputs of the other budgets of a list as well as the main one.
TEST(FitRun, EveryOutputsKeptIndicesAreInputIndices) {
  const Asset asset = testing::SmallAsset(container::SyntheticTextures::kNone, 5, 300);
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  FitRunOptions options;
  options.keep_count = 0.6;
  options.budgets = {bytes->size() * 2 / 5, bytes->size() / 2};
  options.levers = LeverBit(Lever::kPrune);  // positions stay exact: a kept Gaussian is found by them
  options.probes = 2;
  options.probe_size = 32;
  auto run = RunFit(*bytes, nullptr, nullptr, options);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  ASSERT_EQ(run->outputs.size(), 2u);
  for (const FitRunOutput& out : run->outputs) {
    const Gaussians& fitted = out.fitted.asset.gaussians;
    ASSERT_EQ(out.fitted.kept.size(), fitted.size()) << "budget " << out.budget_bytes;
    ASSERT_LT(fitted.size(), asset.gaussians.size() * 6 / 10 + 1) << "budget " << out.budget_bytes;
    for (size_t j = 0; j < fitted.size(); ++j) {
      const uint32_t i = out.fitted.kept[j];
      ASSERT_LT(i, asset.gaussians.size());
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(fitted.positions[3 * j + c], asset.gaussians.positions[3 * i + c])
            << "budget " << out.budget_bytes << ": Gaussian " << j << " is not input Gaussian " << i;
      }
    }
  }
}

// The input's test evaluation may run beside the plan on a second backend
// (FitRunOptions::input_eval_backend): the report and the output must be those of a run that
// evaluates it first, on the run's own backend. The run's backend itself is refused as the second.
TEST(FitRun, TheInputsEvaluationBesideThePlanGivesTheSameReport) {
  const Asset asset = testing::SmallAsset(container::SyntheticTextures::kMixed, 5, 200);
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  const std::unique_ptr<Dataset> dataset = train::MovingBall();
  FitRunOptions options;
  options.budgets = {bytes->size() / 3};
  options.probes = 2;
  options.probe_size = 24;
  const auto run_with = [&](train::Backend* input_eval_backend) {
    auto backend = train::MakeCpuBackend();
    FitRunOptions o = options;
    o.input_eval_backend = input_eval_backend;
    return RunFit(*bytes, dataset.get(), backend.get(), o);
  };
  auto first = run_with(nullptr);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  auto second_backend = train::MakeCpuBackend();
  auto beside = run_with(second_backend.get());
  ASSERT_TRUE(beside.ok()) << beside.status().ToString();
  ASSERT_TRUE(first->json["input"].contains("test"));
  EXPECT_EQ(beside->json["input"]["test"], first->json["input"]["test"]);
  EXPECT_EQ(beside->json["output"]["test"], first->json["output"]["test"]);
  EXPECT_EQ(beside->outputs.at(0).fitted.bytes, first->outputs.at(0).fitted.bytes);
  EXPECT_TRUE(beside->json["input"].contains("test_seconds_beside_plan"));
  EXPECT_FALSE(first->json["input"].contains("test_seconds_beside_plan"));

  auto backend = train::MakeCpuBackend();
  FitRunOptions same = options;
  same.input_eval_backend = backend.get();
  EXPECT_EQ(RunFit(*bytes, dataset.get(), backend.get(), same).status().code(), StatusCode::kInvalidArgument);
}

// Every output, the main one included, carries its own report (fit_run.h), and the run's
// --json report takes the main output's fields from it.
TEST(FitRun, EveryOutputReportsItsSizeLeversAndEstimate) {
  const Asset asset = testing::SmallAsset(container::SyntheticTextures::kMixed, 5, 200);
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  FitRunOptions options;
  options.budgets = {bytes->size() / 2, bytes->size() / 3, bytes->size() * 2};
  options.probes = 2;
  options.probe_size = 24;
  auto run = RunFit(*bytes, nullptr, nullptr, options);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  ASSERT_EQ(run->outputs.size(), 3u);
  EXPECT_EQ(run->main_budget_index, 1u);
  for (const FitRunOutput& out : run->outputs) {
    EXPECT_EQ(out.report["budget_bytes"], out.budget_bytes);
    EXPECT_EQ(out.report["bytes"], out.fitted.bytes.size());
    EXPECT_LE(out.fitted.bytes.size(), out.budget_bytes);
    EXPECT_TRUE(out.report.contains("levers") && out.report.contains("components"));
    ASSERT_TRUE(out.report.contains("estimated_psnr_vs_input")) << out.report.dump();
  }
  // The budget above the input's size takes no move: its estimate is the plan's start (the
  // input as re-encoded), the best there is.
  const FitRunOutput& roomy = run->outputs[2];
  EXPECT_TRUE(roomy.fitted.moves.empty());
  EXPECT_GE(roomy.report["estimated_psnr_vs_input"].get<double>(),
            run->outputs[0].report["estimated_psnr_vs_input"].get<double>());
  const FitRunOutput& main = run->outputs[0];
  EXPECT_EQ(run->json["estimated_psnr_vs_input"], main.report["estimated_psnr_vs_input"]);
  EXPECT_EQ(run->json["levers"]["encodings"], main.report["levers"]["encodings"]);
  EXPECT_EQ(run->json["output"]["components"], main.report["components"]);
}

// FitRunOptions::cancelled is asked after each move: true ends the run with kCancelled.
TEST(FitRun, ACancelledRunStopsAfterTheMoveItWasAskedAt) {
  const Asset asset = testing::SmallAsset(container::SyntheticTextures::kMixed, 5, 200);
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  FitRunOptions options;
  options.budgets = {bytes->size() / 3};
  options.probes = 2;
  options.probe_size = 24;
  int moves = 0, asked = 0;
  options.progress = [&](const FitProgress&) { ++moves; };
  options.cancelled = [&] { return ++asked == 2; };
  auto run = RunFit(*bytes, nullptr, nullptr, options);
  EXPECT_EQ(run.status().code(), StatusCode::kCancelled) << run.status().ToString();
  EXPECT_EQ(moves, 2);
  EXPECT_EQ(asked, 2);
  for (double step : {-0.1, 1.5, std::nan("")}) {
    FitRunOptions o = options;
    o.cancelled = nullptr;
    o.min_texture_step = step;
    EXPECT_EQ(RunFit(*bytes, nullptr, nullptr, o).status().code(), StatusCode::kInvalidArgument) << step;
  }
}

}  // namespace
}  // namespace atex::fit
