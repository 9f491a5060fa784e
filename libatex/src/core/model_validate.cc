// ValidateAsset: everything an in-memory asset must satisfy before it is written
// or used (model.h, format_spec/atex.md). Messages name the array and element.
#include <bit>
#include <cmath>
#include <limits>
#include <cstdint>
#include <string>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "atex/model.h"
#include "core/model_limits.h"

namespace atex {
namespace {

Status CheckSize(const char* what, size_t actual, size_t expected) {
  if (actual != expected) {
    return MakeError(StatusCode::kInvalidArgument, what, " has ", actual, " values, expected ", expected);
  }
  return Status::Ok();
}

// Every value finite and |value| <= max_abs; `row_width` turns a flat index into "row r
// component c".
Status CheckFinite(const char* what, const std::vector<float>& values, size_t row_width,
                   float max_abs = std::numeric_limits<float>::max()) {
  // A branch-free pass (vectorises; this runs on every encode and decode): for non-negative
  // floats the bit patterns order as the values, and NaN/inf lie above every finite bound.
  // Large arrays on several threads (outside a parallel region): the fitter validates each of
  // its candidates, whole assets of hundreds of megabytes.
  const uint32_t limit = std::bit_cast<uint32_t>(max_abs);
  const float* data = values.data();
  const auto count = static_cast<int64_t>(values.size());
  uint32_t bad = 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(static) reduction(| : bad) if (count >= (int64_t{1} << 20) && !omp_in_parallel())
#endif
  for (int64_t i = 0; i < count; ++i)
    bad |= static_cast<uint32_t>((std::bit_cast<uint32_t>(data[i]) & 0x7FFFFFFFu) > limit);
  if (bad == 0) return Status::Ok();
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return MakeError(StatusCode::kOutOfRange, what, " element ", i / row_width, " component ", i % row_width,
                       " is not finite (", values[i], ")");
    }
    if (std::abs(values[i]) > max_abs) {
      return MakeError(StatusCode::kOutOfRange, what, " element ", i / row_width, " component ", i % row_width,
                       " is ", values[i], ", beyond the largest magnitude a renderer can use (", max_abs, ")");
    }
  }
  return Status::Ok();
}

Status CheckArray(const char* what, const std::vector<float>& values, size_t rows, size_t row_width,
                  float max_abs = std::numeric_limits<float>::max()) {
  ATEX_RETURN_IF_ERROR(CheckSize(what, values.size(), rows * row_width));
  return CheckFinite(what, values, row_width == 0 ? 1 : row_width, max_abs);
}

Status ValidateGaussians(const Gaussians& g) {
  if (g.sh_degree < 0 || g.sh_degree > kMaxShDegree) {
    return MakeError(StatusCode::kOutOfRange, "SH degree ", g.sh_degree, " is outside 0..", kMaxShDegree);
  }
  const size_t n = g.size();
  ATEX_RETURN_IF_ERROR(CheckArray("positions", g.positions, n, 3));
  ATEX_RETURN_IF_ERROR(CheckArray("rotations", g.rotations, n, 4, limits::kMaxAbsRotation));
  ATEX_RETURN_IF_ERROR(CheckArray("log_scales", g.log_scales, n, 3));
  ATEX_RETURN_IF_ERROR(CheckArray("opacity_logits", g.opacity_logits, n, 1));
  ATEX_RETURN_IF_ERROR(CheckArray("sh", g.sh, n, static_cast<size_t>(g.sh_coeffs()) * 3));
  if (g.has_time_windows()) {
    ATEX_RETURN_IF_ERROR(CheckArray("time_windows", g.time_windows, n, 2));
    for (size_t i = 0; i < n; ++i) {
      if (g.time_windows[2 * i + 1] < 0) {
        return MakeError(StatusCode::kOutOfRange, "time_windows element ", i, " component 1 (inverse width) is ",
                         g.time_windows[2 * i + 1], ", below 0");
      }
    }
  }
  return Status::Ok();
}

bool ValidSide(uint8_t side) { return side == 1 || side == 2 || side == 4; }

