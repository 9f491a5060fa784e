// Stage 2: tile intersection. Every visible Gaussian emits one key per tile of its
// rectangle: (tile << 32) | depth bits (depth > near > 0, so the IEEE bits sort like
// the depths). A stable radix sort then orders each tile's list by (depth, index),
// because keys are emitted in index order.
#include "cuda_check.h"
#include "render/render_kernels.h"

namespace atex::cuda::render {
namespace {

__global__ void EmitKeysKernel(RenderInputs in, Projected p, const uint32_t* __restrict__ offsets, int tiles_x,
                               uint64_t* __restrict__ keys, uint32_t* __restrict__ values) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= in.count || p.radius[i] <= 0) return;
  const int4 r = p.rects[i];
  const uint64_t depth_bits = __float_as_uint(p.depth[i]);
  uint32_t k = offsets[i] - p.tiles_touched[i];  // offsets are inclusive ends
  for (int ty = r.y; ty < r.w; ++ty) {
    for (int tx = r.x; tx < r.z; ++tx) {
      const uint64_t tile = uint64_t(ty) * tiles_x + tx;
      keys[k] = (tile << 32) | depth_bits;
      values[k] = static_cast<uint32_t>(i);
      ++k;
    }
  }
}

__global__ void TileRangesKernel(const uint64_t* __restrict__ keys, uint32_t count, uint2* __restrict__ ranges) {
  const uint32_t k = blockIdx.x * blockDim.x + threadIdx.x;
  if (k >= count) return;
  const uint32_t tile = static_cast<uint32_t>(keys[k] >> 32);
  if (k == 0) {
    ranges[tile].x = 0;
  } else {
    const uint32_t previous = static_cast<uint32_t>(keys[k - 1] >> 32);
    if (previous != tile) {
      ranges[previous].y = k;
      ranges[tile].x = k;
    }
  }
  if (k == count - 1) ranges[tile].y = count;
}

}  // namespace

Status LaunchEmitKeys(const RenderInputs& in, const Projected& p, const uint32_t* offsets, int tiles_x,
                      uint64_t* keys, uint32_t* values, cudaStream_t stream) {
  if (in.count == 0) return Status::Ok();
  EmitKeysKernel<<<GridFor(in.count, 256), 256, 0, stream>>>(in, p, offsets, tiles_x, keys, values);
  ATEX_CUDA_CHECK_LAUNCH("EmitKeysKernel");
  return Status::Ok();
}

Status LaunchTileRanges(const uint64_t* sorted_keys, uint32_t count, uint2* ranges, cudaStream_t stream) {
  if (count == 0) return Status::Ok();
  TileRangesKernel<<<GridFor(count, 256), 256, 0, stream>>>(sorted_keys, count, ranges);
  ATEX_CUDA_CHECK_LAUNCH("TileRangesKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::render
