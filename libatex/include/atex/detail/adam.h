// One Adam update of one scalar, shared by the CPU and CUDA backends
// (PyTorch's formulation with bias correction; 3DGS uses eps = 1e-15).
#pragma once

#include <cmath>

#include "atex/hd.h"

namespace atex::detail {

// bias1 = 1 - beta1^t, bias2 = 1 - beta2^t for the update count t >= 1.
template <typename T>
ATEX_HD void AdamUpdate(T& param, T& m, T& v, T grad, T lr, T beta1, T beta2, T epsilon, T bias1, T bias2) {
  using std::sqrt;
  m = beta1 * m + (T(1) - beta1) * grad;
  v = beta2 * v + (T(1) - beta2) * grad * grad;
  const T denom = sqrt(v) / sqrt(bias2) + epsilon;
  param -= (lr / bias1) * m / denom;
}

}  // namespace atex::detail
