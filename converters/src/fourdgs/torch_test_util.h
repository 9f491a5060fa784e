// Test helpers: hand-assembled protocol-2 pickles and torch.save-style zip
// archives, built opcode by opcode the way CPython's pickler writes a
// state_dict (so the tests do not need Python).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace atex::fourdgs_testing {

class PickleBuilder {
 public:
  PickleBuilder& Op(uint8_t op);
  PickleBuilder& Raw(const std::vector<uint8_t>& bytes);
  PickleBuilder& Proto(int version = 2);
  PickleBuilder& Mark() { return Op('('); }
  PickleBuilder& Stop() { return Op('.'); }
  PickleBuilder& None() { return Op('N'); }
  PickleBuilder& Bool(bool v) { return Op(v ? 0x88 : 0x89); }
  PickleBuilder& EmptyDict() { return Op('}'); }
  PickleBuilder& EmptyTuple() { return Op(')'); }
  PickleBuilder& EmptyList() { return Op(']'); }
  PickleBuilder& Reduce() { return Op('R'); }
  PickleBuilder& Build() { return Op('b'); }
  PickleBuilder& SetItem() { return Op('s'); }
  PickleBuilder& SetItems() { return Op('u'); }
  PickleBuilder& TupleFromMark() { return Op('t'); }
  PickleBuilder& Tuple(int n);  // TUPLE1..3 (n in 1..3), EMPTY_TUPLE for 0
  PickleBuilder& PersId() { return Op('Q'); }
  PickleBuilder& Str(const std::string& s);       // BINUNICODE
  PickleBuilder& ShortStr(const std::string& s);  // SHORT_BINUNICODE
  PickleBuilder& Int(int64_t v);                  // BININT1 / BININT2 / BININT / LONG1 as CPython picks
  PickleBuilder& Global(const std::string& module, const std::string& name);
  PickleBuilder& Put(uint32_t index);  // BINPUT or LONG_BINPUT
  PickleBuilder& Get(uint32_t index);  // BINGET or LONG_BINGET
  PickleBuilder& IntTuple(const std::vector<int64_t>& v);

  // A whole _rebuild_tensor_v2(...) call for storage `key` of `storage_type`
  // (e.g. "FloatStorage") with `numel` elements.
  PickleBuilder& Tensor(const std::string& key, const std::string& storage_type, int64_t numel, int64_t offset,
                        const std::vector<int64_t>& shape, const std::vector<int64_t>& stride);

  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

struct TensorSpec {
  std::string name;
  std::vector<int64_t> shape;
  std::vector<float> values;  // contiguous, row-major
};

// The data.pkl of torch.save(OrderedDict(tensors)) with float32 storages
// "0", "1", ... and the state_dict's _metadata BUILD.
std::vector<uint8_t> StateDictPickle(const std::vector<TensorSpec>& tensors);

// The whole archive: <prefix>data.pkl, <prefix>data/<k> (little-endian
// float32), <prefix>byteorder and <prefix>version records.
std::vector<uint8_t> StateDictArchive(const std::vector<TensorSpec>& tensors, const std::string& prefix = "archive/",
                                      bool deflate_pickle = false);

// Raw little-endian bytes of floats.
std::vector<uint8_t> FloatBytes(const std::vector<float>& values);

}  // namespace atex::fourdgs_testing
