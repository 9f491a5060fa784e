#include "gltf/gltf_test_scene.h"

#include <cstring>
#include <random>
#include <stdexcept>

#include "atex/deform.h"

namespace atex::testing {

Asset MakeTestAsset(const SceneSpec& spec) {
  std::mt19937_64 rng(spec.seed);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  Asset asset;
  Gaussians& g = asset.gaussians;
  g.sh_degree = spec.sh_degree;
  g.Resize(spec.count);
  for (auto& v : g.positions) v = 2.0f * unit(rng);
  for (auto& v : g.rotations) v = unit(rng);
  for (auto& v : g.log_scales) v = -3.0f + 0.5f * unit(rng);
  for (auto& v : g.opacity_logits) v = 3.0f * unit(rng);
  for (auto& v : g.sh) v = 0.5f * unit(rng);
  if (spec.textures) {
    TexturePool t;
    const uint8_t sides[3] = {1, 2, 4};
    std::uniform_int_distribution<int> pick(0, 2);
    for (size_t i = 0; i < spec.count; ++i) {
      t.heights.push_back(sides[pick(rng)]);
      t.widths.push_back(sides[pick(rng)]);
      const uint8_t u = uint8_t(pick(rng));
      t.axis_u.push_back(u);
      t.axis_v.push_back(uint8_t((u + 1 + pick(rng) % 2) % 3));
    }
    t.RebuildOffsets();
    t.texels.resize(t.texel_count() * 4);
    for (auto& v : t.texels) v = unit(rng);
    asset.textures = std::move(t);
    asset.metadata.texture_mode = "adaptive";
  }
  if (spec.deformation) {
    DeformationConfig c;
    c.grid.channels = 3;
    c.grid.base_resolution = {5, 6, 7, 4};
    c.grid.multires = {1, 2};
    c.mlp_width = 8;
    c.trunk_layers = 2;
    c.heads = {true, true, true, true, false};
    c.sh_coeffs = g.sh_coeffs();
    c.aabb_lo = {-2.5f, -2.5f, -2.5f};
    c.aabb_hi = {2.5f, 2.5f, 2.5f};
    auto field = InitDeformationField(c, spec.seed);
    if (!field.ok()) throw std::runtime_error(field.status().ToString());
    // The initialisation makes time planes constant (1) and scales the last head layers by
    // 0.01, i.e. no motion: vary the time planes and amplify the heads so that it moves.
    for (auto& scale_planes : field->planes) {
      for (int p = 0; p < kNumHexPlanes; ++p) {
        const bool time_plane = p == 2 || p == 4 || p == 5;  // xt, yt, zt
        for (auto& v : scale_planes[size_t(p)]) v = 1.0f + (time_plane ? 0.5f : 0.2f) * unit(rng);
      }
    }
    for (auto& head : field->heads) {
      for (auto& v : head[1].weight) v *= 30.0f;
    }
    asset.deformation = std::move(field).value();
  }
  asset.metadata.axes = "opencv";
  asset.metadata.time_min = 0.0f;
  asset.metadata.time_max = 1.0f;
  asset.metadata.units = "meters";
  asset.metadata.extra = {{"note", "glTF test scene"}, {"seed", spec.seed}};
  for (int k = 0; k < 3; ++k) {
    asset.metadata.bounds_min[k] = -2.0f;
    asset.metadata.bounds_max[k] = 2.0f;
  }
  return asset;
}

static uint32_t U32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

GlbParts SplitGlb(const std::vector<uint8_t>& glb) {
  if (glb.size() < 20 || U32(glb.data()) != 0x46546C67) throw std::runtime_error("not a GLB");
  GlbParts parts;
  const uint32_t json_length = U32(&glb[12]);
  parts.json = nlohmann::json::parse(glb.begin() + 20, glb.begin() + 20 + json_length);
  const size_t bin_at = 20 + json_length;
  if (bin_at + 8 <= glb.size()) {
    const uint32_t bin_length = U32(&glb[bin_at]);
    parts.bin.assign(glb.begin() + long(bin_at + 8), glb.begin() + long(bin_at + 8 + bin_length));
  }
  return parts;
}

std::vector<uint8_t> JoinGlb(const nlohmann::json& json, const std::vector<uint8_t>& bin) {
  std::string text = json.dump();
  while (text.size() % 4) text.push_back(' ');
  std::vector<uint8_t> padded_bin = bin;
  while (padded_bin.size() % 4) padded_bin.push_back(0);
  std::vector<uint8_t> out;
  auto put = [&](uint32_t v) {
    for (int i = 0; i < 4; ++i) out.push_back(uint8_t(v >> (8 * i)));
  };
  put(0x46546C67);
  put(2);
  put(uint32_t(12 + 8 + text.size() + (padded_bin.empty() ? 0 : 8 + padded_bin.size())));
  put(uint32_t(text.size()));
  put(0x4E4F534A);
  out.insert(out.end(), text.begin(), text.end());
  if (!padded_bin.empty()) {
    put(uint32_t(padded_bin.size()));
    put(0x004E4942);
    out.insert(out.end(), padded_bin.begin(), padded_bin.end());
  }
  return out;
}

std::vector<float> ReadFloatAccessor(const GlbParts& glb, int index) {
  const auto& a = glb.json.at("accessors").at(index);
  if (a.at("componentType") != 5126) throw std::runtime_error("not a float accessor");
  const auto& v = glb.json.at("bufferViews").at(a.at("bufferView").get<int>());
  const std::string type = a.at("type");
  const size_t comps = type == "SCALAR" ? 1 : type == "VEC2" ? 2 : type == "VEC3" ? 3 : 4;
  const size_t count = a.at("count");
  const size_t stride = v.value("byteStride", comps * 4);
  const size_t start = v.value("byteOffset", size_t{0}) + a.value("byteOffset", size_t{0});
  std::vector<float> out(count * comps);
  for (size_t i = 0; i < count; ++i) {
    if (start + i * stride + comps * 4 > glb.bin.size()) throw std::runtime_error("accessor outside BIN");
    std::memcpy(&out[i * comps], &glb.bin[start + i * stride], comps * 4);
  }
  return out;
}

bool SameBits(const std::vector<float>& a, const std::vector<float>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
}

}  // namespace atex::testing
