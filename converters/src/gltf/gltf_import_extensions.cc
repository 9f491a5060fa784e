// Readers of our glTF extensions' payloads: textures (ATEX_gaussian_textures) and the deformation
// field (ATEX_gaussian_deformation). Split from gltf_import.cc, which reads the base primitive.
#include "gltf/gltf_import_extensions.h"

#ifdef ATEX_HAVE_TINYGLTF
#include <algorithm>
#include <iterator>

#include "gltf/gltf_accessors.h"
#include "gltf/gltf_json_util.h"
#include "gltf/gltf_names.h"

namespace atex::gltf {
namespace {

using nlohmann::json;

const std::initializer_list<int> kFloatOnly = {kComponentFloat};

Status ReadFloatArray(const tinygltf::Model& model, const json& object, const char* key, size_t expected,
                      const std::string& where, std::vector<float>* out) {
  uint64_t index = 0;
  ATEX_RETURN_IF_ERROR(ReadIndex(object, key, model.accessors.size(), where, &index));
  const std::string name = where + "." + key;
  ATEX_ASSIGN_OR_RETURN(AccessorData a, ResolveAccessor(model, int64_t(index), name));
  ATEX_RETURN_IF_ERROR(CheckAccessor(a, 1, kFloatOnly, expected, name));
  return ReadFloats(a, name, out);
}

Status ReadLinear(const tinygltf::Model& model, const json& layer, int in, int out, const std::string& where,
                  Linear* l) {
  if (!layer.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
  l->in = in;
  l->out = out;
  ATEX_RETURN_IF_ERROR(ReadFloatArray(model, layer, "weight", size_t(in) * size_t(out), where, &l->weight));
  return ReadFloatArray(model, layer, "bias", size_t(out), where, &l->bias);
}

}  // namespace

StatusOr<TexturePool> ReadTextures(const tinygltf::Model& model, const tinygltf::Primitive& primitive, const json& ext,
                                   size_t n) {
  const std::string where = kAtexTextures;
  if (!ext.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
  auto it = primitive.attributes.find(kAttrTextureLayout);
  if (it == primitive.attributes.end())
    return MakeError(StatusCode::kCorrupt, where, ": attribute ", kAttrTextureLayout, " is missing");
  ATEX_ASSIGN_OR_RETURN(AccessorData layout_accessor, ResolveAccessor(model, it->second, kAttrTextureLayout));
  ATEX_RETURN_IF_ERROR(CheckAccessor(layout_accessor, 4, {kComponentUnsignedByte}, n, kAttrTextureLayout));
  std::vector<uint8_t> layout;
  ATEX_RETURN_IF_ERROR(ReadBytes(layout_accessor, kAttrTextureLayout, &layout));
  TexturePool t;
  t.heights.resize(n), t.widths.resize(n), t.axis_u.resize(n), t.axis_v.resize(n);
  for (size_t i = 0; i < n; ++i) {
    t.heights[i] = layout[i * 4 + 0];
    t.widths[i] = layout[i * 4 + 1];
    t.axis_u[i] = layout[i * 4 + 2];
    t.axis_v[i] = layout[i * 4 + 3];
    auto side_ok = [](uint8_t s) { return s == 1 || s == 2 || s == 4; };
    if (!side_ok(t.heights[i]) || !side_ok(t.widths[i]) || t.axis_u[i] > 2 || t.axis_v[i] > 2 ||
        t.axis_u[i] == t.axis_v[i]) {
      return MakeError(StatusCode::kOutOfRange, kAttrTextureLayout, " element ", i, " = (", int(t.heights[i]), ", ",
                       int(t.widths[i]), ", ", int(t.axis_u[i]), ", ", int(t.axis_v[i]),
                       ") is not a valid texture layout");
    }
  }
  t.RebuildOffsets();
  uint64_t texels_index = 0;
  ATEX_RETURN_IF_ERROR(ReadIndex(ext, "texels", model.accessors.size(), where, &texels_index));
  ATEX_ASSIGN_OR_RETURN(AccessorData texels, ResolveAccessor(model, int64_t(texels_index), where + ".texels"));
  ATEX_RETURN_IF_ERROR(CheckAccessor(texels, 4, kFloatOnly, t.texel_count(), where + ".texels"));
  ATEX_RETURN_IF_ERROR(ReadFloats(texels, where + ".texels", &t.texels));
  return t;
}

StatusOr<DeformationField> ReadField(const tinygltf::Model& model, const json& f) {
  const std::string where = std::string(kAtexDeformation) + ".field";
  if (!f.is_object()) return MakeError(StatusCode::kCorrupt, where, " is not an object");
  DeformationField field;
  DeformationConfig& c = field.config;
  auto need = [&](const json& o, const char* key, const std::string& w) -> StatusOr<const json*> {
    auto it = o.find(key);
    if (it == o.end()) return MakeError(StatusCode::kCorrupt, w, ": missing '", key, "'");
    return &*it;
  };
  auto read_vec3 = [&](const char* key, std::array<float, 3>* out) -> Status {
    ATEX_ASSIGN_OR_RETURN(const json* v, need(f, key, where));
    if (!v->is_array() || v->size() != 3) return MakeError(StatusCode::kCorrupt, where, ".", key, " is not 3 numbers");
    for (size_t i = 0; i < 3; ++i)
      ATEX_RETURN_IF_ERROR(ReadFloatValue((*v)[i], StrCat(where, ".", key, "[", i, "]"), &(*out)[i]));
    return Status::Ok();
  };
  ATEX_RETURN_IF_ERROR(read_vec3("aabbLo", &c.aabb_lo));
  ATEX_RETURN_IF_ERROR(read_vec3("aabbHi", &c.aabb_hi));
  ATEX_ASSIGN_OR_RETURN(const json* ts, need(f, "timeScale", where));
  ATEX_RETURN_IF_ERROR(ReadFloatValue(*ts, where + ".timeScale", &c.time_scale));
  ATEX_ASSIGN_OR_RETURN(const json* to, need(f, "timeOffset", where));
  ATEX_RETURN_IF_ERROR(ReadFloatValue(*to, where + ".timeOffset", &c.time_offset));
  constexpr int64_t kMaxDim = 1 << 16;
  int64_t v = 0;
  ATEX_ASSIGN_OR_RETURN(const json* width, need(f, "mlpWidth", where));
  ATEX_RETURN_IF_ERROR(ReadIntValue(*width, where + ".mlpWidth", 1, kMaxDim, &v));
  c.mlp_width = int(v);
  ATEX_ASSIGN_OR_RETURN(const json* shk, need(f, "shCoefficients", where));
  ATEX_RETURN_IF_ERROR(ReadIntValue(*shk, where + ".shCoefficients", 1, ShCoeffCount(kMaxShDegree), &v));
  c.sh_coeffs = int(v);

  ATEX_ASSIGN_OR_RETURN(const json* grid, need(f, "grid", where));
  if (!grid->is_object()) return MakeError(StatusCode::kCorrupt, where, ".grid is not an object");
  const std::string gw = where + ".grid";
  ATEX_ASSIGN_OR_RETURN(const json* channels, need(*grid, "channels", gw));
  ATEX_RETURN_IF_ERROR(ReadIntValue(*channels, gw + ".channels", 1, kMaxDim, &v));
  c.grid.channels = int(v);
  ATEX_ASSIGN_OR_RETURN(const json* base, need(*grid, "baseResolution", gw));
  if (!base->is_array() || base->size() != 4)
    return MakeError(StatusCode::kCorrupt, gw, ".baseResolution is not 4 integers");
  for (size_t i = 0; i < 4; ++i) {
    ATEX_RETURN_IF_ERROR(ReadIntValue((*base)[i], StrCat(gw, ".baseResolution[", i, "]"), 1, kMaxDim, &v));
    c.grid.base_resolution[i] = int(v);
  }
  ATEX_ASSIGN_OR_RETURN(const json* multires, need(*grid, "multires", gw));
  if (!multires->is_array() || multires->empty() || multires->size() > 8) {
    return MakeError(StatusCode::kCorrupt, gw, ".multires is not an array of 1..8 integers");
  }
  c.grid.multires.clear();
  for (size_t i = 0; i < multires->size(); ++i) {
    ATEX_RETURN_IF_ERROR(ReadIntValue((*multires)[i], StrCat(gw, ".multires[", i, "]"), 1, kMaxDim, &v));
    c.grid.multires.push_back(int(v));
  }
  ATEX_ASSIGN_OR_RETURN(const json* trunk, need(f, "trunk", where));
  if (!trunk->is_array() || trunk->empty() || trunk->size() > 64)
    return MakeError(StatusCode::kCorrupt, where, ".trunk is not an array of 1..64 layers");
  c.trunk_layers = int(trunk->size());
  ATEX_ASSIGN_OR_RETURN(const json* heads, need(f, "heads", where));
  if (!heads->is_object()) return MakeError(StatusCode::kCorrupt, where, ".heads is not an object");
  for (int h = 0; h < kNumDeformHeads; ++h) c.heads[h] = heads->contains(kHeadNames[h]);
  for (auto it = heads->begin(); it != heads->end(); ++it) {
    if (std::find(std::begin(kHeadNames), std::end(kHeadNames), it.key()) == std::end(kHeadNames)) {
      return MakeError(StatusCode::kCorrupt, where, ".heads has unknown head '", it.key(), "'");
    }
  }
  // Sizes are checked before anything is read (and accessors are bounded by the bytes present).
  ATEX_RETURN_IF_ERROR(CheckDeformationConfig(c));

  ATEX_ASSIGN_OR_RETURN(const json* planes, need(*grid, "planes", gw));
  if (!planes->is_array() || planes->size() != c.grid.multires.size()) {
    return MakeError(StatusCode::kCorrupt, gw, ".planes needs one entry per multires scale (", c.grid.multires.size(),
                     ")");
  }
  field.planes.resize(c.grid.multires.size());
  for (size_t s = 0; s < planes->size(); ++s) {
    const json& scale = (*planes)[s];
    if (!scale.is_array() || scale.size() != size_t(kNumHexPlanes)) {
      return MakeError(StatusCode::kCorrupt, gw, ".planes[", s, "] is not 6 accessor indices");
    }
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const auto [a, b] = kHexPlaneAxes[size_t(p)];
      const size_t size =
          size_t(c.grid.channels) * size_t(c.grid.resolution(int(s), b)) * size_t(c.grid.resolution(int(s), a));
      json holder = {{"plane", scale[size_t(p)]}};
      ATEX_RETURN_IF_ERROR(ReadFloatArray(model, holder, "plane", size, StrCat(gw, ".planes[", s, "][", p, "]"),
                                          &field.planes[s][size_t(p)]));
    }
  }
  const int feat = c.grid.feature_dim(), w = c.mlp_width;
  field.trunk.resize(trunk->size());
  for (size_t l = 0; l < trunk->size(); ++l) {
    ATEX_RETURN_IF_ERROR(
        ReadLinear(model, (*trunk)[l], l == 0 ? feat : w, w, StrCat(where, ".trunk[", l, "]"), &field.trunk[l]));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!c.heads[h]) continue;
    const json& layers = heads->at(kHeadNames[h]);
    const std::string hw = StrCat(where, ".heads.", kHeadNames[h]);
    if (!layers.is_array() || layers.size() != 2) return MakeError(StatusCode::kCorrupt, hw, " is not 2 layers");
    ATEX_RETURN_IF_ERROR(ReadLinear(model, layers[0], w, w, hw + "[0]", &field.heads[h][0]));
    ATEX_RETURN_IF_ERROR(ReadLinear(model, layers[1], w, c.head_outputs(h), hw + "[1]", &field.heads[h][1]));
  }
  ATEX_RETURN_IF_ERROR(CheckDeformationField(field));
  return field;
}

}  // namespace atex::gltf
#endif
