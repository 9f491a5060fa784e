// The scene side of glTF import: which KHR_gaussian_splatting primitives the default scene
// reaches, and the world transform of each (node matrices or TRS, multiplied down the tree).
#pragma once

#ifdef ATEX_HAVE_TINYGLTF
#include <array>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/status.h"
#include "gltf/tinygltf_config.h"

namespace atex::gltf {

using Mat4 = std::array<double, 16>;  // column-major, as glTF's node.matrix

constexpr Mat4 kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

// One KHR_gaussian_splatting primitive and where it sits in the scene.
struct SplatPrimitive {
  size_t mesh = 0, primitive = 0;
  Mat4 world = kIdentity;
};

// Every splat primitive reachable from the default scene (or from all root nodes when the file
// has no scene), with its node's world transform, in depth-first order. Cycles and shared subtrees
// are refused (glTF requires nodes to form disjoint trees), as are non-finite or malformed
// transforms; errors name the node.
StatusOr<std::vector<SplatPrimitive>> FindSplatPrimitives(const tinygltf::Model& model, const nlohmann::json& doc);

}  // namespace atex::gltf
#endif
