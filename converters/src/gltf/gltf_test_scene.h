// Small deterministic assets and GLB plumbing for the glTF tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/model.h"

namespace atex::testing {

struct SceneSpec {
  size_t count = 50;
  int sh_degree = 2;
  bool textures = true;
  bool deformation = true;
  uint64_t seed = 1;
};

// Random Gaussians (unnormalised rotations, log-scales around -3, logits in [-3, 3]),
// optional random texture layouts/texels and an initialised deformation field whose
// heads are given non-trivial weights. metadata.axes = "opencv".
Asset MakeTestAsset(const SceneSpec& spec);

// Splits a GLB into its JSON and BIN chunks (test-side, independent of the library).
struct GlbParts {
  nlohmann::json json;
  std::vector<uint8_t> bin;
};
GlbParts SplitGlb(const std::vector<uint8_t>& glb);
std::vector<uint8_t> JoinGlb(const nlohmann::json& json, const std::vector<uint8_t>& bin);

// Reads accessor `index` of a plain (uncompressed) GLB as floats [count][components]
// by following the JSON by hand. Float components only.
std::vector<float> ReadFloatAccessor(const GlbParts& glb, int index);

// Bitwise equality of float arrays (NaN-safe, -0 != +0).
bool SameBits(const std::vector<float>& a, const std::vector<float>& b);

}  // namespace atex::testing
