// Image quality metrics and the training loss (docs/conventions.md §7).
//
//   PSNR   = 10·log10(R² / MSE), MSE over every pixel and channel.
//   SSIM   = mean over pixels and channels of
//            ((2μxμy + C1)(2σxy + C2)) / ((μx² + μy² + C1)(σx² + σy² + C2)),
//            with μ, σ from an 11×11 Gaussian window (σ = 1.5, normalised),
//            C1 = (0.01·R)², C2 = (0.03·R)², population (not sample) covariance.
//            Padding kSame: the window is applied as a zero-padded "same"
//            convolution at every pixel (3DGS's ssim(), used for the loss and for
//            reported SSIM). kValid: only pixels whose window lies inside the
//            image are averaged (scikit-image's structural_similarity with
//            gaussian_weights=True, use_sample_covariance=False).
//   DSSIM_R = (1 − SSIM_R) / 2.
//   Loss   L = (1 − λ)·mean|I − Î| + λ·(1 − SSIM(I, Î)), λ = 0.2, R = 1, kSame.
//
// The Gaussian filter is separable: cost O(W·H·window) per filtered map.
#pragma once

#include <cstdint>

#include "atex/image.h"
#include "atex/status.h"

namespace atex {

enum class SsimPadding { kSame, kValid };

struct SsimOptions {
  double data_range = 1.0;  // R
  SsimPadding padding = SsimPadding::kSame;
  int window = 11;          // odd, >= 1
  double sigma = 1.5;       // > 0
};

// All functions below require images of equal width, height and channel count
// (kInvalidArgument otherwise, naming both shapes) with finite values.

// PSNR in dB; +infinity for identical images.
StatusOr<double> Psnr(const Image& a, const Image& b, double data_range = 1.0);
// Mean SSIM; kInvalidArgument for kValid on an image smaller than the window.
StatusOr<double> Ssim(const Image& a, const Image& b, const SsimOptions& options = {});
// (1 − SSIM)/2 with the given data range (DSSIM₁: 1.0, DSSIM₂: 2.0), kSame padding.
StatusOr<double> Dssim(const Image& a, const Image& b, double data_range);

// Everything a test-view evaluation reports.
struct ImageMetrics {
  double psnr = 0;    // dB, R = 1
  double ssim = 0;    // R = 1, kSame
  double dssim1 = 0;  // (1 − SSIM_{R=1})/2
  double dssim2 = 0;  // (1 − SSIM_{R=2})/2
  double l1 = 0;      // mean |a − b|
  double mse = 0;
};
StatusOr<ImageMetrics> CompareImages(const Image& rendered, const Image& target);

// The photometric training loss of conventions §7 for one RGB image, and its
// gradient with respect to `rendered` when `grad` is not null (overwritten).
//   rendered, grad: [height][width][3]; target: [height][width][3].
// T is float (CPU trainer) or double (gradient checks). Sums are accumulated in
// double; the per-pixel maps are computed in T. Where rendered == target the L1
// term contributes zero gradient (PyTorch's sign(0) = 0).
// Precondition: width, height >= 1, lambda_dssim in [0, 1].
template <typename T>
T PhotometricLoss(const T* rendered, const float* target, int width, int height, double lambda_dssim, T* grad);

extern template float PhotometricLoss<float>(const float*, const float*, int, int, double, float*);
extern template double PhotometricLoss<double>(const double*, const float*, int, int, double, double*);

}  // namespace atex
