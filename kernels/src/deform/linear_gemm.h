// Row-major linear layers (PyTorch nn.Linear: weight [out][in], activations [rows][in])
// on cuBLAS's column-major SGEMM. A row-major [rows][cols] matrix with row stride ld is
// the column-major (cols x rows) matrix with leading dimension ld, so no transposes are
// materialised.
#pragma once

#include <cublas_v2.h>
#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda::deform_detail {

// Sets the handle's stream, math mode (FP32, or TF32 tensor cores when allowed) and host
// pointer mode for the lifetime of the guard, and restores the previous settings.
class ScopedCublasSettings {
 public:
  ScopedCublasSettings(cublasHandle_t handle, cudaStream_t stream, bool allow_tf32);
  ~ScopedCublasSettings();
  ScopedCublasSettings(const ScopedCublasSettings&) = delete;
  ScopedCublasSettings& operator=(const ScopedCublasSettings&) = delete;
  const Status& status() const { return status_; }

 private:
  cublasHandle_t handle_;
  cudaStream_t old_stream_ = nullptr;
  cublasMath_t old_math_ = CUBLAS_DEFAULT_MATH;
  cublasPointerMode_t old_pointer_mode_ = CUBLAS_POINTER_MODE_HOST;
  bool restore_ = false;
  Status status_;
};

// y[r][o] = sum_i x[r][i] * w[o][i] + beta * y[r][o].   x: row stride ldx, y: row stride ldy.
Status LinearForward(cublasHandle_t handle, const float* w, int in, int out, const float* x, int ldx, int rows,
                     float beta, float* y, int ldy);
// dx[r][i] = sum_o dy[r][o] * w[o][i] + beta * dx[r][i].
Status LinearBackwardData(cublasHandle_t handle, const float* w, int in, int out, const float* dy, int lddy, int rows,
                          float beta, float* dx, int lddx);
// dw[o][i] = sum_r dy[r][o] * x[r][i] + beta * dw[o][i]   (dw dense [out][in]).
Status LinearBackwardWeight(cublasHandle_t handle, const float* x, int ldx, const float* dy, int lddy, int in,
                            int out, int rows, float beta, float* dw);

}  // namespace atex::cuda::deform_detail
