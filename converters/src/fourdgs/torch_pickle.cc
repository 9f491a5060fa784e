// Safe protocol-2 unpickler for torch.save(state_dict); see torch_pickle.h.
#include "fourdgs/torch_pickle.h"

#include <algorithm>
#include <cstring>
#include <unordered_map>

namespace atex::fourdgs_internal {

int DtypeSize(TorchDtype dtype) {
  switch (dtype) {
    case TorchDtype::kFloat64:
    case TorchDtype::kInt64: return 8;
    case TorchDtype::kFloat32:
    case TorchDtype::kInt32: return 4;
    case TorchDtype::kFloat16:
    case TorchDtype::kBFloat16:
    case TorchDtype::kInt16: return 2;
    default: return 1;
  }
}

const char* DtypeName(TorchDtype dtype) {
  switch (dtype) {
    case TorchDtype::kFloat32: return "float32";
    case TorchDtype::kFloat64: return "float64";
    case TorchDtype::kFloat16: return "float16";
    case TorchDtype::kBFloat16: return "bfloat16";
    case TorchDtype::kInt64: return "int64";
    case TorchDtype::kInt32: return "int32";
    case TorchDtype::kInt16: return "int16";
    case TorchDtype::kInt8: return "int8";
    case TorchDtype::kUInt8: return "uint8";
    default: return "bool";
  }
}

bool IsFloating(TorchDtype dtype) {
  return dtype == TorchDtype::kFloat32 || dtype == TorchDtype::kFloat64 || dtype == TorchDtype::kFloat16 ||
         dtype == TorchDtype::kBFloat16;
}

namespace {

// Opcodes (pickletools names).
enum Op : uint8_t {
  kMark = '(',
  kStop = '.',
  kBinInt = 'J',
  kBinInt1 = 'K',
  kBinInt2 = 'M',
  kNone = 'N',
  kBinPersId = 'Q',
  kReduce = 'R',
  kBinUnicode = 'X',
  kEmptyList = ']',
  kBuild = 'b',
  kGlobal = 'c',
  kBinGet = 'h',
  kLongBinGet = 'j',
  kBinPut = 'q',
  kLongBinPut = 'r',
  kSetItem = 's',
  kTuple = 't',
  kSetItems = 'u',
  kEmptyDict = '}',
  kEmptyTuple = ')',
  kProto = 0x80,
  kNewTrue = 0x88,
  kNewFalse = 0x89,
  kLong1 = 0x8a,
  kTuple1 = 0x85,
  kTuple2 = 0x86,
  kTuple3 = 0x87,
  kShortBinUnicode = 0x8c,
};

struct StorageType {
  const char* name;
  TorchDtype dtype;
};
constexpr StorageType kStorageTypes[] = {
    {"FloatStorage", TorchDtype::kFloat32}, {"DoubleStorage", TorchDtype::kFloat64},
    {"HalfStorage", TorchDtype::kFloat16},  {"BFloat16Storage", TorchDtype::kBFloat16},
    {"LongStorage", TorchDtype::kInt64},    {"IntStorage", TorchDtype::kInt32},
    {"ShortStorage", TorchDtype::kInt16},   {"CharStorage", TorchDtype::kInt8},
    {"ByteStorage", TorchDtype::kUInt8},    {"BoolStorage", TorchDtype::kBool},
};

constexpr const char* kOrderedDict = "collections.OrderedDict";
constexpr const char* kRebuildTensor = "torch._utils._rebuild_tensor_v2";
constexpr const char* kRebuildParameter = "torch._utils._rebuild_parameter";

class Unpickler {
 public:
  Unpickler(const uint8_t* data, size_t size, const std::string& what, const PickleLimits& limits)
      : data_(data), size_(size), what_(what), limits_(limits) {}

  StatusOr<PyRef> Run() {
    while (true) {
      if (pos_ >= size_) return Error(StatusCode::kTruncated, "pickle ends without STOP");
      op_offset_ = pos_;
      const uint8_t op = data_[pos_++];
      if (op == kStop) {
        if (stack_.size() != 1 || !marks_.empty()) {
          return Error(StatusCode::kCorrupt, "STOP with ", stack_.size(), " values and ", marks_.size(),
                       " marks on the stack (expected exactly one value)");
        }
        if (pos_ != size_) return Error(StatusCode::kCorrupt, size_ - pos_, " bytes after STOP");
        return stack_.back();
      }
      ATEX_RETURN_IF_ERROR(Step(op));
    }
  }

