// Reading 3DGS PLY files (binary LE/BE and ASCII) into Gaussians.
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <string_view>

#include "atex/converters/ply.h"
#include "atex/file_io.h"
#include "convert/bytes.h"
#include "ply/ply_compressed.h"
#include "ply/ply_header.h"

namespace atex {

namespace {

using converters::ply::Element;
using converters::ply::Encoding;
using converters::ply::Header;
using converters::ply::Property;
using converters::ply::ScalarSize;
using converters::ply::ScalarType;

// Where a vertex property goes in the Gaussians.
enum class Field : uint8_t { kIgnored, kPosition, kRotation, kLogScale, kOpacity, kSh };

struct Slot {
  Field field = Field::kIgnored;
  uint32_t component = 0;  // index inside the per-Gaussian row of that array
};

// The vertex properties resolved to slots, and the SH degree they imply.
struct VertexLayout {
  std::vector<Slot> slots;  // [properties of the vertex element]
  int sh_degree = 0;
};

bool ParseIndexedName(std::string_view name, std::string_view prefix, uint32_t* index) {
  if (name.size() <= prefix.size() || name.substr(0, prefix.size()) != prefix) return false;
  const char* first = name.data() + prefix.size();
  const char* last = name.data() + name.size();
  auto [ptr, ec] = std::from_chars(first, last, *index);
  return ec == std::errc() && ptr == last && (last - first == 1 || *first != '0');  // no leading zeros
}

StatusOr<VertexLayout> ResolveVertexLayout(const Element& vertex) {
  VertexLayout layout;
  layout.slots.resize(vertex.properties.size());
  // Which required properties were seen: x y z, f_dc 0..2, opacity, scale 0..2, rot 0..3.
  bool pos[3] = {}, dc[3] = {}, scale[3] = {}, rot[4] = {}, opacity = false;
  std::vector<int> rest_property;  // f_rest index -> property index
  for (size_t p = 0; p < vertex.properties.size(); ++p) {
    const Property& prop = vertex.properties[p];
    Slot slot;
    uint32_t index = 0;
    const std::string& name = prop.name;
    if (name == "x" || name == "y" || name == "z") {
      index = static_cast<uint32_t>(name[0] - 'x');
      slot = {Field::kPosition, index};
      pos[index] = true;
    } else if (name == "opacity") {
      slot = {Field::kOpacity, 0};
      opacity = true;
    } else if (ParseIndexedName(name, "scale_", &index) && index < 3) {
      slot = {Field::kLogScale, index};
      scale[index] = true;
    } else if (ParseIndexedName(name, "rot_", &index) && index < 4) {
      slot = {Field::kRotation, index};  // rot_0 = w, our order is (w, x, y, z) too
      rot[index] = true;
    } else if (ParseIndexedName(name, "f_dc_", &index) && index < 3) {
      slot = {Field::kSh, index};  // coefficient 0, channel index
      dc[index] = true;
    } else if (ParseIndexedName(name, "f_rest_", &index)) {
      if (index >= 45) {
        return MakeError(StatusCode::kCorrupt, "PLY vertex property '", name, "': SH above degree 3 (f_rest_0..44)");
      }
      if (rest_property.size() <= index) rest_property.resize(index + 1, -1);
      rest_property[index] = static_cast<int>(p);
      slot = {Field::kSh, 0};  // component fixed below, once the degree is known
    }
    if (slot.field != Field::kIgnored && prop.is_list) {
      return MakeError(StatusCode::kCorrupt, "PLY vertex property '", name, "' is a list, expected a scalar");
    }
    layout.slots[p] = slot;
  }
  auto require = [](bool seen, const char* name) -> Status {
    if (seen) return Status::Ok();
    return MakeError(StatusCode::kCorrupt, "PLY vertex element lacks the property '", name,
                     "' (not a 3D Gaussian splatting file?)");
  };
  static const char* kPos[] = {"x", "y", "z"};
  static const char* kDc[] = {"f_dc_0", "f_dc_1", "f_dc_2"};
  static const char* kScale[] = {"scale_0", "scale_1", "scale_2"};
  static const char* kRot[] = {"rot_0", "rot_1", "rot_2", "rot_3"};
  for (int k = 0; k < 3; ++k) ATEX_RETURN_IF_ERROR(require(pos[k], kPos[k]));
  for (int k = 0; k < 3; ++k) ATEX_RETURN_IF_ERROR(require(dc[k], kDc[k]));
  ATEX_RETURN_IF_ERROR(require(opacity, "opacity"));
  for (int k = 0; k < 3; ++k) ATEX_RETURN_IF_ERROR(require(scale[k], kScale[k]));
  for (int k = 0; k < 4; ++k) ATEX_RETURN_IF_ERROR(require(rot[k], kRot[k]));

  const size_t rest = rest_property.size();
  for (size_t j = 0; j < rest; ++j) {
    if (rest_property[j] < 0) {
      return MakeError(StatusCode::kCorrupt, "PLY vertex element has f_rest_", rest - 1, " but lacks f_rest_", j);
    }
  }
  if (rest != 0 && rest != 9 && rest != 24 && rest != 45) {
    return MakeError(StatusCode::kCorrupt, "PLY vertex element has ", rest,
                     " f_rest properties; a degree 1/2/3 SH needs 9/24/45");
  }
  layout.sh_degree = rest == 0 ? 0 : rest == 9 ? 1 : rest == 24 ? 2 : 3;
  const uint32_t k_count = static_cast<uint32_t>(ShCoeffCount(layout.sh_degree));
  // Component inside sh[i] ([K][3]): DC is coefficient 0; f_rest is channel-major in the file.
  for (size_t p = 0; p < layout.slots.size(); ++p) {
    Slot& slot = layout.slots[p];
    if (slot.field != Field::kSh) continue;
    const std::string& name = vertex.properties[p].name;
    uint32_t index = 0;
    if (ParseIndexedName(name, "f_dc_", &index)) {
      slot.component = index;  // coefficient 0, channel `index`
    } else if (ParseIndexedName(name, "f_rest_", &index)) {
      const uint32_t per_channel = k_count - 1;
      const uint32_t channel = index / per_channel;
      const uint32_t coeff = 1 + index % per_channel;
      slot.component = coeff * 3 + channel;
    }
  }
  return layout;
}

// Pointers to the per-Gaussian rows of every array of `g` for Gaussian i.
struct RowPointers {
  float* fields[6] = {};  // indexed by Field
};

RowPointers RowsOf(Gaussians& g, size_t i) {
  RowPointers rows;
  rows.fields[static_cast<int>(Field::kPosition)] = g.positions.data() + i * 3;
  rows.fields[static_cast<int>(Field::kRotation)] = g.rotations.data() + i * 4;
  rows.fields[static_cast<int>(Field::kLogScale)] = g.log_scales.data() + i * 3;
  rows.fields[static_cast<int>(Field::kOpacity)] = g.opacity_logits.data() + i;
  rows.fields[static_cast<int>(Field::kSh)] = g.sh.data() + i * static_cast<size_t>(g.sh_coeffs()) * 3;
  return rows;
}

Status NonFinite(size_t vertex, const std::string& property, double value) {
  return MakeError(StatusCode::kOutOfRange, "PLY vertex ", vertex, ": property '", property, "' is not finite (",
                   value, ")");
}

// ---------------------------------------------------------------------------
// Binary

template <bool kBigEndian>
double LoadScalar(const uint8_t* p, ScalarType type) {
  using converters::bytes::LoadBE;
  using converters::bytes::LoadLE;
  auto load = [p](auto tag) {
    using T = decltype(tag);
    if constexpr (kBigEndian) {
      return LoadBE<T>(p);
    } else {
      return LoadLE<T>(p);
    }
  };
  switch (type) {
    case ScalarType::kInt8: return load(int8_t{});
    case ScalarType::kUint8: return load(uint8_t{});
    case ScalarType::kInt16: return load(int16_t{});
    case ScalarType::kUint16: return load(uint16_t{});
    case ScalarType::kInt32: return load(int32_t{});
    case ScalarType::kUint32: return load(uint32_t{});
    case ScalarType::kFloat32: return load(float{});
    case ScalarType::kFloat64: return load(double{});
  }
  return 0.0;
}

// Reads the list count at p; fails if it is negative or not an integer.
template <bool kBigEndian>
bool LoadListCount(const uint8_t* p, ScalarType type, uint64_t* count) {
  const double value = LoadScalar<kBigEndian>(p, type);
  if (!(value >= 0)) return false;
  *count = static_cast<uint64_t>(value);
  return true;
}

// Advances `*pos` over one row of `element` (which has list properties).
template <bool kBigEndian>
Status SkipBinaryRow(const uint8_t* data, size_t size, const Element& element, uint64_t row, size_t* pos) {
  for (const auto& prop : element.properties) {
    if (!prop.is_list) {
      const size_t n = ScalarSize(prop.type);
      if (size - *pos < n) {
        return MakeError(StatusCode::kTruncated, "PLY data ends at byte ", size, " inside element '", element.name,
                         "' row ", row);
      }
      *pos += n;
      continue;
    }
    const size_t count_size = ScalarSize(prop.count_type);
    if (size - *pos < count_size) {
      return MakeError(StatusCode::kTruncated, "PLY data ends at byte ", size, " inside element '", element.name,
                       "' row ", row);
    }
    uint64_t count = 0;
    if (!LoadListCount<kBigEndian>(data + *pos, prop.count_type, &count)) {
      return MakeError(StatusCode::kCorrupt, "PLY element '", element.name, "' row ", row, " at byte ", *pos,
                       ": negative list count");
    }
    *pos += count_size;
    const size_t item = ScalarSize(prop.type);
    if (count > (size - *pos) / item) {
      return MakeError(StatusCode::kTruncated, "PLY element '", element.name, "' row ", row, " at byte ", *pos,
                       ": list of ", count, " items runs past the end of the file (", size, " bytes)");
    }
    *pos += static_cast<size_t>(count) * item;
  }
  return Status::Ok();
}

// Skips a whole element; fixed-size rows are skipped in one step.
template <bool kBigEndian>
Status SkipBinaryElement(const uint8_t* data, size_t size, const Element& element, size_t* pos) {
  const size_t min_row = element.MinRowSize();
  if (min_row == 0) return Status::Ok();  // rows without properties occupy no bytes
  if (element.count > (size - *pos) / min_row) {
    return MakeError(StatusCode::kTruncated, "PLY element '", element.name, "' announces ", element.count,
                     " rows of at least ", min_row, " bytes but only ", size - *pos, " bytes follow byte ", *pos);
  }
  const size_t fixed = element.FixedRowSize();
  if (fixed != 0) {
    *pos += static_cast<size_t>(element.count) * fixed;
    return Status::Ok();
  }
  for (uint64_t row = 0; row < element.count; ++row) {
    ATEX_RETURN_IF_ERROR(SkipBinaryRow<kBigEndian>(data, size, element, row, pos));
  }
  return Status::Ok();
}

template <bool kBigEndian>
Status ReadBinaryVertices(const uint8_t* data, size_t size, const Element& vertex, const VertexLayout& layout,
                          size_t* pos, Gaussians* g) {
  const size_t n = g->size();
  for (size_t i = 0; i < n; ++i) {
    RowPointers rows = RowsOf(*g, i);
    for (size_t p = 0; p < vertex.properties.size(); ++p) {
      const Property& prop = vertex.properties[p];
      if (prop.is_list) {
        ATEX_RETURN_IF_ERROR(SkipBinaryRow<kBigEndian>(data, size, Element{vertex.name, 1, {prop}}, i, pos));
        continue;
      }
      const size_t value_size = ScalarSize(prop.type);
      if (size - *pos < value_size) {
        return MakeError(StatusCode::kTruncated, "PLY data ends at byte ", size, " inside vertex ", i, " (property '",
                         prop.name, "')");
      }
      const Slot& slot = layout.slots[p];
      if (slot.field != Field::kIgnored) {
        const double value = LoadScalar<kBigEndian>(data + *pos, prop.type);
        // float -> double -> float is exact, so float32 files round-trip bit for bit; a
        // double beyond the float range becomes Inf and is refused with the rest.
        const float narrowed = static_cast<float>(value);
        if (!std::isfinite(narrowed)) return NonFinite(i, prop.name, value);
        rows.fields[static_cast<int>(slot.field)][slot.component] = narrowed;
      }
      *pos += value_size;
    }
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------
// ASCII

class Tokenizer {
 public:
  Tokenizer(const uint8_t* data, size_t size, size_t pos)
      : data_(reinterpret_cast<const char*>(data)), size_(size), pos_(pos) {}

  // The next whitespace-separated token, or an empty view at the end.
  std::string_view Next() {
    while (pos_ < size_ && IsSpace(data_[pos_])) ++pos_;
    const size_t start = pos_;
    while (pos_ < size_ && !IsSpace(data_[pos_])) ++pos_;
    return std::string_view(data_ + start, pos_ - start);
  }
  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }

 private:
  static bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
  const char* data_;
  size_t size_;
  size_t pos_;
};

bool ParseAsciiValue(std::string_view token, ScalarType type, double* value) {
  const char* first = token.data();
  const char* last = first + token.size();
  if (first != last && *first == '+') ++first;  // from_chars does not take a leading '+'
  if (type == ScalarType::kFloat32) {
    float f = 0;  // parse directly as float: correctly rounded, no double rounding
    auto [ptr, ec] = std::from_chars(first, last, f);
    *value = f;
    return ec == std::errc() && ptr == last;
  }
  auto [ptr, ec] = std::from_chars(first, last, *value);
  return ec == std::errc() && ptr == last;
}

Status AsciiError(const Tokenizer& tokens, const Element& element, uint64_t row, std::string_view token) {
  if (token.empty()) {
    return MakeError(StatusCode::kTruncated, "PLY ASCII data ends at byte ", tokens.position(), " inside element '",
                     element.name, "' row ", row);
  }
  return MakeError(StatusCode::kCorrupt, "PLY ASCII element '", element.name, "' row ", row, " before byte ",
                   tokens.position(), ": '", std::string(token.substr(0, 40)), "' is not a number");
}

Status SkipAsciiElement(Tokenizer& tokens, const Element& element) {
  if (element.properties.empty()) return Status::Ok();
  // Every row has at least one token of at least one character plus a separator.
  if (element.count > tokens.remaining() / 2 + 1) {
    return MakeError(StatusCode::kTruncated, "PLY element '", element.name, "' announces ", element.count,
                     " rows but only ", tokens.remaining(), " bytes follow");
  }
  for (uint64_t row = 0; row < element.count; ++row) {
    for (const auto& prop : element.properties) {
      std::string_view token = tokens.Next();
      double value = 0;
      if (!ParseAsciiValue(token, prop.is_list ? prop.count_type : prop.type, &value)) {
        return AsciiError(tokens, element, row, token);
      }
      if (!prop.is_list) continue;
      if (!(value >= 0) || value > static_cast<double>(tokens.remaining())) {
        return MakeError(StatusCode::kCorrupt, "PLY ASCII element '", element.name, "' row ", row,
                         ": bad list count ", value);
      }
      for (uint64_t k = 0, count = static_cast<uint64_t>(value); k < count; ++k) {
        token = tokens.Next();
        if (token.empty()) return AsciiError(tokens, element, row, token);
      }
    }
  }
  return Status::Ok();
}

Status ReadAsciiVertices(Tokenizer& tokens, const Element& vertex, const VertexLayout& layout, Gaussians* g) {
  const size_t n = g->size();
  for (size_t i = 0; i < n; ++i) {
    RowPointers rows = RowsOf(*g, i);
    for (size_t p = 0; p < vertex.properties.size(); ++p) {
      const Property& prop = vertex.properties[p];
      std::string_view token = tokens.Next();
      double value = 0;
      if (!ParseAsciiValue(token, prop.is_list ? prop.count_type : prop.type, &value)) {
        return AsciiError(tokens, vertex, i, token);
      }
      if (prop.is_list) {
        if (!(value >= 0) || value > static_cast<double>(tokens.remaining())) {
          return MakeError(StatusCode::kCorrupt, "PLY ASCII vertex ", i, ": bad list count ", value);
        }
        for (uint64_t k = 0, count = static_cast<uint64_t>(value); k < count; ++k) {
          if (tokens.Next().empty()) return AsciiError(tokens, vertex, i, {});
        }
        continue;
      }
      const Slot& slot = layout.slots[p];
      if (slot.field == Field::kIgnored) continue;
      const float narrowed = static_cast<float>(value);  // a double beyond the float range becomes Inf
      if (!std::isfinite(narrowed)) return NonFinite(i, prop.name, value);
      rows.fields[static_cast<int>(slot.field)][slot.component] = narrowed;
    }
  }
  return Status::Ok();
}

}  // namespace

StatusOr<Gaussians> ReadPlyGaussiansFromMemory(const uint8_t* data, size_t size) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "PLY: null data");
  ATEX_ASSIGN_OR_RETURN(Header header, converters::ply::ParseHeader(data, size));
  size_t vertex_index = header.elements.size();
  for (size_t e = 0; e < header.elements.size(); ++e) {
    if (header.elements[e].name == "vertex") {
      vertex_index = e;
      break;
    }
  }
  if (vertex_index == header.elements.size()) {
    return MakeError(StatusCode::kCorrupt, "PLY header has no 'vertex' element");
  }
  const Element& vertex = header.elements[vertex_index];
  // PlayCanvas compressed PLY: chunked quantised layout instead of x, y, z, ...
  if (converters::ply::IsCompressedPly(header)) return converters::ply::ReadCompressedPly(data, size, header);
  ATEX_ASSIGN_OR_RETURN(VertexLayout layout, ResolveVertexLayout(vertex));

