// Small random fields and Gaussians for the deform tests.
#pragma once

#include <cstdint>
#include <random>

#include "atex/deform.h"
#include "atex/model.h"

namespace atex::testing {

// A field with the config's shapes and random values: planes U(plane_lo,
// plane_hi), weights and biases U(-weight_scale, weight_scale).
BasicDeformationField<double> RandomField(const DeformationConfig& config, uint64_t seed, double plane_lo = 0.5,
                                          double plane_hi = 1.5, double weight_scale = 0.6);

// n Gaussians with positions U(lo, hi) per axis and random other parameters.
BasicGaussians<double> RandomGaussians(size_t n, int sh_degree, uint64_t seed, double lo = -1.0, double hi = 1.0);

// A small config that exercises every code path: 2 scales, 3 channels,
// distinct resolutions per axis, 2 trunk layers, all five heads, SH degree 1.
DeformationConfig SmallConfig();

}  // namespace atex::testing
