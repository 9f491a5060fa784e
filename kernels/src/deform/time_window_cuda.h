// Time-local Gaussians on the GPU (docs/conventions.md §3, "Time-local Gaussians"): the
// window's penalty taken off the deformed opacity logits after the deformation field ran.
#pragma once

#include <cstddef>

#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

// opacity_logits[i] -= min(½(k_i·(time − c_i))², kMaxTimeWindowPenalty) for i < n, where
// windows [n][2] holds (c_i, k_i) (model.h TimeWindowPenalty, in float). No gradient
// changes: the penalty is a constant of each Gaussian, so ∂logit'/∂logit = 1.
Status ApplyTimeWindows(const float* windows, float* opacity_logits, size_t n, float time, cudaStream_t stream);

}  // namespace atex::cuda
