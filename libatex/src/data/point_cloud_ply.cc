// A plain PLY point reader and writer (atex/point_cloud.h). libatex cannot use the
// converters' PLY reader (converters/ sits above libatex), and this one needs only the
// vertex positions and colours of any PLY, not the 3DGS attribute layout.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <sstream>

#include "atex/file_io.h"
#include "atex/point_cloud.h"

namespace atex {
namespace {

constexpr size_t kMaxHeaderBytes = 1 << 16;
constexpr double kShC0 = 0.28209479177387814;

enum class Encoding { kAscii, kLittle, kBig };

struct PlyType {
  const char* names[2];
  int bytes;
  bool is_float, is_signed;
  double max;  // for colour scaling of integer types
};
constexpr PlyType kTypes[] = {
    {{"char", "int8"}, 1, false, true, 127},           {{"uchar", "uint8"}, 1, false, false, 255},
    {{"short", "int16"}, 2, false, true, 32767},       {{"ushort", "uint16"}, 2, false, false, 65535},
    {{"int", "int32"}, 4, false, true, 2147483647.0},  {{"uint", "uint32"}, 4, false, false, 4294967295.0},
    {{"float", "float32"}, 4, true, true, 1},          {{"double", "float64"}, 8, true, true, 1},
};

const PlyType* FindType(const std::string& name) {
  for (const PlyType& t : kTypes) {
    if (name == t.names[0] || name == t.names[1]) return &t;
  }
  return nullptr;
}

struct Property {
  std::string name;
  const PlyType* type = nullptr;
  const PlyType* count_type = nullptr;  // list properties only
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Encoding encoding = Encoding::kAscii;
  std::vector<Element> elements;
  size_t body = 0;  // byte offset of the data
};

StatusOr<Header> ParseHeader(const uint8_t* data, size_t size, const std::string& what) {
  if (size < 4 || std::memcmp(data, "ply", 3) != 0 || (data[3] != '\n' && data[3] != '\r')) {
    return MakeError(StatusCode::kBadMagic, what, ": not a PLY file (no 'ply' line)");
  }
  const size_t limit = std::min(size, kMaxHeaderBytes);
  const char* text = reinterpret_cast<const char*>(data);
  Header header;
  bool have_format = false;
  size_t pos = 0;
  int line_number = 0;
  while (true) {
    const size_t end = std::string_view(text + pos, limit - pos).find('\n');
    if (end == std::string_view::npos) {
      return MakeError(StatusCode::kTruncated, what, ": PLY header has no end_header within ", limit, " bytes");
    }
    std::string line(text + pos, end);
    pos += end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream in(line);
    std::string word;
    in >> word;
    auto bad = [&](const char* why) {
      return MakeError(StatusCode::kCorrupt, what, ": PLY header line ", line_number, " ('", line, "'): ", why);
    };
    if (line_number == 1 || word.empty() || word == "comment" || word == "obj_info") continue;
    if (word == "end_header") break;
    if (word == "format") {
      std::string kind, version;
      in >> kind >> version;
      if (kind == "ascii") header.encoding = Encoding::kAscii;
      else if (kind == "binary_little_endian") header.encoding = Encoding::kLittle;
      else if (kind == "binary_big_endian") header.encoding = Encoding::kBig;
      else return bad("unknown format");
      if (version != "1.0") return bad("unsupported version (1.0 only)");
      have_format = true;
    } else if (word == "element") {
      Element e;
      std::string count;
      in >> e.name >> count;
      auto [ptr, ec] = std::from_chars(count.data(), count.data() + count.size(), e.count);
      if (e.name.empty() || ec != std::errc() || ptr != count.data() + count.size()) return bad("bad element count");
      header.elements.push_back(std::move(e));
    } else if (word == "property") {
      if (header.elements.empty()) return bad("property before any element");
      Property p;
      std::string type;
      in >> type;
      if (type == "list") {
        std::string count_type;
        in >> count_type >> type;
        p.count_type = FindType(count_type);
        if (!p.count_type || p.count_type->is_float) return bad("bad list count type");
      }
      p.type = FindType(type);
      in >> p.name;
      if (!p.type || p.name.empty()) return bad("bad property");
      header.elements.back().properties.push_back(std::move(p));
    } else {
      return bad("unknown keyword");
    }
  }
  if (!have_format) return MakeError(StatusCode::kCorrupt, what, ": PLY header has no format line");
  header.body = pos;
  return header;
}

// Reads values of the PLY body one at a time, binary or ASCII, with bounds checks.
class BodyReader {
 public:
  BodyReader(const uint8_t* data, size_t size, size_t pos, Encoding encoding, const std::string& what)
      : data_(data), size_(size), pos_(pos), encoding_(encoding), what_(what) {}

  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }

