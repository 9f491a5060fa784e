// ReadTorchStateDict: the zip archive of torch.save (>= 1.6) -> named tensors.
//
// Layout: `<name>/data.pkl` (the pickle), `<name>/data/<key>` (one raw
// storage per key, numel * element size bytes), `<name>/byteorder` ("little"
// or "big"; absent in older files = little) and a few version records that
// are not needed here.
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "atex/converters/fourdgs.h"
#include "atex/zip.h"
#include "fourdgs/torch_pickle.h"

namespace atex {

using fourdgs_internal::DtypeName;
using fourdgs_internal::DtypeSize;
using fourdgs_internal::IsFloating;
using fourdgs_internal::PyKind;
using fourdgs_internal::PyRef;
using fourdgs_internal::TorchDtype;

const TorchTensor* TorchStateDict::Find(const std::string& name) const {
  for (const TorchTensor& t : tensors) {
    if (t.name == name) return &t;
  }
  return nullptr;
}

namespace {

// Magic number that starts the legacy (pre-zip) torch.save stream:
// PROTO 2, LONG1 of 10 bytes 0x1950a86a20f9469cfc6c.
constexpr uint8_t kLegacyMagic[] = {0x80, 0x02, 0x8a, 0x0a, 0x6c, 0xfc, 0x9c, 0x46, 0xf9, 0x20, 0x6a, 0xa8, 0x50, 0x19};

float HalfToFloat(uint16_t h) {
  const uint32_t sign = static_cast<uint32_t>(h & 0x8000) << 16;
  const uint32_t exponent = (h >> 10) & 0x1f;
  const uint32_t mantissa = h & 0x3ff;
  if (exponent == 0) {  // zero or subnormal: mantissa * 2^-24
    const float magnitude = std::ldexp(static_cast<float>(mantissa), -24);
    return sign ? -magnitude : magnitude;
  }
  if (exponent == 31) return std::bit_cast<float>(sign | 0x7f800000u | (mantissa << 13));
  return std::bit_cast<float>(sign | ((exponent + 112) << 23) | (mantissa << 13));
}

// Element i of a raw storage as float (floating dtypes only).
float LoadElement(const uint8_t* p, TorchDtype dtype, bool big_endian) {
  uint8_t bytes[8];
  const int n = DtypeSize(dtype);
  for (int k = 0; k < n; ++k) bytes[k] = big_endian ? p[n - 1 - k] : p[k];
  switch (dtype) {
    case TorchDtype::kFloat32: {
      uint32_t u;
      std::memcpy(&u, bytes, 4);
      return std::bit_cast<float>(u);
    }
    case TorchDtype::kFloat64: {
      uint64_t u;
      std::memcpy(&u, bytes, 8);
      return static_cast<float>(std::bit_cast<double>(u));
    }
    case TorchDtype::kFloat16: {
      uint16_t u;
      std::memcpy(&u, bytes, 2);
      return HalfToFloat(u);
    }
    default: {  // bfloat16: the high half of a float32
      uint16_t u;
      std::memcpy(&u, bytes, 2);
      return std::bit_cast<float>(static_cast<uint32_t>(u) << 16);
    }
  }
}

struct StorageBytes {
  const uint8_t* data = nullptr;
  size_t size = 0;
  std::vector<uint8_t> owned;  // when the member was compressed
};

class StateDictReader {
 public:
  StateDictReader(const ZipArchive& zip, const std::string& what, const TorchReadLimits& limits)
      : zip_(zip), what_(what), limits_(limits) {}

  StatusOr<TorchStateDict> Read() {
    ATEX_RETURN_IF_ERROR(FindPrefix());
    ATEX_RETURN_IF_ERROR(ReadByteOrder());
    const ZipEntry* pickle_entry = zip_.Find(prefix_ + "data.pkl");
    if (pickle_entry->uncompressed_size > limits_.max_pickle_bytes) {
      return MakeError(StatusCode::kLimitExceeded, what_, ": ", prefix_, "data.pkl is ",
                       pickle_entry->uncompressed_size, " bytes, limit ", limits_.max_pickle_bytes);
    }
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> pickle, zip_.Extract(*pickle_entry));
    ATEX_ASSIGN_OR_RETURN(PyRef root, fourdgs_internal::Unpickle(pickle.data(), pickle.size(),
                                                                 what_ + ": " + prefix_ + "data.pkl"));
    if (root->kind != PyKind::kDict) {
      return MakeError(StatusCode::kUnsupported, what_, ": the pickled object is not a dict (a state_dict)");
    }
    if (root->entries.size() > limits_.max_tensors) {
      return MakeError(StatusCode::kLimitExceeded, what_, ": ", root->entries.size(), " entries, limit ",
                       limits_.max_tensors);
    }
    TorchStateDict state;
    for (const auto& [key, value] : root->entries) {
      if (key->kind != PyKind::kString) {
        return MakeError(StatusCode::kUnsupported, what_, ": a state_dict key that is not a string");
      }
      if (value->kind != PyKind::kTensor) {
        return MakeError(StatusCode::kUnsupported, what_, ": state_dict entry '", key->text, "' is not a tensor");
      }
      if (state.Find(key->text) != nullptr) {
        return MakeError(StatusCode::kCorrupt, what_, ": duplicate state_dict key '", key->text, "'");
      }
      ATEX_ASSIGN_OR_RETURN(TorchTensor tensor, Materialise(key->text, *value));
      state.tensors.push_back(std::move(tensor));
    }
    return state;
  }

