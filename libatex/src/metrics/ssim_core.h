// SSIM of two interleaved images and its gradient with respect to the first,
// templated on the scalar type. Not a public header.
//
// With m = G⊛x, n = G⊛y, e = G⊛x², f = G⊛y², c = G⊛(xy) (zero-padded "same"):
//   A1 = 2mn + C1, A2 = 2(c − mn) + C2, B1 = m² + n² + C1, B2 = (e − m²) + (f − n²) + C2,
//   S = A1·A2 / (B1·B2)
//   ∂S/∂m = 2n(A2 − A1)/(B1B2) − 2m·S/B1 + 2m·S/B2,  ∂S/∂e = −S/B2,  ∂S/∂c = 2A1/(B1B2)
// and, G being symmetric (self-adjoint with zero padding),
//   ∂L/∂x = G⊛(g·∂S/∂m) + 2x·G⊛(g·∂S/∂e) + y·G⊛(g·∂S/∂c), g = ∂L/∂S per pixel.
#pragma once

#include <vector>

#include "metrics/gaussian_filter.h"

namespace atex::metrics_detail {

struct SsimParams {
  double c1 = 0, c2 = 0;
  int window = 11;
  double sigma = 1.5;
  bool valid = false;  // average only where the window lies inside the image
};

// Returns the mean SSIM over the averaged region. When `grad` is not null,
// adds grad_scale · ∂(mean SSIM)/∂x to it. x, y, grad: [height][width][channels].
// Precondition (valid): width, height >= window.
template <typename T>
double SsimMeanAndGrad(const T* x, const T* y, int width, int height, int channels, const SsimParams& params,
                       T grad_scale, T* grad) {
  const size_t n = size_t(width) * height * channels;
  const std::vector<T> taps = GaussianTaps<T>(params.window, params.sigma);
  std::vector<T> mx(n), my(n), exx(n), eyy(n), exy(n), scratch(n), product(n);
  GaussianFilterSame(x, mx.data(), scratch.data(), width, height, channels, taps);
  GaussianFilterSame(y, my.data(), scratch.data(), width, height, channels, taps);
  for (size_t i = 0; i < n; ++i) product[i] = x[i] * x[i];
  GaussianFilterSame(product.data(), exx.data(), scratch.data(), width, height, channels, taps);
  for (size_t i = 0; i < n; ++i) product[i] = y[i] * y[i];
  GaussianFilterSame(product.data(), eyy.data(), scratch.data(), width, height, channels, taps);
  for (size_t i = 0; i < n; ++i) product[i] = x[i] * y[i];
  GaussianFilterSame(product.data(), exy.data(), scratch.data(), width, height, channels, taps);

  const int r = params.valid ? params.window / 2 : 0;
  const int x0 = r, x1 = width - r, y0 = r, y1 = height - r;
  const double count = double(x1 - x0) * double(y1 - y0) * channels;
  const T c1 = static_cast<T>(params.c1), c2 = static_cast<T>(params.c2);
  const T g = grad ? static_cast<T>(grad_scale / count) : T(0);  // ∂L/∂S of each averaged pixel
  double sum = 0;
  // When a gradient is wanted, the three ∂L/∂(m, e, c) maps reuse mx, exx, exy (zero outside the region).
  for (int py = 0; py < height; ++py) {
    for (int px = 0; px < width; ++px) {
      const bool inside = px >= x0 && px < x1 && py >= y0 && py < y1;
      for (int ch = 0; ch < channels; ++ch) {
        const size_t i = (size_t(py) * width + px) * channels + ch;
        const T m = mx[i], nn = my[i];
        const T a1 = 2 * m * nn + c1;
        const T a2 = 2 * (exy[i] - m * nn) + c2;
        const T b1 = m * m + nn * nn + c1;
        const T b2 = (exx[i] - m * m) + (eyy[i] - nn * nn) + c2;
        const T denominator = b1 * b2;
        const T s = a1 * a2 / denominator;
        if (inside) sum += static_cast<double>(s);
        if (grad) {
          if (inside) {
            mx[i] = g * (2 * nn * (a2 - a1) / denominator - 2 * m * s / b1 + 2 * m * s / b2);
            exx[i] = g * (-s / b2);
            exy[i] = g * (2 * a1 / denominator);
          } else {
            mx[i] = exx[i] = exy[i] = T(0);
          }
        }
      }
    }
  }
  if (grad) {
    GaussianFilterSame(mx.data(), my.data(), scratch.data(), width, height, channels, taps);     // my := G⊛dm
    GaussianFilterSame(exx.data(), eyy.data(), scratch.data(), width, height, channels, taps);   // eyy := G⊛de
    GaussianFilterSame(exy.data(), product.data(), scratch.data(), width, height, channels, taps);  // product := G⊛dc
    for (size_t i = 0; i < n; ++i) grad[i] += my[i] + 2 * x[i] * eyy[i] + y[i] * product[i];
  }
  return sum / count;
}

}  // namespace atex::metrics_detail
