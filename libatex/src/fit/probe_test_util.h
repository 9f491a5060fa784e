// For the probe renderers' tests (cpu_probes_test.cc, incremental_probes_test.cc): comparing
// sets of probe images.
#pragma once

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <gtest/gtest.h>

#include "atex/image.h"

namespace atex::fit::testing {

// Largest difference of one pixel channel between two image sets (expects equal shapes).
inline float MaxDifference(const std::vector<Image>& a, const std::vector<Image>& b) {
  EXPECT_EQ(a.size(), b.size());
  float worst = 0;
  for (size_t k = 0; k < a.size() && k < b.size(); ++k) {
    EXPECT_EQ(a[k].pixels.size(), b[k].pixels.size());
    for (size_t p = 0; p < a[k].pixels.size() && p < b[k].pixels.size(); ++p) {
      worst = std::max(worst, std::abs(a[k].pixels[p] - b[k].pixels[p]));
    }
  }
  return worst;
}

// Mean of every channel of every pixel (to check that the probes see the asset).
inline double MeanValue(const std::vector<Image>& images) {
  double sum = 0, count = 0;
  for (const Image& i : images) {
    sum += std::accumulate(i.pixels.begin(), i.pixels.end(), 0.0);
    count += static_cast<double>(i.pixels.size());
  }
  return sum / count;
}

}  // namespace atex::fit::testing