 private:
  template <typename... Args>
  Status Error(StatusCode code, const Args&... args) const {
    return MakeError(code, what_, ": byte ", op_offset_, ": ", args...);
  }

  Status Need(size_t n) const {
    if (size_ - pos_ < n) {
      return Error(StatusCode::kTruncated, "opcode 0x", std::hex, int(data_[op_offset_]), std::dec, " needs ", n,
                   " argument bytes, ", size_ - pos_, " left");
    }
    return Status::Ok();
  }
  uint64_t ReadLE(size_t n) {
    uint64_t v = 0;
    for (size_t i = 0; i < n; ++i) v |= static_cast<uint64_t>(data_[pos_ + i]) << (8 * i);
    pos_ += n;
    return v;
  }

  StatusOr<PyRef> New(PyKind kind) {
    if (++objects_ > limits_.max_objects) {
      return Error(StatusCode::kLimitExceeded, "more than ", limits_.max_objects, " objects");
    }
    auto obj = std::make_shared<PyObject>();
    obj->kind = kind;
    return obj;
  }
  Status Push(StatusOr<PyRef> obj) {
    if (!obj.ok()) return obj.status();
    stack_.push_back(std::move(obj).value());
    return Status::Ok();
  }
  StatusOr<PyRef> Pop() {
    const size_t floor = marks_.empty() ? 0 : marks_.back();
    if (stack_.size() <= floor) return Error(StatusCode::kCorrupt, "stack underflow");
    PyRef v = std::move(stack_.back());
    stack_.pop_back();
    return v;
  }
  // Values above the topmost MARK, which is removed.
  StatusOr<std::vector<PyRef>> PopToMark() {
    if (marks_.empty()) return Error(StatusCode::kCorrupt, "no MARK on the stack");
    const size_t mark = marks_.back();
    marks_.pop_back();
    std::vector<PyRef> values(std::make_move_iterator(stack_.begin() + mark), std::make_move_iterator(stack_.end()));
    stack_.resize(mark);
    return values;
  }

  // Makes `child` part of `parent`: seals it and updates the depth.
  Status Adopt(PyObject& parent, const PyRef& child) {
    child->sealed = true;
    parent.depth = std::max(parent.depth, child->depth + 1);
    if (parent.depth > limits_.max_depth) {
      return Error(StatusCode::kLimitExceeded, "values nested deeper than ", limits_.max_depth);
    }
    return Status::Ok();
  }

  Status MakeTuple(std::vector<PyRef> values) {
    ATEX_ASSIGN_OR_RETURN(PyRef tuple, New(PyKind::kTuple));
    for (const PyRef& v : values) ATEX_RETURN_IF_ERROR(Adopt(*tuple, v));
    tuple->items = std::move(values);
    stack_.push_back(std::move(tuple));
    return Status::Ok();
  }

  Status SetItems(const PyRef& dict, std::vector<PyRef>& kv) {
    if (dict->kind != PyKind::kDict) return Error(StatusCode::kCorrupt, "SETITEM(S) on a value that is not a dict");
    if (dict->sealed) return Error(StatusCode::kUnsupported, "SETITEM(S) on a dict already stored elsewhere");
    if (kv.size() % 2 != 0) return Error(StatusCode::kCorrupt, "SETITEMS with an odd number of values");
    for (size_t i = 0; i < kv.size(); i += 2) {
      // An unsealed dict is inside nothing, so only itself could close a cycle.
      if (kv[i] == dict || kv[i + 1] == dict) return Error(StatusCode::kCorrupt, "a dict inserted into itself");
      ATEX_RETURN_IF_ERROR(Adopt(*dict, kv[i]));
      ATEX_RETURN_IF_ERROR(Adopt(*dict, kv[i + 1]));
      // A repeated key replaces the value, as in Python (compared as strings or ints).
      bool replaced = false;
      for (auto& entry : dict->entries) {
        const PyObject& k = *entry.first;
        if (k.kind == kv[i]->kind && k.integer == kv[i]->integer && k.text == kv[i]->text &&
            (k.kind == PyKind::kString || k.kind == PyKind::kInt)) {
          entry.second = kv[i + 1];
          replaced = true;
          break;
        }
      }
      if (!replaced) dict->entries.emplace_back(kv[i], kv[i + 1]);
    }
    return Status::Ok();
  }

