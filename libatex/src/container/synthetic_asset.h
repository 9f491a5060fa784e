// Deterministic synthetic assets for tests, benchmarks, fuzz seeds and the demo
// sample. The same options give the same floats on every platform: the random
// numbers come from splitmix64 and use only +, -, *, / and sqrt.
#pragma once

#include <cstddef>
#include <cstdint>

#include "atex/model.h"

namespace atex::container {

enum class SyntheticTextures {
  kNone,
  kUniform,      // every Gaussian uniform_h x uniform_w
  kMixed,        // sides drawn from {1, 2, 4}, square and anisotropic
};

struct SyntheticAssetOptions {
  uint64_t seed = 1;
  size_t gaussians = 1000;
  int sh_degree = 3;
  SyntheticTextures textures = SyntheticTextures::kMixed;
  int uniform_h = 4, uniform_w = 4;
  bool deformation = true;
  // Deformation size: small by default; D-NeRF's (C 32, 64^3 x 25, multires 1, 2,
  // width 64) when realistic_deformation is set.
  bool realistic_deformation = false;
  bool sh_head = false;  // enable the SH head (and the opacity head)
  bool stats = true;
};

Asset MakeSyntheticAsset(const SyntheticAssetOptions& options);

}  // namespace atex::container
