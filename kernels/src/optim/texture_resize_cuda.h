// Texture growth on the device: every Gaussian's texels (and the same for both Adam
// moments) resampled onto its new grid with detail::UpsampleTexture.
#pragma once

#include <cstdint>

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

// For each of the n Gaussians: src block (old_layout h×w at old_offsets) → dst block (new_layout h'×w' at
// new_offsets). Layouts are [N][4] (h, w, axis_u, axis_v); offsets [N+1] in texels; texel rows of 4.
// share_power p in {0, 1, 2}: each resampled block is multiplied by GrownMomentShare^p (texels: 0;
// rescaled Adam moments m: 1, v: 2).
Status ResampleTexels(const float* src, const uint8_t* old_layout, const uint32_t* old_offsets, float* dst,
                      const uint8_t* new_layout, const uint32_t* new_offsets, int n, int share_power,
                      cudaStream_t stream);

}  // namespace atex::cuda
