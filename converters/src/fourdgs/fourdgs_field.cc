// FourDgsFieldFromStateDict: 4DGaussians' deform_network state_dict ->
// DeformationField, and ParseFourDgsCfgArgs.
//
// Keys used (4DGaussians scene/deformation.py, scene/hexplane.py):
//   deformation_net.grid.aabb                 [2][3]  (max, min)
//   deformation_net.grid.grids.<s>.<p>        [1][C][res_b][res_a], p in xy xz xt yz yt zt order
//   deformation_net.feature_out.<2i>.weight   [W][in]  (nn.Sequential: Linear, ReLU, Linear, ...)
//   deformation_net.<head>.1.weight / .3.weight  (nn.Sequential: ReLU, Linear, ReLU, Linear)
// with <head> = pos_deform, scales_deform, rotations_deform, opacity_deform, shs_deform.
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <map>
#include <numeric>

#include "atex/converters/fourdgs.h"
#include "atex/deform.h"

namespace atex {
namespace {

constexpr const char* kNet = "deformation_net.";
constexpr const char* kHeadKeys[kNumDeformHeads] = {"pos_deform", "scales_deform", "rotations_deform",
                                                    "opacity_deform", "shs_deform"};

std::string ShapeString(const std::vector<int64_t>& shape) {
  std::string s = "[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + "]";
}

class FieldBuilder {
 public:
  FieldBuilder(const TorchStateDict& state, const std::string& what) : state_(state), what_(what) {}

  StatusOr<DeformationField> Build(const FourDgsHeadFlags& flags, int sh_coeffs) {
    ATEX_RETURN_IF_ERROR(CheckKeys());
    DeformationField field;
    DeformationConfig& config = field.config;
    ATEX_RETURN_IF_ERROR(ReadAabb(&config));
    ATEX_RETURN_IF_ERROR(ReadGrids(&field));
    ATEX_RETURN_IF_ERROR(ReadTrunk(&field));
    config.sh_coeffs = sh_coeffs;
    const bool off[kNumDeformHeads] = {flags.no_dx, flags.no_ds, flags.no_dr, flags.no_do, flags.no_dshs};
    for (int h = 0; h < kNumDeformHeads; ++h) {
      config.heads[h] = false;
      if (off[h] || Find(StrCat(kNet, kHeadKeys[h], ".1.weight")) == nullptr) continue;
      ATEX_RETURN_IF_ERROR(ReadHead(h, &field));
      config.heads[h] = true;
    }
    config.time_scale = 1.0f;  // 4DGaussians samples t in [0, 1] as given
    config.time_offset = 0.0f;
    const Status shape_check = CheckDeformationField(field);
    if (!shape_check.ok()) {
      return MakeError(StatusCode::kCorrupt, what_, ": the checkpoint does not form a valid field: ",
                       shape_check.message());
    }
    return field;
  }

 private:
  const TorchTensor* Find(const std::string& key) const { return state_.Find(key); }

  // Refuses deform_network variants that this importer cannot reproduce.
  Status CheckKeys() const {
    for (const TorchTensor& t : state_.tensors) {
      if (t.name.rfind(kNet, 0) != 0) continue;  // timenet.*, *_poc buffers: unused by the forward pass
      const std::string rest = t.name.substr(std::string(kNet).size());
      if (rest.rfind("static_mlp.", 0) == 0 || rest.rfind("empty_voxel.", 0) == 0) {
        return MakeError(StatusCode::kUnsupported, what_, ": '", t.name,
                         "': checkpoints trained with static_mlp or empty_voxel masks are not supported");
      }
      bool known = rest == "grid.aabb" || rest.rfind("grid.grids.", 0) == 0 || rest.rfind("feature_out.", 0) == 0;
      for (const char* head : kHeadKeys) known = known || rest.rfind(StrCat(head, "."), 0) == 0;
      if (!known) {
        return MakeError(StatusCode::kUnsupported, what_, ": unknown deformation key '", t.name,
                         "' (a 4DGaussians variant this importer does not know)");
      }
    }
    return Status::Ok();
  }

