// Shared inputs of the benchmarks: the deformation fields are the trainer's documented
// defaults per dataset kind (train::DefaultConfig), so the benchmarks measure what
// `atex train` builds; the synthetic models are trained-model-sized assets.
#pragma once

#include "atex/model.h"
#include "atex/train/config.h"
#include "container/synthetic_asset.h"

inline atex::DeformationConfig DatasetDeformation(const char* dataset_kind) {
  const atex::train::TrainConfig config = atex::train::DefaultConfig(dataset_kind);
  atex::DeformationConfig c = config.stage1.deformation;
  // The trainer sets the SH width from the Gaussians; only an enabled SH head needs it.
  c.sh_coeffs = c.heads[atex::kHeadSH] ? atex::ShCoeffCount(config.stage1.sh_degree) : 1;
  return c;
}

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
