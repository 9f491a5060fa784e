// Row gathers for densification / pruning edits (GaussianEdit in train/backend.h).
#pragma once

#include <cstddef>
#include <cstdint>

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

// dst[j][:] = src[source[j]][:] for j < m, rows of `width` floats; when reset is non-null and
// reset[j] != 0 the row is zeroed instead (fresh Adam moments).
Status GatherRows(const float* src, float* dst, int width, const uint32_t* source, const uint8_t* reset, size_t m,
                  cudaStream_t stream);

// Variable-size blocks: dst[dst_offset[j] .. + 4*count[j]) = src[src_offset[source[j]] ..], in floats
// (texel rows of 4); offsets are in texels.
Status GatherTexelBlocks(const float* src, const uint32_t* src_offsets, float* dst, const uint32_t* dst_offsets,
                         const uint32_t* source, size_t m, cudaStream_t stream);

}  // namespace atex::cuda