  StatusOr<const TorchTensor*> Require(const std::string& key, const std::vector<int64_t>& rank_hint) const {
    const TorchTensor* t = Find(key);
    if (t == nullptr) return MakeError(StatusCode::kNotFound, what_, ": no tensor '", key, "'");
    if (!t->floating) {
      return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' is ", t->dtype, ", expected floating point");
    }
    if (t->shape.size() != rank_hint.size()) {
      return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' has shape ", ShapeString(t->shape), ", expected ",
                       rank_hint.size(), " dimensions");
    }
    for (size_t d = 0; d < rank_hint.size(); ++d) {
      if (rank_hint[d] >= 0 && t->shape[d] != rank_hint[d]) {
        return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' has shape ", ShapeString(t->shape),
                         ", expected dimension ", d, " = ", rank_hint[d]);
      }
    }
    for (size_t i = 0; i < t->values.size(); ++i) {
      if (!std::isfinite(t->values[i])) {
        return MakeError(StatusCode::kOutOfRange, what_, ": '", key, "' value ", i, " is ", t->values[i]);
      }
    }
    return t;
  }

  Status ReadAabb(DeformationConfig* config) const {
    ATEX_ASSIGN_OR_RETURN(const TorchTensor* aabb, Require(StrCat(kNet, "grid.aabb"), {2, 3}));
    for (int a = 0; a < 3; ++a) {
      config->aabb_lo[a] = aabb->values[a];      // 4DGaussians' aabb[0] (the max corner)
      config->aabb_hi[a] = aabb->values[3 + a];  // aabb[1] (the min corner)
    }
    return Status::Ok();
  }

  Status ReadGrids(DeformationField* field) {
    DeformationConfig& config = field->config;
    int scales = 0;
    while (Find(StrCat(kNet, "grid.grids.", scales, ".0")) != nullptr) ++scales;
    if (scales == 0) return MakeError(StatusCode::kNotFound, what_, ": no 'deformation_net.grid.grids.0.0'");
    if (Find(StrCat(kNet, "grid.grids.", scales + 1, ".0")) != nullptr) {
      return MakeError(StatusCode::kCorrupt, what_, ": grid scale ", scales, " is missing");
    }
    std::vector<std::array<int, 4>> res(scales);  // per scale, x y z t
    int channels = -1;
    field->planes.resize(scales);
    for (int s = 0; s < scales; ++s) {
      std::array<int, 4> r{-1, -1, -1, -1};
      for (int p = 0; p < kNumHexPlanes; ++p) {
        const std::string key = StrCat(kNet, "grid.grids.", s, ".", p);
        ATEX_ASSIGN_OR_RETURN(const TorchTensor* t, Require(key, {1, channels, -1, -1}));
        if (t->shape[1] < 1) return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' has no channels");
        channels = static_cast<int>(t->shape[1]);
        const int axes[2] = {kHexPlaneAxes[p][0], kHexPlaneAxes[p][1]};
        const int64_t dims[2] = {t->shape[3], t->shape[2]};  // (res_a, res_b)
        for (int k = 0; k < 2; ++k) {
          if (dims[k] < 1 || dims[k] > (1 << 16)) {
            return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' has shape ", ShapeString(t->shape));
          }
          if (r[axes[k]] >= 0 && r[axes[k]] != dims[k]) {
            return MakeError(StatusCode::kCorrupt, what_, ": '", key, "' has shape ", ShapeString(t->shape),
                             " but another plane of scale ", s, " gives axis ", axes[k], " resolution ", r[axes[k]]);
          }
          r[axes[k]] = static_cast<int>(dims[k]);
        }
        field->planes[s][p] = t->values;
      }
      if (Find(StrCat(kNet, "grid.grids.", s, ".6")) != nullptr) {
        return MakeError(StatusCode::kUnsupported, what_, ": grid scale ", s, " has more than six planes");
      }
      res[s] = r;
    }
    // Resolutions -> base resolution and spatial multipliers: base = gcd over
    // scales per axis; every scale must use one multiplier for x, y and z and
    // the same time resolution (4DGaussians multiplies space only).
    HexPlaneConfig& grid = config.grid;
    grid.channels = channels;
    for (int axis = 0; axis < 3; ++axis) {
      int g = 0;
      for (int s = 0; s < scales; ++s) g = std::gcd(g, res[s][axis]);
      grid.base_resolution[axis] = g;
    }
    grid.base_resolution[3] = res[0][3];
    grid.multires.assign(scales, 1);
    for (int s = 0; s < scales; ++s) {
      const int m = res[s][0] / grid.base_resolution[0];
      if (res[s][1] != m * grid.base_resolution[1] || res[s][2] != m * grid.base_resolution[2] ||
          res[s][3] != grid.base_resolution[3]) {
        return MakeError(StatusCode::kUnsupported, what_, ": grid scale ", s, " has resolution (", res[s][0], ", ",
                         res[s][1], ", ", res[s][2], ", ", res[s][3],
                         "), not one spatial multiple of the base resolution with the common time resolution");
      }
      grid.multires[s] = m;
    }
    return Status::Ok();
  }

  Status ReadLinear(const std::string& prefix, int in, int out, Linear* layer) const {
    ATEX_ASSIGN_OR_RETURN(const TorchTensor* w, Require(prefix + ".weight", {out, in}));
    ATEX_ASSIGN_OR_RETURN(const TorchTensor* b, Require(prefix + ".bias", {w->shape[0]}));
    layer->out = static_cast<int>(w->shape[0]);
    layer->in = static_cast<int>(w->shape[1]);
    layer->weight = w->values;
    layer->bias = b->values;
    return Status::Ok();
  }

  Status ReadTrunk(DeformationField* field) {
    DeformationConfig& config = field->config;
    const int feat = config.grid.feature_dim();
    Linear first;
    ATEX_RETURN_IF_ERROR(ReadLinear(StrCat(kNet, "feature_out.0"), -1, -1, &first));
    if (first.in != feat) {
      return MakeError(StatusCode::kUnsupported, what_, ": 'deformation_net.feature_out.0.weight' takes ", first.in,
                       " inputs but the grid gives ", feat, " features (grid_pe or no_grid checkpoints are not "
                       "supported)");
    }
    config.mlp_width = first.out;
    field->trunk.push_back(std::move(first));
    for (int i = 2;; i += 2) {
      const std::string prefix = StrCat(kNet, "feature_out.", i);
      if (Find(prefix + ".weight") == nullptr) {
        if (Find(StrCat(kNet, "feature_out.", i + 1, ".weight")) != nullptr ||
            Find(StrCat(kNet, "feature_out.", i + 2, ".weight")) != nullptr) {
          return MakeError(StatusCode::kUnsupported, what_, ": unexpected layout of deformation_net.feature_out");
        }
        break;
      }
      Linear layer;
      ATEX_RETURN_IF_ERROR(ReadLinear(prefix, config.mlp_width, config.mlp_width, &layer));
      field->trunk.push_back(std::move(layer));
    }
    config.trunk_layers = static_cast<int>(field->trunk.size());
    return Status::Ok();
  }

  Status ReadHead(int h, DeformationField* field) {
    const int w = field->config.mlp_width;
    const std::string prefix = StrCat(kNet, kHeadKeys[h]);
    ATEX_RETURN_IF_ERROR(ReadLinear(prefix + ".1", w, w, &field->heads[h][0]));
    const int outputs = field->config.head_outputs(h);
    const TorchTensor* last = Find(prefix + ".3.weight");
    if (h == kHeadSH && last != nullptr && last->shape.size() == 2 && last->shape[0] != outputs) {
      return MakeError(StatusCode::kUnsupported, what_, ": '", prefix, ".3.weight' has ", last->shape[0],
                       " outputs but the Gaussians have ", field->config.sh_coeffs,
                       " SH coefficients per channel (4DGaussians' SH head assumes SH degree 3)");
    }
    return ReadLinear(prefix + ".3", w, outputs, &field->heads[h][1]);
  }

  const TorchStateDict& state_;
  std::string what_;
};

}  // namespace

