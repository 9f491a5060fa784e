// Rasterisation on the GPU, structured like gsplat: per-Gaussian projection,
// tile intersection (radix sort of tile|depth keys), per-tile rasterisation, each
// with its backward. Computes the functions of docs/conventions.md §4–§6 with the
// same per-element mathematics as the CPU reference (atex/detail/*.h); the forward
// pass's texture sample is rearranged for speed (render/forward_texture.h), equal up to
// float rounding and the hardware tanh.
#pragma once

#include <cstdint>
#include <memory>

#include <cuda_runtime.h>

#include "atex/detail/projection.h"
#include "atex/status.h"

namespace atex::cuda {

// Deformed Gaussians at the view's time and their optional textures (device pointers).
struct RenderInputs {
  int count = 0;                  // N
  int sh_coeffs = 1;              // K of the sh array
  int active_sh_degree = 0;       // degrees above this are ignored
  const float* positions = nullptr;   // [N][3]
  const float* rotations = nullptr;   // [N][4] (w, x, y, z), unnormalised
  const float* log_scales = nullptr;  // [N][3]
  const float* opacity = nullptr;     // [N] logits
  const float* sh = nullptr;          // [N][K][3]
  // Textures (all null = plain 4DGS).
  const float* texels = nullptr;      // [T][4] raw RGBA
  const uint32_t* texel_offsets = nullptr;  // [N+1]
  const uint8_t* texture_layout = nullptr;  // [N][4]: height, width, axis_u, axis_v
  float background[3] = {0, 0, 0};
  ATEX_HD bool textured() const { return texels != nullptr; }
};

// Gradients with respect to the deformed Gaussians, ACCUMULATED (+=).
struct RenderGradients {
  float* positions = nullptr;   // [N][3]
  float* rotations = nullptr;   // [N][4]
  float* log_scales = nullptr;  // [N][3]
  float* opacity = nullptr;     // [N] (w.r.t. the logit)
  float* sh = nullptr;          // [N][K][3]
  float* texels = nullptr;      // [T][4] (null when untextured)
};

// Statistics of one view, ACCUMULATED (+=) per visible Gaussian (null = skip that kind).
struct RenderStats {
  float grad_scale = 1;          // multiplies |dL/dm| to give the single-view loss's gradient
  float* grad_norm_sum = nullptr;  // [N] |dL/dm| in NDC units (conventions §6)
  float* visible_count = nullptr;  // [N]
  float* max_radius = nullptr;     // [N]
  int bins = 0;                    // texture statistics (paper §2), bin of this view's time
  int bin = 0;
  float* demand_sum = nullptr;     // [N][bins]
  float* bin_count = nullptr;      // [N][bins]
  float* scale_u_sum = nullptr;    // [N][bins] deformed scale along axis_u
  float* scale_v_sum = nullptr;    // [N][bins]
};

// The most (tile, Gaussian) pairs one view may have: the tile lists are indexed with 32 bits
// and sorted by CUB with an int count. A view past it is refused with kLimitExceeded.
inline constexpr uint64_t kMaxTileEntries = 0x7FFFFFFFull;

class RenderEngine {
 public:
  explicit RenderEngine(cudaStream_t stream);
  ~RenderEngine();

  // Renders colour [H][W][3] (and alpha [H][W] = 1 − T_final when non-null). When importance is
  // non-null, adds each Gaussian's blending weights over all pixels (+=). Keeps what Backward needs.
  // kLimitExceeded when the workspace does not fit on the device, or the view has more than
  // kMaxTileEntries (tile, Gaussian) pairs.
  Status Forward(const detail::CameraModel<float>& camera, const RenderInputs& in, float* color, float* alpha,
                 float* importance);
  // Backward of the last Forward for dL/dcolor (and dL/dalpha when non-null).
  Status Backward(const detail::CameraModel<float>& camera, const RenderInputs& in, const float* grad_color,
                  const float* grad_alpha, const RenderGradients& grads, const RenderStats* stats);

  // Number of visible Gaussians of the last Forward (copied to the host; synchronises).
  StatusOr<int> VisibleCount();
  size_t workspace_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace atex::cuda