  size_t pos = header.data_offset;
  const bool ascii = header.encoding == Encoding::kAscii;
  const bool big = header.encoding == Encoding::kBinaryBigEndian;
  Tokenizer tokens(data, size, pos);
  // Elements before the vertex element must be stepped over.
  for (size_t e = 0; e < vertex_index; ++e) {
    if (ascii) {
      ATEX_RETURN_IF_ERROR(SkipAsciiElement(tokens, header.elements[e]));
    } else if (big) {
      ATEX_RETURN_IF_ERROR(SkipBinaryElement<true>(data, size, header.elements[e], &pos));
    } else {
      ATEX_RETURN_IF_ERROR(SkipBinaryElement<false>(data, size, header.elements[e], &pos));
    }
  }

  // Compare the announced count with the bytes present before allocating anything.
  const size_t remaining = ascii ? tokens.remaining() : size - pos;
  const uint64_t min_row = ascii ? 2 * vertex.properties.size() : vertex.MinRowSize();
  if (vertex.count > 0 && vertex.count > (remaining + (ascii ? 1 : 0)) / min_row) {
    return MakeError(StatusCode::kTruncated, "PLY vertex element announces ", vertex.count, " vertices of at least ",
                     min_row, " bytes but only ", remaining, " bytes of data follow the header");
  }
  Gaussians g;
  g.sh_degree = layout.sh_degree;
  g.Resize(static_cast<size_t>(vertex.count));
  if (ascii) {
    ATEX_RETURN_IF_ERROR(ReadAsciiVertices(tokens, vertex, layout, &g));
  } else if (big) {
    ATEX_RETURN_IF_ERROR(ReadBinaryVertices<true>(data, size, vertex, layout, &pos, &g));
  } else {
    ATEX_RETURN_IF_ERROR(ReadBinaryVertices<false>(data, size, vertex, layout, &pos, &g));
  }
  return g;
}

StatusOr<Gaussians> ReadPlyGaussians(const std::string& path) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  auto result = ReadPlyGaussiansFromMemory(bytes.data(), bytes.size());
  if (!result.ok()) return result.status().WithContext(path);
  return result;
}

}  // namespace atex