StatusOr<DeformationField> FourDgsFieldFromStateDict(const TorchStateDict& state, const FourDgsHeadFlags& flags,
                                                     int sh_coeffs, const std::string& what) {
  if (sh_coeffs < 1 || sh_coeffs > ShCoeffCount(kMaxShDegree)) {
    return MakeError(StatusCode::kInvalidArgument, what, ": sh_coeffs ", sh_coeffs, " outside 1..16");
  }
  FieldBuilder builder(state, what);
  return builder.Build(flags, sh_coeffs);
}

namespace {

// Value text of `name=value` in a Namespace repr, where `name` starts the
// text or follows '(', ',' or whitespace (so "xno_dx=" is not "no_dx=").
// A plain scan: std::regex recurses per character and a hostile file could
// exhaust the stack.
std::string FindCfgValue(const std::string& text, const std::string& name) {
  const std::string key = name + "=";
  for (size_t pos = text.find(key); pos != std::string::npos; pos = text.find(key, pos + 1)) {
    const char before = pos == 0 ? '(' : text[pos - 1];
    if (before != '(' && before != ',' && before != ' ' && before != '\t' && before != '\n') continue;
    size_t end = pos + key.size();
    while (end < text.size() && end - (pos + key.size()) < 64 &&
           (std::isalnum(static_cast<unsigned char>(text[end])) || text[end] == '_' || text[end] == '.' ||
            text[end] == '+' || text[end] == '-')) {
      ++end;
    }
    return text.substr(pos + key.size(), end - (pos + key.size()));
  }
  return std::string();
}

}  // namespace

