// Base attributes of a KHR_gaussian_splatting primitive (accessors -> our raw parameters), with the
// component types and value ranges the extension allows.
#ifdef ATEX_HAVE_TINYGLTF

#include "gltf/gltf_import_base.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "gltf/gltf_accessors.h"
#include "gltf/gltf_names.h"

namespace atex::gltf {

Status ReadAttribute(const tinygltf::Model& model, const tinygltf::Primitive& primitive, const std::string& name,
                     int components, std::initializer_list<int> types, size_t count, std::vector<float>* out,
                     bool* present, bool normalized_integers) {
  auto it = primitive.attributes.find(name);
  if (it == primitive.attributes.end()) {
    if (present != nullptr) {
      *present = false;
      return Status::Ok();
    }
    return MakeError(StatusCode::kCorrupt, "splat primitive lacks attribute ", name);
  }
  if (present != nullptr) *present = true;
  const std::string where = "attribute " + name;
  ATEX_ASSIGN_OR_RETURN(AccessorData a, ResolveAccessor(model, it->second, where));
  ATEX_RETURN_IF_ERROR(CheckAccessor(a, components, types, count, where));
  if (normalized_integers && a.component_type != kComponentFloat && !a.normalized) {
    return MakeError(StatusCode::kCorrupt, where, " has integer components that are not normalized");
  }
  return ReadFloats(a, where, out);
}

namespace {

// Component types of KHR_gaussian_splatting's attribute table (KhronosGroup/glTF at 77b44be, as
// rewritten by the editorial review 63770cc): ROTATION float or normalized signed byte/short; SCALE float or
// unsigned byte/short, normalized or not (linear values, never negative); OPACITY float or
// normalized unsigned byte/short; SH float.
const std::initializer_list<int> kFloatOnly = {kComponentFloat};
const std::initializer_list<int> kRotationTypes = {kComponentFloat, kComponentByte, kComponentShort};
const std::initializer_list<int> kScaleTypes = {kComponentFloat, kComponentUnsignedByte, kComponentUnsignedShort};
// What `atex export --quantize` wrote before it followed that table: SHORT normalized SCALE, linear.
const std::initializer_list<int> kOurLegacyScaleTypes = {kComponentFloat, kComponentUnsignedByte,
                                                         kComponentUnsignedShort, kComponentShort};
const std::initializer_list<int> kOpacityTypes = {kComponentFloat, kComponentUnsignedByte, kComponentUnsignedShort};

// SCALE: the linear scales ([N][3]). A signed integer SCALE is outside the extension's table; the
// January 2026 text that allowed signed types stored log-scales, and a file does not say which
// text it follows, so such files are refused rather than guessed at, except in our own files
// (`ours`: they carry extras.atex, and atex has only ever written linear scales), where the
// SHORT normalized type is what `atex export --quantize` wrote before it used UNSIGNED_SHORT.
Status ReadScales(const tinygltf::Model& model, const tinygltf::Primitive& primitive, size_t n, bool ours,
                  std::vector<float>* scales) {
  auto it = primitive.attributes.find(kAttrScale);
  if (it == primitive.attributes.end())
    return MakeError(StatusCode::kCorrupt, "splat primitive lacks attribute ", kAttrScale);
  const std::string where = std::string("attribute ") + kAttrScale;
  ATEX_ASSIGN_OR_RETURN(AccessorData a, ResolveAccessor(model, it->second, where));
  const bool signed_type = a.component_type == kComponentByte || a.component_type == kComponentShort;
  if (signed_type && !(ours && a.component_type == kComponentShort && a.normalized)) {
    return MakeError(StatusCode::kUnsupported, where, " has the signed component type ", a.component_type,
                     ": KHR_gaussian_splatting allows float or unsigned integers for its linear scales (signed "
                     "types come from the superseded draft that stored log-scales, and the file does not say "
                     "which it follows)");
  }
  ATEX_RETURN_IF_ERROR(CheckAccessor(a, 3, ours ? kOurLegacyScaleTypes : kScaleTypes, n, where));
  return ReadFloats(a, where, scales);
}

}  // namespace

StatusOr<Gaussians> ReadBase(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                             const GltfImportOptions& options, bool ours) {
  if (primitive.mode != kModePoints) {
    return MakeError(StatusCode::kCorrupt, "splat primitive has mode ", primitive.mode,
                     ", KHR_gaussian_splatting needs POINTS (0)");
  }
  Gaussians g;
  std::vector<float> positions;
  ATEX_RETURN_IF_ERROR(
      ReadAttribute(model, primitive, kAttrPosition, 3,
                    {kComponentFloat, kComponentByte, kComponentUnsignedByte, kComponentShort, kComponentUnsignedShort},
                    0, &positions));
  const size_t n = positions.size() / 3;
  if (n > options.max_gaussians)
    return MakeError(StatusCode::kLimitExceeded, n, " Gaussians exceed the limit of ", options.max_gaussians);
  g.positions = std::move(positions);

  std::vector<float> xyzw, scales, opacities;
  ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, kAttrRotation, 4, kRotationTypes, n, &xyzw, nullptr, true));
  ATEX_RETURN_IF_ERROR(ReadScales(model, primitive, n, ours, &scales));
  ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, kAttrOpacity, 1, kOpacityTypes, n, &opacities, nullptr, true));
  g.rotations.resize(n * 4);
  for (size_t i = 0; i < n; ++i) {
    g.rotations[i * 4 + 0] = xyzw[i * 4 + 3];
    g.rotations[i * 4 + 1] = xyzw[i * 4 + 0];
    g.rotations[i * 4 + 2] = xyzw[i * 4 + 1];
    g.rotations[i * 4 + 3] = xyzw[i * 4 + 2];
  }
  g.log_scales.resize(n * 3);
  for (size_t i = 0; i < n * 3; ++i) {
    if (!(scales[i] >= 0)) {
      return MakeError(StatusCode::kOutOfRange, "attribute ", kAttrScale, " element ", i / 3, " component ", i % 3,
                       " is ", scales[i], " (scales must be positive)");
    }
    // A zero scale (flat splats of some tools) becomes the smallest normal float's log.
    g.log_scales[i] = float(std::log(std::max(double(scales[i]), double(std::numeric_limits<float>::min()))));
  }
  g.opacity_logits.resize(n);
  constexpr double kEps = 1e-7;  // opacity 0 or 1 has an infinite logit: clamp to a finite one
  for (size_t i = 0; i < n; ++i) {
    if (!(opacities[i] >= 0 && opacities[i] <= 1)) {
      return MakeError(StatusCode::kOutOfRange, "attribute ", kAttrOpacity, " element ", i, " is ", opacities[i],
                       " (outside [0, 1])");
    }
    const double o = std::clamp(double(opacities[i]), kEps, 1 - kEps);
    g.opacity_logits[i] = float(std::log(o / (1 - o)));
  }

  // SH: degree 0 is required; higher degrees only when complete (the extension forbids partial degrees).
  int degree = -1;
  for (int l = 0; l <= kMaxShDegree; ++l) {
    bool complete = true, any = false;
    for (int c = 0; c <= 2 * l; ++c) {
      const bool has = primitive.attributes.count(ShAttribute(l, c)) != 0;
      complete = complete && has;
      any = any || has;
    }
    if (complete) {
      degree = l;
    } else {
      if (any) return MakeError(StatusCode::kCorrupt, "SH degree ", l, " is only partially present");
      break;
    }
  }
  if (degree < 0) {
    return MakeError(StatusCode::kUnsupported, "splat primitive has no ", ShAttribute(0, 0),
                     " (other lighting methods are not supported)");
  }
  g.sh_degree = degree;
  const size_t k_count = size_t(g.sh_coeffs());
  g.sh.resize(n * k_count * 3);
  std::vector<float> coef;
  for (int l = 0; l <= degree; ++l) {
    for (int c = 0; c <= 2 * l; ++c) {
      ATEX_RETURN_IF_ERROR(ReadAttribute(model, primitive, ShAttribute(l, c), 3, kFloatOnly, n, &coef));
      const size_t k = size_t(l * l + c);
      for (size_t i = 0; i < n; ++i) {
        for (int ch = 0; ch < 3; ++ch) g.sh[(i * k_count + k) * 3 + ch] = coef[i * 3 + ch];
      }
    }
  }
  return g;
}

void LinearToDisplayColour(Gaussians& g) {
  constexpr double kC0 = 0.28209479177387814;
  const int k = g.sh_coeffs();
  for (size_t i = 0; i < g.size(); ++i) {
    float* sh = &g.sh[i * size_t(k) * 3];  // [k][3]
    for (int c = 0; c < 3; ++c) {
      const double linear = std::clamp(0.5 + kC0 * double(sh[c]), 0.0, 1.0);
      const double display = linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055;
      // d display / d linear: 12.92 on the straight segment, 1.055/2.4 x^(1/2.4 - 1) above it.
      const double slope = linear <= 0.0031308 ? 12.92 : std::min(12.92, 1.055 / 2.4 * std::pow(linear, 1 / 2.4 - 1));
      sh[c] = float((display - 0.5) / kC0);
      for (int j = 1; j < k; ++j) sh[j * 3 + c] = float(double(sh[j * 3 + c]) * slope);
    }
  }
}

}  // namespace atex::gltf

#endif  // ATEX_HAVE_TINYGLTF