  Status Read(const PlyType& type, double* value) {
    if (encoding_ == Encoding::kAscii) return ReadAscii(value);
    if (size_t(type.bytes) > remaining()) {
      return MakeError(StatusCode::kTruncated, what_, ": PLY data ends at byte ", size_, " inside a value");
    }
    uint8_t b[8];
    std::memcpy(b, data_ + pos_, type.bytes);
    pos_ += type.bytes;
    if (encoding_ == Encoding::kBig) std::reverse(b, b + type.bytes);
    *value = Decode(type, b);
    return Status::Ok();
  }

 private:
  static double Decode(const PlyType& t, const uint8_t* b) {
    if (t.is_float) {
      if (t.bytes == 4) {
        float f;
        std::memcpy(&f, b, 4);
        return f;
      }
      double d;
      std::memcpy(&d, b, 8);
      return d;
    }
    uint64_t u = 0;
    for (int i = 0; i < t.bytes; ++i) u |= uint64_t(b[i]) << (8 * i);
    if (t.is_signed && (u >> (8 * t.bytes - 1)) & 1) return double(int64_t(u) - (int64_t(1) << (8 * t.bytes)));
    return double(u);
  }

  Status ReadAscii(double* value) {
    while (pos_ < size_ && std::isspace(data_[pos_])) ++pos_;
    const char* begin = reinterpret_cast<const char*>(data_ + pos_);
    const char* end = reinterpret_cast<const char*>(data_ + size_);
    auto [ptr, ec] = std::from_chars(begin, end, *value);
    if (ec != std::errc() || ptr == begin) {
      return MakeError(pos_ >= size_ ? StatusCode::kTruncated : StatusCode::kCorrupt, what_,
                       ": PLY ascii data: expected a number at byte ", pos_);
    }
    pos_ += size_t(ptr - begin);
    return Status::Ok();
  }

  const uint8_t* data_;
  size_t size_;
  size_t pos_;
  Encoding encoding_;
  const std::string& what_;
};

// Smallest bytes one instance of `e` can take in the body (1 per value for ASCII).
uint64_t MinInstanceBytes(const Element& e, Encoding encoding) {
  uint64_t bytes = 0;
  for (const Property& p : e.properties) {
    const uint64_t value =
        encoding == Encoding::kAscii ? 2 : uint64_t(p.count_type ? p.count_type->bytes : p.type->bytes);
    bytes += value;
  }
  return std::max<uint64_t>(bytes, 1);
}

}  // namespace

