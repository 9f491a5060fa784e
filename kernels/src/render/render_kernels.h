// Launchers of the rasterisation stages (internal to kernels/src/render).
#pragma once

#include <cstdint>

#include <cuda_runtime.h>

#include "atex/detail/composite.h"
#include "atex/detail/projection.h"
#include "atex/status.h"
#include "render/render_cuda.h"

namespace atex::cuda::render {

// Per-Gaussian results of the projection stage (device arrays of the workspace).
struct Projected {
  int32_t* radius = nullptr;          // [N] 0 = not visible
  float* mean2d = nullptr;            // [N][2]
  float* depth = nullptr;             // [N]
  float* conic = nullptr;             // [N][3]
  float* opacity = nullptr;           // [N] sigmoid(logit)
  float* color = nullptr;             // [N][3] c_SH (clamped)
  detail::TextureFrame<float>* frames = nullptr;  // [N] (textured only)
  int4* rects = nullptr;              // [N] tile rectangle (x0, y0, x1, y1)
  uint32_t* tiles_touched = nullptr;  // [N]
};

// The per-Gaussian row of splat gradients ([N][kWidth] floats) that the raster backward
// accumulates (atomically, per warp) and the projection backward reads: dL/d of the
// rasteriser's inputs of detail::SplatGrad, flattened. Written here once; both sides use
// the named offsets (and SplatGradLayout::Store / the Load helpers below).
struct SplatGradLayout {
  static constexpr int kMean2d = 0;       // [2] pixel centre (x, y)
  static constexpr int kConic = 2;        // [3] inverse 2D covariance (a, b, c)
  static constexpr int kOpacity = 5;      // [1] sigmoid(logit)
  static constexpr int kColor = 6;        // [3] c_SH
  static constexpr int kUntexturedWidth = 9;  // an untextured splat's row ends here
  static constexpr int kAxisU = 9;        // [3] texture frame (detail::TextureFrame)
  static constexpr int kAxisV = 12;       // [3]
  static constexpr int kNormal = 15;      // [3]
  static constexpr int kOffsetU = 18;     // [1]
  static constexpr int kOffsetV = 19;     // [1]
  static constexpr int kOffsetN = 20;     // [1]
  static constexpr int kInvScaleU = 21;   // [1]
  static constexpr int kInvScaleV = 22;   // [1]
  static constexpr int kWidth = 23;

  // g as kWidth values in the order above.
  __host__ __device__ static void Store(const detail::SplatGrad<float>& g, float* v) {
    v[kMean2d] = g.mean2d[0];
    v[kMean2d + 1] = g.mean2d[1];
    for (int k = 0; k < 3; ++k) {
      v[kConic + k] = g.conic[k];
      v[kColor + k] = g.color[k];
      v[kAxisU + k] = g.frame.axis_u[k];
      v[kAxisV + k] = g.frame.axis_v[k];
      v[kNormal + k] = g.frame.normal[k];
    }
    v[kOpacity] = g.opacity;
    v[kOffsetU] = g.frame.offset_u;
    v[kOffsetV] = g.frame.offset_v;
    v[kOffsetN] = g.frame.offset_n;
    v[kInvScaleU] = g.frame.inv_scale_u;
    v[kInvScaleV] = g.frame.inv_scale_v;
  }
  // The texture-frame gradient of a stored row.
  __host__ __device__ static detail::TextureFrame<float> LoadFrame(const float* v) {
    detail::TextureFrame<float> f;
    f.axis_u = {{v[kAxisU], v[kAxisU + 1], v[kAxisU + 2]}};
    f.axis_v = {{v[kAxisV], v[kAxisV + 1], v[kAxisV + 2]}};
    f.normal = {{v[kNormal], v[kNormal + 1], v[kNormal + 2]}};
    f.offset_u = v[kOffsetU];
    f.offset_v = v[kOffsetV];
    f.offset_n = v[kOffsetN];
    f.inv_scale_u = v[kInvScaleU];
    f.inv_scale_v = v[kInvScaleV];
    return f;
  }
};
static_assert(SplatGradLayout::kWidth == SplatGradLayout::kInvScaleV + 1 &&
                  SplatGradLayout::kUntexturedWidth == SplatGradLayout::kColor + 3 &&
                  SplatGradLayout::kAxisU == SplatGradLayout::kUntexturedWidth &&
                  SplatGradLayout::kWidth == 2 + 3 + 1 + 3 + 14,
              "splat-gradient row: mean2d 2, conic 3, opacity 1, colour 3, texture frame 14 (3+3+3+5)");
inline constexpr int kSplatGradWidth = SplatGradLayout::kWidth;

// Per-Gaussian gradients of the rasteriser's inputs (accumulated by the raster backward).
struct SplatGrads {
  float* values = nullptr;  // [N][SplatGradLayout::kWidth], zeroed by the caller
};

// The texture data of the splats the backward rasteriser's block streams through shared
// memory (the forward one uses ForwardTextureBatch, render/forward_texture.h), one slot per
// splat of the batch: the frame, the layout (read once per batch instead of once
// per pixel) and the activations of 1×1 textures, which are the same at every pixel.
template <int kSlots>
struct TextureBatch {
  detail::TextureFrame<float> frame[kSlots];
  uint32_t texel_offset[kSlots];
  uchar2 size[kSlots];  // (h, w)
  detail::ConstantTexel<float> constant[kSlots];

