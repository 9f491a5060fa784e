// Parsing of a PLY header (the text up to and including `end_header`).
// Internal to converters/src/ply.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex::converters::ply {

enum class Encoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

enum class ScalarType : uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

// Size in bytes of one value of `type`.
size_t ScalarSize(ScalarType type);

struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;  // item type for a list
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;  // only for lists
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;

  // Bytes of one row in a binary file if no property is a list, else 0.
  size_t FixedRowSize() const;
  // Smallest possible bytes of one binary row (a list with zero items still has its count).
  size_t MinRowSize() const;
};

struct Header {
  Encoding encoding = Encoding::kBinaryLittleEndian;
  std::vector<Element> elements;
  size_t data_offset = 0;  // first byte after the end_header line
};

// Limits that keep a hostile header small.
inline constexpr size_t kMaxHeaderBytes = size_t{1} << 20;
inline constexpr size_t kMaxElements = 256;
inline constexpr size_t kMaxPropertiesPerElement = 4096;

// Parses the header at the start of `data`. Errors name the header line.
StatusOr<Header> ParseHeader(const uint8_t* data, size_t size);

}  // namespace atex::converters::ply
