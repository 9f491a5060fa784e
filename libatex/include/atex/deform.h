// The HexPlane + MLP deformation field of 4DGaussians: forward, backward,
// initialisation and the plane regularisers (docs/conventions.md §3 is the
// normative definition; this module is its executable form on the CPU).
//
// Every function is templated on the scalar type (float for assets and
// training, double for gradient checks), deduced from the inputs only (output
// pointers do not take part, so nullptr can be passed), and explicitly
// instantiated for both.
// Work is batched (the MLP as matrix products over fixed blocks of Gaussians)
// and parallel with OpenMP where built in; results do not depend on the number
// of threads (fixed blocks, reductions in a fixed order, plane gradients
// gathered per channel in Gaussian order).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// What the forward pass keeps for the backward pass. Treat as opaque; the
// shapes are documented for memory planning (S = scales, C = channels,
// W = MLP width, N = Gaussians).
template <typename T>
struct BasicDeformCache {
  size_t count = 0;                 // N of the forward pass that filled it
  double time = 0;                  // scene time of that pass
  std::vector<T> samples;           // [N][S][6][C] plane samples
  std::vector<T> features;          // [N][S*C] trunk input (per-scale products, scale-major)
  std::vector<std::vector<T>> trunk;  // [trunk_layers][N][W] trunk outputs before the next ReLU
  std::array<std::vector<T>, kNumDeformHeads> head_hidden;  // [N][W] first head layer before its ReLU; empty if off

  // Bytes held (for memory budgeting).
  size_t bytes() const;
};
using DeformCache = BasicDeformCache<float>;

// Checks that a field's arrays agree with its config: plane sizes
// C*res_b*res_a, layer shapes (trunk: feat->W then W->W; heads W->W->outputs),
// disabled heads empty, positive sizes, a non-degenerate AABB and finite
// time mapping. Values are not scanned (use ValidateAsset for finiteness).
// The message names the plane (scale, index) or layer.
template <typename T>
Status CheckDeformationField(const BasicDeformationField<T>& field);

// Checks a config alone (the shapes a field built from it would have) and the
// size limits: every dimension >= 1, at most 2^31 parameters.
Status CheckDeformationConfig(const DeformationConfig& config);

// Deforms `canonical` to scene time `time` (docs/conventions.md §3):
// deformed = canonical + residuals of the enabled heads (a disabled head
// leaves its parameter unchanged). `deformed` is resized and overwritten; it
// must not alias `canonical`. When `cache` is not null it is filled for
// DeformBackward (same field, canonical and time). Fails with
// kInvalidArgument when the shapes disagree (array sizes, or the SH head
// enabled for a different SH degree than the Gaussians').
template <typename T>
Status DeformForward(const BasicDeformationField<T>& field, const BasicGaussians<T>& canonical, double time,
                     std::type_identity_t<BasicGaussians<T>>* deformed,
                     std::type_identity_t<BasicDeformCache<T>>* cache);

// Vector-Jacobian product of DeformForward. grad_deformed holds dL/d(deformed
// parameters) (same shapes as canonical). Gradients are ADDED to grad_field
// (planes, trunk and head layers) and grad_canonical (positions, through the
// residual and through the sampling coordinates; log-scales, rotations,
// opacity logits and SH through the residual). Either output may be null to
// skip it; an output whose arrays are empty is first resized to zeros,
// otherwise its shapes must match. `cache` must come from DeformForward with
// the same field, canonical and time (kInvalidArgument otherwise).
template <typename T>
Status DeformBackward(const BasicDeformationField<T>& field, const BasicGaussians<T>& canonical, double time,
                      const BasicDeformCache<T>& cache, const BasicGaussians<T>& grad_deformed,
                      std::type_identity_t<BasicDeformationField<T>>* grad_field,
                      std::type_identity_t<BasicGaussians<T>>* grad_canonical);

