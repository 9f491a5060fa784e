// The CPU reference rasteriser: 3DGS/gsplat EWA splatting with AdaTex4D's
// per-Gaussian RGBA texture planes (docs/conventions.md §1, §2, §4, §5, §6),
// forward and backward, in float (production) or double (gradient checks).
//
// This is the executable definition of the method: the CUDA backend computes the
// same functions and reuses the per-element mathematics of atex/detail/
// (projection.h, sh.h, texture.h, composite.h). The pipeline is gsplat's:
//   1. per Gaussian: projection (visibility, centre, conic, radius, tile
//      rectangle, depth), SH colour, texture frame;
//   2. per 16×16 tile: the Gaussians whose rectangle covers it, in (depth, index)
//      order;
//   3. per pixel: front-to-back compositing; backward goes back to front from the
//      last contributor.
// Tiles are processed in parallel with OpenMP where available. Per-Gaussian
// gradients are accumulated per (tile, Gaussian) pair and summed in ascending
// tile order, so results are bit-identical for any thread count.
//
// Textures: the texture frame comes from the DEFORMED rotation, centre and scales;
// the texture plane's axes (axis_u, axis_v) are those chosen at attachment from the
// canonical scales (AttachTextures) and never change.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>
#include <vector>

#include "atex/camera.h"
#include "atex/detail/texture.h"
#include "atex/image.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// ---------------------------------------------------------------------------
// Settings and results

// The default near plane, in scene units: the 3DGS rasterizer (and 4DGaussians, whose
// numbers the paper compares with) culls Gaussians at camera z <= 0.2. With 0.01, the
// held-out cameras of Panoptic's dome score 10-13 dB lower on the same trained model
// (BENCHMARKS.md, stage 1; the cause, Gaussians close in front of those cameras, is not verified).
inline constexpr float kDefaultNearPlane = 0.2f;

struct RenderSettings {
  std::array<float, 3> background{0, 0, 0};  // b, RGB
  float near_plane = kDefaultNearPlane;      // Gaussians with camera z <= near are invisible
  int active_sh_degree = 3;                  // 0..3; min(active_sh_degree, gaussians.sh_degree) is evaluated
};

// What RenderBackward needs from the forward pass. Filled by RenderForward; treat as
// opaque (the layout follows the engine, not a format).
template <typename T>
struct BasicRenderState {
  int tiles_x = 0, tiles_y = 0;               // ceil(width/16), ceil(height/16)
  int sh_degree = 0;                          // SH degree evaluated
  bool textured = false;                      // rendered with a texture pool
  std::vector<T> conic;                       // [N][3] (A, B, C) of Σ₂⁻¹ (zero when invisible)
  std::vector<T> opacity;                     // [N] sigmoid(logit)
  std::vector<T> color;                       // [N][3] c_SH (zero when invisible)
  std::vector<detail::TextureFrame<T>> frames;  // [N] texture frames (textured only)
  std::vector<uint64_t> tile_ranges;  // [tiles_y*tiles_x + 1] entries of tile t: [tile_ranges[t], tile_ranges[t+1])
  std::vector<int32_t> tile_gaussians;        // [E] Gaussian of each entry; per tile in (depth, index) order
  std::vector<uint64_t> gaussian_entry_ranges;  // [N+1] Gaussian g owns gaussian_entries[r[g] .. r[g+1])
  std::vector<uint64_t> gaussian_entries;     // [E] entry ids of each Gaussian in ascending tile order
  std::vector<T> final_transmittance;         // [H][W] T_final
  std::vector<int32_t> contributor_end;  // [H][W] 1 + position (in its tile list) of the last added entry, 0 = none
};

template <typename T>
struct BasicRenderOutput {
  int width = 0, height = 0;
  std::vector<T> color;           // [H][W][3] Î = C + T_final b
  std::vector<T> alpha;           // [H][W] 1 − T_final
  std::vector<int32_t> radius;    // [N] rasterised radius in pixels, 0 = not visible (conventions §4.5)
  std::vector<T> mean2d;          // [N][2] projected centre in pixels (zero behind the near plane)
  std::vector<T> depth;           // [N] camera-space z (every Gaussian)
  std::vector<T> importance;      // [N] Σ over pixels of the blending weight w_i = α̃_i T_i
  BasicRenderState<T> state;      // for RenderBackward
};
using RenderOutput = BasicRenderOutput<float>;

