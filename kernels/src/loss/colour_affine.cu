#include "loss/colour_affine.h"

#include "cuda_check.h"

namespace atex::cuda::loss_detail {
namespace {

struct Affine {
  float gain[3];
  float offset[3];
};

Affine ToKernel(const train::ColourAffine& c) {
  return {{c.gain[0], c.gain[1], c.gain[2]}, {c.offset[0], c.offset[1], c.offset[2]}};
}

// One thread per value of the [pixels][3] image.
__global__ void ColourAffineKernel(const float* __restrict__ in, float* __restrict__ out, size_t values, Affine a) {
  const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= values) return;
  const int c = static_cast<int>(i % 3);
  out[i] = fmaf(a.gain[c], in[i], a.offset[c]);
}

__global__ void ScaleGradientKernel(float* __restrict__ grad, size_t values, Affine a) {
  const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= values) return;
  grad[i] *= a.gain[i % 3];
}

constexpr int kThreads = 256;
unsigned Blocks(size_t values) { return static_cast<unsigned>((values + kThreads - 1) / kThreads); }

}  // namespace

Status LaunchColourAffine(const float* in, float* out, size_t pixels, const train::ColourAffine& colour,
                          cudaStream_t stream) {
  if (pixels == 0) return Status::Ok();
  ColourAffineKernel<<<Blocks(3 * pixels), kThreads, 0, stream>>>(in, out, 3 * pixels, ToKernel(colour));
  ATEX_CUDA_CHECK_LAUNCH("ColourAffineKernel");
  return Status::Ok();
}

Status LaunchScaleGradient(float* grad, size_t pixels, const train::ColourAffine& colour, cudaStream_t stream) {
  if (pixels == 0) return Status::Ok();
  ScaleGradientKernel<<<Blocks(3 * pixels), kThreads, 0, stream>>>(grad, 3 * pixels, ToKernel(colour));
  ATEX_CUDA_CHECK_LAUNCH("ScaleGradientKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::loss_detail