  Status String(size_t length) {
    ATEX_RETURN_IF_ERROR(Need(length));
    ATEX_ASSIGN_OR_RETURN(PyRef s, New(PyKind::kString));
    s->text.assign(reinterpret_cast<const char*>(data_ + pos_), length);
    pos_ += length;
    stack_.push_back(std::move(s));
    return Status::Ok();
  }

  Status Integer(int64_t value) {
    ATEX_ASSIGN_OR_RETURN(PyRef v, New(PyKind::kInt));
    v->integer = value;
    stack_.push_back(std::move(v));
    return Status::Ok();
  }

  StatusOr<std::string> Line() {
    const uint8_t* end = static_cast<const uint8_t*>(std::memchr(data_ + pos_, '\n', size_ - pos_));
    if (end == nullptr) return Error(StatusCode::kTruncated, "GLOBAL name without a newline");
    std::string line(reinterpret_cast<const char*>(data_ + pos_), end - (data_ + pos_));
    pos_ = static_cast<size_t>(end - data_) + 1;
    if (line.size() > 256) return Error(StatusCode::kCorrupt, "GLOBAL name of ", line.size(), " bytes");
    return line;
  }

  Status Global() {
    ATEX_ASSIGN_OR_RETURN(std::string module, Line());
    ATEX_ASSIGN_OR_RETURN(std::string name, Line());
    const std::string full = module + "." + name;
    ATEX_ASSIGN_OR_RETURN(PyRef g, New(PyKind::kGlobal));
    g->text = full;
    if (full == kOrderedDict || full == kRebuildTensor || full == kRebuildParameter) {
      stack_.push_back(std::move(g));
      return Status::Ok();
    }
    if (module == "torch") {
      for (const StorageType& t : kStorageTypes) {
        if (name == t.name) {
          g->dtype = t.dtype;
          g->integer = 1;  // marks a storage type
          stack_.push_back(std::move(g));
          return Status::Ok();
        }
      }
    }
    return Error(StatusCode::kUnsupported, "GLOBAL '", full, "' is not allowed (a torch.save(state_dict) of tensors ",
                 "only needs OrderedDict, _rebuild_tensor_v2 and storage types)");
  }

  // BINPERSID: ('storage', <torch.XStorage>, key, location, numel) -> storage.
  Status PersistentId() {
    ATEX_ASSIGN_OR_RETURN(PyRef pid, Pop());
    const auto& it = pid->items;
    if (pid->kind != PyKind::kTuple || it.size() != 5 || it[0]->kind != PyKind::kString || it[0]->text != "storage" ||
        it[1]->kind != PyKind::kGlobal || it[1]->integer != 1 || it[2]->kind != PyKind::kString ||
        it[3]->kind != PyKind::kString || it[4]->kind != PyKind::kInt) {
      return Error(StatusCode::kUnsupported,
                   "persistent id is not ('storage', torch.<Type>Storage, key, location, numel)");
    }
    if (it[4]->integer < 0) return Error(StatusCode::kCorrupt, "storage numel ", it[4]->integer, " is negative");
    ATEX_ASSIGN_OR_RETURN(PyRef storage, New(PyKind::kStorage));
    storage->dtype = it[1]->dtype;
    storage->text = it[2]->text;
    storage->location = it[3]->text;
    storage->numel = it[4]->integer;
    stack_.push_back(std::move(storage));
    return Status::Ok();
  }

  static bool IntTuple(const PyRef& v, std::vector<int64_t>* out) {
    if (v->kind != PyKind::kTuple) return false;
    out->clear();
    for (const PyRef& x : v->items) {
      if (x->kind != PyKind::kInt) return false;
      out->push_back(x->integer);
    }
    return true;
  }

