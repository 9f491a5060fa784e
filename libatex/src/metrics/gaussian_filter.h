// Separable, zero-padded ("same") Gaussian filtering of interleaved images,
// shared by SSIM and the training loss. Not a public header.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

namespace atex::metrics_detail {

// Normalised 1-D Gaussian taps exp(−k²/(2σ²)) for k = −r..r, r = window/2. [window]
template <typename T>
std::vector<T> GaussianTaps(int window, double sigma) {
  const int r = window / 2;
  std::vector<double> taps(window);
  double sum = 0;
  for (int k = -r; k <= r; ++k) sum += taps[k + r] = std::exp(-double(k) * k / (2 * sigma * sigma));
  std::vector<T> out(window);
  for (int i = 0; i < window; ++i) out[i] = static_cast<T>(taps[i] / sum);
  return out;
}

// out = G ⊛ in with zero padding, per channel. The filter is symmetric, so it is
// also its own adjoint (used by the backward pass).
//   in, out: [height][width][channels]; scratch: [height][width][channels] work space.
template <typename T>
void GaussianFilterSame(const T* in, T* out, T* scratch, int width, int height, int channels,
                        const std::vector<T>& taps) {
  const int r = static_cast<int>(taps.size()) / 2;
  const size_t row = size_t(width) * channels;
  // Horizontal pass into scratch: for each tap, a contiguous multiply-add over the valid range.
  for (int y = 0; y < height; ++y) {
    const T* src = in + size_t(y) * row;
    T* dst = scratch + size_t(y) * row;
    std::fill(dst, dst + row, T(0));
    for (int k = -r; k <= r; ++k) {
      const T w = taps[k + r];
      const int x0 = std::max(0, -k), x1 = std::min(width, width - k);
      if (x0 >= x1) continue;
      const T* s = src + ptrdiff_t(k) * channels;
      for (size_t i = size_t(x0) * channels; i < size_t(x1) * channels; ++i) dst[i] += w * s[i];
    }
  }
  // Vertical pass into out: whole rows at a time.
  for (int y = 0; y < height; ++y) {
    T* dst = out + size_t(y) * row;
    std::fill(dst, dst + row, T(0));
    const int k0 = std::max(-r, -y), k1 = std::min(r, height - 1 - y);
    for (int k = k0; k <= k1; ++k) {
      const T w = taps[k + r];
      const T* s = scratch + size_t(y + k) * row;
      for (size_t i = 0; i < row; ++i) dst[i] += w * s[i];
    }
  }
}

}  // namespace atex::metrics_detail
