// A minimal, safe unpickler for what `torch.save(state_dict)` writes into
// `data.pkl` (pickle protocol 2): nested dicts of tensors that point at
// storages by persistent id. It never executes anything: the only callables
// are an allow-list evaluated by hand (collections.OrderedDict,
// torch._utils._rebuild_tensor_v2, torch._utils._rebuild_parameter), and every
// other opcode or global is refused with an error naming it and its byte
// offset.
//
// Safety: every read is bounds-checked; object count, memo size and nesting
// depth are limited; a container can only be filled (SETITEM(S), BUILD)
// before it is placed into another one, so the result is a finite tree (no
// cycles, bounded depth, no recursive destruction deeper than the limit).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "atex/status.h"

namespace atex::fourdgs_internal {

// Element types of torch storages (torch.<Name>Storage).
enum class TorchDtype : uint8_t {
  kFloat32,
  kFloat64,
  kFloat16,
  kBFloat16,
  kInt64,
  kInt32,
  kInt16,
  kInt8,
  kUInt8,
  kBool
};
int DtypeSize(TorchDtype dtype);
const char* DtypeName(TorchDtype dtype);
bool IsFloating(TorchDtype dtype);

struct PyObject;
using PyRef = std::shared_ptr<PyObject>;

enum class PyKind : uint8_t {
  kNone,
  kBool,
  kInt,
  kString,
  kTuple,
  kList,
  kDict,      // dict or collections.OrderedDict (insertion order kept)
  kGlobal,    // an allow-listed global (callable or storage type), unevaluated
  kStorage,   // persistent id ('storage', type, key, location, numel)
  kTensor,    // result of _rebuild_tensor_v2 / _rebuild_parameter
};

struct PyObject {
  PyKind kind = PyKind::kNone;
  int depth = 1;          // nesting depth of this value (leaves: 1)
  bool sealed = false;    // placed inside another value: no longer mutable
  int64_t integer = 0;    // kBool (0/1), kInt; kGlobal: 1 for a storage type
  std::string text;       // kString; kGlobal: "module.name"; kStorage: key
  std::vector<PyRef> items;                        // kTuple, kList
  std::vector<std::pair<PyRef, PyRef>> entries;    // kDict, in insertion order
  // kStorage
  TorchDtype dtype = TorchDtype::kFloat32;
  std::string location;
  int64_t numel = 0;
  // kTensor
  PyRef storage;
  int64_t storage_offset = 0;
  std::vector<int64_t> shape;
  std::vector<int64_t> stride;
};

struct PickleLimits {
  size_t max_objects = size_t{1} << 20;
  size_t max_memo = size_t{1} << 20;
  int max_depth = 32;
  int max_tensor_dims = 16;
};

// Parses a whole pickle (`what` names it in messages, e.g. "deformation.pth:
// archive/data.pkl"). Returns the value left by STOP.
StatusOr<PyRef> Unpickle(const uint8_t* data, size_t size, const std::string& what, const PickleLimits& limits = {});

}  // namespace atex::fourdgs_internal
