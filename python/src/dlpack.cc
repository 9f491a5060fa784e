// atex.Tensor: a DLPack producer (__dlpack__, __dlpack_device__) over C++-owned memory,
// readable as numpy without a copy on the host.
#include "dlpack.h"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <string>

#include "common.h"

namespace atex::python {

namespace {

// What a DLManagedTensor owns: a reference to the memory's owner and the shape array.
struct ManagerContext {
  std::shared_ptr<const void> owner;
  std::vector<int64_t> shape;
  dlpack::ManagedTensor managed{};
};

void DeleteManaged(dlpack::ManagedTensor* self) {
  delete static_cast<ManagerContext*>(self->manager_ctx);
}

// The capsule's destructor: a capsule still named "dltensor" was never consumed, so its
// tensor is ours to free; a consumer renames it "used_dltensor" and calls the deleter itself.
void DestroyCapsule(PyObject* capsule) {
  if (PyCapsule_IsValid(capsule, "dltensor")) {
    auto* managed = static_cast<dlpack::ManagedTensor*>(PyCapsule_GetPointer(capsule, "dltensor"));
    if (managed != nullptr && managed->deleter != nullptr) managed->deleter(managed);
  }
}

py::object ToCapsule(const TensorData& t) {
  auto* context = new ManagerContext{t.owner, t.shape, {}};
  dlpack::ManagedTensor& m = context->managed;
  m.dl_tensor.data = t.data;
  m.dl_tensor.device = t.device;
  m.dl_tensor.ndim = static_cast<int32_t>(context->shape.size());
  m.dl_tensor.dtype = t.dtype;
  m.dl_tensor.shape = context->shape.data();
  m.dl_tensor.strides = nullptr;  // C order
  m.dl_tensor.byte_offset = 0;
  m.manager_ctx = context;
  m.deleter = DeleteManaged;
  PyObject* capsule = PyCapsule_New(&m, "dltensor", DestroyCapsule);
  if (capsule == nullptr) {
    delete context;
    throw py::error_already_set();
  }
  return py::reinterpret_steal<py::object>(capsule);
}

py::dtype NumpyType(const dlpack::DataType& t) {
  if (t.code == dlpack::kFloat && t.bits == 32) return py::dtype::of<float>();
  if (t.code == dlpack::kInt && t.bits == 32) return py::dtype::of<int32_t>();
  if (t.code == dlpack::kUInt && t.bits == 8) return py::dtype::of<uint8_t>();
  if (t.code == dlpack::kUInt && t.bits == 64) return py::dtype::of<uint64_t>();
  ThrowStatus(MakeError(StatusCode::kInternal, "atex.Tensor: no numpy type for DLPack type ", int(t.code), "/",
                        int(t.bits)));
}

const char* DeviceName(int32_t type) {
  switch (type) {
    case dlpack::kCpu: return "cpu";
    case dlpack::kCuda: return "cuda";
    case dlpack::kCudaHost: return "cuda-host";
    default: return "unknown";
  }
}

}  // namespace

int64_t TensorData::elements() const {
  int64_t n = 1;
  for (int64_t s : shape) n *= s;
  return n;
}

py::object MakeTensor(TensorData data) { return py::cast(std::move(data)); }

void RegisterTensor(py::module_& m) {
  py::class_<TensorData>(m, "Tensor",
                         "Memory produced by libatex (a render, deformed Gaussians), exchanged without a copy.\n\n"
                         "Implements the DLPack protocol (__dlpack__, __dlpack_device__), so torch.from_dlpack(t),\n"
                         "numpy.from_dlpack(t) or cupy.from_dlpack(t) share its memory; numpy.asarray(t) and\n"
                         "t.numpy() give a numpy view of host memory. The memory lives as long as any of them.")
      .def_property_readonly("shape", [](const TensorData& t) { return py::tuple(py::cast(t.shape)); })
      .def_property_readonly("dtype", [](const TensorData& t) { return NumpyType(t.dtype); })
      .def_property_readonly("device", [](const TensorData& t) { return std::string(DeviceName(t.device.device_type)); })
      .def_property_readonly("data_ptr", [](const TensorData& t) { return reinterpret_cast<uintptr_t>(t.data); },
                             "Address of the first element (compare with torch's tensor.data_ptr()).")
      .def(
          "__dlpack__",
          [](const TensorData& t, py::object stream, py::object max_version, py::object dl_device, py::object copy) {
            // Host memory needs no stream synchronisation. Device tensors are produced after
            // the device work finished (the backend synchronises), so any consumer stream may
            // use them at once. A copy is never made: copy=True cannot be honoured.
            if (!copy.is_none() && copy.cast<bool>()) {
              ThrowStatus(MakeError(StatusCode::kUnsupported, "atex.Tensor.__dlpack__: copy=True is not supported"));
            }
            if (!dl_device.is_none()) {
              auto requested = dl_device.cast<std::pair<int, int>>();
              if (requested.first != t.device.device_type || requested.second != t.device.device_id) {
                ThrowStatus(MakeError(StatusCode::kUnsupported,
                                      "atex.Tensor.__dlpack__: the tensor is on another device (no copies)"));
              }
            }
            (void)stream;
            (void)max_version;  // the unversioned capsule, which every consumer accepts
            return ToCapsule(t);
          },
          py::kw_only(), py::arg("stream") = py::none(), py::arg("max_version") = py::none(),
          py::arg("dl_device") = py::none(), py::arg("copy") = py::none(),
          "A DLPack capsule ('dltensor') sharing this tensor's memory.")
      .def("__dlpack_device__",
           [](const TensorData& t) { return py::make_tuple(t.device.device_type, t.device.device_id); },
           "(device type, device id) as DLPack numbers: (1, 0) for the host, (2, n) for CUDA device n.")
      .def(
          "numpy",
          [](py::object self) {
            const auto& t = self.cast<const TensorData&>();
            if (t.device.device_type != dlpack::kCpu) {
              ThrowStatus(MakeError(StatusCode::kUnsupported, "atex.Tensor.numpy(): the tensor is on ",
                                    DeviceName(t.device.device_type), ", not the host"));
            }
            std::vector<py::ssize_t> shape(t.shape.begin(), t.shape.end());
            std::vector<py::ssize_t> strides(shape.size());
            py::ssize_t stride = t.dtype.bits / 8;
            for (size_t i = shape.size(); i-- > 0;) {
              strides[i] = stride;
              stride *= shape[i];
            }
            py::array view(NumpyType(t.dtype), shape, strides, t.data, self);
            if (t.read_only) {
              py::detail::array_proxy(view.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
            }
            return view;
          },
          "A numpy view of host memory (no copy; the view keeps this tensor alive; read-only for shared memory).")
      .def("__array__", [](py::object self, py::object dtype) {
            py::object view = self.attr("numpy")();
            return dtype.is_none() ? view : view.attr("astype")(dtype);
          }, py::arg("dtype") = py::none())
      .def("__repr__", [](const TensorData& t) {
        std::string shape;
        for (size_t i = 0; i < t.shape.size(); ++i) shape += (i ? ", " : "") + std::to_string(t.shape[i]);
        return "atex.Tensor(shape=(" + shape + "), device=" + DeviceName(t.device.device_type) + ")";
      });
}

}  // namespace atex::python
