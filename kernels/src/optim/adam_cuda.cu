#include "optim/adam_cuda.h"

#include <cmath>

#include "atex/detail/adam.h"
#include "cuda_check.h"

namespace atex::cuda {
namespace {

__global__ void AdamKernel(float* __restrict__ params, const float* __restrict__ grads, float* __restrict__ m,
                           float* __restrict__ v, size_t count, float lr_first, float lr_rest, int period, int split,
                           float beta1, float beta2, float epsilon, float bias1, float bias2) {
  for (size_t e = blockIdx.x * size_t(blockDim.x) + threadIdx.x; e < count; e += size_t(gridDim.x) * blockDim.x) {
    const float lr = static_cast<int>(e % period) < split ? lr_first : lr_rest;
    if (lr == 0.0f) continue;
    float p = params[e], mm = m[e], vv = v[e];
    detail::AdamUpdate(p, mm, vv, grads[e], lr, beta1, beta2, epsilon, bias1, bias2);
    params[e] = p;
    m[e] = mm;
    v[e] = vv;
  }
}

__global__ void NonFiniteKernel(const float* __restrict__ values, size_t count, int* flag) {
  bool bad = false;
  for (size_t e = blockIdx.x * size_t(blockDim.x) + threadIdx.x; e < count; e += size_t(gridDim.x) * blockDim.x) {
    const float x = values[e];
    bad |= !(x - x == 0.0f);
  }
  if (__syncthreads_or(bad) && threadIdx.x == 0) atomicOr(flag, 1);
}

int Blocks(size_t count, int threads) {
  const size_t blocks = (count + threads - 1) / threads;
  return static_cast<int>(blocks < 65535 * 8 ? (blocks > 0 ? blocks : 1) : 65535 * 8);
}

}  // namespace

Status AdamStep(const AdamLaunch& a, cudaStream_t stream) {
  if (a.count == 0) return Status::Ok();
  if (a.step < 1 || a.period < 1) return MakeError(StatusCode::kInternal, "AdamStep: bad step or period");
  const float bias1 = static_cast<float>(1.0 - std::pow(static_cast<double>(a.beta1), static_cast<double>(a.step)));
  const float bias2 = static_cast<float>(1.0 - std::pow(static_cast<double>(a.beta2), static_cast<double>(a.step)));
  AdamKernel<<<Blocks(a.count, 256), 256, 0, stream>>>(a.params, a.grads, a.m, a.v, a.count, a.lr_first, a.lr_rest,
                                                        a.period, a.split, a.beta1, a.beta2, a.epsilon, bias1, bias2);
  ATEX_CUDA_CHECK_LAUNCH("AdamKernel");
  return Status::Ok();
}

Status FlagNonFinite(const float* values, size_t count, int* flag, cudaStream_t stream) {
  if (count == 0) return Status::Ok();
  NonFiniteKernel<<<Blocks(count, 256), 256, 0, stream>>>(values, count, flag);
  ATEX_CUDA_CHECK_LAUNCH("NonFiniteKernel");
  return Status::Ok();
}

}  // namespace atex::cuda
