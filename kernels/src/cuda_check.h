// CUDA error handling for the kernels: every runtime/cuBLAS call is checked and
// turned into an atex::Status naming the call and the place.
#pragma once

#include <cublas_v2.h>
#include <cuda_runtime.h>

#include "atex/status.h"

namespace atex::cuda {

inline Status CudaStatus(cudaError_t error, const char* what, const char* file, int line) {
  if (error == cudaSuccess) return Status::Ok();
  return MakeError(error == cudaErrorNoDevice || error == cudaErrorInsufficientDriver ? StatusCode::kNoDevice
                                                                                      : StatusCode::kInternal,
                   "CUDA error in ", what, " (", file, ":", line, "): ", cudaGetErrorName(error), " - ",
                   cudaGetErrorString(error));
}

inline Status CublasStatus(cublasStatus_t error, const char* what, const char* file, int line) {
  if (error == CUBLAS_STATUS_SUCCESS) return Status::Ok();
  return MakeError(StatusCode::kInternal, "cuBLAS error ", static_cast<int>(error), " in ", what, " (", file, ":",
                   line, ")");
}

}  // namespace atex::cuda

#define ATEX_CUDA_RETURN_IF_ERROR(call) \
  ATEX_RETURN_IF_ERROR(::atex::cuda::CudaStatus((call), #call, __FILE__, __LINE__))
#define ATEX_CUBLAS_RETURN_IF_ERROR(call) \
  ATEX_RETURN_IF_ERROR(::atex::cuda::CublasStatus((call), #call, __FILE__, __LINE__))
// After a kernel launch: launch-configuration errors (and, in debug builds, execution errors).
#define ATEX_CUDA_CHECK_LAUNCH(name) \
  ATEX_RETURN_IF_ERROR(::atex::cuda::CudaStatus(cudaGetLastError(), name, __FILE__, __LINE__))
