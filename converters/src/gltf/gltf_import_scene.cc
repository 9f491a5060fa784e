// The scene side of glTF import (gltf_import_scene.h): node transforms and the traversal that
// finds the splat primitives. Split from gltf_import.cc.
#include "gltf/gltf_import_scene.h"

#ifdef ATEX_HAVE_TINYGLTF
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "gltf/gltf_names.h"

namespace atex::gltf {
namespace {

using nlohmann::json;

Mat4 Multiply(const Mat4& a, const Mat4& b) {
  Mat4 out{};
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + r] * b[c * 4 + k];
      out[c * 4 + r] = s;
    }
  }
  return out;
}

StatusOr<Mat4> NodeMatrix(const tinygltf::Node& node, size_t index) {
  const std::string where = StrCat("nodes[", index, "]");
  for (const auto* v : {&node.matrix, &node.translation, &node.rotation, &node.scale}) {
    for (double x : *v) {
      if (!std::isfinite(x)) return MakeError(StatusCode::kOutOfRange, where, " has a non-finite transform value");
    }
  }
  if (node.matrix.size() == 16) {
    Mat4 m;
    std::copy(node.matrix.begin(), node.matrix.end(), m.begin());
    return m;
  }
  if (!node.matrix.empty())
    return MakeError(StatusCode::kCorrupt, where, ".matrix has ", node.matrix.size(), " values");
  double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
  if (!node.translation.empty()) {
    if (node.translation.size() != 3) return MakeError(StatusCode::kCorrupt, where, ".translation is not 3 numbers");
    std::copy(node.translation.begin(), node.translation.end(), t);
  }
  if (!node.rotation.empty()) {
    if (node.rotation.size() != 4) return MakeError(StatusCode::kCorrupt, where, ".rotation is not 4 numbers");
    std::copy(node.rotation.begin(), node.rotation.end(), q);
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(n > 0)) return MakeError(StatusCode::kCorrupt, where, ".rotation is a zero quaternion");
    for (double& x : q) x /= n;
  }
  if (!node.scale.empty()) {
    if (node.scale.size() != 3) return MakeError(StatusCode::kCorrupt, where, ".scale is not 3 numbers");
    std::copy(node.scale.begin(), node.scale.end(), s);
  }
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  const double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                       2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                       2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)};  // row-major
  Mat4 m{};
  for (int c = 0; c < 3; ++c) {
    for (int row = 0; row < 3; ++row) m[c * 4 + row] = r[row * 3 + c] * s[c];
  }
  m[12] = t[0], m[13] = t[1], m[14] = t[2], m[15] = 1;
  return m;
}

}  // namespace

StatusOr<std::vector<SplatPrimitive>> FindSplatPrimitives(const tinygltf::Model& model, const json& doc) {
  auto is_splat = [&](size_t mesh, size_t primitive) {
    const json* p = nullptr;
    try {
      p = &doc.at("meshes").at(mesh).at("primitives").at(primitive);
    } catch (...) {
      return false;
    }
    auto e = p->find("extensions");
    return e != p->end() && e->is_object() && e->contains(kKhrGaussianSplatting);
  };
  std::vector<int> roots;
  if (!model.scenes.empty()) {
    int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (size_t(scene) >= model.scenes.size())
      return MakeError(StatusCode::kCorrupt, "'scene' ", scene, " does not exist");
    roots = model.scenes[size_t(scene)].nodes;
  } else {
    std::vector<bool> is_child(model.nodes.size(), false);
    for (const auto& n : model.nodes) {
      for (int c : n.children) {
        if (c >= 0 && size_t(c) < model.nodes.size()) is_child[size_t(c)] = true;
      }
    }
    for (size_t i = 0; i < model.nodes.size(); ++i) {
      if (!is_child[i]) roots.push_back(int(i));
    }
  }
  std::vector<SplatPrimitive> found;
  std::vector<bool> visited(model.nodes.size(), false);
  std::vector<std::pair<int, Mat4>> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it) stack.push_back({*it, kIdentity});
  while (!stack.empty()) {
    auto [index, parent] = stack.back();
    stack.pop_back();
    if (index < 0 || size_t(index) >= model.nodes.size())
      return MakeError(StatusCode::kCorrupt, "node index ", index, " does not exist");
    if (visited[size_t(index)])
      return MakeError(StatusCode::kCorrupt, "nodes[", index, "] is reached twice (cycle or shared node)");
    visited[size_t(index)] = true;
    const tinygltf::Node& node = model.nodes[size_t(index)];
    ATEX_ASSIGN_OR_RETURN(Mat4 local, NodeMatrix(node, size_t(index)));
    const Mat4 world = Multiply(parent, local);
    if (node.mesh >= 0) {
      if (size_t(node.mesh) >= model.meshes.size())
        return MakeError(StatusCode::kCorrupt, "nodes[", index, "].mesh ", node.mesh, " does not exist");
      const auto& mesh = model.meshes[size_t(node.mesh)];
      for (size_t p = 0; p < mesh.primitives.size(); ++p) {
        if (is_splat(size_t(node.mesh), p)) found.push_back({size_t(node.mesh), p, world});
      }
    }
    for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.push_back({*c, world});
  }
  return found;
}

}  // namespace atex::gltf
#endif