template <typename T>
struct BasicRenderGradients {
  BasicGaussians<T> gaussians;    // dL/d(deformed Gaussian parameters), shaped like the input
  std::vector<T> texels;          // [texel_count][4] (empty without textures)
  std::vector<T> mean2d;          // [N][2] dL/d(projected centre) in PIXEL units (through the falloff G only)
};
using RenderGradients = BasicRenderGradients<float>;

// ---------------------------------------------------------------------------
// Rendering

// Renders `gaussians` (already deformed to the camera's time) seen by `camera`.
// `textures` = null renders plain 4DGS; otherwise it must hold one plane per Gaussian.
// Fails with kInvalidArgument (sizes that do not match, camera without size, focal
// length <= 0, world_to_camera not rigid, bad settings), kOutOfRange (NaN/Inf
// anywhere, a zero quaternion, texture dims/axes out of range) or kLimitExceeded
// (image or tile-list size beyond the engine's limits), naming the element.
// (T is deduced from `gaussians`, so `textures` and the gradient pointers may be nullptr.)
template <typename T>
StatusOr<BasicRenderOutput<T>> RenderForward(const Camera& camera, const BasicGaussians<T>& gaussians,
                                             const BasicTexturePool<std::type_identity_t<T>>* textures,
                                             const RenderSettings& settings);

// Gradients of a loss L given dL/dÎ (`grad_color`, [H][W][3]) and optionally
// dL/dalpha (`grad_alpha`, [H][W], may be null). The camera, Gaussians, textures and
// settings must be those of the forward pass `forward`. `out` is resized and zeroed by
// the call; Gaussians that are not visible get zero gradients.
template <typename T>
Status RenderBackward(const Camera& camera, const BasicGaussians<T>& gaussians,
                      const BasicTexturePool<std::type_identity_t<T>>* textures, const RenderSettings& settings,
                      const BasicRenderOutput<T>& forward, const std::type_identity_t<T>* grad_color,
                      const std::type_identity_t<T>* grad_alpha, BasicRenderGradients<T>* out);

// The colour of a float render as an RGB Image (values as rendered, not clamped).
Image RenderedImage(const RenderOutput& output);

// ---------------------------------------------------------------------------
// Texture pools

enum class TextureMode : int { kNone = 0, kUniform = 1, kAdaptive = 2 };
// "none", "uniform", "adaptive" (Metadata::texture_mode).
std::string_view TextureModeName(TextureMode mode);
StatusOr<TextureMode> ParseTextureMode(std::string_view name);

// Structural check of a pool for `gaussian_count` Gaussians: sizes, dims in {1, 2, 4},
// axes in {0, 1, 2} and distinct, offsets = prefix sums of h·w, texels.size() =
// 4·offsets[N], every texel finite.
template <typename T>
Status ValidateTexturePool(const BasicTexturePool<T>& pool, size_t gaussian_count);

// One zero-texel plane per canonical Gaussian: uniform → 4×4, adaptive → 1×1
// (kNone is rejected: no pool). axis_u = the axis of the largest canonical scale,
// axis_v = the second largest (ties: lower axis index).
template <typename T>
StatusOr<BasicTexturePool<T>> AttachTextures(const BasicGaussians<T>& canonical, TextureMode mode);

// A pool with new sides (each in {1, 2, 4}); every Gaussian's texels are resampled
// with detail::UpsampleTexture (corner-aligned bilinear: growth leaves renders
// unchanged up to rounding). Each array in `extra` (e.g. the two Adam moments,
// [texel_count][4] in the old layout) is resampled the same way, in place.
template <typename T>
StatusOr<BasicTexturePool<T>> ResizeTextures(const BasicTexturePool<T>& pool, std::span<const uint8_t> new_heights,
                                             std::span<const uint8_t> new_widths,
                                             std::span<std::vector<T>* const> extra = {});

}  // namespace atex