// A new field for native training (docs/conventions.md §3, "Initialisation"):
// spatial planes U(0.1, 0.5), time planes 1; linear weights Xavier-uniform,
// biases 0; the last layer of every head scaled by 0.01. Disabled heads are
// empty. Deterministic for a seed on every platform (own RNG mapping).
StatusOr<DeformationField> InitDeformationField(const DeformationConfig& config, uint64_t seed);

// The regularisers of 4DGaussians' fine stage (scene/regulation.py and
// GaussianModel.compute_regulation), exactly:
//   plane_tv        * sum over scales and spatial planes (xy, xz, yz) of
//                     mean_{c,b,a} (second difference of the plane along b)^2
//   time_smoothness * the same over the time planes (xt, yt, zt), whose b axis is time
//   time_l1         * sum over scales and time planes of mean |1 - plane|
// (4DGaussians calls the first term "plane TV" although it is the same
// second-difference smoothness along the plane's height axis.) A plane with
// fewer than 3 rows contributes 0 to the smoothness terms (PyTorch would give
// NaN). The gradient is ADDED to *grad (same shapes as field) when not null;
// |x| has gradient 0 at 0 as in PyTorch. Sums are accumulated in double.
// Precondition: CheckDeformationField(field) passes and *grad has the field's
// shapes; otherwise NaN is returned and *grad is left untouched.
struct RegularizerWeights {
  float plane_tv = 2e-4f;
  float time_smoothness = 1e-3f;
  float time_l1 = 1e-4f;
};
template <typename T>
T DeformRegularizer(const BasicDeformationField<T>& field, const RegularizerWeights& weights,
                    std::type_identity_t<BasicDeformationField<T>>* grad);

// A field with the same config and shapes whose every value is zero.
template <typename T>
BasicDeformationField<T> ZerosLike(const BasicDeformationField<T>& field);

// Element-wise conversions (e.g. float asset -> double for gradient checks).
template <typename U, typename T>
BasicDeformationField<U> Cast(const BasicDeformationField<T>& field);
template <typename U, typename T>
BasicGaussians<U> Cast(const BasicGaussians<T>& gaussians);

// Number of scalar parameters (planes + trunk + enabled heads).
template <typename T>
size_t ParameterCount(const BasicDeformationField<T>& field);

// ---------------------------------------------------------------------------
// Template definitions of the conversions (header-only so any U, T pair works).
// A field of the same shapes whose every parameter array is map(array) (a
// std::vector<U> of the same length).
template <typename U, typename T, typename Map>
BasicDeformationField<U> MapDeformationField(const BasicDeformationField<T>& field, Map map) {
  auto map_linear = [&](const BasicLinear<T>& l) {
    BasicLinear<U> out;
    out.in = l.in;
    out.out = l.out;
    out.weight = map(l.weight);
    out.bias = map(l.bias);
    return out;
  };
  BasicDeformationField<U> out;
  out.config = field.config;
  out.planes.resize(field.planes.size());
  for (size_t s = 0; s < field.planes.size(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) out.planes[s][p] = map(field.planes[s][p]);
  }
  for (const auto& l : field.trunk) out.trunk.push_back(map_linear(l));
  for (int h = 0; h < kNumDeformHeads; ++h) {
    for (int k = 0; k < 2; ++k) out.heads[h][k] = map_linear(field.heads[h][k]);
  }
  return out;
}

template <typename U, typename T>
BasicDeformationField<U> Cast(const BasicDeformationField<T>& field) {
  return MapDeformationField<U>(field, [](const std::vector<T>& v) { return std::vector<U>(v.begin(), v.end()); });
}

template <typename U, typename T>
BasicGaussians<U> Cast(const BasicGaussians<T>& g) {
  auto convert = [](const std::vector<T>& v) { return std::vector<U>(v.begin(), v.end()); };
  BasicGaussians<U> out;
  out.sh_degree = g.sh_degree;
  out.positions = convert(g.positions);
  out.rotations = convert(g.rotations);
  out.log_scales = convert(g.log_scales);
  out.opacity_logits = convert(g.opacity_logits);
  out.sh = convert(g.sh);
  return out;
}

}  // namespace atex