 private:
  // The archive's record prefix: "<name>/" of the single "<name>/data.pkl".
  Status FindPrefix() {
    int found = 0;
    for (const ZipEntry& e : zip_.entries()) {
      const std::string& n = e.name;
      const size_t slash = n.find('/');
      const bool top_level = n == "data.pkl";
      const bool nested = slash != std::string::npos && n.find('/', slash + 1) == std::string::npos &&
                          n.compare(slash + 1, std::string::npos, "data.pkl") == 0;
      if (top_level || nested) {
        prefix_ = top_level ? "" : n.substr(0, slash + 1);
        ++found;
      }
    }
    if (found != 1) {
      return MakeError(StatusCode::kCorrupt, what_, ": expected one '<name>/data.pkl' record, found ", found,
                       " (not a torch.save archive)");
    }
    return Status::Ok();
  }

  Status ReadByteOrder() {
    const ZipEntry* entry = zip_.Find(prefix_ + "byteorder");
    if (entry == nullptr) return Status::Ok();  // written since torch 1.12; older files are little-endian
    if (entry->uncompressed_size > 16) {
      return MakeError(StatusCode::kCorrupt, what_, ": byteorder record of ", entry->uncompressed_size, " bytes");
    }
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, zip_.Extract(*entry));
    const std::string order(bytes.begin(), bytes.end());
    if (order == "big") {
      big_endian_ = true;
    } else if (order != "little") {
      return MakeError(StatusCode::kCorrupt, what_, ": byteorder '", order, "' is neither 'little' nor 'big'");
    }
    return Status::Ok();
  }

  StatusOr<const StorageBytes*> Storage(const fourdgs_internal::PyObject& storage, const std::string& key_name) {
    auto it = storages_.find(storage.text);
    if (it != storages_.end()) return &it->second;
    const std::string record = prefix_ + "data/" + storage.text;
    const ZipEntry* entry = zip_.Find(record);
    if (entry == nullptr) {
      return MakeError(StatusCode::kCorrupt, what_, ": tensor '", key_name, "' refers to storage '", storage.text,
                       "' but the archive has no record ", record);
    }
    const uint64_t elem = static_cast<uint64_t>(DtypeSize(storage.dtype));
    if (static_cast<uint64_t>(storage.numel) > std::numeric_limits<uint64_t>::max() / elem ||
        entry->uncompressed_size != static_cast<uint64_t>(storage.numel) * elem) {
      return MakeError(StatusCode::kCorrupt, what_, ": storage '", storage.text, "' (", DtypeName(storage.dtype),
                       ") announces ", storage.numel, " elements but ", record, " holds ", entry->uncompressed_size,
                       " bytes");
    }
    StorageBytes bytes;
    if (entry->method == 0) {
      ATEX_ASSIGN_OR_RETURN(ZipArchive::View view, zip_.StoredView(*entry));
      bytes.data = view.data;
      bytes.size = view.size;
    } else {
      ATEX_ASSIGN_OR_RETURN(bytes.owned, zip_.Extract(*entry));
      bytes.data = bytes.owned.data();
      bytes.size = bytes.owned.size();
    }
    storage_elements_ += static_cast<uint64_t>(storage.numel);
    auto inserted = storages_.emplace(storage.text, std::move(bytes));
    // The owned vector moved into the map; re-point data at its new home.
    StorageBytes& stored = inserted.first->second;
    if (!stored.owned.empty()) stored.data = stored.owned.data();
    return &stored;
  }

