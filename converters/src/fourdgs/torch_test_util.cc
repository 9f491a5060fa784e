#include "fourdgs/torch_test_util.h"

#include <bit>
#include <cstring>

#include "atex/zip.h"

namespace atex::fourdgs_testing {

PickleBuilder& PickleBuilder::Op(uint8_t op) {
  bytes_.push_back(op);
  return *this;
}

PickleBuilder& PickleBuilder::Raw(const std::vector<uint8_t>& bytes) {
  bytes_.insert(bytes_.end(), bytes.begin(), bytes.end());
  return *this;
}

PickleBuilder& PickleBuilder::Proto(int version) {
  Op(0x80);
  return Op(static_cast<uint8_t>(version));
}

PickleBuilder& PickleBuilder::Tuple(int n) {
  if (n == 0) return EmptyTuple();
  return Op(static_cast<uint8_t>(0x85 + n - 1));
}

static void PutLE(std::vector<uint8_t>& out, uint64_t v, int n) {
  for (int i = 0; i < n; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

PickleBuilder& PickleBuilder::Str(const std::string& s) {
  Op('X');
  PutLE(bytes_, s.size(), 4);
  bytes_.insert(bytes_.end(), s.begin(), s.end());
  return *this;
}

PickleBuilder& PickleBuilder::ShortStr(const std::string& s) {
  Op(0x8c);
  PutLE(bytes_, s.size(), 1);
  bytes_.insert(bytes_.end(), s.begin(), s.end());
  return *this;
}

PickleBuilder& PickleBuilder::Int(int64_t v) {
  if (v >= 0 && v < 256) {
    Op('K');
    PutLE(bytes_, v, 1);
  } else if (v >= 0 && v < 65536) {
    Op('M');
    PutLE(bytes_, v, 2);
  } else if (v >= INT32_MIN && v <= INT32_MAX) {
    Op('J');
    PutLE(bytes_, static_cast<uint32_t>(v), 4);
  } else {
    // LONG1: minimal two's complement little-endian.
    std::vector<uint8_t> digits;
    int64_t x = v;
    while (true) {
      digits.push_back(static_cast<uint8_t>(x & 0xff));
      const int64_t next = x >> 8;
      const bool sign = digits.back() & 0x80;
      if ((next == 0 && !sign) || (next == -1 && sign)) break;
      x = next;
    }
    Op(0x8a);
    PutLE(bytes_, digits.size(), 1);
    bytes_.insert(bytes_.end(), digits.begin(), digits.end());
  }
  return *this;
}

PickleBuilder& PickleBuilder::Global(const std::string& module, const std::string& name) {
  Op('c');
  bytes_.insert(bytes_.end(), module.begin(), module.end());
  bytes_.push_back('\n');
  bytes_.insert(bytes_.end(), name.begin(), name.end());
  bytes_.push_back('\n');
  return *this;
}

PickleBuilder& PickleBuilder::Put(uint32_t index) {
  if (index < 256) {
    Op('q');
    PutLE(bytes_, index, 1);
  } else {
    Op('r');
    PutLE(bytes_, index, 4);
  }
  return *this;
}

PickleBuilder& PickleBuilder::Get(uint32_t index) {
  if (index < 256) {
    Op('h');
    PutLE(bytes_, index, 1);
  } else {
    Op('j');
    PutLE(bytes_, index, 4);
  }
  return *this;
}

PickleBuilder& PickleBuilder::IntTuple(const std::vector<int64_t>& v) {
  if (v.size() <= 3) {
    for (int64_t x : v) Int(x);
    return Tuple(static_cast<int>(v.size()));
  }
  Mark();
  for (int64_t x : v) Int(x);
  return TupleFromMark();
}

PickleBuilder& PickleBuilder::Tensor(const std::string& key, const std::string& storage_type, int64_t numel,
                                     int64_t offset, const std::vector<int64_t>& shape,
                                     const std::vector<int64_t>& stride) {
  Global("torch._utils", "_rebuild_tensor_v2");
  Mark();
  Mark().Str("storage").Global("torch", storage_type).Str(key).Str("cpu").Int(numel).TupleFromMark().PersId();
  Int(offset);
  IntTuple(shape);
  IntTuple(stride);
  Bool(false);
  Global("collections", "OrderedDict").EmptyTuple().Reduce();
  TupleFromMark();
  return Reduce();
}

std::vector<uint8_t> StateDictPickle(const std::vector<TensorSpec>& tensors) {
  PickleBuilder p;
  p.Proto(2).Global("collections", "OrderedDict").EmptyTuple().Reduce().Put(0);
  p.Mark();
  for (size_t i = 0; i < tensors.size(); ++i) {
    const TensorSpec& t = tensors[i];
    std::vector<int64_t> stride(t.shape.size(), 1);
    for (size_t d = t.shape.size(); d-- > 1;) stride[d - 1] = stride[d] * t.shape[d];
    p.Str(t.name);
    p.Tensor(std::to_string(i), "FloatStorage", static_cast<int64_t>(t.values.size()), 0, t.shape, stride);
  }
  p.SetItems();
  // state: {'_metadata': OrderedDict({'': {'version': 1}})}
  p.EmptyDict().Str("_metadata").Global("collections", "OrderedDict").EmptyTuple().Reduce();
  p.Str("").EmptyDict().Str("version").Int(1).SetItem().SetItem();
  p.SetItem().Build().Stop();
  return p.bytes();
}

std::vector<uint8_t> FloatBytes(const std::vector<float>& values) {
  std::vector<uint8_t> out;
  out.reserve(values.size() * 4);
  for (float v : values) PutLE(out, std::bit_cast<uint32_t>(v), 4);
  return out;
}

std::vector<uint8_t> StateDictArchive(const std::vector<TensorSpec>& tensors, const std::string& prefix,
                                      bool deflate_pickle) {
  ZipWriter zip;
  const std::vector<uint8_t> pickle = StateDictPickle(tensors);
  (void)zip.Add(prefix + "data.pkl", pickle.data(), pickle.size(), deflate_pickle);
  const std::string order = "little";
  (void)zip.Add(prefix + "byteorder", reinterpret_cast<const uint8_t*>(order.data()), order.size(), false);
  for (size_t i = 0; i < tensors.size(); ++i) {
    const std::vector<uint8_t> raw = FloatBytes(tensors[i].values);
    (void)zip.Add(prefix + "data/" + std::to_string(i), raw.data(), raw.size(), false);
  }
  const std::string version = "3\n";
  (void)zip.Add(prefix + "version", reinterpret_cast<const uint8_t*>(version.data()), version.size(), false);
  return zip.Finish();
}

}  // namespace atex::fourdgs_testing
