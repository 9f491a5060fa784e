// SSIM + L1 on the GPU (docs/conventions.md §7), two passes over the image:
//
// Forward: each block loads a (32+10) x (16+10) pixel tile of x and y (all three
// channels, zero outside the image) into shared memory, blurs the five moment images
// (x, y, x^2, y^2, xy) horizontally into shared memory and then vertically, and
// evaluates the SSIM map S, |x - y| and (x - y)^2. With gradients it also writes the
// partial derivatives of S with respect to the three moments that depend on x
// (mu_x, E[x^2], E[xy]); block sums go to double accumulators.
//
// Backward: dS/dx(q) = sum_p G(p - q) (dmu(p) + 2 x(q) dxx(p) + y(q) dxy(p)), i.e. the
// same blur applied to the three derivative maps (the zero-padded "same" blur with a
// symmetric window is self-adjoint), combined with x and y at q.
//
// Shared-memory rows store pixels with their 3 channels interleaved, so a warp reading
// 32 consecutive pixels of one channel hits addresses 3 words apart (no bank conflicts).
#include "loss/ssim_kernels.h"

#include <cmath>
#include <cstdint>

#include "cuda_check.h"

namespace atex::cuda::loss_detail {
namespace {

constexpr int kRadius = kWindow / 2;  // 5
constexpr int kTileW = 32;            // output pixels per block along x (= threadIdx.x)
constexpr int kInW = kTileW + 2 * kRadius;
constexpr int kRowFloats = kInW * 3;

// Forward tiles: 32 x 16 outputs, 32 x 8 threads (2 output rows each).
constexpr int kFwdRows = 8;
constexpr int kFwdTileH = 16;
constexpr int kFwdInH = kFwdTileH + 2 * kRadius;
// Backward tiles: 32 x 14 outputs, 32 x 7 threads (three maps fit in 48 KiB of shared memory).
constexpr int kBwdRows = 7;
constexpr int kBwdTileH = 14;
constexpr int kBwdInH = kBwdTileH + 2 * kRadius;

// Loads rows [y0, y0 + rows) x pixels [x0, x0 + kInW) of an [H][W][3] image into tile[rows][kRowFloats].
__device__ __forceinline__ void LoadTile(const float* __restrict__ image, int width, int height, int x0, int y0,
                                         int rows, float* tile, int tid, int threads) {
  for (int i = tid; i < rows * kRowFloats; i += threads) {
    const int r = i / kRowFloats;
    const int cc = i - r * kRowFloats;
    const int px = x0 + cc / 3;
    const int py = y0 + r;
    float v = 0.0f;
    if (px >= 0 && px < width && py >= 0 && py < height) {
      v = image[(static_cast<int64_t>(py) * width + px) * 3 + (cc - (cc / 3) * 3)];
    }
    tile[i] = v;
  }
}

__device__ __forceinline__ double WarpSum(double v) {
  for (int offset = 16; offset > 0; offset /= 2) v += __shfl_xor_sync(0xffffffffu, v, offset);
  return v;
}

template <bool kMaps>
__global__ void __launch_bounds__(kTileW* kFwdRows)
    SsimForwardKernel(const float* __restrict__ x, const float* __restrict__ y, int width, int height, float c1,
                      float c2, GaussianWindow window, float* __restrict__ dmu, float* __restrict__ dxx,
                      float* __restrict__ dxy, double* sums) {
  __shared__ float tile_x[kFwdInH * kRowFloats];
  __shared__ float tile_y[kFwdInH * kRowFloats];
  __shared__ float blurred[5][kFwdInH][kTileW];  // horizontal pass: mu_x, mu_y, E[x^2], E[y^2], E[xy]
  __shared__ double warp_sums[3][kFwdRows];
  const int tid = threadIdx.y * kTileW + threadIdx.x;
  constexpr int kThreads = kTileW * kFwdRows;
  const int out_x0 = blockIdx.x * kTileW;
  const int out_y0 = blockIdx.y * kFwdTileH;
  LoadTile(x, width, height, out_x0 - kRadius, out_y0 - kRadius, kFwdInH, tile_x, tid, kThreads);
  LoadTile(y, width, height, out_x0 - kRadius, out_y0 - kRadius, kFwdInH, tile_y, tid, kThreads);
  __syncthreads();

  float sum_dssim = 0.0f, sum_abs = 0.0f, sum_sq = 0.0f;
  for (int ch = 0; ch < 3; ++ch) {
    for (int i = tid; i < kFwdInH * kTileW; i += kThreads) {
      const int r = i / kTileW;
      const int col = i - r * kTileW;
      const float* row_x = tile_x + r * kRowFloats + col * 3 + ch;
      const float* row_y = tile_y + r * kRowFloats + col * 3 + ch;
      float mx = 0.0f, my = 0.0f, exx = 0.0f, eyy = 0.0f, exy = 0.0f;
#pragma unroll
      for (int k = 0; k < kWindow; ++k) {
        const float w = window.w[k];
        const float a = row_x[3 * k];
        const float b = row_y[3 * k];
        mx += w * a;
        my += w * b;
        exx += w * (a * a);
        eyy += w * (b * b);
        exy += w * (a * b);
      }
      blurred[0][r][col] = mx;
      blurred[1][r][col] = my;
      blurred[2][r][col] = exx;
      blurred[3][r][col] = eyy;
      blurred[4][r][col] = exy;
    }
    __syncthreads();
    const int col = threadIdx.x;
    const int px = out_x0 + col;
    for (int tr = threadIdx.y; tr < kFwdTileH; tr += kFwdRows) {
      const int py = out_y0 + tr;
      float m[5] = {0.0f, 0.0f, 0.0f, 0.0f, 0.0f};
#pragma unroll
      for (int k = 0; k < kWindow; ++k) {
        const float w = window.w[k];
#pragma unroll
        for (int j = 0; j < 5; ++j) m[j] += w * blurred[j][tr + k][col];
      }
      if (px < width && py < height) {
        const float mx = m[0], my = m[1];
        const float mx2 = mx * mx, my2 = my * my, mxy = mx * my;
        const float sxx = m[2] - mx2, syy = m[3] - my2, sxy = m[4] - mxy;
        const float a1 = 2.0f * mxy + c1;
        const float a2 = 2.0f * sxy + c2;
        const float b1 = mx2 + my2 + c1;
        const float b2 = sxx + syy + c2;
        const float den = b1 * b2;
        const float s = (a1 * a2) / den;
        sum_dssim += 1.0f - s;
        const float vx = tile_x[(tr + kRadius) * kRowFloats + (col + kRadius) * 3 + ch];
        const float vy = tile_y[(tr + kRadius) * kRowFloats + (col + kRadius) * 3 + ch];
        const float d = vx - vy;
        sum_abs += fabsf(d);
        sum_sq += d * d;
        if constexpr (kMaps) {
          const int64_t idx = (static_cast<int64_t>(py) * width + px) * 3 + ch;
          // dS/dmu_x = 2 mu_y (A2 - A1) / (B1 B2) - 2 mu_x S (1/B1 - 1/B2)
          dmu[idx] = (2.0f * my * (a2 - a1) - 2.0f * mx * s * (b2 - b1)) / den;
          dxx[idx] = -s / b2;              // dS/dE[x^2]
          dxy[idx] = (2.0f * a1) / den;    // dS/dE[xy]
        }
      }
    }
    __syncthreads();  // `blurred` is rewritten for the next channel
  }
  const int warp = tid / 32;
  const double s0 = WarpSum(sum_dssim), s1 = WarpSum(sum_abs), s2 = WarpSum(sum_sq);
  if (threadIdx.x == 0) {
    warp_sums[0][warp] = s0;
    warp_sums[1][warp] = s1;
    warp_sums[2][warp] = s2;
  }
  __syncthreads();
  if (tid < 3) {
    double total = 0.0;
    for (int w = 0; w < kFwdRows; ++w) total += warp_sums[tid][w];
    atomicAdd(sums + tid, total);
  }
}

__global__ void __launch_bounds__(kTileW* kBwdRows)
    SsimBackwardKernel(const float* __restrict__ x, const float* __restrict__ y, const float* __restrict__ dmu,
                       const float* __restrict__ dxx, const float* __restrict__ dxy, int width, int height,
                       GaussianWindow window, float l1_coeff, float ssim_coeff, float* __restrict__ grad) {
  __shared__ float tiles[3][kBwdInH * kRowFloats];
  __shared__ float blurred[3][kBwdInH][kTileW];
  const int tid = threadIdx.y * kTileW + threadIdx.x;
  constexpr int kThreads = kTileW * kBwdRows;
  const int out_x0 = blockIdx.x * kTileW;
  const int out_y0 = blockIdx.y * kBwdTileH;
  LoadTile(dmu, width, height, out_x0 - kRadius, out_y0 - kRadius, kBwdInH, tiles[0], tid, kThreads);
  LoadTile(dxx, width, height, out_x0 - kRadius, out_y0 - kRadius, kBwdInH, tiles[1], tid, kThreads);
  LoadTile(dxy, width, height, out_x0 - kRadius, out_y0 - kRadius, kBwdInH, tiles[2], tid, kThreads);
  __syncthreads();
  for (int ch = 0; ch < 3; ++ch) {
    for (int i = tid; i < kBwdInH * kTileW; i += kThreads) {
      const int r = i / kTileW;
      const int col = i - r * kTileW;
      float m[3] = {0.0f, 0.0f, 0.0f};
#pragma unroll
      for (int k = 0; k < kWindow; ++k) {
        const float w = window.w[k];
#pragma unroll
        for (int j = 0; j < 3; ++j) m[j] += w * tiles[j][r * kRowFloats + (col + k) * 3 + ch];
      }
#pragma unroll
      for (int j = 0; j < 3; ++j) blurred[j][r][col] = m[j];
    }
    __syncthreads();
    const int col = threadIdx.x;
    const int px = out_x0 + col;
    for (int tr = threadIdx.y; tr < kBwdTileH; tr += kBwdRows) {
      const int py = out_y0 + tr;
      float m[3] = {0.0f, 0.0f, 0.0f};
#pragma unroll
      for (int k = 0; k < kWindow; ++k) {
        const float w = window.w[k];
#pragma unroll
        for (int j = 0; j < 3; ++j) m[j] += w * blurred[j][tr + k][col];
      }
      if (px < width && py < height) {
        const int64_t idx = (static_cast<int64_t>(py) * width + px) * 3 + ch;
        const float vx = x[idx];
        const float vy = y[idx];
        const float d = vx - vy;
        const float sign = d > 0.0f ? 1.0f : (d < 0.0f ? -1.0f : 0.0f);
        grad[idx] = l1_coeff * sign + ssim_coeff * (m[0] + 2.0f * vx * m[1] + vy * m[2]);
      }
    }
    __syncthreads();
  }
}

__global__ void LossFinalizeKernel(const double* sums, double count, double lambda, double scale, float* loss,
                                   float* sse) {
  loss[0] += static_cast<float>(scale * ((1.0 - lambda) * sums[1] + lambda * sums[0]) / count);
  if (sse) sse[0] += static_cast<float>(sums[2]);
}

}  // namespace

GaussianWindow MakeGaussianWindow(double sigma) {
  GaussianWindow window;
  double weights[kWindow];
  double total = 0.0;
  for (int i = 0; i < kWindow; ++i) {
    const double d = i - kRadius;
    weights[i] = std::exp(-d * d / (2.0 * sigma * sigma));
    total += weights[i];
  }
  for (int i = 0; i < kWindow; ++i) window.w[i] = static_cast<float>(weights[i] / total);
  return window;
}

Status LaunchSsimForward(const float* x, const float* y, int width, int height, float c1, float c2,
                         const GaussianWindow& window, float* dmu, float* dxx, float* dxy, double* sums,
                         cudaStream_t stream) {
  const dim3 blocks((width + kTileW - 1) / kTileW, (height + kFwdTileH - 1) / kFwdTileH);
  const dim3 threads(kTileW, kFwdRows);
  if (dmu && dxx && dxy) {
    SsimForwardKernel<true><<<blocks, threads, 0, stream>>>(x, y, width, height, c1, c2, window, dmu, dxx, dxy, sums);
  } else {
    SsimForwardKernel<false><<<blocks, threads, 0, stream>>>(x, y, width, height, c1, c2, window, nullptr, nullptr,
                                                             nullptr, sums);
  }
  ATEX_CUDA_CHECK_LAUNCH("SsimForwardKernel");
  return Status::Ok();
}

Status LaunchSsimBackward(const float* x, const float* y, const float* dmu, const float* dxx, const float* dxy,
                          int width, int height, const GaussianWindow& window, float l1_coeff, float ssim_coeff,
                          float* grad, cudaStream_t stream) {
  const dim3 blocks((width + kTileW - 1) / kTileW, (height + kBwdTileH - 1) / kBwdTileH);
  const dim3 threads(kTileW, kBwdRows);
  SsimBackwardKernel<<<blocks, threads, 0, stream>>>(x, y, dmu, dxx, dxy, width, height, window, l1_coeff, ssim_coeff,
                                                     grad);
  ATEX_CUDA_CHECK_LAUNCH("SsimBackwardKernel");
  return Status::Ok();
}

Status LaunchLossFinalize(const double* sums, double count, double lambda, double scale, float* loss, float* sse,
                          cudaStream_t stream) {
  LossFinalizeKernel<<<1, 1, 0, stream>>>(sums, count, lambda, scale, loss, sse);
  ATEX_CUDA_CHECK_LAUNCH("LossFinalizeKernel");
  return Status::Ok();
}

}  // namespace atex::cuda::loss_detail