  // Gaussian `id` into `slot` (one thread per slot, before the block's __syncthreads).
  __device__ void Load(const RenderInputs& in, const Projected& p, uint32_t id, int slot) {
    frame[slot] = p.frames[id];
    const uchar4 layout = reinterpret_cast<const uchar4*>(in.texture_layout)[id];  // [N][4] bytes
    texel_offset[slot] = in.texel_offsets[id];
    size[slot] = make_uchar2(layout.x, layout.y);
    if (layout.x == 1 && layout.y == 1) {
      constant[slot] = detail::MakeConstantTexel(in.texels + size_t(texel_offset[slot]) * 4);
    }
  }

  // The texture fields of SplatParams for the splat in `slot`.
  __device__ void Fill(const RenderInputs& in, int slot, detail::SplatParams<float>* s) const {
    s->frame = &frame[slot];
    s->texels = in.texels + size_t(texel_offset[slot]) * 4;
    s->tex_h = size[slot].x;
    s->tex_w = size[slot].y;
    s->constant = s->tex_h == 1 && s->tex_w == 1 ? &constant[slot] : nullptr;
  }
};

// Shapes: N = in.count Gaussians, K = in.sh_coeffs, T = tiles_x * tiles_y, E = (tile, Gaussian)
// pairs (the last inclusive prefix sum of tiles_touched), H × W = cam.height × cam.width.
// RenderInputs: positions [N, 3], rotations [N, 4], log_scales [N, 3], opacity [N], sh [N, K, 3],
// texels [texel_count, 4], texel_offsets [N + 1], texture_layout [N, 4] bytes (h, w, axis_u, axis_v).

// Projection, colour and texture frames: fills every array of `out` for [N] Gaussians.
Status LaunchProject(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& out,
                     cudaStream_t stream);

// Emits (tile << 32 | depth bits, index) pairs; `offsets` [N] are the inclusive prefix sums of
// tiles_touched; keys [E], values [E].
Status LaunchEmitKeys(const RenderInputs& in, const Projected& p, const uint32_t* offsets, int tiles_x,
                      uint64_t* keys, uint32_t* values, cudaStream_t stream);
// ranges[t] = [first, last) of tile t in the sorted keys (ranges [T] zeroed by the caller);
// sorted_keys [count].
Status LaunchTileRanges(const uint64_t* sorted_keys, uint32_t count, uint2* ranges, cudaStream_t stream);

// ranges [T], sorted_ids [E]; outputs: color [H, W, 3], alpha [H, W] (may be null),
// final_transmittance [H, W], contributor_end [H, W], importance [N] (added to; may be null).
Status LaunchRasterForward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                           const uint2* ranges, const uint32_t* sorted_ids, float* color, float* alpha,
                           float* final_transmittance, uint32_t* contributor_end, float* importance,
                           cudaStream_t stream);

// ranges [T], sorted_ids [E], final_transmittance [H, W], contributor_end [H, W] as the forward
// left them; grad_color [H, W, 3], grad_alpha [H, W] (may be null). Adds to splat_grads
// [N, SplatGradLayout::kWidth] and grad_texels [texel_count, 4] (textured only).
Status LaunchRasterBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                            const uint2* ranges, const uint32_t* sorted_ids, const float* final_transmittance,
                            const uint32_t* contributor_end, const float* grad_color, const float* grad_alpha,
                            const SplatGrads& splat_grads, float* grad_texels, cudaStream_t stream);

// splat_grads [N, SplatGradLayout::kWidth] → adds to grads: positions [N, 3], rotations [N, 4],
// log_scales [N, 3], opacity [N], sh [N, K, 3]; stats (may be null) per RenderStats.
Status LaunchProjectBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                             const SplatGrads& splat_grads, const RenderGradients& grads, const RenderStats* stats,
                             cudaStream_t stream);

inline int GridFor(size_t count, int threads) {
  const size_t blocks = (count + threads - 1) / threads;
  return static_cast<int>(blocks > 0 ? blocks : 1);
}

}  // namespace atex::cuda::render
