// The photometric training loss (conventions §7) and its gradient.
#include <cmath>
#include <vector>

#include "atex/metrics.h"
#include "metrics/ssim_core.h"

namespace atex {

template <typename T>
T PhotometricLoss(const T* rendered, const float* target, int width, int height, double lambda_dssim, T* grad) {
  const size_t n = size_t(width) * height * 3;
  const double l1_weight = 1.0 - lambda_dssim;
  // L1 term: mean |r − t|; its gradient is sign(r − t)/n (zero where equal).
  const T l1_grad = static_cast<T>(l1_weight / double(n));
  double abs_sum = 0;
  for (size_t i = 0; i < n; ++i) {
    const T d = rendered[i] - static_cast<T>(target[i]);
    abs_sum += std::abs(static_cast<double>(d));
    if (grad) grad[i] = d > 0 ? l1_grad : (d < 0 ? -l1_grad : T(0));
  }
  double loss = l1_weight * abs_sum / double(n);
  if (lambda_dssim != 0) {
    std::vector<T> y(target, target + n);  // the target in T precision
    metrics_detail::SsimParams params;
    params.c1 = 0.01 * 0.01;
    params.c2 = 0.03 * 0.03;
    const double ssim = metrics_detail::SsimMeanAndGrad<T>(rendered, y.data(), width, height, 3, params,
                                                           static_cast<T>(-lambda_dssim), grad);
    loss += lambda_dssim * (1.0 - ssim);
  }
  return static_cast<T>(loss);
}

template float PhotometricLoss<float>(const float*, const float*, int, int, double, float*);
template double PhotometricLoss<double>(const double*, const float*, int, int, double, double*);

}  // namespace atex