Status ValidateTextures(const TexturePool& t, size_t n) {
  ATEX_RETURN_IF_ERROR(CheckSize("texture heights", t.heights.size(), n));
  ATEX_RETURN_IF_ERROR(CheckSize("texture widths", t.widths.size(), n));
  ATEX_RETURN_IF_ERROR(CheckSize("texture axis_u", t.axis_u.size(), n));
  ATEX_RETURN_IF_ERROR(CheckSize("texture axis_v", t.axis_v.size(), n));
  ATEX_RETURN_IF_ERROR(CheckSize("texture offsets", t.offsets.size(), n + 1));
  if (t.offsets[0] != 0)
    return MakeError(StatusCode::kInvalidArgument, "texture offsets[0] is ", t.offsets[0], ", not 0");
  for (size_t i = 0; i < n; ++i) {
    if (!ValidSide(t.heights[i]) || !ValidSide(t.widths[i])) {
      return MakeError(StatusCode::kOutOfRange, "texture of Gaussian ", i, " is ", int{t.heights[i]}, "x",
                       int{t.widths[i]}, "; each side must be 1, 2 or 4");
    }
    if (t.axis_u[i] > 2 || t.axis_v[i] > 2 || t.axis_u[i] == t.axis_v[i]) {
      return MakeError(StatusCode::kOutOfRange, "texture axes of Gaussian ", i, " are (", int{t.axis_u[i]}, ", ",
                       int{t.axis_v[i]}, "); they must be distinct values in 0..2");
    }
    const uint64_t expected = t.offsets[i] + uint64_t{t.heights[i]} * t.widths[i];
    if (t.offsets[i + 1] != expected) {
      return MakeError(StatusCode::kInvalidArgument, "texture offsets[", i + 1, "] is ", t.offsets[i + 1],
                       ", expected ", expected, " (prefix sum of h*w; call RebuildOffsets)");
    }
  }
  return CheckArray("texels", t.texels, t.offsets[n], kTexelChannels);
}

Status ValidateDeformationConfig(const DeformationConfig& c, int gaussian_sh_coeffs) {
  const HexPlaneConfig& g = c.grid;
  if (g.channels < 1 || g.channels > limits::kMaxChannels) {
    return MakeError(StatusCode::kOutOfRange, "deformation channels ", g.channels, " outside 1..",
                     limits::kMaxChannels);
  }
  for (int a = 0; a < 4; ++a) {
    if (g.base_resolution[a] < 1 || g.base_resolution[a] > limits::kMaxBaseResolution) {
      return MakeError(StatusCode::kOutOfRange, "deformation base_resolution[", a, "] = ", g.base_resolution[a],
                       " outside 1..", limits::kMaxBaseResolution);
    }
  }
  if (g.multires.empty() || g.scales() > limits::kMaxScales) {
    return MakeError(StatusCode::kOutOfRange, "deformation has ", g.multires.size(), " scales; expected 1..",
                     limits::kMaxScales);
  }
  for (int s = 0; s < g.scales(); ++s) {
    if (g.multires[s] < 1 || g.multires[s] > limits::kMaxMultires) {
      return MakeError(StatusCode::kOutOfRange, "deformation multires[", s, "] = ", g.multires[s], " outside 1..",
                       limits::kMaxMultires);
    }
    for (int a = 0; a < 3; ++a) {
      if (int64_t{g.base_resolution[a]} * g.multires[s] > limits::kMaxSpatialResolution) {
        return MakeError(StatusCode::kOutOfRange, "deformation resolution of axis ", a, " at scale ", s, " is above ",
                         limits::kMaxSpatialResolution);
      }
    }
  }
  if (c.mlp_width < 1 || c.mlp_width > limits::kMaxMlpWidth) {
    return MakeError(StatusCode::kOutOfRange, "deformation mlp_width ", c.mlp_width, " outside 1..",
                     limits::kMaxMlpWidth);
  }
  if (c.trunk_layers < 1 || c.trunk_layers > limits::kMaxTrunkLayers) {
    return MakeError(StatusCode::kOutOfRange, "deformation trunk_layers ", c.trunk_layers, " outside 1..",
                     limits::kMaxTrunkLayers);
  }
  if (c.sh_coeffs != 1 && c.sh_coeffs != 4 && c.sh_coeffs != 9 && c.sh_coeffs != 16) {
    return MakeError(StatusCode::kOutOfRange, "deformation sh_coeffs ", c.sh_coeffs, " is not 1, 4, 9 or 16");
  }
  if (c.heads[kHeadSH] && c.sh_coeffs != gaussian_sh_coeffs) {
    return MakeError(StatusCode::kInvalidArgument, "deformation SH head has sh_coeffs ", c.sh_coeffs,
                     " but the Gaussians have ", gaussian_sh_coeffs, " SH coefficients");
  }
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(c.aabb_lo[a]) || !std::isfinite(c.aabb_hi[a])) {
      return MakeError(StatusCode::kOutOfRange, "deformation AABB axis ", a, " is not finite");
    }
    if (c.aabb_lo[a] == c.aabb_hi[a]) {
      return MakeError(StatusCode::kOutOfRange, "deformation AABB axis ", a, " is empty (lo == hi == ", c.aabb_lo[a],
                       ")");
    }
  }
  if (!std::isfinite(c.time_scale) || !std::isfinite(c.time_offset)) {
    return MakeError(StatusCode::kOutOfRange, "deformation time_scale/time_offset not finite");
  }
  return Status::Ok();
}

