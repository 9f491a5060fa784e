// CUDA error handling for the kernels: every runtime/cuBLAS call is checked and
// turned into an atex::Status naming the call and the place.
#pragma once

#include <cublas_v2.h>
#include <cuda_runtime.h>

#include <string>

#include "atex/status.h"

namespace atex::cuda {

// "12.0 GiB free of 79.1 GiB on the device" (or why it is unknown).
inline std::string DeviceMemoryNote() {
  size_t free_bytes = 0, total_bytes = 0;
  if (cudaMemGetInfo(&free_bytes, &total_bytes) != cudaSuccess) {
    (void)cudaGetLastError();
    return "free device memory unknown";
  }
  return StrCat(free_bytes / double(1ull << 30), " GiB free of ", total_bytes / double(1ull << 30),
                " GiB on the device");
}

// Out of device memory is a limit (kLimitExceeded, as the CPU backend reports a model that
// does not fit), not a bug: the message says how much was asked (when `requested` > 0) and
// how much is free. The error is not sticky; it is cleared so later launch checks do not
// see it again.
inline Status OutOfDeviceMemory(const char* what, size_t requested, const char* file, int line) {
  (void)cudaGetLastError();
  const std::string asked = requested > 0 ? StrCat(requested / double(1ull << 20), " MiB asked; ") : std::string();
  return MakeError(StatusCode::kLimitExceeded, "out of GPU memory in ", what, " (", file, ":", line, "): ", asked,
                   DeviceMemoryNote(), ". Use fewer Gaussians (stage1.densify.max_gaussians), a smaller batch "
                   "(stage1.batch_size, stage2.batch_size) or --downscale");
}

inline Status CudaStatus(cudaError_t error, const char* what, const char* file, int line) {
  if (error == cudaSuccess) return Status::Ok();
  if (error == cudaErrorMemoryAllocation) return OutOfDeviceMemory(what, 0, file, line);
  return MakeError(error == cudaErrorNoDevice || error == cudaErrorInsufficientDriver ? StatusCode::kNoDevice
                                                                                      : StatusCode::kInternal,
                   "CUDA error in ", what, " (", file, ":", line, "): ", cudaGetErrorName(error), " - ",
                   cudaGetErrorString(error));
}

inline Status CublasStatus(cublasStatus_t error, const char* what, const char* file, int line) {
  if (error == CUBLAS_STATUS_SUCCESS) return Status::Ok();
  if (error == CUBLAS_STATUS_ALLOC_FAILED) return OutOfDeviceMemory(what, 0, file, line);
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
