// Test helpers: compare two assets array by array, exactly or within a
// tolerance, with messages that name the array and index of the first mismatch.
#pragma once

#include <gtest/gtest.h>

#include "atex/model.h"

namespace atex::testing {

// Every array, config and metadata field identical (floats compared bitwise
// equal as values: -0 == +0).
::testing::AssertionResult AssetsEqual(const Asset& a, const Asset& b);

// Per-array absolute tolerances for lossy encodings; the structure (counts,
// texture dims, axes, configs, metadata) must still match exactly.
struct Tolerances {
  float positions = 0, rotations = 0, log_scales = 0, opacities = 0, sh = 0, texels = 0, grids = 0, mlp = 0, stats = 0;
};
::testing::AssertionResult AssetsNear(const Asset& a, const Asset& b, const Tolerances& tolerances);

}  // namespace atex::testing
