// Shared pieces of the Python module: raising atex.Error from a Status, numpy views of
// C++ arrays that keep their owner alive, JSON <-> Python, and the asset holder.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/container.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::python {

namespace py = pybind11;

// Creates atex.Error (a subclass of Exception with .code, .name and .message) in `module`.
void RegisterError(py::module_& module);
// Raises atex.Error carrying the status's number, name and message. Needs the GIL.
[[noreturn]] void ThrowStatus(const Status& status);
inline void ThrowIfError(const Status& status) {
  if (!status.ok()) ThrowStatus(status);
}
template <typename T>
T ValueOrThrow(StatusOr<T>&& value) {
  if (!value.ok()) ThrowStatus(value.status());
  return std::move(value).value();
}

// A numpy array over `data` with `shape` (C order) whose base is `owner`: no copy, and
// the owner lives as long as the array. Read-only unless `writeable`.
template <typename T>
py::array ArrayView(const T* data, std::vector<py::ssize_t> shape, py::handle owner, bool writeable = false) {
  std::vector<py::ssize_t> strides(shape.size());
  py::ssize_t stride = sizeof(T);
  for (size_t i = shape.size(); i-- > 0;) {
    strides[i] = stride;
    stride *= shape[i];
  }
  // numpy refuses a null data pointer for an empty array only when the base is not set; an
  // empty std::vector may give nullptr, which is fine with a base.
  py::array out(py::dtype::of<T>(), std::move(shape), std::move(strides), data, owner);
  if (!writeable) py::detail::array_proxy(out.ptr())->flags &= ~py::detail::npy_api::NPY_ARRAY_WRITEABLE_;
  return out;
}

// JSON <-> Python objects (through the json module's text form: reports are small).
py::object JsonToPython(const nlohmann::json& json);
nlohmann::json PythonToJson(py::handle object);

// What a Python atex.Asset holds: the asset (never changed after construction, so its
// numpy views are read-only and a backend loaded with it stays valid), the encodings of
// the file it came from (writes keep them), and the backends it was loaded into.
struct AssetHolder {
  Asset asset;
  std::optional<WriteOptions> file_encodings;
  std::mutex backends_mutex;
  struct LoadedBackend {
    std::string name;         // "cpu" or "cuda"
    std::string description;  // e.g. "cuda: NVIDIA H100 ..."
    std::unique_ptr<train::Backend> backend;
    std::mutex mutex;         // one render at a time per backend
  };
  std::vector<std::unique_ptr<LoadedBackend>> backends;
};
using AssetPtr = std::shared_ptr<AssetHolder>;

// Returns the asset's backend of that name ("auto", "cuda" or "cpu"), loading it on first
// use. Call without the GIL.
StatusOr<AssetHolder::LoadedBackend*> BackendFor(AssetHolder& holder, const std::string& name);
// A fresh backend ("auto": CUDA when built and a device is present, else the CPU reference).
StatusOr<std::unique_ptr<train::Backend>> MakeBackend(const std::string& name, std::string* description);

void RegisterTensor(py::module_& m);
void RegisterAsset(py::module_& m);
void RegisterRender(py::module_& m);
void RegisterFitTrain(py::module_& m);
void RegisterExport(py::module_& m);

}  // namespace atex::python
