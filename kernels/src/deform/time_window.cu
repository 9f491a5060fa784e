#include "deform/time_window_cuda.h"

#include "atex/model.h"
#include "cuda_check.h"

namespace atex::cuda {
namespace {

__global__ void ApplyTimeWindowsKernel(const float* __restrict__ windows, float* __restrict__ opacity_logits, size_t n,
                                       float time) {
  constexpr float kCap = static_cast<float>(kMaxTimeWindowPenalty);
  for (size_t i = blockIdx.x * size_t(blockDim.x) + threadIdx.x; i < n; i += size_t(gridDim.x) * blockDim.x) {
    const float q = windows[2 * i + 1] * (time - windows[2 * i]);
    opacity_logits[i] -= fminf(0.5f * q * q, kCap);
  }
}

}  // namespace

Status ApplyTimeWindows(const float* windows, float* opacity_logits, size_t n, float time, cudaStream_t stream) {
  if (n == 0) return Status::Ok();
  if (windows == nullptr || opacity_logits == nullptr) {
    return MakeError(StatusCode::kInvalidArgument, "ApplyTimeWindows: null windows or opacity logits");
  }
  constexpr int kThreads = 256;
  const size_t blocks = (n + kThreads - 1) / kThreads;
  ApplyTimeWindowsKernel<<<static_cast<unsigned>(blocks < 65535u * 8 ? blocks : 65535u * 8), kThreads, 0, stream>>>(
      windows, opacity_logits, n, time);
  ATEX_CUDA_RETURN_IF_ERROR(cudaGetLastError());
  return Status::Ok();
}

}  // namespace atex::cuda
