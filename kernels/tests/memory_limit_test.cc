// Issue 24: out of GPU memory is a limit (kLimitExceeded, as on the CPU), never an
// internal error, and the message says how much was asked and how much is free. The
// device stays usable afterwards (the error is not left pending for later checks).
#include <gtest/gtest.h>

#include "cuda_check.h"
#include "device_buffer.h"
#include "gpu_test_support.h"

namespace atex::cuda {
namespace {

TEST(DeviceMemory, AnAllocationBeyondTheCardIsALimitNamingBothSizes) {
  ATEX_REQUIRE_CUDA_DEVICE();
  size_t free_bytes = 0, total_bytes = 0;
  ASSERT_EQ(cudaMemGetInfo(&free_bytes, &total_bytes), cudaSuccess);
  DeviceBuffer<float> huge;
  const Status s = huge.Resize(2 * (total_bytes / sizeof(float)));  // twice the card
  EXPECT_EQ(s.code(), StatusCode::kLimitExceeded) << s.ToString();
  EXPECT_NE(s.message().find("MiB asked"), std::string::npos) << s.ToString();
  EXPECT_NE(s.message().find("GiB free of"), std::string::npos) << s.ToString();
  EXPECT_EQ(cudaGetLastError(), cudaSuccess);  // cleared: the next launch check is clean
  DeviceBuffer<float> small;
  EXPECT_TRUE(small.Resize(1024).ok());
  // Beyond the address space: refused before cudaMalloc.
  EXPECT_EQ(huge.Resize(SIZE_MAX / 2).code(), StatusCode::kLimitExceeded);
}

TEST(DeviceMemory, CudaStatusMapsAllocationFailuresToTheLimitCode) {
  // No device needed: the mapping of the error values.
  const Status oom = CudaStatus(cudaErrorMemoryAllocation, "cudaMalloc", __FILE__, __LINE__);
  EXPECT_EQ(oom.code(), StatusCode::kLimitExceeded) << oom.ToString();
  EXPECT_NE(oom.message().find("out of GPU memory"), std::string::npos);
  EXPECT_EQ(CublasStatus(CUBLAS_STATUS_ALLOC_FAILED, "cublasCreate", __FILE__, __LINE__).code(),
            StatusCode::kLimitExceeded);
  EXPECT_EQ(CudaStatus(cudaErrorInvalidValue, "x", __FILE__, __LINE__).code(), StatusCode::kInternal);
}

}  // namespace
}  // namespace atex::cuda
