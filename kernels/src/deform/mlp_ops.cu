// The small memory-bound kernels around the MLP's GEMMs: bias + ReLU, residual bias,
// accumulation, and the backward column kernels (ReLU mask, bias gradients, the data
// gradient of the narrow head output layers fused with the mask).
//
// Column kernels use 32x8 thread blocks: threadIdx.x walks 32 adjacent columns (one
// coalesced row segment per warp), threadIdx.y and blockIdx.y stride over rows, and each
// thread keeps its column's partial sum in a register; the 8 partials of a block are
// combined in shared memory and added with one atomic per column and block.
#include <algorithm>
#include <cstdint>

#include "cuda_check.h"
#include "deform/deform_internal.h"

namespace atex::cuda::deform_detail {
namespace {

constexpr int kThreads1d = 256;
constexpr int kTileCols = 32;
constexpr int kTileRows = 8;

unsigned Blocks1d(int64_t count) {
  const int64_t blocks = (count + kThreads1d - 1) / kThreads1d;
  return static_cast<unsigned>(std::min<int64_t>(blocks, 1 << 20));  // grid-stride loops cover the rest
}

__global__ void BiasReluKernel(float* x, const float* __restrict__ bias, int64_t count, int width) {
  for (int64_t i = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x; i < count;
       i += static_cast<int64_t>(gridDim.x) * blockDim.x) {
    const float v = x[i] + __ldg(bias + i % width);
    x[i] = v > 0.0f ? v : 0.0f;
  }
}

__global__ void AddBiasKernel(const float* in, const float* __restrict__ bias, int64_t count, int width, float* out) {
  for (int64_t i = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x; i < count;
       i += static_cast<int64_t>(gridDim.x) * blockDim.x) {
    out[i] = in[i] + __ldg(bias + i % width);
  }
}

__global__ void AccumulateKernel(float* dst, const float* __restrict__ src, int64_t count) {
  for (int64_t i = blockIdx.x * static_cast<int64_t>(blockDim.x) + threadIdx.x; i < count;
       i += static_cast<int64_t>(gridDim.x) * blockDim.x) {
    dst[i] += src[i];
  }
}

// Adds the block's per-column partial sums to sums[column] (one atomic per column).
__device__ __forceinline__ void FlushColumnSums(float partial, int column, int width, float* sums) {
  __shared__ float part[kTileRows][kTileCols + 1];
  part[threadIdx.y][threadIdx.x] = partial;
  __syncthreads();
  if (threadIdx.y == 0 && column < width) {
    float total = 0.0f;
#pragma unroll
    for (int r = 0; r < kTileRows; ++r) total += part[r][threadIdx.x];
    atomicAdd(sums + column, total);
  }
}

__global__ void ColumnSumKernel(const float* __restrict__ x, int64_t rows, int width, int ld, float* sums) {
  const int column = blockIdx.x * kTileCols + threadIdx.x;
  float partial = 0.0f;
  if (column < width) {
    for (int64_t r = blockIdx.y * static_cast<int64_t>(kTileRows) + threadIdx.y; r < rows;
         r += static_cast<int64_t>(gridDim.y) * kTileRows) {
      partial += x[r * ld + column];
    }
  }
  FlushColumnSums(partial, column, width, sums);
}

__global__ void ReluBackwardKernel(float* d, const float* __restrict__ post, int64_t rows, int width, int ld,
                                   float* bias_grad) {
  const int column = blockIdx.x * kTileCols + threadIdx.x;
  float partial = 0.0f;
  if (column < width) {
    for (int64_t r = blockIdx.y * static_cast<int64_t>(kTileRows) + threadIdx.y; r < rows;
         r += static_cast<int64_t>(gridDim.y) * kTileRows) {
      const int64_t i = r * ld + column;
      const float v = post[i] > 0.0f ? d[i] : 0.0f;
      d[i] = v;
      partial += v;
    }
  }
  if (bias_grad) FlushColumnSums(partial, column, width, bias_grad);  // uniform branch: bias_grad is a parameter
}

// Dynamic shared memory: weight[k_count][32] of this block's columns.
__global__ void NarrowLinearBackwardKernel(const float* __restrict__ g, int k_count, const float* __restrict__ weight,
                                           const float* __restrict__ post, int64_t rows, int width, int ld, float* d,
                                           float* bias_grad) {
  extern __shared__ float weight_tile[];  // [k_count][kTileCols]
  const int column0 = blockIdx.x * kTileCols;
  const int tid = threadIdx.y * kTileCols + threadIdx.x;
  for (int i = tid; i < k_count * kTileCols; i += kTileCols * kTileRows) {
    const int k = i / kTileCols;
    const int c = column0 + i % kTileCols;
    weight_tile[i] = c < width ? weight[static_cast<int64_t>(k) * width + c] : 0.0f;
  }
  __syncthreads();
  const int column = column0 + threadIdx.x;
  float partial = 0.0f;
  if (column < width) {
    for (int64_t r = blockIdx.y * static_cast<int64_t>(kTileRows) + threadIdx.y; r < rows;
         r += static_cast<int64_t>(gridDim.y) * kTileRows) {
      const int64_t i = r * ld + column;
      float v = 0.0f;
      if (post[i] > 0.0f) {
        const float* g_row = g + r * k_count;  // the same address across the warp: a broadcast
        for (int k = 0; k < k_count; ++k) v += __ldg(g_row + k) * weight_tile[k * kTileCols + threadIdx.x];
      }
      d[i] = v;
      partial += v;
    }
  }
  if (bias_grad) FlushColumnSums(partial, column, width, bias_grad);
}

dim3 ColumnGrid(int64_t rows, int width) {
  const unsigned column_tiles = static_cast<unsigned>((width + kTileCols - 1) / kTileCols);
  const int64_t row_tiles = (rows + kTileRows - 1) / kTileRows;
  // About 4096 blocks in all is plenty to fill the GPU; more only adds atomics.
  const int64_t cap = std::max<int64_t>(1, 4096 / static_cast<int64_t>(column_tiles));
  return dim3(column_tiles,
              static_cast<unsigned>(std::max<int64_t>(1, std::min(row_tiles, std::min<int64_t>(cap, 65535)))));
}

}  // namespace

Status LaunchBiasRelu(float* x, const float* bias, int64_t rows, int width, cudaStream_t stream) {
  const int64_t count = rows * width;
  if (count <= 0) return Status::Ok();
  BiasReluKernel<<<Blocks1d(count), kThreads1d, 0, stream>>>(x, bias, count, width);
  ATEX_CUDA_CHECK_LAUNCH("BiasReluKernel");
  return Status::Ok();
}

Status LaunchAddBias(const float* in, const float* bias, int64_t rows, int width, float* out, cudaStream_t stream) {
  const int64_t count = rows * width;
  if (count <= 0) return Status::Ok();
  AddBiasKernel<<<Blocks1d(count), kThreads1d, 0, stream>>>(in, bias, count, width, out);
  ATEX_CUDA_CHECK_LAUNCH("AddBiasKernel");
  return Status::Ok();
}

Status LaunchAccumulate(float* dst, const float* src, int64_t count, cudaStream_t stream) {
  if (count <= 0) return Status::Ok();
  AccumulateKernel<<<Blocks1d(count), kThreads1d, 0, stream>>>(dst, src, count);
  ATEX_CUDA_CHECK_LAUNCH("AccumulateKernel");
  return Status::Ok();
}

Status LaunchColumnSumAdd(const float* x, int64_t rows, int width, int ld, float* sums, cudaStream_t stream) {
  if (rows <= 0 || width <= 0) return Status::Ok();
  ColumnSumKernel<<<ColumnGrid(rows, width), dim3(kTileCols, kTileRows), 0, stream>>>(x, rows, width, ld, sums);
  ATEX_CUDA_CHECK_LAUNCH("ColumnSumKernel");
  return Status::Ok();
}

Status LaunchReluBackward(float* d, const float* post, int64_t rows, int width, int ld, float* bias_grad,
                          cudaStream_t stream) {
  if (rows <= 0 || width <= 0) return Status::Ok();
  ReluBackwardKernel<<<ColumnGrid(rows, width), dim3(kTileCols, kTileRows), 0, stream>>>(d, post, rows, width, ld,
                                                                                       bias_grad);
  ATEX_CUDA_CHECK_LAUNCH("ReluBackwardKernel");
  return Status::Ok();
}

Status LaunchNarrowLinearBackward(const float* g, int k_count, const float* weight, const float* post, int64_t rows,
                                  int width, int ld, float* d, float* bias_grad, cudaStream_t stream) {
  if (rows <= 0 || width <= 0) return Status::Ok();
  if (k_count < 1 || k_count > kMaxHeadOutputs) {
    return MakeError(StatusCode::kInternal, "NarrowLinearBackward: ", k_count, " outputs");
  }
  const size_t shared = static_cast<size_t>(k_count) * kTileCols * sizeof(float);  // <= 32 KiB
  NarrowLinearBackwardKernel<<<ColumnGrid(rows, width), dim3(kTileCols, kTileRows), shared, stream>>>(
      g, k_count, weight, post, rows, width, ld, d, bias_grad);
  ATEX_CUDA_CHECK_LAUNCH("NarrowLinearBackwardKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::deform_detail
