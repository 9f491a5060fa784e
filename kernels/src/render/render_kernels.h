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

// Per-Gaussian gradients of the rasteriser's inputs (accumulated by the raster backward).
struct SplatGrads {
  float* values = nullptr;  // [N][kSplatGradWidth], see SplatGradLayout in rasterize_backward.cu
};
inline constexpr int kSplatGradWidth = 2 + 3 + 1 + 3 + 14;  // mean2d, conic, opacity, color, frame

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

Status LaunchProject(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& out,
                     cudaStream_t stream);

// Emits (tile << 32 | depth bits, index) pairs; `offsets` are the inclusive prefix sums of tiles_touched.
Status LaunchEmitKeys(const RenderInputs& in, const Projected& p, const uint32_t* offsets, int tiles_x,
                      uint64_t* keys, uint32_t* values, cudaStream_t stream);
// ranges[t] = [first, last) of tile t in the sorted keys (ranges zeroed by the caller).
Status LaunchTileRanges(const uint64_t* sorted_keys, uint32_t count, uint2* ranges, cudaStream_t stream);

Status LaunchRasterForward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                           const uint2* ranges, const uint32_t* sorted_ids, float* color, float* alpha,
                           float* final_transmittance, uint32_t* contributor_end, float* importance,
                           cudaStream_t stream);

Status LaunchRasterBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                            const uint2* ranges, const uint32_t* sorted_ids, const float* final_transmittance,
                            const uint32_t* contributor_end, const float* grad_color, const float* grad_alpha,
                            const SplatGrads& splat_grads, float* grad_texels, cudaStream_t stream);

Status LaunchProjectBackward(const detail::CameraModel<float>& cam, const RenderInputs& in, const Projected& p,
                             const SplatGrads& splat_grads, const RenderGradients& grads, const RenderStats* stats,
                             cudaStream_t stream);

inline int GridFor(size_t count, int threads) {
  const size_t blocks = (count + threads - 1) / threads;
  return static_cast<int>(blocks > 0 ? blocks : 1);
}

}  // namespace atex::cuda::render
