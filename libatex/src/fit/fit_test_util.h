// For the fitter's tests (fit_test.cc, fit_levers_test.cc, fit_run_test.cc, texture_shrink_test.cc):
// a small synthetic asset with SH degree 2, the SH head and the given textures.
#pragma once

#include <cstddef>
#include <cstdint>

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

}  // namespace atex::fit::testing
