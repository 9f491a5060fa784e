// .npy / .npz reading and writing. The header is a Python dict literal such as
// {'descr': '<f4', 'fortran_order': False, 'shape': (81, 100, 100, 3), }
// which is tokenised here (strings, True/False, integer tuples), never evaluated.
#include "atex/npy.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "atex/file_io.h"
#include "data/byte_reader.h"

namespace atex {
namespace {

constexpr char kMagic[] = "\x93NUMPY";
constexpr size_t kMagicSize = 6;
constexpr size_t kMaxHeaderBytes = 1u << 20;  // numpy itself refuses headers above 10 KB by default
constexpr int kMaxDims = 32;                  // numpy's NPY_MAXDIMS

// --- header literal ---------------------------------------------------------
struct HeaderFields {
  std::optional<std::string> descr;
  std::optional<bool> fortran_order;
  std::optional<std::vector<int64_t>> shape;
};

class HeaderParser {
 public:
  HeaderParser(std::string_view text, const std::string& what) : text_(text), what_(what) {}

  Status Parse(HeaderFields& fields) {
    SkipSpace();
    if (!Consume('{')) return Error("expected '{'");
    while (true) {
      SkipSpace();
      if (Consume('}')) break;
      std::string key;
      ATEX_RETURN_IF_ERROR(ParseString(key));
      SkipSpace();
      if (!Consume(':')) return Error("expected ':' after key '" + key + "'");
      SkipSpace();
      if (key == "descr") {
        if (Peek() == '[') {
          return MakeError(StatusCode::kUnsupported, what_, ": structured dtype (a field list) is not supported");
        }
        std::string value;
        ATEX_RETURN_IF_ERROR(ParseString(value));
        fields.descr = value;
      } else if (key == "fortran_order") {
        bool value = false;
        ATEX_RETURN_IF_ERROR(ParseBool(value));
        fields.fortran_order = value;
      } else if (key == "shape") {
        std::vector<int64_t> value;
        ATEX_RETURN_IF_ERROR(ParseShape(value));
        fields.shape = std::move(value);
      } else {
        return Error("unexpected key '" + key + "'");
      }
      SkipSpace();
      if (Consume(',')) continue;
      SkipSpace();
      if (Consume('}')) break;
      return Error("expected ',' or '}'");
    }
    SkipSpace();
    if (pos_ != text_.size()) return Error("trailing characters after the dict");
    return Status::Ok();
  }

 private:
  char Peek() const { return pos_ < text_.size() ? text_[pos_] : '\0'; }
  bool Consume(char c) {
    if (Peek() != c) return false;
    ++pos_;
    return true;
  }
  void SkipSpace() {
    while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\n' || text_[pos_] == '\t' ||
                                   text_[pos_] == '\r')) {
      ++pos_;
    }
  }
  Status Error(const std::string& message) const {
    return MakeError(StatusCode::kCorrupt, what_, ": npy header, character ", pos_, ": ", message);
  }
  Status ParseString(std::string& out) {
    const char quote = Peek();
    if (quote != '\'' && quote != '"') return Error("expected a quoted string");
    ++pos_;
    const size_t start = pos_;
    while (pos_ < text_.size() && text_[pos_] != quote) {
      if (text_[pos_] == '\\') return Error("escape sequences are not expected in an npy header");
      ++pos_;
    }
    if (pos_ >= text_.size()) return Error("unterminated string");
    out.assign(text_.substr(start, pos_ - start));
    ++pos_;
    return Status::Ok();
  }
  Status ParseBool(bool& out) {
    if (text_.substr(pos_, 4) == "True") {
      pos_ += 4;
      out = true;
      return Status::Ok();
    }
    if (text_.substr(pos_, 5) == "False") {
      pos_ += 5;
      out = false;
      return Status::Ok();
    }
    return Error("expected True or False");
  }
  Status ParseShape(std::vector<int64_t>& out) {
    if (!Consume('(')) return Error("expected '(' for the shape tuple");
    while (true) {
      SkipSpace();
      if (Consume(')')) return Status::Ok();
      if (Peek() < '0' || Peek() > '9') return Error("expected a non-negative integer dimension");
      int64_t value = 0;
      while (Peek() >= '0' && Peek() <= '9') {
        const int digit = Peek() - '0';
        if (value > (std::numeric_limits<int64_t>::max() - digit) / 10) return Error("dimension overflows int64");
        value = value * 10 + digit;
        ++pos_;
      }
      Consume('L');  // Python 2 long suffix, written by old numpy versions
      if (out.size() >= kMaxDims) return Error("more than 32 dimensions");
      out.push_back(value);
      SkipSpace();
      if (Consume(',')) continue;
      SkipSpace();
      if (Consume(')')) return Status::Ok();
      return Error("expected ',' or ')' in the shape tuple");
    }
  }

