// The photometric loss on the GPU, forward and backward, computing exactly
// docs/conventions.md §7 (parity with libatex's PhotometricLoss):
//   L = (1 - λ)·mean|x − y| + λ·(1 − SSIM(x, y)), SSIM with an 11×11 Gaussian window (σ = 1.5),
//   zero-padded "same" convolution, data range 1, averaged over pixels and RGB.
#pragma once

#include <cstdint>
#include <memory>

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

class LossEngine {
 public:
  explicit LossEngine(cudaStream_t stream);
  ~LossEngine();

  // rendered, target: device [H][W][3] float. Writes grad = scale · dL/d(rendered) (not accumulated) and
  // adds scale · L to *loss_device (device scalar). Also adds the squared error sum to *sse_device when
  // non-null (for PSNR without another pass).
  Status Compute(const float* rendered, const float* target, int width, int height, float lambda_dssim, float scale,
                 float* grad, float* loss_device, float* sse_device);

  // SSIM only (evaluation), returned to the host.
  StatusOr<double> Ssim(const float* a, const float* b, int width, int height, float data_range);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace atex::cuda
