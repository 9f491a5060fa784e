// Internal pieces of the CUDA deformation engine: layout checks, the grid geometry
// handed to the sampling kernels, and the launchers of every kernel (host-callable,
// so deform_engine.cc stays plain C++).
#pragma once

#include <cstdint>

#include <cuda_runtime.h>

#include "atex/detail/hexplane.h"
#include "atex/status.h"
#include "deform/deform_cuda.h"

namespace atex::cuda {

// OK when `layout` is DeformLayout::Make(layout.config) for a valid config that the kernels support.
Status CheckDeformLayout(const DeformLayout& layout);
int EnabledHeadCount(const DeformationConfig& config);

namespace deform_detail {

inline constexpr int kMaxScales = 16;        // multires entries (CheckDeformationConfig allows 16)
inline constexpr int kMaxHeadOutputs = 256;  // outputs of one head (SH degree 3 needs 48); 32 KiB of shared memory

// Everything a sampling thread needs, passed by value as a kernel parameter.
struct GridGeometry {
  int scales = 0;
  int channels = 0;
  int resolution[kMaxScales][4] = {};             // x, y, z, t per scale
  long long plane_offset[kMaxScales][6] = {};     // floats into the device grid, channel-last planes
  float aabb_lo[3] = {};                          // normalisation: (x - lo) * scale - 1
  float aabb_scale[3] = {};
  float time_norm = 0;                            // normalised time of this pass
};
// Normalised time t_norm = time_scale * time + time_offset, evaluated as the CPU engine does.
float NormalizedTime(const DeformationConfig& config, float time);

// Geometry of a checked layout at scene time `time` (the time mapping of the CPU engine).
GridGeometry MakeGridGeometry(const DeformLayout& layout, float time);

// features[N][S*C] = per scale the channel-wise product of the six plane samples at the
// normalised (position, time), scales concatenated (docs/conventions.md §3).
Status LaunchSampleFeatures(const GridGeometry& geometry, const float* grid, const float* positions /*[N][3]*/,
                            int n, float* features /*[N][S*C]*/, cudaStream_t stream);
// Vector-Jacobian product of LaunchSampleFeatures: ADDS dL/d(grid) (atomics; null = skip) and
// dL/d(positions) through the sampling coordinates (null = skip).
Status LaunchSampleFeaturesBackward(const GridGeometry& geometry, const float* grid, const float* positions, int n,
                                    const float* grad_features /*[N][S*C]*/, float* grad_grid,
                                    float* grad_positions /*[N][3]*/, cudaStream_t stream);

// ---- small fused kernels around the GEMMs (mlp_ops.cu) ----------------------------
// x[r][j] = max(x[r][j] + bias[j], 0) for r < rows, j < width (row stride = width).
Status LaunchBiasRelu(float* x, const float* bias, int64_t rows, int width, cudaStream_t stream);
// out[r][j] = in[r][j] + bias[j] (row stride = width); out may equal in.
Status LaunchAddBias(const float* in, const float* bias, int64_t rows, int width, float* out, cudaStream_t stream);
// dst[i] += src[i], i < count.
Status LaunchAccumulate(float* dst, const float* src, int64_t count, cudaStream_t stream);
// Column sums: sums[j] += sum_r x[r*ld + j] for j < width.
Status LaunchColumnSumAdd(const float* x, int64_t rows, int width, int ld, float* sums, cudaStream_t stream);
// ReLU backward in place: d[r*ld + j] = post[r*ld + j] > 0 ? d[...] : 0 (post = ReLU output), and, when
// bias_grad is not null, bias_grad[j] += sum_r of the result.
Status LaunchReluBackward(float* d, const float* post, int64_t rows, int width, int ld, float* bias_grad,
                          cudaStream_t stream);
// The data gradient of a narrow output layer fused with the ReLU before it:
// d[r*ld + j] = post[r*ld + j] > 0 ? sum_k g[r*k_count + k] * weight[k*width + j] : 0 (weight [k_count][width]),
// and bias_grad[j] += sum_r d[r*ld + j] when bias_grad is not null. k_count <= kMaxHeadOutputs.
Status LaunchNarrowLinearBackward(const float* g, int k_count, const float* weight, const float* post, int64_t rows,
                                  int width, int ld, float* d, float* bias_grad, cudaStream_t stream);

// ---- plane regulariser (plane_regularizer.cu) ----------------------------------------
// ADDS the gradient of atex::DeformRegularizer to grad_grid (null = skip) and its value to *accumulator
// (device double; null = skip).
Status LaunchPlaneRegularizer(const DeformLayout& layout, const float* grid, float plane_tv, float time_smoothness,
                              float time_l1, float* grad_grid, double* accumulator, cudaStream_t stream);
// *loss += float(*accumulator).
Status LaunchAddScalar(const double* accumulator, float* loss, cudaStream_t stream);

}  // namespace deform_detail
}  // namespace atex::cuda
