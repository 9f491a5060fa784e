// The synthetic models of the CPU benchmarks: trained-model-sized assets (needs
// libatex/src on the include path, as bench/CMakeLists.txt gives the CPU benchmarks).
#pragma once

#include "atex/model.h"
#include "container/synthetic_asset.h"

// A synthetic model with SH degree 3, a D-NeRF-sized deformation field and statistics.
inline atex::Asset SyntheticModel(size_t gaussians, atex::container::SyntheticTextures textures, uint64_t seed) {
  atex::container::SyntheticAssetOptions o;
  o.seed = seed;
  o.gaussians = gaussians;
  o.sh_degree = 3;
  o.textures = textures;
  o.deformation = true;
  o.realistic_deformation = true;
  o.stats = true;
  return atex::container::MakeSyntheticAsset(o);
}
