// The fitter on a 4D asset with time-local Gaussians (model.h time_windows): the fitted file keeps
// each kept Gaussian's window (the prune lever's subsets carry them) and is never over budget.
#include <map>
#include <tuple>

#include <gtest/gtest.h>

#include "atex/container.h"
#include "atex/fit_run.h"
#include "container/synthetic_asset.h"

namespace atex::fit {
namespace {

TEST(FitTimeWindows, PrunedFilesKeepTheWindowsOfTheGaussiansTheyKeep) {
  container::SyntheticAssetOptions o;
  o.seed = 11;
  o.gaussians = 300;
  o.sh_degree = 1;
  o.textures = container::SyntheticTextures::kNone;
  Asset asset = container::MakeSyntheticAsset(o);
  Gaussians& g = asset.gaussians;
  g.time_windows.assign(2 * g.size(), 0.0f);
  for (size_t i = 0; i < g.size(); i += 3) {  // a third of them time-local, with distinct windows
    g.time_windows[2 * i] = 0.01f * float(i % 100);
    g.time_windows[2 * i + 1] = 20.0f + float(i);
  }
  auto bytes = EncodeAsset(asset, {});
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  FitRunOptions options;
  options.budgets = {bytes->size() / 2};
  options.levers = LeverBit(Lever::kPrune);
  options.probes = 2;
  options.probe_size = 32;
  auto run = RunFit(*bytes, nullptr, nullptr, options);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  const FitRunOutput& out = run->outputs[0];
  EXPECT_LE(out.fitted.bytes.size(), options.budgets[0]);
  const Gaussians& kept = out.fitted.asset.gaussians;
  ASSERT_LT(kept.size(), g.size());
  ASSERT_EQ(kept.time_windows.size(), 2 * kept.size());
  // Every kept Gaussian is an input Gaussian (same position) with the input's window.
  std::map<std::tuple<float, float, float>, size_t> input_of;
  for (size_t i = 0; i < g.size(); ++i)
    input_of[{g.positions[3 * i], g.positions[3 * i + 1], g.positions[3 * i + 2]}] = i;
  size_t matched = 0;
  for (size_t j = 0; j < kept.size(); ++j) {
    const auto it = input_of.find({kept.positions[3 * j], kept.positions[3 * j + 1], kept.positions[3 * j + 2]});
    if (it == input_of.end()) continue;  // a re-quantised position (the encoding lever is off: not expected)
    ++matched;
    EXPECT_EQ(kept.time_windows[2 * j], g.time_windows[2 * it->second]) << "Gaussian " << j;
    EXPECT_EQ(kept.time_windows[2 * j + 1], g.time_windows[2 * it->second + 1]) << "Gaussian " << j;
  }
  EXPECT_EQ(matched, kept.size());
  auto decoded = DecodeAsset(out.fitted.bytes.data(), out.fitted.bytes.size());
  ASSERT_TRUE(decoded.ok()) << decoded.status().ToString();
  EXPECT_EQ(decoded->gaussians.time_windows, kept.time_windows);
}

}  // namespace
}  // namespace atex::fit