  StatusOr<TorchTensor> Materialise(const std::string& name, const fourdgs_internal::PyObject& t) {
    const fourdgs_internal::PyObject& storage = *t.storage;
    TorchTensor out;
    out.name = name;
    out.dtype = DtypeName(storage.dtype);
    out.shape = t.shape;
    out.floating = IsFloating(storage.dtype);
    auto where = [&] { return StrCat(what_, ": tensor '", name, "'"); };

    // Element count and the furthest element, with overflow checks.
    if (t.storage_offset < 0) {
      return MakeError(StatusCode::kCorrupt, where(), ": negative storage offset ", t.storage_offset);
    }
    uint64_t count = 1;
    uint64_t last = static_cast<uint64_t>(t.storage_offset);
    constexpr uint64_t kHuge = uint64_t{1} << 62;
    for (size_t d = 0; d < t.shape.size(); ++d) {
      if (t.shape[d] < 0 || t.stride[d] < 0) {
        return MakeError(StatusCode::kCorrupt, where(), ": size ", t.shape[d], " / stride ", t.stride[d],
                         " of dimension ", d, " is negative");
      }
      const uint64_t size = static_cast<uint64_t>(t.shape[d]);
      if (size != 0 && count > kHuge / size) {
        return MakeError(StatusCode::kLimitExceeded, where(), ": element count overflows");
      }
      count *= size;
    }
    if (count > 0) {
      for (size_t d = 0; d < t.shape.size(); ++d) {
        const uint64_t extent = static_cast<uint64_t>(t.shape[d] - 1);
        const uint64_t stride = static_cast<uint64_t>(t.stride[d]);
        if (stride != 0 && extent > (kHuge - last) / stride) {
          return MakeError(StatusCode::kLimitExceeded, where(), ": stride ", stride, " of dimension ", d,
                           " overflows");
        }
        last += extent * stride;
      }
      if (last >= static_cast<uint64_t>(storage.numel)) {
        return MakeError(StatusCode::kCorrupt, where(), " of shape ", ShapeString(t.shape), ", offset ",
                         t.storage_offset, " reaches element ", last, " of a storage of ", storage.numel);
      }
    }
    if (count > static_cast<uint64_t>(storage.numel)) {
      return MakeError(StatusCode::kUnsupported, where(), " has ", count, " elements, more than its storage (",
                       storage.numel, "): expanded views are not supported");
    }
    ATEX_ASSIGN_OR_RETURN(const StorageBytes* bytes, Storage(storage, name));
    if (!out.floating) return out;
    if (materialised_ + count > limits_.max_elements || materialised_ + count > 2 * storage_elements_ + (1u << 20)) {
      return MakeError(StatusCode::kLimitExceeded, where(), ": materialising ", count,
                       " more values exceeds the limit (views of shared storages?)");
    }
    materialised_ += count;
    out.values.resize(count);
    // Row-major walk over the index space.
    const size_t dims = t.shape.size();
    std::vector<int64_t> index(dims, 0);
    const int elem = DtypeSize(storage.dtype);
    for (uint64_t i = 0; i < count; ++i) {
      uint64_t offset = static_cast<uint64_t>(t.storage_offset);
      for (size_t d = 0; d < dims; ++d) offset += static_cast<uint64_t>(index[d]) * static_cast<uint64_t>(t.stride[d]);
      out.values[i] = LoadElement(bytes->data + offset * elem, storage.dtype, big_endian_);
      for (size_t d = dims; d-- > 0;) {
        if (++index[d] < t.shape[d]) break;
        index[d] = 0;
      }
    }
    return out;
  }

  static std::string ShapeString(const std::vector<int64_t>& shape) {
    std::string s = "[";
    for (size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
    return s + "]";
  }

  const ZipArchive& zip_;
  std::string what_;
  TorchReadLimits limits_;
  std::string prefix_;
  bool big_endian_ = false;
  std::unordered_map<std::string, StorageBytes> storages_;
  uint64_t storage_elements_ = 0;
  uint64_t materialised_ = 0;
};

}  // namespace

StatusOr<TorchStateDict> ReadTorchStateDict(const uint8_t* data, size_t size, const std::string& what,
                                            const TorchReadLimits& limits) {
  if (size >= sizeof(kLegacyMagic) && std::memcmp(data, kLegacyMagic, sizeof(kLegacyMagic)) == 0) {
    return MakeError(StatusCode::kUnsupported, what,
                     ": legacy (pre-1.6, non-zip) torch.save format; re-save it with a current PyTorch");
  }
  ATEX_ASSIGN_OR_RETURN(ZipArchive zip, ZipArchive::FromView(data, size, what));
  StateDictReader reader(zip, what, limits);
  return reader.Read();
}

}  // namespace atex
