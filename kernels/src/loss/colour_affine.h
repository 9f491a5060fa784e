// The per-view camera colour correction of training (atex/train/colour_correction.h) on the
// GPU: rendered' = gain · rendered + offset before the loss, and dL/d(rendered) =
// gain · dL/d(rendered') after it.
#pragma once

#include <cstddef>

#include <cuda_runtime.h>

#include "atex/status.h"
#include "atex/train/colour_correction.h"

namespace atex::cuda::loss_detail {

// out[p][c] = gain[c] · in[p][c] + offset[c].   in, out: device [pixels][3] (may not alias).
Status LaunchColourAffine(const float* in, float* out, size_t pixels, const train::ColourAffine& colour,
                          cudaStream_t stream);

// grad[p][c] *= gain[c].   grad: device [pixels][3], in place.
Status LaunchScaleGradient(float* grad, size_t pixels, const train::ColourAffine& colour, cudaStream_t stream);

}  // namespace atex::cuda::loss_detail
