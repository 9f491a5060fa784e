// RunFit (fit_run.h) as the CLI and Python use it: what each output of a run reports.
#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit_run.h"
#include "container/synthetic_asset.h"
#include "fit/fit_test_util.h"

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

}  // namespace
}  // namespace atex::fit