StatusOr<PointCloud> ParsePlyPoints(const uint8_t* data, size_t size, const std::string& what) {
  ATEX_ASSIGN_OR_RETURN(Header header, ParseHeader(data, size, what));
  BodyReader body(data, size, header.body, header.encoding, what);
  for (const Element& e : header.elements) {
    if (e.count > kMaxPointCloudPoints) {
      return MakeError(StatusCode::kLimitExceeded, what, ": PLY element '", e.name, "' has ", e.count,
                       " entries (limit ", kMaxPointCloudPoints, ")");
    }
    // Enough bytes for the announced count, before anything is allocated from it.
    if (e.count > (body.remaining() + 1) / MinInstanceBytes(e, header.encoding)) {
      return MakeError(StatusCode::kTruncated, what, ": PLY element '", e.name, "' announces ", e.count,
                       " entries but only ", body.remaining(), " bytes follow byte ", body.position());
    }
    const bool vertex = e.name == "vertex";
    int pos_index[3] = {-1, -1, -1}, rgb_index[3] = {-1, -1, -1}, dc_index[3] = {-1, -1, -1};
    for (size_t i = 0; i < e.properties.size(); ++i) {
      const Property& p = e.properties[i];
      static const char* const kPos[3] = {"x", "y", "z"};
      static const char* const kRgb[3] = {"red", "green", "blue"};
      static const char* const kDc[3] = {"f_dc_0", "f_dc_1", "f_dc_2"};
      for (int a = 0; a < 3; ++a) {
        if (p.count_type) continue;
        if (p.name == kPos[a]) pos_index[a] = int(i);
        if (p.name == kRgb[a]) rgb_index[a] = int(i);
        if (p.name == kDc[a]) dc_index[a] = int(i);
      }
    }
    if (vertex && (pos_index[0] < 0 || pos_index[1] < 0 || pos_index[2] < 0)) {
      return MakeError(StatusCode::kCorrupt, what, ": PLY vertex element has no x, y, z properties");
    }
    const bool use_rgb = rgb_index[0] >= 0 && rgb_index[1] >= 0 && rgb_index[2] >= 0;
    const bool use_dc = !use_rgb && dc_index[0] >= 0 && dc_index[1] >= 0 && dc_index[2] >= 0;
    PointCloud cloud;
    if (vertex) {
      cloud.positions.reserve(e.count * 3);
      if (use_rgb || use_dc) cloud.colours.reserve(e.count * 3);
    }
    std::vector<double> values(e.properties.size());
    for (uint64_t n = 0; n < e.count; ++n) {
      for (size_t i = 0; i < e.properties.size(); ++i) {
        const Property& p = e.properties[i];
        if (!p.count_type) {
          ATEX_RETURN_IF_ERROR(body.Read(*p.type, &values[i]));
          continue;
        }
        double count;
        ATEX_RETURN_IF_ERROR(body.Read(*p.count_type, &count));
        if (!(count >= 0) || count > double(body.remaining())) {
          return MakeError(StatusCode::kCorrupt, what, ": PLY element '", e.name, "' entry ", n, " list '", p.name,
                           "' has length ", count, " near byte ", body.position());
        }
        double ignored;
        for (uint64_t k = 0; k < uint64_t(count); ++k) ATEX_RETURN_IF_ERROR(body.Read(*p.type, &ignored));
      }
      if (!vertex) continue;
      for (int a = 0; a < 3; ++a) {
        const double x = values[pos_index[a]];
        if (!std::isfinite(x) || std::abs(x) > 3.0e38) {
          return MakeError(StatusCode::kOutOfRange, what, ": PLY vertex ", n, " has a non-finite coordinate");
        }
        cloud.positions.push_back(float(x));
      }
      for (int a = 0; a < 3 && (use_rgb || use_dc); ++a) {
        double c;
        if (use_rgb) {
          const PlyType& t = *e.properties[rgb_index[a]].type;
          c = t.is_float ? values[rgb_index[a]] : values[rgb_index[a]] / t.max;
        } else {
          c = 0.5 + kShC0 * values[dc_index[a]];
        }
        cloud.colours.push_back(float(std::isfinite(c) ? std::clamp(c, 0.0, 1.0) : 0.5));
      }
    }
    if (vertex) return cloud;
  }
  return MakeError(StatusCode::kCorrupt, what, ": PLY file has no vertex element");
}

Status WritePlyPoints(const std::string& path, const PointCloud& cloud) {
  const bool colours = cloud.has_colours();
  if (cloud.positions.size() % 3 != 0 || (colours && cloud.colours.size() != cloud.positions.size())) {
    return MakeError(StatusCode::kInvalidArgument, path, ": point cloud arrays of mismatched sizes");
  }
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment written by libatex\nelement vertex " +
                       std::to_string(cloud.size()) + "\nproperty float x\nproperty float y\nproperty float z\n";
  if (colours) header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "end_header\n";
  std::vector<uint8_t> bytes(header.begin(), header.end());
  bytes.reserve(bytes.size() + cloud.size() * (colours ? 15 : 12));
  for (size_t i = 0; i < cloud.size(); ++i) {
    for (int a = 0; a < 3; ++a) {
      uint32_t u;
      std::memcpy(&u, &cloud.positions[3 * i + a], 4);
      for (int k = 0; k < 4; ++k) bytes.push_back(uint8_t(u >> (8 * k)));
    }
    for (int a = 0; a < 3 && colours; ++a) {
      const float c = cloud.colours[3 * i + a];
      bytes.push_back(uint8_t(std::lround(std::clamp(std::isfinite(c) ? c : 0.0f, 0.0f, 1.0f) * 255.0f)));
    }
  }
  return WriteFileAtomic(path, bytes);
}

}  // namespace atex
