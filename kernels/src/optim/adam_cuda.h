// Fused Adam over one parameter buffer (PyTorch semantics, atex/detail/adam.h).
#pragma once

#include <cstddef>

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

// Element e uses lr_first when (e % period) < split, else lr_rest: this serves the
// SH buffer [N][K][3], where the DC coefficient (period 3K, split 3) has its own rate.
// Elements with lr 0 are left untouched (frozen groups), moments included.
struct AdamLaunch {
  float* params = nullptr;
  const float* grads = nullptr;
  float* m = nullptr;
  float* v = nullptr;
  size_t count = 0;
  float lr_first = 0, lr_rest = 0;
  int period = 1, split = 1;
  float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-15f;
  long long step = 1;  // update count after this update (>= 1), for bias correction
};
Status AdamStep(const AdamLaunch& launch, cudaStream_t stream);

// Sets *flag (device int) to 1 if any of `count` values is NaN or Inf (never clears it).
Status FlagNonFinite(const float* values, size_t count, int* flag, cudaStream_t stream);

}  // namespace atex::cuda
