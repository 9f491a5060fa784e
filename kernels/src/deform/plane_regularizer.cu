// 4DGaussians' plane regularisers (atex::DeformRegularizer, libatex/include/atex/deform.h):
//   plane_tv        * sum over scales and spatial planes of mean (second difference along b)^2
//   time_smoothness * the same over the time planes (xt, yt, zt; b is time)
//   time_l1         * sum over scales and time planes of mean |1 - plane|
// One thread per plane value; the gradient is gathered (each thread writes only its own
// value: deterministic, no atomics) and the value is reduced per block in double and
// added to a device double accumulator.
#include <algorithm>
#include <cstdint>

#include "atex/detail/hexplane.h"
#include "cuda_check.h"
#include "deform/deform_internal.h"

namespace atex::cuda::deform_detail {
namespace {

constexpr int kThreads = 256;
constexpr int kPlanesPerLaunch = kMaxScales * 6;

struct RegPlane {
  long long offset = 0;    // floats into the grid
  int res_a = 1, res_b = 1;
  float smooth_scale = 0;  // weight / count of second differences (0: term off or fewer than 3 rows)
  float l1_scale = 0;      // weight / count of values (0: term off or spatial plane)
};

struct RegPlanes {
  RegPlane plane[kPlanesPerLaunch];
  int channels = 0;
};

__device__ __forceinline__ float SecondDifference(const float* column, long long row_stride, int b) {
  const float p0 = column[b * row_stride];
  const float p1 = column[(b + 1) * row_stride];
  const float p2 = column[(b + 2) * row_stride];
  return (p2 - p1) - (p1 - p0);  // first differences, then their difference (4DGaussians' order)
}

__global__ void __launch_bounds__(kThreads)
    PlaneRegularizerKernel(RegPlanes planes, const float* __restrict__ grid, float* grad_grid, double* accumulator) {
  const RegPlane& plane = planes.plane[blockIdx.y];
  const long long row = static_cast<long long>(plane.res_a) * planes.channels;  // one b row: [res_a][C]
  const long long count = row * plane.res_b;
  double value = 0.0;
  for (long long i = blockIdx.x * static_cast<long long>(blockDim.x) + threadIdx.x; i < count;
       i += static_cast<long long>(gridDim.x) * blockDim.x) {
    const int b = static_cast<int>(i / row);
    const float* column = grid + plane.offset + (i - b * row);  // this (a, c) at b = 0
    const float v = column[b * row];
    float grad = 0.0f;
    if (plane.smooth_scale != 0.0f) {
      const int last = plane.res_b - 3;  // last b that starts a second difference
      float chain = 0.0f;                // sum_j d(second_j^2)/d(value) / 2
      if (b <= last) {
        const float s = SecondDifference(column, row, b);
        value += static_cast<double>(plane.smooth_scale) * static_cast<double>(s) * static_cast<double>(s);
        chain += s;
      }
      if (b - 1 >= 0 && b - 1 <= last) chain -= 2.0f * SecondDifference(column, row, b - 1);
      if (b - 2 >= 0 && b - 2 <= last) chain += SecondDifference(column, row, b - 2);
      grad += 2.0f * plane.smooth_scale * chain;
    }
    if (plane.l1_scale != 0.0f) {
      const float d = 1.0f - v;
      value += static_cast<double>(plane.l1_scale) * static_cast<double>(d < 0.0f ? -d : d);
      // d|1 - v|/dv = -sign(1 - v), 0 at v = 1 (PyTorch's sign).
      grad += d > 0.0f ? -plane.l1_scale : (d < 0.0f ? plane.l1_scale : 0.0f);
    }
    if (grad_grid) grad_grid[plane.offset + i] += grad;
  }
  if (!accumulator) return;
  __shared__ double partial[kThreads];
  partial[threadIdx.x] = value;
  __syncthreads();
  for (int stride = kThreads / 2; stride > 0; stride /= 2) {
    if (threadIdx.x < stride) partial[threadIdx.x] += partial[threadIdx.x + stride];
    __syncthreads();
  }
  if (threadIdx.x == 0) atomicAdd(accumulator, partial[0]);
}

__global__ void AddScalarKernel(const double* accumulator, float* loss) { *loss += static_cast<float>(*accumulator); }

}  // namespace

Status LaunchPlaneRegularizer(const DeformLayout& layout, const float* grid, float plane_tv, float time_smoothness,
                              float time_l1, float* grad_grid, double* accumulator, cudaStream_t stream) {
  if (!grad_grid && !accumulator) return Status::Ok();
  const HexPlaneConfig& config = layout.config.grid;
  RegPlanes planes;
  planes.channels = config.channels;
  int used = 0;
  long long largest = 0;
  for (int s = 0; s < config.scales(); ++s) {
    for (int p = 0; p < 6; ++p) {
      RegPlane& plane = planes.plane[used++];
      plane.offset = static_cast<long long>(layout.plane_offset[static_cast<size_t>(s) * 6 + p]);
      plane.res_a = config.resolution(s, kHexPlaneAxes[p][0]);
      plane.res_b = config.resolution(s, kHexPlaneAxes[p][1]);
      const bool time_plane = detail::IsTimePlane(p);
      const double values = static_cast<double>(plane.res_a) * plane.res_b * config.channels;
      const double differences = static_cast<double>(plane.res_a) * (plane.res_b - 2) * config.channels;
      const float smooth_weight = time_plane ? time_smoothness : plane_tv;
      plane.smooth_scale = plane.res_b >= 3 ? static_cast<float>(smooth_weight / differences) : 0.0f;
      plane.l1_scale = time_plane ? static_cast<float>(time_l1 / values) : 0.0f;
      largest = std::max(largest, static_cast<long long>(values));
    }
  }
  if (used == 0 || largest == 0) return Status::Ok();
  const long long blocks_x = std::min<long long>((largest + kThreads - 1) / kThreads, 4096);
  PlaneRegularizerKernel<<<dim3(static_cast<unsigned>(blocks_x), static_cast<unsigned>(used)), kThreads, 0,
                           stream>>>(planes, grid, grad_grid, accumulator);
  ATEX_CUDA_CHECK_LAUNCH("PlaneRegularizerKernel");
  return Status::Ok();
}

Status LaunchAddScalar(const double* accumulator, float* loss, cudaStream_t stream) {
  AddScalarKernel<<<1, 1, 0, stream>>>(accumulator, loss);
  ATEX_CUDA_CHECK_LAUNCH("AddScalarKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::deform_detail