Status ValidateLinear(const std::string& name, const Linear& layer, int in, int out) {
  if (layer.in != in || layer.out != out) {
    return MakeError(StatusCode::kInvalidArgument, name, " is ", layer.in, "->", layer.out, ", expected ", in, "->",
                     out);
  }
  ATEX_RETURN_IF_ERROR(
      CheckArray((name + " weight").c_str(), layer.weight, static_cast<size_t>(out), in, limits::kMaxAbsNetworkValue));
  return CheckArray((name + " bias").c_str(), layer.bias, static_cast<size_t>(out), 1, limits::kMaxAbsNetworkValue);
}

Status ValidateDeformation(const DeformationField& d, int gaussian_sh_coeffs) {
  const DeformationConfig& c = d.config;
  ATEX_RETURN_IF_ERROR(ValidateDeformationConfig(c, gaussian_sh_coeffs));
  const HexPlaneConfig& g = c.grid;
  if (d.planes.size() != static_cast<size_t>(g.scales())) {
    return MakeError(StatusCode::kInvalidArgument, "deformation has ", d.planes.size(), " plane sets, expected ",
                     g.scales());
  }
  for (int s = 0; s < g.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const size_t expected = static_cast<size_t>(g.channels) * g.resolution(s, kHexPlaneAxes[p][0]) *
                              g.resolution(s, kHexPlaneAxes[p][1]);
      const std::string name = StrCat("deformation plane (scale ", s, ", plane ", p, ")");
      ATEX_RETURN_IF_ERROR(CheckArray(name.c_str(), d.planes[s][p], expected, 1, limits::kMaxAbsNetworkValue));
    }
  }
  if (d.trunk.size() != static_cast<size_t>(c.trunk_layers)) {
    return MakeError(StatusCode::kInvalidArgument, "deformation trunk has ", d.trunk.size(), " layers, config says ",
                     c.trunk_layers);
  }
  for (int l = 0; l < c.trunk_layers; ++l) {
    ATEX_RETURN_IF_ERROR(ValidateLinear(StrCat("trunk layer ", l), d.trunk[l], l == 0 ? g.feature_dim() : c.mlp_width,
                                        c.mlp_width));
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (c.heads[h]) {
      ATEX_RETURN_IF_ERROR(ValidateLinear(StrCat("head ", h, " layer 0"), d.heads[h][0], c.mlp_width, c.mlp_width));
      ATEX_RETURN_IF_ERROR(
          ValidateLinear(StrCat("head ", h, " layer 1"), d.heads[h][1], c.mlp_width, c.head_outputs(h)));
    } else {
      for (int k = 0; k < 2; ++k) {
        const Linear& layer = d.heads[h][k];
        if (layer.in != 0 || layer.out != 0 || !layer.weight.empty() || !layer.bias.empty()) {
          return MakeError(StatusCode::kInvalidArgument, "head ", h, " is disabled but layer ", k, " is not empty");
        }
      }
    }
  }
  return Status::Ok();
}

Status ValidateStats(const GaussianStats& s, size_t n) {
  ATEX_RETURN_IF_ERROR(CheckArray("stats texture_demand", s.texture_demand, n, 1));
  ATEX_RETURN_IF_ERROR(CheckArray("stats peak_scale_u", s.peak_scale_u, n, 1));
  ATEX_RETURN_IF_ERROR(CheckArray("stats peak_scale_v", s.peak_scale_v, n, 1));
  return CheckArray("stats importance", s.importance, n, 1);
}

// Strict UTF-8 (no overlongs, no surrogates, at most U+10FFFF).
bool IsValidUtf8(const std::string& s) {
  size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    size_t extra;
    uint32_t cp;
    if (c < 0x80) { ++i; continue; }
    if (c >= 0xC2 && c <= 0xDF) { extra = 1; cp = c & 0x1F; }
    else if (c >= 0xE0 && c <= 0xEF) { extra = 2; cp = c & 0x0F; }
    else if (c >= 0xF0 && c <= 0xF4) { extra = 3; cp = c & 0x07; }
    else return false;
    if (i + extra >= s.size()) return false;  // sequence cut off
    for (size_t k = 1; k <= extra; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) return false;
      cp = (cp << 6) | (cc & 0x3F);
    }
    if ((extra == 2 && cp < 0x800) || (extra == 3 && cp < 0x10000) || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) {
      return false;
    }
    i += extra + 1;
  }
  return true;
}

