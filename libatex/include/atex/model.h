// The in-memory model of an AdaTex4D asset.
//
// Everything is structure-of-arrays with the shapes written next to each field
// ([N][3] = N rows of 3 values, row-major, contiguous). The numeric conventions
// (quaternion order, SH layout, texture addressing, HexPlane layout) are the
// normative ones of docs/conventions.md; the container (format_spec/atex.md)
// stores exactly these arrays.
//
// The Basic* templates exist so that the reference engine can run the same
// code in double precision for gradient checks; the asset itself is float.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/status.h"

namespace atex {

// Number of SH coefficients per colour channel for a degree (0..3): (d+1)^2.
constexpr int ShCoeffCount(int degree) { return (degree + 1) * (degree + 1); }
inline constexpr int kMaxShDegree = 3;

// ---------------------------------------------------------------------------
// Gaussians (canonical, time-independent parameters; also the deformed ones at
// one time, which have the same shape).
template <typename T>
struct BasicGaussians {
  int sh_degree = 0;              // 0..3
  std::vector<T> positions;       // [N][3] world units
  std::vector<T> rotations;       // [N][4] quaternion (w, x, y, z), not necessarily unit; normalised on use
  std::vector<T> log_scales;      // [N][3] natural log of the standard deviations along the local axes
  std::vector<T> opacity_logits;  // [N]    opacity = sigmoid(logit)
  std::vector<T> sh;              // [N][K][3], K = ShCoeffCount(sh_degree); coefficient-major, RGB innermost; k=0 is DC
  // [N][2] (centre c in scene time, inverse width k >= 0) or empty: time-local Gaussians
  // (docs/conventions.md §3, "Time-local Gaussians"). At time t the deformed opacity logit is lowered by
  // TimeWindowPenalty(c, k, t); k = 0 leaves a Gaussian as it is. Empty: none is time-local.
  // Only deformed (4D) models have them; the deformed Gaussians of one time have none.
  std::vector<T> time_windows;

  size_t size() const { return opacity_logits.size(); }
  int sh_coeffs() const { return ShCoeffCount(sh_degree); }
  bool has_time_windows() const { return !time_windows.empty(); }

  // Resizes every array for n Gaussians (new entries are zero; time_windows only when present).
  void Resize(size_t n) {
    positions.resize(n * 3);
    rotations.resize(n * 4);
    log_scales.resize(n * 3);
    opacity_logits.resize(n);
    sh.resize(n * static_cast<size_t>(sh_coeffs()) * 3);
    if (!time_windows.empty()) time_windows.resize(n * 2);
  }
};

// The largest amount TimeWindowPenalty takes off a logit: far outside its window a
// Gaussian's opacity is sigmoid(logit - 40) < 1e-17, and every value stays finite.
inline constexpr double kMaxTimeWindowPenalty = 40.0;
// The time window of a time-local Gaussian, in logit space: ½(k·(t − c))², capped at
// kMaxTimeWindowPenalty (docs/conventions.md §3, "Time-local Gaussians"). 0 when k = 0.
template <typename T>
T TimeWindowPenalty(T centre, T inverse_width, double time) {
  const double q = double(inverse_width) * (time - double(centre));
  const double penalty = 0.5 * q * q;
  return static_cast<T>(penalty < kMaxTimeWindowPenalty ? penalty : kMaxTimeWindowPenalty);
}
using Gaussians = BasicGaussians<float>;

// ---------------------------------------------------------------------------
// Packed variable-size texture pool: one RGBA plane per Gaussian.
inline constexpr int kMaxTextureSide = 4;  // each side in {1, 2, 4}
inline constexpr int kTexelChannels = 4;   // raw R, G, B, A parameters (before tanh)

template <typename T>
struct BasicTexturePool {
  std::vector<uint8_t> heights;   // [N] texels along v (the axis_v direction), in {1, 2, 4}
  std::vector<uint8_t> widths;    // [N] texels along u (the axis_u direction), in {1, 2, 4}
  std::vector<uint8_t> axis_u;    // [N] canonical local axis p in {0, 1, 2} spanning u
  std::vector<uint8_t> axis_v;    // [N] canonical local axis q in {0, 1, 2}, q != p, spanning v
  std::vector<uint64_t>
      offsets;  // [N+1] first texel of Gaussian i; DERIVED (exclusive prefix sum of h*w), never stored
  std::vector<T> texels;          // [offsets[N]][h][w][4] packed; Gaussian i owns rows offsets[i] .. offsets[i+1]-1,
                                  // row-major over (v, u), RGBA innermost

  size_t size() const { return heights.size(); }
  uint64_t texel_count() const { return offsets.empty() ? 0 : offsets.back(); }

