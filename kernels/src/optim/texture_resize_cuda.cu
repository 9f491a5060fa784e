#include "optim/texture_resize_cuda.h"

#include "atex/detail/texture.h"
#include "cuda_check.h"

namespace atex::cuda {
namespace {

__global__ void ResampleKernel(const float* __restrict__ src, const uint8_t* __restrict__ old_layout,
                               const uint32_t* __restrict__ old_offsets, float* __restrict__ dst,
                               const uint8_t* __restrict__ new_layout, const uint32_t* __restrict__ new_offsets,
                               int n) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  detail::UpsampleTexture(src + size_t(old_offsets[i]) * 4, old_layout[4 * i], old_layout[4 * i + 1],
                          dst + size_t(new_offsets[i]) * 4, new_layout[4 * i], new_layout[4 * i + 1], 4);
}

}  // namespace

Status ResampleTexels(const float* src, const uint8_t* old_layout, const uint32_t* old_offsets, float* dst,
                      const uint8_t* new_layout, const uint32_t* new_offsets, int n, cudaStream_t stream) {
  if (n == 0) return Status::Ok();
  ResampleKernel<<<(n + 127) / 128, 128, 0, stream>>>(src, old_layout, old_offsets, dst, new_layout, new_offsets, n);
  ATEX_CUDA_CHECK_LAUNCH("ResampleKernel");
  return Status::Ok();
}

}  // namespace atex::cuda
