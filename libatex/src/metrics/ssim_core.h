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

// The five filtered maps of SSIM (m, n, e, f, c above) and two work arrays, [height][width][channels] each.
template <typename T>
struct SsimMaps {
  std::vector<T> mx, my, exx, eyy, exy, scratch, product;

  SsimMaps(const T* x, const T* y, int width, int height, int channels, const std::vector<T>& taps) {
    const size_t n = size_t(width) * height * channels;
    for (std::vector<T>* v : {&mx, &my, &exx, &eyy, &exy, &scratch, &product}) v->resize(n);
    GaussianFilterSame(x, mx.data(), scratch.data(), width, height, channels, taps);
    GaussianFilterSame(y, my.data(), scratch.data(), width, height, channels, taps);
    for (size_t i = 0; i < n; ++i) product[i] = x[i] * x[i];
    GaussianFilterSame(product.data(), exx.data(), scratch.data(), width, height, channels, taps);
    for (size_t i = 0; i < n; ++i) product[i] = y[i] * y[i];
    GaussianFilterSame(product.data(), eyy.data(), scratch.data(), width, height, channels, taps);
    for (size_t i = 0; i < n; ++i) product[i] = x[i] * y[i];
    GaussianFilterSame(product.data(), exy.data(), scratch.data(), width, height, channels, taps);
  }
};

// SSIM's four terms at one pixel (A1, A2, B1, B2 above; S = A1·A2 / (B1·B2)) from its maps.
template <typename T>
struct SsimTerms {
  T a1, a2, b1, b2;
  SsimTerms(const SsimMaps<T>& maps, size_t i, T c1, T c2) {
    const T m = maps.mx[i], nn = maps.my[i];
    a1 = 2 * m * nn + c1;
    a2 = 2 * (maps.exy[i] - m * nn) + c2;
    b1 = m * m + nn * nn + c1;
    b2 = (maps.exx[i] - m * m) + (maps.eyy[i] - nn * nn) + c2;
  }
};

// Returns the mean SSIM over the averaged region. When `grad` is not null,
// adds grad_scale · ∂(mean SSIM)/∂x to it. x, y, grad: [height][width][channels].
// Precondition (valid): width, height >= window.
template <typename T>
double SsimMeanAndGrad(const T* x, const T* y, int width, int height, int channels, const SsimParams& params,
                       T grad_scale, T* grad) {
  const size_t n = size_t(width) * height * channels;
  const std::vector<T> taps = GaussianTaps<T>(params.window, params.sigma);
  SsimMaps<T> maps(x, y, width, height, channels, taps);
  std::vector<T>&mx = maps.mx, &my = maps.my, &exx = maps.exx, &eyy = maps.eyy, &exy = maps.exy,
  &scratch = maps.scratch, &product = maps.product;

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
        const auto [a1, a2, b1, b2] = SsimTerms<T>(maps, i, c1, c2);
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

// The mean SSIM of x against y for several parameter sets at once, which differ only in their
// constants (c1, c2): the five filtered maps depend only on the images and the window, so they
// are computed once. Each mean is the value SsimMeanAndGrad returns for its set, bit for bit
// (the same arithmetic in the same order). x, y: [height][width][channels]; `means` gets one
// value per set. Preconditions: `params` is not empty and its sets share window, sigma and
// valid; with valid, width, height >= window.
inline void SsimMeans(const double* x, const double* y, int width, int height, int channels,
                      const std::vector<SsimParams>& params, std::vector<double>* means) {
  const SsimParams& shape = params.front();
  const SsimMaps<double> maps(x, y, width, height, channels, GaussianTaps<double>(shape.window, shape.sigma));
  const int r = shape.valid ? shape.window / 2 : 0;
  const int x0 = r, x1 = width - r, y0 = r, y1 = height - r;
  const double count = double(x1 - x0) * double(y1 - y0) * channels;
  means->assign(params.size(), 0.0);
  for (size_t p = 0; p < params.size(); ++p) {
    double sum = 0;
    for (int py = y0; py < y1; ++py) {
      for (int px = x0; px < x1; ++px) {
        for (int ch = 0; ch < channels; ++ch) {
          const size_t i = (size_t(py) * width + px) * channels + ch;
          const auto [a1, a2, b1, b2] = SsimTerms<double>(maps, i, params[p].c1, params[p].c2);
          sum += a1 * a2 / (b1 * b2);
        }
      }
    }
    (*means)[p] = sum / count;
  }
}

}  // namespace atex::metrics_detail