  std::string_view text_;
  const std::string& what_;
  size_t pos_ = 0;
};

struct ParsedDescr {
  NpyDtype dtype;
  bool big_endian;
};

StatusOr<ParsedDescr> ParseDescr(const std::string& descr, const std::string& what) {
  if (descr.size() < 2) return MakeError(StatusCode::kCorrupt, what, ": dtype descr '", descr, "' is too short");
  const char order = descr[0];
  if (order != '<' && order != '>' && order != '|' && order != '=') {
    return MakeError(StatusCode::kCorrupt, what, ": dtype descr '", descr, "' has no byte-order character");
  }
  const std::string code = descr.substr(1);
  static const struct {
    const char* code;
    NpyDtype dtype;
  } kCodes[] = {{"b1", NpyDtype::kBool},    {"i1", NpyDtype::kInt8},    {"u1", NpyDtype::kUint8},
                {"i2", NpyDtype::kInt16},   {"u2", NpyDtype::kUint16},  {"i4", NpyDtype::kInt32},
                {"u4", NpyDtype::kUint32},  {"i8", NpyDtype::kInt64},   {"u8", NpyDtype::kUint64},
                {"f2", NpyDtype::kFloat16}, {"f4", NpyDtype::kFloat32}, {"f8", NpyDtype::kFloat64}};
  for (const auto& entry : kCodes) {
    if (code == entry.code) return ParsedDescr{entry.dtype, order == '>'};
  }
  if (code[0] == 'O') {
    return MakeError(StatusCode::kUnsupported, what, ": dtype '", descr,
                     "' holds pickled Python objects, which are never loaded");
  }
  return MakeError(StatusCode::kUnsupported, what, ": dtype '", descr,
                   "' is not supported (only bool, integer and float16/32/64)");
}

// IEEE 754 binary16 -> double, exact.
double HalfToDouble(uint16_t h) {
  const int sign = (h >> 15) & 1;
  const int exponent = (h >> 10) & 0x1F;
  const int mantissa = h & 0x3FF;
  double value;
  if (exponent == 0) {
    value = std::ldexp(static_cast<double>(mantissa), -24);
  } else if (exponent == 31) {
    value = mantissa ? std::numeric_limits<double>::quiet_NaN() : std::numeric_limits<double>::infinity();
  } else {
    value = std::ldexp(static_cast<double>(mantissa + 1024), exponent - 25);
  }
  return sign ? -value : value;
}

template <typename T>
T LoadAs(const uint8_t* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));  // x86/ARM hosts are little-endian, as the stored data
  return value;
}

}  // namespace

size_t NpyDtypeSize(NpyDtype dtype) {
  switch (dtype) {
    case NpyDtype::kBool:
    case NpyDtype::kInt8:
    case NpyDtype::kUint8: return 1;
    case NpyDtype::kInt16:
    case NpyDtype::kUint16:
    case NpyDtype::kFloat16: return 2;
    case NpyDtype::kInt32:
    case NpyDtype::kUint32:
    case NpyDtype::kFloat32: return 4;
    default: return 8;
  }
}

const char* NpyDtypeDescr(NpyDtype dtype) {
  switch (dtype) {
    case NpyDtype::kBool: return "|b1";
    case NpyDtype::kInt8: return "|i1";
    case NpyDtype::kUint8: return "|u1";
    case NpyDtype::kInt16: return "<i2";
    case NpyDtype::kUint16: return "<u2";
    case NpyDtype::kInt32: return "<i4";
    case NpyDtype::kUint32: return "<u4";
    case NpyDtype::kInt64: return "<i8";
    case NpyDtype::kUint64: return "<u8";
    case NpyDtype::kFloat16: return "<f2";
    case NpyDtype::kFloat32: return "<f4";
    case NpyDtype::kFloat64: return "<f8";
  }
  return "?";
}

uint64_t NpyArray::element_count() const {
  uint64_t count = 1;
  for (int64_t d : shape) count *= static_cast<uint64_t>(d);
  return count;
}

