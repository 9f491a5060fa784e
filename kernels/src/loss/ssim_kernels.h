// Launchers of the SSIM / L1 kernels (ssim_kernels.cu). Images are device [H][W][3]
// float; SSIM uses an 11x11 Gaussian window (sigma 1.5) applied as two separable 11-tap
// passes with zero padding and "same" output size (docs/conventions.md §7).
#pragma once

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda::loss_detail {

inline constexpr int kWindow = 11;
struct GaussianWindow {
  float w[kWindow];  // normalised 1-D weights; the 2-D window is their outer product
};
// exp(-(i-5)^2 / (2 sigma^2)) normalised to sum 1, computed in double then rounded.
GaussianWindow MakeGaussianWindow(double sigma);

// Sums over all pixels and channels, added (atomically, in double) to sums[0..2]:
//   sums[0] += sum (1 - S)     (S = the SSIM map)
//   sums[1] += sum |x - y|
//   sums[2] += sum (x - y)^2
// When derivative maps are requested (dmu, dxx, dxy not null), also writes per pixel and
// channel the partial derivatives of S with respect to mu_x, E[x^2] and E[xy] (the
// blurred moments), each [H][W][3]; SsimBackward turns them into dS/dx.
Status LaunchSsimForward(const float* x, const float* y, int width, int height, float c1, float c2,
                         const GaussianWindow& window, float* dmu, float* dxx, float* dxy, double* sums,
                         cudaStream_t stream);

// grad[p] = l1_coeff * sign(x - y) + ssim_coeff * (blur(dmu) + 2 x blur(dxx) + y blur(dxy)) at every pixel and
// channel p (sign(0) = 0; blur = the same zero-padded window, which is its own adjoint).
Status LaunchSsimBackward(const float* x, const float* y, const float* dmu, const float* dxx, const float* dxy,
                          int width, int height, const GaussianWindow& window, float l1_coeff, float ssim_coeff,
                          float* grad, cudaStream_t stream);

// loss[0] += float(scale * ((1 - lambda) * sums[1] + lambda * sums[0]) / count); sse[0] += float(sums[2]) when
// sse is not null.
Status LaunchLossFinalize(const double* sums, double count, double lambda, double scale, float* loss, float* sse,
                          cudaStream_t stream);

}  // namespace atex::cuda::loss_detail