  Status Reduce() {
    ATEX_ASSIGN_OR_RETURN(PyRef args, Pop());
    ATEX_ASSIGN_OR_RETURN(PyRef callable, Pop());
    if (callable->kind != PyKind::kGlobal || args->kind != PyKind::kTuple) {
      return Error(StatusCode::kUnsupported, "REDUCE of a value that is not an allowed global with a tuple");
    }
    args->sealed = true;
    const auto& a = args->items;
    if (callable->text == kOrderedDict) {
      if (!a.empty()) return Error(StatusCode::kUnsupported, "OrderedDict(...) with arguments");
      return Push(New(PyKind::kDict));
    }
    if (callable->text == kRebuildTensor) {
      // (storage, storage_offset, size, stride, requires_grad, backward_hooks[, metadata])
      if ((a.size() != 6 && a.size() != 7) || a[0]->kind != PyKind::kStorage || a[1]->kind != PyKind::kInt ||
          a[4]->kind != PyKind::kBool || a[5]->kind != PyKind::kDict) {
        return Error(StatusCode::kUnsupported, "_rebuild_tensor_v2 with unexpected arguments (", a.size(),
                     " values)");
      }
      ATEX_ASSIGN_OR_RETURN(PyRef t, New(PyKind::kTensor));
      if (!IntTuple(a[2], &t->shape) || !IntTuple(a[3], &t->stride) || t->shape.size() != t->stride.size()) {
        return Error(StatusCode::kCorrupt, "_rebuild_tensor_v2: size and stride must be tuples of ints of one length");
      }
      if (t->shape.size() > static_cast<size_t>(limits_.max_tensor_dims)) {
        return Error(StatusCode::kLimitExceeded, "tensor with ", t->shape.size(), " dimensions");
      }
      t->storage = a[0];
      t->storage_offset = a[1]->integer;
      return Push(std::move(t));
    }
    if (callable->text == kRebuildParameter) {
      // (data, requires_grad, backward_hooks): the parameter is its data tensor.
      if (a.size() != 3 || a[0]->kind != PyKind::kTensor || a[1]->kind != PyKind::kBool ||
          a[2]->kind != PyKind::kDict) {
        return Error(StatusCode::kUnsupported, "_rebuild_parameter with unexpected arguments");
      }
      stack_.push_back(a[0]);
      return Status::Ok();
    }
    return Error(StatusCode::kUnsupported, "REDUCE of '", callable->text, "', which is not callable here");
  }

  Status Build() {
    ATEX_ASSIGN_OR_RETURN(PyRef state, Pop());
    if (stack_.empty()) return Error(StatusCode::kCorrupt, "BUILD without a target");
    const PyRef& target = stack_.back();
    // OrderedDict state (the state_dict's _metadata): accepted and dropped.
    if (target->kind == PyKind::kDict && !target->sealed &&
        (state->kind == PyKind::kDict || state->kind == PyKind::kNone)) {
      return Status::Ok();
    }
    return Error(StatusCode::kUnsupported, "BUILD is only accepted for an OrderedDict's attribute dict");
  }

  Status Memo(uint64_t index) {
    const size_t floor = marks_.empty() ? 0 : marks_.back();
    if (stack_.size() <= floor) return Error(StatusCode::kCorrupt, "PUT with an empty stack");
    if (memo_.size() >= limits_.max_memo && memo_.find(index) == memo_.end()) {
      return Error(StatusCode::kLimitExceeded, "more than ", limits_.max_memo, " memo entries");
    }
    memo_[index] = stack_.back();
    return Status::Ok();
  }
  Status Get(uint64_t index) {
    auto it = memo_.find(index);
    if (it == memo_.end()) return Error(StatusCode::kCorrupt, "GET of memo entry ", index, ", which was never PUT");
    stack_.push_back(it->second);
    return Status::Ok();
  }

