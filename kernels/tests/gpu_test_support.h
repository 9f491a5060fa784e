// Helpers shared by the CUDA backend's tests: skipping without a device, device
// copies of host vectors, NaN poisoning and relative errors.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <cuda_runtime.h>
#include <gtest/gtest.h>

#include "atex/status.h"
#include "device_buffer.h"

namespace atex::cuda::testing {

// Number of usable CUDA devices (0 when the driver or the device is missing).
inline int CudaDeviceCount() {
  int count = 0;
  if (cudaGetDeviceCount(&count) != cudaSuccess) {
    cudaGetLastError();  // clear the error so that later calls start clean
    return 0;
  }
  return count;
}

// Skips the calling test (body or SetUp) with a message when there is no device.
#define ATEX_REQUIRE_CUDA_DEVICE()                                                      \
  do {                                                                                  \
    if (::atex::cuda::testing::CudaDeviceCount() == 0) {                                \
      GTEST_SKIP() << "no CUDA device (cudaGetDeviceCount failed or returned 0)";       \
    }                                                                                   \
  } while (0)

#define ATEX_ASSERT_OK(expr)                                      \
  do {                                                            \
    const ::atex::Status atex_test_status_ = (expr);              \
    ASSERT_TRUE(atex_test_status_.ok()) << atex_test_status_.ToString(); \
  } while (0)

#define ATEX_ASSERT_CUDA(expr)                                                         \
  do {                                                                                 \
    const cudaError_t atex_test_error_ = (expr);                                       \
    ASSERT_EQ(atex_test_error_, cudaSuccess) << #expr << ": " << cudaGetErrorString(atex_test_error_); \
  } while (0)

// A device copy of a host vector (synchronous).
template <typename T>
Status ToDevice(const std::vector<T>& host, DeviceBuffer<T>* device) {
  ATEX_RETURN_IF_ERROR(device->Upload(host));
  ATEX_CUDA_RETURN_IF_ERROR(cudaDeviceSynchronize());
  return Status::Ok();
}

// Allocates n floats filled with NaN (all bits set), so unwritten outputs show.
inline Status PoisonedDevice(size_t n, DeviceBuffer<float>* device) {
  ATEX_RETURN_IF_ERROR(device->Resize(n));
  if (n > 0) ATEX_CUDA_RETURN_IF_ERROR(cudaMemset(device->data(), 0xFF, n * sizeof(float)));
  return Status::Ok();
}

inline std::vector<float> ToHost(const DeviceBuffer<float>& device) {
  std::vector<float> host;
  const Status status = device.Download(&host);
  if (!status.ok()) host.assign(device.size(), std::numeric_limits<float>::quiet_NaN());
  return host;
}

// Index of the first non-finite value, or -1.
template <typename T>
long long FirstNonFinite(const std::vector<T>& v) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(static_cast<double>(v[i]))) return static_cast<long long>(i);
  }
  return -1;
}

// ||got - want|| / ||want - base|| in double (base empty = 0): the error relative to the size of
// the quantity being compared (for accumulated outputs, the increment). NaN anywhere gives NaN.
template <typename A, typename B>
double RelativeError(const std::vector<A>& got, const std::vector<B>& want, const std::vector<float>& base = {}) {
  if (got.size() != want.size() || (!base.empty() && base.size() != want.size())) {
    return std::numeric_limits<double>::infinity();
  }
  double diff = 0, norm = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    const double g = static_cast<double>(got[i]);
    const double w = static_cast<double>(want[i]);
    const double b = base.empty() ? 0.0 : static_cast<double>(base[i]);
    diff += (g - w) * (g - w);
    norm += (w - b) * (w - b);
  }
  if (std::isnan(diff)) return std::numeric_limits<double>::quiet_NaN();
  if (norm == 0) return std::sqrt(diff);
  return std::sqrt(diff / norm);
}

}  // namespace atex::cuda::testing
