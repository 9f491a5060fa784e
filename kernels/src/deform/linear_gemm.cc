#include "deform/linear_gemm.h"

#include "cuda_check.h"

namespace atex::cuda::deform_detail {

ScopedCublasSettings::ScopedCublasSettings(cublasHandle_t handle, cudaStream_t stream, bool allow_tf32)
    : handle_(handle) {
  status_ = CublasStatus(cublasGetStream(handle_, &old_stream_), "cublasGetStream", __FILE__, __LINE__);
  if (status_.ok())
    status_ = CublasStatus(cublasGetMathMode(handle_, &old_math_), "cublasGetMathMode", __FILE__, __LINE__);
  if (status_.ok()) {
    status_ = CublasStatus(cublasGetPointerMode(handle_, &old_pointer_mode_), "cublasGetPointerMode", __FILE__,
                           __LINE__);
  }
  if (!status_.ok()) return;
  restore_ = true;
  status_ = CublasStatus(cublasSetStream(handle_, stream), "cublasSetStream", __FILE__, __LINE__);
  // CUBLAS_DEFAULT_MATH never lowers FP32 to TF32 (that needs CUBLAS_TF32_TENSOR_OP_MATH).
  if (status_.ok()) {
    status_ = CublasStatus(cublasSetMathMode(handle_, allow_tf32 ? CUBLAS_TF32_TENSOR_OP_MATH : CUBLAS_DEFAULT_MATH),
                           "cublasSetMathMode", __FILE__, __LINE__);
  }
  if (status_.ok()) {
    status_ = CublasStatus(cublasSetPointerMode(handle_, CUBLAS_POINTER_MODE_HOST), "cublasSetPointerMode", __FILE__,
                           __LINE__);
  }
}

ScopedCublasSettings::~ScopedCublasSettings() {
  if (!restore_) return;
  cublasSetStream(handle_, old_stream_);
  cublasSetMathMode(handle_, old_math_);
  cublasSetPointerMode(handle_, old_pointer_mode_);
}

Status LinearForward(cublasHandle_t handle, const float* w, int in, int out, const float* x, int ldx, int rows,
                     float beta, float* y, int ldy) {
  if (rows <= 0) return Status::Ok();
  const float one = 1.0f;
  // Column-major: Y (out x rows) = W^T (out x in) * X (in x rows), W viewed as (in x out), ld = in.
  ATEX_CUBLAS_RETURN_IF_ERROR(
      cublasSgemm(handle, CUBLAS_OP_T, CUBLAS_OP_N, out, rows, in, &one, w, in, x, ldx, &beta, y, ldy));
  return Status::Ok();
}

Status LinearBackwardData(cublasHandle_t handle, const float* w, int in, int out, const float* dy, int lddy, int rows,
                          float beta, float* dx, int lddx) {
  if (rows <= 0) return Status::Ok();
  const float one = 1.0f;
  // Column-major: dX (in x rows) = W (in x out) * dY (out x rows).
  ATEX_CUBLAS_RETURN_IF_ERROR(
      cublasSgemm(handle, CUBLAS_OP_N, CUBLAS_OP_N, in, rows, out, &one, w, in, dy, lddy, &beta, dx, lddx));
  return Status::Ok();
}

Status LinearBackwardWeight(cublasHandle_t handle, const float* x, int ldx, const float* dy, int lddy, int in,
                            int out, int rows, float beta, float* dw) {
  if (rows <= 0) {
    if (beta == 1.0f) return Status::Ok();
    return MakeError(StatusCode::kInternal, "LinearBackwardWeight with no rows and beta != 1");
  }
  const float one = 1.0f;
  // Column-major: dW viewed as (in x out), ld = in: dW = X (in x rows) * dY^T (rows x out).
  ATEX_CUBLAS_RETURN_IF_ERROR(
      cublasSgemm(handle, CUBLAS_OP_N, CUBLAS_OP_T, in, out, rows, &one, x, ldx, dy, lddy, &beta, dw, in));
  return Status::Ok();
}

}  // namespace atex::cuda::deform_detail
