#include "ply/ply_header.h"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <string_view>

namespace atex::converters::ply {

namespace {

std::vector<std::string_view> SplitWords(std::string_view line) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) words.push_back(line.substr(i, j - i));
    i = j;
  }
  return words;
}

bool ParseScalarType(std::string_view name, ScalarType* type) {
  struct Entry {
    const char* name;
    ScalarType type;
  };
  static constexpr Entry kTypes[] = {
      {"char", ScalarType::kInt8},     {"int8", ScalarType::kInt8},       {"uchar", ScalarType::kUint8},
      {"uint8", ScalarType::kUint8},   {"short", ScalarType::kInt16},     {"int16", ScalarType::kInt16},
      {"ushort", ScalarType::kUint16}, {"uint16", ScalarType::kUint16},   {"int", ScalarType::kInt32},
      {"int32", ScalarType::kInt32},   {"uint", ScalarType::kUint32},     {"uint32", ScalarType::kUint32},
      {"float", ScalarType::kFloat32}, {"float32", ScalarType::kFloat32}, {"double", ScalarType::kFloat64},
      {"float64", ScalarType::kFloat64},
  };
  for (const auto& entry : kTypes) {
    if (name == entry.name) {
      *type = entry.type;
      return true;
    }
  }
  return false;
}

Status HeaderError(size_t line_number, std::string_view line, std::string_view why) {
  std::string shown(line.substr(0, 80));
  return MakeError(StatusCode::kCorrupt, "PLY header line ", line_number, " ('", shown, "'): ", why);
}

}  // namespace

size_t ScalarSize(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

size_t Element::FixedRowSize() const {
  size_t size = 0;
  for (const auto& p : properties) {
    if (p.is_list) return 0;
    size += ScalarSize(p.type);
  }
  return size;
}

size_t Element::MinRowSize() const {
  size_t size = 0;
  for (const auto& p : properties) size += p.is_list ? ScalarSize(p.count_type) : ScalarSize(p.type);
  return size;
}

StatusOr<Header> ParseHeader(const uint8_t* data, size_t size) {
  if (size < 4 || std::memcmp(data, "ply", 3) != 0 || (data[3] != '\n' && data[3] != '\r')) {
    return MakeError(StatusCode::kBadMagic, "not a PLY file: it does not start with the line 'ply'");
  }
  Header header;
  bool have_format = false;
  bool done = false;
  size_t pos = 0;
  size_t line_number = 0;
  const size_t limit = std::min(size, kMaxHeaderBytes);
  while (!done) {
    // Find the end of this line.
    size_t end = pos;
    while (end < limit && data[end] != '\n') ++end;
    if (end >= limit) {
      if (limit < size) {
        return MakeError(StatusCode::kLimitExceeded, "PLY header: no 'end_header' within the first ", kMaxHeaderBytes,
                         " bytes");
      }
      return MakeError(StatusCode::kTruncated, "PLY header: file ends at byte ", size, " before 'end_header'");
    }
    ++line_number;
    std::string_view line(reinterpret_cast<const char*>(data + pos), end - pos);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos = end + 1;
    if (line_number == 1) continue;  // "ply", checked above
    const auto words = SplitWords(line);
    if (words.empty()) continue;
    const std::string_view keyword = words[0];
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "format") {
      if (have_format) return HeaderError(line_number, line, "second 'format' line");
      if (words.size() != 3) return HeaderError(line_number, line, "expected 'format <encoding> 1.0'");
      if (words[2] != "1.0") {
        return MakeError(StatusCode::kUnsupported, "PLY header line ", line_number, ": format version '",
                         std::string(words[2]), "' (only 1.0 is defined)");
      }
      if (words[1] == "ascii") {
        header.encoding = Encoding::kAscii;
      } else if (words[1] == "binary_little_endian") {
        header.encoding = Encoding::kBinaryLittleEndian;
      } else if (words[1] == "binary_big_endian") {
        header.encoding = Encoding::kBinaryBigEndian;
      } else {
        return MakeError(StatusCode::kUnsupported, "PLY header line ", line_number, ": unknown encoding '",
                         std::string(words[1]), "'");
      }
      have_format = true;
    } else if (keyword == "element") {
      if (words.size() != 3) return HeaderError(line_number, line, "expected 'element <name> <count>'");
      if (header.elements.size() >= kMaxElements) {
        return MakeError(StatusCode::kLimitExceeded, "PLY header line ", line_number, ": more than ", kMaxElements,
                         " elements");
      }
      Element element;
      element.name = std::string(words[1]);
      const auto* first = words[2].data();
      const auto* last = first + words[2].size();
      auto [ptr, ec] = std::from_chars(first, last, element.count);
      if (ec != std::errc() || ptr != last) {
        return HeaderError(line_number, line, "element count is not a non-negative integer below 2^64");
      }
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      if (header.elements.empty()) return HeaderError(line_number, line, "property before any element");
      Element& element = header.elements.back();
      if (element.properties.size() >= kMaxPropertiesPerElement) {
        return MakeError(StatusCode::kLimitExceeded, "PLY header line ", line_number, ": element '", element.name,
                         "' has more than ", kMaxPropertiesPerElement, " properties");
      }
      Property property;
      if (words.size() >= 2 && words[1] == "list") {
        if (words.size() != 5) return HeaderError(line_number, line, "expected 'property list <count> <item> <name>'");
        property.is_list = true;
        if (!ParseScalarType(words[2], &property.count_type) || !ParseScalarType(words[3], &property.type)) {
          return HeaderError(line_number, line, "unknown list type");
        }
        if (property.count_type == ScalarType::kFloat32 || property.count_type == ScalarType::kFloat64) {
          return HeaderError(line_number, line, "list count type must be an integer type");
        }
        property.name = std::string(words[4]);
      } else {
        if (words.size() != 3) return HeaderError(line_number, line, "expected 'property <type> <name>'");
        if (!ParseScalarType(words[1], &property.type)) return HeaderError(line_number, line, "unknown property type");
        property.name = std::string(words[2]);
      }
      for (const auto& other : element.properties) {
        if (other.name == property.name) return HeaderError(line_number, line, "duplicate property name");
      }
      element.properties.push_back(std::move(property));
    } else if (keyword == "end_header") {
      done = true;
    } else {
      return HeaderError(line_number, line, "unknown keyword");
    }
  }
  if (!have_format) return MakeError(StatusCode::kCorrupt, "PLY header has no 'format' line");
  header.data_offset = pos;
  return header;
}

}  // namespace atex::converters::ply