std::vector<double> NpyArray::ToDouble() const {
  const size_t esize = NpyDtypeSize(dtype);
  const size_t count = data.size() / esize;
  std::vector<double> out(count);
  const uint8_t* p = data.data();
  for (size_t i = 0; i < count; ++i, p += esize) {
    switch (dtype) {
      case NpyDtype::kBool: out[i] = p[0] != 0 ? 1.0 : 0.0; break;
      case NpyDtype::kInt8: out[i] = static_cast<int8_t>(p[0]); break;
      case NpyDtype::kUint8: out[i] = p[0]; break;
      case NpyDtype::kInt16: out[i] = LoadAs<int16_t>(p); break;
      case NpyDtype::kUint16: out[i] = LoadAs<uint16_t>(p); break;
      case NpyDtype::kInt32: out[i] = LoadAs<int32_t>(p); break;
      case NpyDtype::kUint32: out[i] = LoadAs<uint32_t>(p); break;
      case NpyDtype::kInt64: out[i] = static_cast<double>(LoadAs<int64_t>(p)); break;
      case NpyDtype::kUint64: out[i] = static_cast<double>(LoadAs<uint64_t>(p)); break;
      case NpyDtype::kFloat16: out[i] = HalfToDouble(LoadAs<uint16_t>(p)); break;
      case NpyDtype::kFloat32: out[i] = LoadAs<float>(p); break;
      case NpyDtype::kFloat64: out[i] = LoadAs<double>(p); break;
    }
  }
  return out;
}

std::vector<float> NpyArray::ToFloat() const {
  if (dtype == NpyDtype::kFloat32) {
    std::vector<float> out(data.size() / 4);
    if (!out.empty()) std::memcpy(out.data(), data.data(), out.size() * 4);
    return out;
  }
  const std::vector<double> values = ToDouble();
  return std::vector<float>(values.begin(), values.end());
}

StatusOr<double> NpyArray::Scalar(const std::string& what) const {
  if (element_count() != 1) {
    return MakeError(StatusCode::kInvalidArgument, what, ": expected a single value, the array has ",
                     element_count(), " elements");
  }
  return ToDouble()[0];
}

NpyArray NpyArray::FromFloats(std::vector<int64_t> shape, const std::vector<float>& values) {
  NpyArray array;
  array.dtype = NpyDtype::kFloat32;
  array.shape = std::move(shape);
  array.data.resize(values.size() * 4);
  if (!values.empty()) std::memcpy(array.data.data(), values.data(), array.data.size());
  return array;
}

NpyArray NpyArray::FromDoubles(std::vector<int64_t> shape, const std::vector<double>& values) {
  NpyArray array;
  array.dtype = NpyDtype::kFloat64;
  array.shape = std::move(shape);
  array.data.resize(values.size() * 8);
  if (!values.empty()) std::memcpy(array.data.data(), values.data(), array.data.size());
  return array;
}

StatusOr<NpyArray> DecodeNpy(const uint8_t* data, size_t size, const std::string& what) {
  if (size < kMagicSize + 4) {
    return MakeError(StatusCode::kTruncated, what, ": ", size, " bytes is too small for an .npy header");
  }
  if (std::memcmp(data, kMagic, kMagicSize) != 0) {
    return MakeError(StatusCode::kBadMagic, what, ": not an .npy array (no \\x93NUMPY magic at byte 0)");
  }
  const int major = data[6];
  const int minor = data[7];
  size_t header_len = 0;
  size_t header_start = 0;
  if (major == 1) {
    header_len = LoadLE16(data + 8);
    header_start = 10;
  } else if (major == 2 || major == 3) {
    if (size < 12) return MakeError(StatusCode::kTruncated, what, ": .npy v", major, " header length truncated");
    header_len = LoadLE32(data + 8);
    header_start = 12;
  } else {
    return MakeError(StatusCode::kUnsupportedVersion, what, ": .npy format version ", major, ".", minor,
                     " (1.0, 2.0 and 3.0 are supported)");
  }
  if (header_len > kMaxHeaderBytes) {
    return MakeError(StatusCode::kLimitExceeded, what, ": .npy header of ", header_len, " bytes");
  }
  if (header_len > size - header_start) {
    return MakeError(StatusCode::kTruncated, what, ": .npy header of ", header_len, " bytes at byte ", header_start,
                     " runs past the end (", size, " bytes)");
  }
  const std::string_view text(reinterpret_cast<const char*>(data + header_start), header_len);
  HeaderFields fields;
  ATEX_RETURN_IF_ERROR(HeaderParser(text, what).Parse(fields));
  if (!fields.descr || !fields.fortran_order || !fields.shape) {
    return MakeError(StatusCode::kCorrupt, what, ": .npy header lacks ",
                     !fields.descr ? "'descr'" : !fields.fortran_order ? "'fortran_order'" : "'shape'");
  }
  ATEX_ASSIGN_OR_RETURN(const ParsedDescr descr, ParseDescr(*fields.descr, what));
  if (*fields.fortran_order) {
    return MakeError(StatusCode::kUnsupported, what, ": Fortran-order arrays are not supported (save with C order)");
  }

  NpyArray array;
  array.dtype = descr.dtype;
  array.shape = std::move(*fields.shape);
  const size_t esize = NpyDtypeSize(array.dtype);
  const size_t data_start = header_start + header_len;
  const uint64_t present = size - data_start;
  // Element count with overflow checks; a zero dimension makes the array empty.
  uint64_t count = 1;
  bool empty = false;
  for (int64_t d : array.shape) empty |= d == 0;
  if (!empty) {
    for (size_t i = 0; i < array.shape.size(); ++i) {
      const uint64_t d = static_cast<uint64_t>(array.shape[i]);
      if (count > present / esize / d) {
        return MakeError(StatusCode::kTruncated, what, ": shape needs more than the ", present,
                         " data bytes present (dimension ", i, " = ", d, ")");
      }
      count *= d;
    }
  } else {
    count = 0;
  }
  const uint64_t needed = count * esize;
  if (needed > present) {
    return MakeError(StatusCode::kTruncated, what, ": shape needs ", needed, " data bytes, only ", present,
                     " present after the header at byte ", data_start);
  }
  if (needed < present) {
    return MakeError(StatusCode::kCorrupt, what, ": ", present - needed, " unexpected bytes after the ", needed,
                     " data bytes");
  }
  array.data.assign(data + data_start, data + size);
  if (descr.big_endian && esize > 1) {
    for (size_t i = 0; i < array.data.size(); i += esize) {
      std::reverse(array.data.begin() + i, array.data.begin() + i + esize);
    }
  }
  return array;
}

