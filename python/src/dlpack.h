// The DLPack C ABI (https://dmlc.github.io/dlpack/latest/c_api.html), the unversioned form
// every consumer (torch.from_dlpack, numpy.from_dlpack, CuPy, JAX) accepts, declared here
// from the public specification; and atex.Tensor, which hands C++ memory to those consumers
// without a copy.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <pybind11/pybind11.h>

namespace atex::python {

namespace dlpack {
enum DeviceType : int32_t { kCpu = 1, kCuda = 2, kCudaHost = 3 };
enum TypeCode : uint8_t { kInt = 0, kUInt = 1, kFloat = 2 };
struct Device {
  int32_t device_type;
  int32_t device_id;
};
struct DataType {
  uint8_t code;
  uint8_t bits;
  uint16_t lanes;
};
struct Tensor {
  void* data;
  Device device;
  int32_t ndim;
  DataType dtype;
  int64_t* shape;
  int64_t* strides;  // in elements; may be null for C order
  uint64_t byte_offset;
};
struct ManagedTensor {
  Tensor dl_tensor;
  void* manager_ctx;
  void (*deleter)(ManagedTensor* self);
};
}  // namespace dlpack

// A block of memory, its element type and shape (C order), on the host or a CUDA device,
// kept alive by `owner` (a shared_ptr to whatever holds it: an image, an asset).
struct TensorData {
  std::shared_ptr<const void> owner;
  void* data = nullptr;
  dlpack::DataType dtype{dlpack::kFloat, 32, 1};
  std::vector<int64_t> shape;
  dlpack::Device device{dlpack::kCpu, 0};
  // Shared memory that must not change (an asset's arrays, a dataset's cached image): numpy
  // views are read-only. (Unversioned DLPack has no read-only flag; consumers are trusted.)
  bool read_only = false;

  int64_t elements() const;
};

// Makes an atex.Tensor Python object from `data`.
pybind11::object MakeTensor(TensorData data);

}  // namespace atex::python