  // Recomputes offsets from heights and widths. Call after changing dims.
  void RebuildOffsets() {
    offsets.assign(heights.size() + 1, 0);
    for (size_t i = 0; i < heights.size(); ++i) {
      offsets[i + 1] = offsets[i] + static_cast<uint64_t>(heights[i]) * widths[i];
    }
  }
};
using TexturePool = BasicTexturePool<float>;

// ---------------------------------------------------------------------------
// Deformation field: HexPlane grids + MLP trunk + five residual heads, as in
// 4DGaussians (docs/conventions.md, "Deformation field").
enum DeformHead : int { kHeadPosition = 0, kHeadScale = 1, kHeadRotation = 2, kHeadOpacity = 3, kHeadSH = 4 };
inline constexpr int kNumDeformHeads = 5;
inline constexpr int kNumHexPlanes = 6;  // xy, xz, xt, yz, yt, zt (itertools.combinations order)
// Coordinate pairs (a, b) of each plane; the plane tensor is [C][res_b][res_a].
inline constexpr std::array<std::array<int, 2>, kNumHexPlanes> kHexPlaneAxes = {
    {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

struct HexPlaneConfig {
  int channels = 32;                                // C, features per plane
  std::array<int, 4> base_resolution{64, 64, 64, 25};  // x, y, z, t
  std::vector<int> multires{1, 2};                  // spatial multipliers, one grid set per entry

  int scales() const { return static_cast<int>(multires.size()); }
  // Resolution of coordinate `axis` (0..3) at scale `s`; time is never multiplied.
  int resolution(int s, int axis) const { return axis == 3 ? base_resolution[3] : base_resolution[axis] * multires[s]; }
  int feature_dim() const { return channels * scales(); }
};

struct DeformationConfig {
  HexPlaneConfig grid;
  int mlp_width = 64;   // W
  int trunk_layers = 1; // Linear(feat, W), then (trunk_layers - 1) x [ReLU, Linear(W, W)]
  std::array<bool, kNumDeformHeads> heads{true, true, true, false, false};
  int sh_coeffs = 1;    // K of the Gaussians this field deforms (dSH head has 3K outputs)
  // Space: x_norm = (x - aabb_lo) * 2 / (aabb_hi - aabb_lo) - 1, per axis (lo > hi is allowed).
  std::array<float, 3> aabb_lo{-1, -1, -1};
  std::array<float, 3> aabb_hi{1, 1, 1};
  // Time: t_norm = time_scale * t + time_offset. Native assets map [time_min, time_max] onto [-1, 1].
  float time_scale = 2.0f;
  float time_offset = -1.0f;

  // Output size of head h: 3, 3, 4, 1, 3K.
  int head_outputs(int h) const {
    switch (h) {
      case kHeadPosition: return 3;
      case kHeadScale: return 3;
      case kHeadRotation: return 4;
      case kHeadOpacity: return 1;
      default: return 3 * sh_coeffs;
    }
  }
};

template <typename T>
struct BasicLinear {
  int in = 0, out = 0;
  std::vector<T> weight;  // [out][in] (PyTorch nn.Linear layout)
  std::vector<T> bias;    // [out]
};

template <typename T>
struct BasicDeformationField {
  DeformationConfig config;
  // planes[s][p]: [C][res_b][res_a] for scale s and plane p (kHexPlaneAxes[p] = (a, b)).
  std::vector<std::array<std::vector<T>, kNumHexPlanes>> planes;
  std::vector<BasicLinear<T>> trunk;                                   // trunk_layers layers
  std::array<std::array<BasicLinear<T>, 2>, kNumDeformHeads>
      heads;  // [h][0]: W->W, [h][1]: W->head_outputs(h); empty if off
};
using DeformationField = BasicDeformationField<float>;
using Linear = BasicLinear<float>;

// ---------------------------------------------------------------------------
// Per-Gaussian statistics that training leaves for `atex fit` (optional).
struct GaussianStats {
  std::vector<float> texture_demand;  // [N] score g of the last growth evaluation (paper eq. 5); 0 if never visible
  std::vector<float> peak_scale_u;    // [N] mean deformed in-plane scale along u in the highest-demand bin
  std::vector<float> peak_scale_v;    // [N] same along v
  std::vector<float> importance;      // [N] accumulated blending weight (sum of w_i over rendered pixels)
  size_t size() const { return importance.size(); }
};

// ---------------------------------------------------------------------------
// Scene metadata (stored as JSON in the META chunk).
struct Metadata {
  std::array<float, 3> bounds_min{0, 0, 0};  // scene AABB of the canonical positions
  std::array<float, 3> bounds_max{0, 0, 0};
  float time_min = 0.0f;                     // scene time range, in the dataset's time units
  float time_max = 1.0f;
  std::array<float, 3> background{0, 0, 0};  // RGB in [0, 1]
  std::string texture_mode = "none";         // "none", "uniform" or "adaptive"
  std::string axes = "opencv";               // camera convention of the cameras it was trained with
  // World up axis: "+x", "-x", "+y", "-y", "+z" or "-z"; empty when the file does not
  // record it (older files: WorldUpAxis in atex/world_up.h derives it from `axes`).
  std::string up;
  std::string units = "unknown";             // world units, e.g. "meters"
  nlohmann::json extra = nlohmann::json::object();  // provenance: trainer, config, dataset, commit, date
};

// ---------------------------------------------------------------------------
struct Asset {
  Gaussians gaussians;
  std::optional<TexturePool> textures;          // absent: plain 4DGS
  std::optional<DeformationField> deformation;  // absent: static scene
  std::optional<GaussianStats> stats;
  Metadata metadata;
};

// Structural validation of an in-memory asset: array sizes agree with N and
// the configs, texture dims in {1,2,4}, axes valid and distinct, offsets match
// the dims, every float finite. The message names the array and element index.
Status ValidateAsset(const Asset& asset);

// Metadata <-> JSON (the META chunk's content).
nlohmann::json MetadataToJson(const Metadata& metadata);
StatusOr<Metadata> MetadataFromJson(const nlohmann::json& json);

}  // namespace atex