  Status Step(uint8_t op) {
    switch (op) {
      case kProto: {
        ATEX_RETURN_IF_ERROR(Need(1));
        const int version = data_[pos_++];
        if (op_offset_ != 0 || version < 2 || version > 5) {
          return Error(StatusCode::kUnsupported, "PROTO ", version, " (expected protocol 2..5 at byte 0)");
        }
        return Status::Ok();
      }
      case kMark:
        marks_.push_back(stack_.size());
        return Status::Ok();
      case kEmptyDict: return Push(New(PyKind::kDict));
      case kEmptyList: return Push(New(PyKind::kList));
      case kEmptyTuple: return MakeTuple({});
      case kNone: return Push(New(PyKind::kNone));
      case kNewTrue:
      case kNewFalse: {
        ATEX_ASSIGN_OR_RETURN(PyRef b, New(PyKind::kBool));
        b->integer = op == kNewTrue ? 1 : 0;
        stack_.push_back(std::move(b));
        return Status::Ok();
      }
      case kBinInt: {
        ATEX_RETURN_IF_ERROR(Need(4));
        return Integer(static_cast<int32_t>(static_cast<uint32_t>(ReadLE(4))));
      }
      case kBinInt1: {
        ATEX_RETURN_IF_ERROR(Need(1));
        return Integer(static_cast<int64_t>(ReadLE(1)));
      }
      case kBinInt2: {
        ATEX_RETURN_IF_ERROR(Need(2));
        return Integer(static_cast<int64_t>(ReadLE(2)));
      }
      case kLong1: {
        ATEX_RETURN_IF_ERROR(Need(1));
        const size_t n = data_[pos_++];
        if (n > 8) return Error(StatusCode::kUnsupported, "LONG1 of ", n, " bytes (integers beyond 64 bits)");
        ATEX_RETURN_IF_ERROR(Need(n));
        uint64_t v = ReadLE(n);
        if (n > 0 && n < 8 && (v >> (8 * n - 1)) & 1) v |= ~uint64_t{0} << (8 * n);  // sign-extend
        return Integer(static_cast<int64_t>(v));
      }
      case kBinUnicode: {
        ATEX_RETURN_IF_ERROR(Need(4));
        return String(ReadLE(4));
      }
      case kShortBinUnicode: {
        ATEX_RETURN_IF_ERROR(Need(1));
        return String(ReadLE(1));
      }
      case kTuple: {
        ATEX_ASSIGN_OR_RETURN(std::vector<PyRef> values, PopToMark());
        return MakeTuple(std::move(values));
      }
      case kTuple1:
      case kTuple2:
      case kTuple3: {
        const size_t n = op - kTuple1 + 1;
        std::vector<PyRef> values(n);
        for (size_t i = n; i-- > 0;) {
          ATEX_ASSIGN_OR_RETURN(values[i], Pop());
        }
        return MakeTuple(std::move(values));
      }
      case kGlobal: return Global();
      case kBinPersId: return PersistentId();
      case kReduce: return Reduce();
      case kBuild: return Build();
      case kSetItem: {
        std::vector<PyRef> kv(2);
        ATEX_ASSIGN_OR_RETURN(kv[1], Pop());
        ATEX_ASSIGN_OR_RETURN(kv[0], Pop());
        if (stack_.empty() || (!marks_.empty() && stack_.size() <= marks_.back())) {
          return Error(StatusCode::kCorrupt, "SETITEM without a dict");
        }
        return SetItems(stack_.back(), kv);
      }
      case kSetItems: {
        ATEX_ASSIGN_OR_RETURN(std::vector<PyRef> kv, PopToMark());
        if (stack_.empty() || (!marks_.empty() && stack_.size() <= marks_.back())) {
          return Error(StatusCode::kCorrupt, "SETITEMS without a dict");
        }
        return SetItems(stack_.back(), kv);
      }
      case kBinPut: {
        ATEX_RETURN_IF_ERROR(Need(1));
        return Memo(ReadLE(1));
      }
      case kLongBinPut: {
        ATEX_RETURN_IF_ERROR(Need(4));
        return Memo(ReadLE(4));
      }
      case kBinGet: {
        ATEX_RETURN_IF_ERROR(Need(1));
        return Get(ReadLE(1));
      }
      case kLongBinGet: {
        ATEX_RETURN_IF_ERROR(Need(4));
        return Get(ReadLE(4));
      }
      default:
        return Error(StatusCode::kUnsupported, "opcode 0x", std::hex, int(op), std::dec,
                     (op >= 0x20 && op < 0x7f ? StrCat(" ('", char(op), "')") : std::string()),
                     " is not accepted (not part of a torch.save(state_dict) pickle)");
    }
  }

  const uint8_t* data_;
  size_t size_;
  std::string what_;
  PickleLimits limits_;
  size_t pos_ = 0;
  size_t op_offset_ = 0;
  size_t objects_ = 0;
  std::vector<PyRef> stack_;
  std::vector<size_t> marks_;
  std::unordered_map<uint64_t, PyRef> memo_;
};

}  // namespace

StatusOr<PyRef> Unpickle(const uint8_t* data, size_t size, const std::string& what, const PickleLimits& limits) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, what, ": null pickle data");
  Unpickler unpickler(data, size, what, limits);
  return unpickler.Run();
}

}  // namespace atex::fourdgs_internal
