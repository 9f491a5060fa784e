// An owning, typed device allocation (cudaMalloc; never managed memory) that can
// grow. Contents are not preserved by Resize unless asked.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include <cuda_runtime.h>

#include "cuda_check.h"

namespace atex::cuda {

template <typename T>
class DeviceBuffer {
 public:
  DeviceBuffer() = default;
  ~DeviceBuffer() { Free(); }
  DeviceBuffer(const DeviceBuffer&) = delete;
  DeviceBuffer& operator=(const DeviceBuffer&) = delete;
  DeviceBuffer(DeviceBuffer&& other) noexcept { *this = std::move(other); }
  DeviceBuffer& operator=(DeviceBuffer&& other) noexcept {
    if (this != &other) {
      Free();
      data_ = std::exchange(other.data_, nullptr);
      size_ = std::exchange(other.size_, 0);
      capacity_ = std::exchange(other.capacity_, 0);
    }
    return *this;
  }

  // Ensures room for n elements; with keep = true the first min(size, n) survive.
  Status Resize(size_t n, bool keep = false) {
    if (n <= capacity_) {
      size_ = n;
      return Status::Ok();
    }
    const size_t capacity = n + n / 4;  // headroom: densification grows arrays step by step
    T* fresh = nullptr;
    if (capacity > SIZE_MAX / sizeof(T)) {
      return MakeError(StatusCode::kLimitExceeded, "device buffer of ", n, " elements of ", sizeof(T),
                       " bytes overflows the address space");
    }
    const cudaError_t allocated = cudaMalloc(&fresh, capacity * sizeof(T));
    if (allocated == cudaErrorMemoryAllocation) {
      return OutOfDeviceMemory("cudaMalloc (device buffer)", capacity * sizeof(T), __FILE__, __LINE__);
    }
    ATEX_CUDA_RETURN_IF_ERROR(allocated);
    if (keep && size_ > 0) {
      const cudaError_t e = cudaMemcpy(fresh, data_, size_ * sizeof(T), cudaMemcpyDeviceToDevice);
      if (e != cudaSuccess) {
        cudaFree(fresh);
        return CudaStatus(e, "cudaMemcpy (grow)", __FILE__, __LINE__);
      }
    }
    Free();
    data_ = fresh;
    size_ = n;
    capacity_ = capacity;
    return Status::Ok();
  }
  Status Upload(const T* host, size_t n, cudaStream_t stream = nullptr) {
    ATEX_RETURN_IF_ERROR(Resize(n));
    if (n == 0) return Status::Ok();
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(data_, host, n * sizeof(T), cudaMemcpyHostToDevice, stream));
    return Status::Ok();
  }
  Status Upload(const std::vector<T>& host, cudaStream_t stream = nullptr) {
    return Upload(host.data(), host.size(), stream);
  }
  Status Download(std::vector<T>* host, cudaStream_t stream = nullptr) const {
    host->resize(size_);
    if (size_ == 0) return Status::Ok();
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemcpyAsync(host->data(), data_, size_ * sizeof(T), cudaMemcpyDeviceToHost, stream));
    ATEX_CUDA_RETURN_IF_ERROR(cudaStreamSynchronize(stream));
    return Status::Ok();
  }
  Status Zero(cudaStream_t stream = nullptr) {
    if (size_ == 0) return Status::Ok();
    ATEX_CUDA_RETURN_IF_ERROR(cudaMemsetAsync(data_, 0, size_ * sizeof(T), stream));
    return Status::Ok();
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  size_t size() const { return size_; }
  size_t bytes() const { return size_ * sizeof(T); }

 private:
  void Free() {
    if (data_) cudaFree(data_);
    data_ = nullptr;
    size_ = capacity_ = 0;
  }
  T* data_ = nullptr;
  size_t size_ = 0;
  size_t capacity_ = 0;
};

}  // namespace atex::cuda