Status ParseFourDgsCfgArgs(const std::string& text, FourDgsHeadFlags* flags) {
  // Boolean `name=True|False` and integer `name=N` fields of the Namespace repr.
  auto find_value = [&](const std::string& name) { return FindCfgValue(text, name); };
  auto read_bool = [&](const std::string& name, bool* value) -> Status {
    const std::string v = find_value(name);
    if (v.empty()) return Status::Ok();
    if (v == "True") {
      *value = true;
    } else if (v == "False") {
      *value = false;
    } else {
      return MakeError(StatusCode::kCorrupt, "cfg_args: ", name, "=", v, " is not True or False");
    }
    return Status::Ok();
  };
  ATEX_RETURN_IF_ERROR(read_bool("no_dx", &flags->no_dx));
  ATEX_RETURN_IF_ERROR(read_bool("no_ds", &flags->no_ds));
  ATEX_RETURN_IF_ERROR(read_bool("no_dr", &flags->no_dr));
  ATEX_RETURN_IF_ERROR(read_bool("no_do", &flags->no_do));
  ATEX_RETURN_IF_ERROR(read_bool("no_dshs", &flags->no_dshs));
  for (const char* unsupported : {"apply_rotation", "static_mlp", "empty_voxel", "no_grid"}) {
    bool on = false;
    ATEX_RETURN_IF_ERROR(read_bool(unsupported, &on));
    if (on) {
      return MakeError(StatusCode::kUnsupported, "cfg_args: ", unsupported,
                       "=True: this 4DGaussians variant is not supported");
    }
  }
  const std::string grid_pe = find_value("grid_pe");
  if (!grid_pe.empty() && grid_pe != "0") {
    return MakeError(StatusCode::kUnsupported, "cfg_args: grid_pe=", grid_pe, " is not supported");
  }
  return Status::Ok();
}

}  // namespace atex