StatusOr<NpyArray> ReadNpyFile(const std::string& path) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  return DecodeNpy(bytes.data(), bytes.size(), path);
}

std::vector<uint8_t> EncodeNpy(const NpyArray& array) {
  std::string header = StrCat("{'descr': '", NpyDtypeDescr(array.dtype), "', 'fortran_order': False, 'shape': (");
  for (size_t i = 0; i < array.shape.size(); ++i) {
    header += StrCat(array.shape[i], array.shape.size() == 1 ? "," : (i + 1 < array.shape.size() ? ", " : ""));
  }
  header += "), }";
  // Pad with spaces and a final newline so that the data starts at a multiple of 64 bytes.
  const bool v2 = header.size() + 1 + 10 > 0xFFFF;
  const size_t prefix = v2 ? 12 : 10;
  const size_t total = (prefix + header.size() + 1 + 63) / 64 * 64;
  header.append(total - prefix - header.size() - 1, ' ');
  header += '\n';
  std::vector<uint8_t> out(prefix);
  std::memcpy(out.data(), kMagic, kMagicSize);
  out[6] = v2 ? 2 : 1;
  out[7] = 0;
  if (v2) {
    StoreLE32(out.data() + 8, static_cast<uint32_t>(header.size()));
  } else {
    StoreLE16(out.data() + 8, static_cast<uint16_t>(header.size()));
  }
  out.insert(out.end(), header.begin(), header.end());
  out.insert(out.end(), array.data.begin(), array.data.end());
  return out;
}

Status WriteNpyFile(const std::string& path, const NpyArray& array) {
  return WriteFileAtomic(path, EncodeNpy(array));
}

StatusOr<std::map<std::string, NpyArray>> DecodeNpz(const uint8_t* data, size_t size, const std::string& what,
                                                    const ZipLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(ZipArchive archive, ZipArchive::FromView(data, size, what, limits));
  std::map<std::string, NpyArray> arrays;
  for (const ZipEntry& entry : archive.entries()) {
    const std::string& name = entry.name;
    if (name.size() < 5 || name.compare(name.size() - 4, 4, ".npy") != 0) {
      return MakeError(StatusCode::kCorrupt, what, ": member '", name, "' is not an .npy array");
    }
    const std::string key = name.substr(0, name.size() - 4);
    if (arrays.count(key)) return MakeError(StatusCode::kCorrupt, what, ": duplicate member '", name, "'");
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, archive.Extract(entry));
    ATEX_ASSIGN_OR_RETURN(NpyArray array, DecodeNpy(bytes.data(), bytes.size(), StrCat(what, ":", name)));
    arrays.emplace(key, std::move(array));
  }
  return arrays;
}

StatusOr<std::map<std::string, NpyArray>> ReadNpzFile(const std::string& path, const ZipLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  return DecodeNpz(bytes.data(), bytes.size(), path, limits);
}

std::vector<uint8_t> EncodeNpz(const std::map<std::string, NpyArray>& arrays, bool compress) {
  ZipWriter writer;
  for (const auto& [name, array] : arrays) {
    const std::vector<uint8_t> bytes = EncodeNpy(array);
    // Names come from the caller's map keys; an empty name is the only refusal and cannot hold a value here.
    (void)writer.Add(name + ".npy", bytes.data(), bytes.size(), compress);
  }
  return writer.Finish();
}

Status WriteNpzFile(const std::string& path, const std::map<std::string, NpyArray>& arrays, bool compress) {
  return WriteFileAtomic(path, EncodeNpz(arrays, compress));
}

}  // namespace atex