// JSON values in `extra` must be writable and read back unchanged: finite
// numbers, valid UTF-8, bounded nesting.
Status ValidateJsonValue(const nlohmann::json& value, int depth, const std::string& where) {
  if (depth > limits::kMaxJsonDepth) {
    return MakeError(StatusCode::kLimitExceeded, "metadata ", where, " is nested deeper than ", limits::kMaxJsonDepth);
  }
  if (value.is_number_float() && !std::isfinite(value.get<double>())) {
    return MakeError(StatusCode::kOutOfRange, "metadata ", where, " holds a non-finite number");
  }
  if (value.is_string() && !IsValidUtf8(value.get_ref<const std::string&>())) {
    return MakeError(StatusCode::kInvalidArgument, "metadata ", where, " holds invalid UTF-8");
  }
  if (value.is_object()) {
    for (auto it = value.begin(); it != value.end(); ++it) {
      if (!IsValidUtf8(it.key()))
        return MakeError(StatusCode::kInvalidArgument, "metadata ", where, " has a key that is not UTF-8");
      ATEX_RETURN_IF_ERROR(ValidateJsonValue(it.value(), depth + 1, where + "." + it.key()));
    }
  } else if (value.is_array()) {
    for (size_t i = 0; i < value.size(); ++i) {
      ATEX_RETURN_IF_ERROR(ValidateJsonValue(value[i], depth + 1, StrCat(where, "[", i, "]")));
    }
  }
  return Status::Ok();
}

Status ValidateMetadata(const Metadata& m, const Asset& asset) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(m.bounds_min[a]) || !std::isfinite(m.bounds_max[a])) {
      return MakeError(StatusCode::kOutOfRange, "metadata bounds axis ", a, " is not finite");
    }
    if (m.bounds_min[a] > m.bounds_max[a]) {
      return MakeError(StatusCode::kOutOfRange, "metadata bounds axis ", a, ": min ", m.bounds_min[a], " > max ",
                       m.bounds_max[a]);
    }
    if (!(m.background[a] >= 0.0f && m.background[a] <= 1.0f)) {
      return MakeError(StatusCode::kOutOfRange, "metadata background[", a, "] = ", m.background[a],
                       " is outside [0, 1]");
    }
  }
  if (!std::isfinite(m.time_min) || !std::isfinite(m.time_max) || m.time_min > m.time_max) {
    return MakeError(StatusCode::kOutOfRange, "metadata time range [", m.time_min, ", ", m.time_max, "] is invalid");
  }
  if (m.texture_mode != "none" && m.texture_mode != "uniform" && m.texture_mode != "adaptive") {
    return MakeError(StatusCode::kInvalidArgument, "metadata texture_mode '", m.texture_mode,
                     "' is not none, uniform or adaptive");
  }
  if (asset.textures.has_value() == (m.texture_mode == "none")) {
    return MakeError(StatusCode::kInvalidArgument, "metadata texture_mode is '", m.texture_mode, "' but the asset ",
                     asset.textures ? "has" : "has no", " textures");
  }
  if (m.texture_mode == "uniform" && asset.textures) {
    const TexturePool& t = *asset.textures;
    for (size_t i = 1; i < t.size(); ++i) {
      if (t.heights[i] != t.heights[0] || t.widths[i] != t.widths[0]) {
        return MakeError(StatusCode::kInvalidArgument, "texture_mode is 'uniform' but Gaussian ", i, " has a ",
                         int{t.heights[i]}, "x", int{t.widths[i]}, " texture and Gaussian 0 ", int{t.heights[0]}, "x",
                         int{t.widths[0]});
      }
    }
  }
  if (!IsValidUtf8(m.axes) || !IsValidUtf8(m.units) || !IsValidUtf8(m.texture_mode)) {
    return MakeError(StatusCode::kInvalidArgument, "metadata axes/units is not valid UTF-8");
  }
  if (!m.extra.is_object()) return MakeError(StatusCode::kInvalidArgument, "metadata extra is not a JSON object");
  return ValidateJsonValue(m.extra, 1, "extra");
}

}  // namespace

Status ValidateAsset(const Asset& asset) {
  try {
    ATEX_RETURN_IF_ERROR(ValidateGaussians(asset.gaussians));
    const size_t n = asset.gaussians.size();
    if (asset.textures) ATEX_RETURN_IF_ERROR(ValidateTextures(*asset.textures, n));
    if (asset.deformation) ATEX_RETURN_IF_ERROR(ValidateDeformation(*asset.deformation, asset.gaussians.sh_coeffs()));
    if (asset.gaussians.has_time_windows() && !asset.deformation) {
      return MakeError(StatusCode::kInvalidArgument,
                       "time_windows (time-local Gaussians) need a deformation field: a static asset has no time");
    }
    if (asset.stats) ATEX_RETURN_IF_ERROR(ValidateStats(*asset.stats, n));
    return ValidateMetadata(asset.metadata, asset);
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "ValidateAsset: ", e.what());
  }
}

}  // namespace atex
