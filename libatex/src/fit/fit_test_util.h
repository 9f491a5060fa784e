// For the fitter's tests (fit_test.cc, fit_levers_test.cc, fit_run_test.cc, texture_shrink_test.cc,
// refill_test.cc): a small synthetic asset with SH degree 2, the SH head and the given textures,
// and a plan built for it on the CPU.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>

#include <gtest/gtest.h>

#include "atex/fit.h"
#include "atex/train/backend.h"
#include "container/synthetic_asset.h"

namespace atex::fit::testing {

inline Asset SmallAsset(container::SyntheticTextures textures, uint64_t seed = 3, size_t n = 240) {
  container::SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = n;
  o.sh_degree = 2;
  o.textures = textures;
  o.sh_head = true;
  return container::MakeSyntheticAsset(o);
}

// A plan of SmallAsset(textures, seed) down to its minimum, with its backend and renderer.
// `adjust` changes the plan's options before it is built. The plan's kept states serve the
// fixture's own asset: MakePlan returns its local fixture by name (copy elision keeps the
// asset's address; tests that rely on it check Plan::tail).
struct PlanFixture {
  Asset asset;
  std::unique_ptr<train::Backend> backend;
  std::unique_ptr<ProbeRenderer> renderer;
  Plan plan;
  WriteOptions write;
  uint64_t minimum = 0;
};

inline PlanFixture MakePlan(container::SyntheticTextures textures, uint64_t seed,
                            const std::function<void(PlanOptions*)>& adjust = {}) {
  PlanFixture f;
  f.asset = SmallAsset(textures, seed);
  f.backend = train::MakeCpuBackend();
  f.renderer = std::make_unique<ProbeRenderer>(f.backend.get(), OrbitProbes(f.asset, 4, 40, 30));
  f.write.write_stats = false;
  auto minimum = MinimumBytes(f.asset, f.write);
  EXPECT_TRUE(minimum.ok()) << minimum.status().ToString();
  f.minimum = *minimum;
  PlanOptions o;
  o.write = f.write;
  o.floor_bytes = f.minimum;
  o.prune_fraction = 0.2;
  o.texture_fraction = 0.3;
  if (adjust) adjust(&o);
  auto plan = BuildPlan(f.asset, f.renderer.get(), o);
  EXPECT_TRUE(plan.ok()) << plan.status().ToString();
  f.plan = std::move(*plan);
  return f;
}

}  // namespace atex::fit::testing
