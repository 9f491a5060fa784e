// The stages of the reference rasteriser (render.h), separately callable so that
// tests can perturb a stage's input (e.g. the projected centres) and check its
// gradient by finite differences. Not part of the public API.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/render.h"

namespace atex::render_internal {

// Engine limits (kLimitExceeded beyond them): no allocation is sized from an
// unchecked count.
inline constexpr int kMaxImageSide = 1 << 15;
inline constexpr uint64_t kMaxPixels = uint64_t{1} << 26;
inline constexpr uint64_t kMaxTileEntries = uint64_t{1} << 27;       // (tile, Gaussian) pairs
inline constexpr uint64_t kMaxEntryTexelValues = uint64_t{1} << 29;  // per-entry texel gradients in backward

Status ValidateCamera(const Camera& camera);
Status ValidateSettings(const RenderSettings& settings);
template <typename T>
Status ValidateGaussians(const BasicGaussians<T>& gaussians);

// Stage 1+2: per-Gaussian projection, SH colour and texture frames, then the tile
// lists. Fills out->radius, mean2d, depth, and out->state except the per-pixel
// arrays. Inputs must be validated.
template <typename T>
Status BuildRenderState(const detail::CameraModel<T>& cam, const BasicGaussians<T>& gaussians,
                        const BasicTexturePool<T>* textures, int sh_degree, BasicRenderOutput<T>* out);

// Stage 3: compositing. Reads out->mean2d and out->state (tile lists, conic, opacity,
// colour, frames); writes color, alpha, importance, final_transmittance, contributor_end.
// Allocation happens before the parallel region (may throw std::bad_alloc).
template <typename T>
void RasterizeForward(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures,
                      const RenderSettings& settings, BasicRenderOutput<T>* out);

// Stage 3 for one tile `t`: composites its pixels into out->color, alpha,
// state.final_transmittance and state.contributor_end (sized by the caller) and adds each
// pair's Σ w to weights[k] for the tile's k-th entry (null: not wanted). `splats` and
// `skip_below` are scratch of LongestTile(*out) entries. RasterizeForward is this over
// every tile; the fitter's probe renderer (src/fit/cpu_probes.cc) calls it for the tiles
// whose splats changed. Instantiated for float.
template <typename T>
void RasterizeTile(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures,
                   const detail::Vec3<T>& background, int t, detail::SplatParams<T>* splats, T* skip_below, T* weights,
                   BasicRenderOutput<T>* out);

// Entries of the longest tile list of a render state.
template <typename T>
inline uint64_t LongestTile(const BasicRenderOutput<T>& out) {
  uint64_t longest = 0;
  const auto& ranges = out.state.tile_ranges;
  for (size_t t = 0; t + 1 < ranges.size(); ++t) longest = std::max(longest, ranges[t + 1] - ranges[t]);
  return longest;
}

// Gradients of the rasteriser's inputs: per Gaussian the SplatGrad (mean2d, conic,
// opacity, c_SH, texture frame) and the texel gradients [texel_count][4].
template <typename T>
struct RasterGradients {
  std::vector<detail::SplatGrad<T>> splats;  // [N]
  std::vector<T> texels;                     // [texel_count][4]
};

// Stage 3 backward. `forward` as left by RasterizeForward.
template <typename T>
Status RasterizeBackward(const detail::CameraModel<T>& cam, const BasicTexturePool<T>* textures,
                         const RenderSettings& settings, const BasicRenderOutput<T>& forward, const T* grad_color,
                         const T* grad_alpha, RasterGradients<T>* out);

// Stage 1 backward: from the rasteriser's input gradients to the Gaussian parameters.
template <typename T>
void ProjectionBackward(const detail::CameraModel<T>& cam, const BasicGaussians<T>& gaussians,
                        const BasicTexturePool<T>* textures, const BasicRenderOutput<T>& forward,
                        const RasterGradients<T>& raster, BasicRenderGradients<T>* out);

// The rasteriser's view of Gaussian `index` (valid for Gaussians in the tile lists).
template <typename T>
inline detail::SplatParams<T> MakeSplatParams(const BasicRenderOutput<T>& out, const BasicTexturePool<T>* textures,
                                              int32_t index) {
  const auto& st = out.state;
  const size_t i = static_cast<size_t>(index);
  detail::SplatParams<T> s;
  s.mean2d = {{out.mean2d[2 * i], out.mean2d[2 * i + 1]}};
  s.conic = {{st.conic[3 * i], st.conic[3 * i + 1], st.conic[3 * i + 2]}};
  s.opacity = st.opacity[i];
  s.color = {{st.color[3 * i], st.color[3 * i + 1], st.color[3 * i + 2]}};
  if (textures != nullptr) {
    s.frame = &st.frames[i];
    s.texels = textures->texels.data() + textures->offsets[i] * 4;
    s.tex_h = textures->heights[i];
    s.tex_w = textures->widths[i];
  } else {
    s.frame = nullptr;
    s.texels = nullptr;
    s.tex_h = s.tex_w = 0;
  }
  return s;
}

// A falloff exponent below which splat `s` cannot reach α̃ ≥ 1/255 even with the
// largest texture factor: power < ln(1/(255 α f_max)) − 1e-3 ⇒ α̃ < 1/255 (the 1e-3
// margin dwarfs exp's rounding). Lets the CPU loops skip exp and the texture sample
// for far pixels without changing any result. +inf for α = 0 (nothing contributes).
template <typename T>
inline T SkipPowerBelow(const detail::SplatParams<T>& s) {
  const double max_factor = s.frame != nullptr ? detail::kTextureAlphaFactorBound : 1.0;
  return static_cast<T>(std::log(detail::kMinSplatAlpha / (double(s.opacity) * max_factor)) - 1e-3);
}

// Gaussian i's quantities as detail vectors.
template <typename T>
inline detail::Vec3<T> Load3(const std::vector<T>& a, size_t i) {
  return {{a[3 * i], a[3 * i + 1], a[3 * i + 2]}};
}
template <typename T>
inline detail::Vec4<T> Load4(const std::vector<T>& a, size_t i) {
  return {{a[4 * i], a[4 * i + 1], a[4 * i + 2], a[4 * i + 3]}};
}

}  // namespace atex::render_internal
