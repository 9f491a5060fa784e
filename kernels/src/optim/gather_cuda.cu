#include "optim/gather_cuda.h"

#include "cuda_check.h"

namespace atex::cuda {
namespace {

__global__ void GatherRowsKernel(const float* __restrict__ src, float* __restrict__ dst, int width,
                                 const uint32_t* __restrict__ source, const uint8_t* __restrict__ reset, size_t m) {
  const size_t total = m * width;
  for (size_t e = blockIdx.x * size_t(blockDim.x) + threadIdx.x; e < total; e += size_t(gridDim.x) * blockDim.x) {
    const size_t j = e / width;
    const int c = static_cast<int>(e % width);
    dst[e] = (reset != nullptr && reset[j]) ? 0.0f : src[size_t(source[j]) * width + c];
  }
}

// One warp per destination Gaussian (a block holds at most 16 texels = 64 floats).
__global__ void GatherTexelsKernel(const float* __restrict__ src, const uint32_t* __restrict__ src_offsets,
                                   float* __restrict__ dst, const uint32_t* __restrict__ dst_offsets,
                                   const uint32_t* __restrict__ source, size_t m) {
  const size_t j = (blockIdx.x * size_t(blockDim.x) + threadIdx.x) / 32;
  const int lane = threadIdx.x % 32;
  if (j >= m) return;
  const uint32_t s = source[j];
  const size_t from = size_t(src_offsets[s]) * 4;
  const size_t count = (size_t(src_offsets[s + 1]) - src_offsets[s]) * 4;
  const size_t to = size_t(dst_offsets[j]) * 4;
  for (size_t k = lane; k < count; k += 32) dst[to + k] = src[from + k];
}

int Blocks(size_t count, int threads) {
  const size_t blocks = (count + threads - 1) / threads;
  return static_cast<int>(blocks < 65535 * 8 ? (blocks > 0 ? blocks : 1) : 65535 * 8);
}

}  // namespace

Status GatherRows(const float* src, float* dst, int width, const uint32_t* source, const uint8_t* reset, size_t m,
                  cudaStream_t stream) {
  if (m == 0 || width == 0) return Status::Ok();
  GatherRowsKernel<<<Blocks(m * width, 256), 256, 0, stream>>>(src, dst, width, source, reset, m);
  ATEX_CUDA_CHECK_LAUNCH("GatherRowsKernel");
  return Status::Ok();
}

Status GatherTexelBlocks(const float* src, const uint32_t* src_offsets, float* dst, const uint32_t* dst_offsets,
                         const uint32_t* source, size_t m, cudaStream_t stream) {
  if (m == 0) return Status::Ok();
  const size_t threads = m * 32;
  GatherTexelsKernel<<<static_cast<int>((threads + 255) / 256), 256, 0, stream>>>(src, src_offsets, dst,
                                                                                  dst_offsets, source, m);
  ATEX_CUDA_CHECK_LAUNCH("GatherTexelsKernel");
  return Status::Ok();
}

}  // namespace atex::cuda
