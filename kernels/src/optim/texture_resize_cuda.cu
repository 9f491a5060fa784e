#include "optim/texture_resize_cuda.h"

#include "atex/detail/texture.h"
#include "cuda_check.h"

namespace atex::cuda {
namespace {

__global__ void ResampleKernel(const float* __restrict__ src, const uint8_t* __restrict__ old_layout,
                               const uint32_t* __restrict__ old_offsets, float* __restrict__ dst,
                               const uint8_t* __restrict__ new_layout, const uint32_t* __restrict__ new_offsets,
                               int n, int share_power) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= n) return;
  const int h = old_layout[4 * i], w = old_layout[4 * i + 1], new_h = new_layout[4 * i], new_w = new_layout[4 * i + 1];
  float* out = dst + size_t(new_offsets[i]) * 4;
  detail::UpsampleTexture(src + size_t(old_offsets[i]) * 4, h, w, out, new_h, new_w, 4);
  if (share_power == 0) return;
  const float share = detail::GrownMomentShare<float>(h, w, new_h, new_w);
  const float factor = share_power == 1 ? share : share * share;
  for (int k = 0; k < new_h * new_w * 4; ++k) out[k] *= factor;
}

}  // namespace

Status ResampleTexels(const float* src, const uint8_t* old_layout, const uint32_t* old_offsets, float* dst,
                      const uint8_t* new_layout, const uint32_t* new_offsets, int n, int share_power,
                      cudaStream_t stream) {
  if (n == 0) return Status::Ok();
  if (share_power < 0 || share_power > 2) {
    return MakeError(StatusCode::kInternal, "ResampleTexels: share_power ", share_power);
  }
  ResampleKernel<<<(n + 127) / 128, 128, 0, stream>>>(src, old_layout, old_offsets, dst, new_layout, new_offsets, n,
                                                      share_power);
  ATEX_CUDA_CHECK_LAUNCH("ResampleKernel");
  return Status::Ok();
}

}  // namespace atex::cuda
