// Synthetic Gaussians for the converters' tests and fuzz seeds (test-only, header-only).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "atex/model.h"

namespace atex::converters::testing {

// n Gaussians with plausible trained values: positions in [-extent, extent],
// log-scales around ln 0.02, opacity logits in [-4, 4], SH DC in [-1.5, 1.5],
// higher SH in [-0.4, 0.4], random unnormalised quaternions.
inline Gaussians RandomGaussians(size_t n, int sh_degree, uint32_t seed, float extent = 5.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  Gaussians g;
  g.sh_degree = sh_degree;
  g.Resize(n);
  for (auto& v : g.positions) v = extent * unit(rng);
  for (auto& v : g.log_scales) v = std::log(0.02f) + 1.5f * unit(rng);
  for (auto& v : g.opacity_logits) v = 4.0f * unit(rng);
  for (size_t i = 0; i < n; ++i) {
    float* q = &g.rotations[i * 4];
    float norm = 0;
    do {
      for (int k = 0; k < 4; ++k) q[k] = 2.0f * unit(rng);
      norm = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
    } while (norm < 0.05f);
    const int k_count = g.sh_coeffs();
    for (int k = 0; k < k_count; ++k) {
      for (int c = 0; c < 3; ++c) {
        g.sh[(i * k_count + k) * 3 + c] = (k == 0 ? 1.5f : 0.4f) * unit(rng);
      }
    }
  }
  return g;
}

}  // namespace atex::converters::testing
