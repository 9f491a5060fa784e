#include "spz/spz_container.h"

#include <array>
#include <cstring>
#include <limits>
#include <string>
#include <thread>
#include <type_traits>

#include "convert/bytes.h"
#include "spz/spz_compress.h"

namespace atex::converters::spz {

namespace {

using bytes::AppendLE;
using bytes::LoadLE;

constexpr size_t kLegacyHeaderBytes = 16;
constexpr size_t kNgspHeaderBytes = 32;
constexpr size_t kTocEntryBytes = 16;
constexpr uint32_t kExtensionCoordinateSystem = 0xADBE0003u;
// Streams above this total are decompressed on one thread each.
constexpr uint64_t kParallelThreshold = uint64_t{1} << 20;

// The six attribute arrays in file order, with their names for messages.
template <typename Vector>
struct StreamRefT {
  const char* name;
  Vector* array;
  uint64_t expected;  // bytes the header implies
};
using StreamRef = StreamRefT<std::vector<uint8_t>>;

template <typename Packed>
auto Streams(Packed& p) {
  using Vector = std::conditional_t<std::is_const_v<Packed>, const std::vector<uint8_t>, std::vector<uint8_t>>;
  const uint64_t n = p.num_points;
  return std::array<StreamRefT<Vector>, 6>{{{"positions", &p.positions, n * p.position_bytes()},
           {"alphas", &p.alphas, n},
           {"colors", &p.colors, n * 3},
           {"scales", &p.scales, n * 3},
           {"rotations", &p.rotations, n * p.rotation_bytes()},
           {"spherical harmonics", &p.sh, n * p.sh_bytes()}}};
}

// Header fields shared by all versions; checks their ranges.
Status CheckHeaderFields(const PackedSpz& p, const SpzReadOptions& options, const char* where) {
  if (p.sh_degree > kMaxStoredShDegree) {
    return MakeError(StatusCode::kOutOfRange, "SPZ ", where, " byte 12: SH degree ", p.sh_degree, " (0..4)");
  }
  if (p.fractional_bits > kMaxFractionalBits) {
    return MakeError(StatusCode::kOutOfRange, "SPZ ", where, " byte 13: fractional bits ", p.fractional_bits,
                     " (0..", kMaxFractionalBits, ")");
  }
  if (p.num_points > options.max_points) {
    return MakeError(StatusCode::kLimitExceeded, "SPZ ", where, " byte 8: ", p.num_points,
                     " Gaussians exceed the reader's limit of ", options.max_points);
  }
  return Status::Ok();
}

Status ParseExtensions(const uint8_t* data, size_t begin, size_t end, ParsedSpz* parsed) {
  size_t pos = begin;
  while (pos < end) {
    if (end - pos < 8) {
      return MakeError(StatusCode::kCorrupt, "SPZ v4 extension record at byte ", pos, ": ", end - pos,
                       " bytes left before the table of contents, a record header needs 8");
    }
    const uint32_t type = LoadLE<uint32_t>(data + pos);
    const uint32_t length = LoadLE<uint32_t>(data + pos + 4);
    if (length > end - pos - 8) {
      return MakeError(StatusCode::kCorrupt, "SPZ v4 extension record at byte ", pos, " (type 0x", std::hex, type,
                       std::dec, ") announces ", length, " payload bytes but only ", end - pos - 8, " remain");
    }
    if (type == kExtensionCoordinateSystem) {
      if (length != 4) {
        return MakeError(StatusCode::kCorrupt, "SPZ v4 coordinate-system extension at byte ", pos, " has ", length,
                         " payload bytes (expected 4)");
      }
      const uint32_t value = LoadLE<uint32_t>(data + pos + 8);
      if (value >= kSpzCoordinateSystemCount) {
        return MakeError(StatusCode::kOutOfRange, "SPZ v4 coordinate-system extension at byte ", pos,
                         ": unknown system ", value);
      }
      parsed->coordinate_system = value;
    }
    ++parsed->extension_records;  // unknown types are skipped by length, as the spec asks
    pos += 8 + static_cast<size_t>(length);
  }
  return Status::Ok();
}

StatusOr<ParsedSpz> ParseNgsp(const uint8_t* data, size_t size, const SpzReadOptions& options) {
  if (size < kNgspHeaderBytes) {
    return MakeError(StatusCode::kTruncated, "SPZ v4 file of ", size, " bytes is shorter than its 32-byte header");
  }
  ParsedSpz parsed;
  PackedSpz& p = parsed.packed;
  const uint32_t version = LoadLE<uint32_t>(data + 4);
  if (version != 4) {
    return MakeError(version > 4 ? StatusCode::kUnsupportedVersion : StatusCode::kCorrupt, "SPZ byte 4: version ",
                     version, " with a plaintext NGSP header (only version 4 has one)");
  }
  p.version = 4;
  p.num_points = LoadLE<uint32_t>(data + 8);
  p.sh_degree = data[12];
  p.fractional_bits = data[13];
  p.flags = data[14];
  const uint32_t num_streams = data[15];
  const uint32_t toc_offset = LoadLE<uint32_t>(data + 16);
  for (size_t i = 20; i < kNgspHeaderBytes; ++i) {
    if (data[i] != 0) return MakeError(StatusCode::kCorrupt, "SPZ v4 header byte ", i, " is reserved but not zero");
  }
  ATEX_RETURN_IF_ERROR(CheckHeaderFields(p, options, "v4 header"));
  if (toc_offset < kNgspHeaderBytes || toc_offset > size ||
      uint64_t{num_streams} * kTocEntryBytes > size - toc_offset) {
    return MakeError(StatusCode::kCorrupt, "SPZ v4 header byte 16: table of contents at byte ", toc_offset, " with ",
                     num_streams, " entries does not fit the file's ", size, " bytes");
  }
  if (p.flags & kFlagHasExtensions) ATEX_RETURN_IF_ERROR(ParseExtensions(data, kNgspHeaderBytes, toc_offset, &parsed));

  // The non-empty arrays, in file order, are the streams.
  std::vector<StreamRef> streams;
  uint64_t total = 0;
  for (const StreamRef& s : Streams(p)) {
    if (s.expected == 0) continue;
    streams.push_back(s);
    total += s.expected;
  }
  if (num_streams != streams.size()) {
    return MakeError(StatusCode::kCorrupt, "SPZ v4 header byte 15: ", num_streams, " streams, but ", p.num_points,
                     " Gaussians of SH degree ", p.sh_degree, " need ", streams.size());
  }
  if (total > options.max_decompressed_bytes) {
    return MakeError(StatusCode::kLimitExceeded, "SPZ v4: ", p.num_points, " Gaussians decode to ", total,
                     " bytes, above the reader's limit of ", options.max_decompressed_bytes);
  }
  struct Range {
    size_t offset, size;
  };
  std::vector<Range> ranges(streams.size());
  size_t offset = toc_offset + num_streams * kTocEntryBytes;
  for (size_t i = 0; i < streams.size(); ++i) {
    const size_t entry = toc_offset + i * kTocEntryBytes;
    const uint64_t compressed = LoadLE<uint64_t>(data + entry);
    const uint64_t uncompressed = LoadLE<uint64_t>(data + entry + 8);
    if (uncompressed != streams[i].expected) {
      return MakeError(StatusCode::kCorrupt, "SPZ v4 table of contents entry ", i, " (", streams[i].name,
                       ", byte ", entry, "): ", uncompressed, " bytes, the header implies ", streams[i].expected);
    }
    if (compressed > size - offset) {
      return MakeError(StatusCode::kTruncated, "SPZ v4 stream ", i, " (", streams[i].name, ") at byte ", offset,
                       " needs ", compressed, " bytes, the file has ", size - offset, " left");
    }
    ranges[i] = {offset, static_cast<size_t>(compressed)};
    offset += static_cast<size_t>(compressed);
  }
  if (offset != size) {
    return MakeError(StatusCode::kCorrupt, "SPZ v4: ", size - offset, " bytes after the last stream (byte ", offset,
                     ")");
  }

  std::vector<Status> results(streams.size());
  auto decode = [&](size_t i) {
    const std::string what = "v4 stream " + std::to_string(i) + " (" + streams[i].name + ") at byte " +
                             std::to_string(ranges[i].offset);
    auto decoded = ZstdDecompressExact(data + ranges[i].offset, ranges[i].size, streams[i].expected, what);
    if (!decoded.ok()) {
      results[i] = decoded.status();
      return;
    }
    *streams[i].array = std::move(decoded).value();
  };
  if (total >= kParallelThreshold && streams.size() > 1) {
    std::vector<std::thread> threads;
    try {
      for (size_t i = 1; i < streams.size(); ++i) threads.emplace_back(decode, i);
    } catch (const std::system_error&) {
      // No threads available: the remaining streams are decoded below on this thread.
    }
    decode(0);
    for (auto& t : threads) t.join();
    for (size_t i = threads.size() + 1; i < streams.size(); ++i) decode(i);
  } else {
    for (size_t i = 0; i < streams.size(); ++i) decode(i);
  }
  for (const Status& s : results) ATEX_RETURN_IF_ERROR(s);
  return parsed;
}

StatusOr<ParsedSpz> ParseLegacy(const uint8_t* data, size_t size, const SpzReadOptions& options) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, GzipDecompress(data, size, options.max_decompressed_bytes));
  if (raw.size() < kLegacyHeaderBytes) {
    return MakeError(StatusCode::kTruncated, "SPZ gzip payload of ", raw.size(),
                     " bytes is shorter than its 16-byte header");
  }
  ParsedSpz parsed;
  PackedSpz& p = parsed.packed;
  if (LoadLE<uint32_t>(raw.data()) != kMagic) {
    return MakeError(StatusCode::kBadMagic, "SPZ gzip payload does not start with 'NGSP'");
  }
  const uint32_t version = LoadLE<uint32_t>(raw.data() + 4);
  if (version < 1 || version > 3) {
    return MakeError(version > 3 ? StatusCode::kUnsupportedVersion : StatusCode::kCorrupt,
                     "SPZ gzip payload byte 4: version ", version, " (gzip files are versions 1..3)");
  }
  p.version = static_cast<int>(version);
  p.num_points = LoadLE<uint32_t>(raw.data() + 8);
  p.sh_degree = raw[12];
  p.fractional_bits = raw[13];
  p.flags = raw[14];
  ATEX_RETURN_IF_ERROR(CheckHeaderFields(p, options, "gzip payload"));
  size_t offset = kLegacyHeaderBytes;
  for (const StreamRef& s : Streams(p)) {
    if (s.expected > raw.size() - offset) {
      return MakeError(StatusCode::kTruncated, "SPZ gzip payload: ", s.name, " of ", p.num_points,
                       " Gaussians need ", s.expected, " bytes at byte ", offset, " but only ", raw.size() - offset,
                       " remain");
    }
    s.array->assign(raw.begin() + static_cast<ptrdiff_t>(offset),
                    raw.begin() + static_cast<ptrdiff_t>(offset + s.expected));
    offset += static_cast<size_t>(s.expected);
  }
  // Bytes after the arrays are extension records (flag 0x2); none of them changes
  // how the core arrays decode, so they are skipped.
  return parsed;
}

}  // namespace

StatusOr<ParsedSpz> ParseSpzContainer(const uint8_t* data, size_t size, const SpzReadOptions& options) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "SPZ: null data");
  if (size >= 4 && LoadLE<uint32_t>(data) == kMagic) return ParseNgsp(data, size, options);
  if (size >= 2 && data[0] == 0x1f && data[1] == 0x8b) return ParseLegacy(data, size, options);
  return MakeError(StatusCode::kBadMagic,
                   "not an SPZ file: neither the 'NGSP' header of version 4 nor the gzip magic of versions 1-3");
}

StatusOr<std::vector<uint8_t>> SerializeSpz(const PackedSpz& packed, const SpzWriteOptions& options) {
  if (packed.version == 3) {
    std::vector<uint8_t> raw;
    raw.reserve(kLegacyHeaderBytes + packed.positions.size() + packed.alphas.size() + packed.colors.size() +
                packed.scales.size() + packed.rotations.size() + packed.sh.size());
    AppendLE<uint32_t>(raw, kMagic);
    AppendLE<uint32_t>(raw, 3);
    AppendLE<uint32_t>(raw, packed.num_points);
    raw.push_back(static_cast<uint8_t>(packed.sh_degree));
    raw.push_back(static_cast<uint8_t>(packed.fractional_bits));
    raw.push_back(packed.flags);
    raw.push_back(0);  // reserved
    for (const auto& s : Streams(packed)) raw.insert(raw.end(), s.array->begin(), s.array->end());
    return GzipCompress(raw.data(), raw.size(), options.zlib_level);
  }
  if (packed.version != 4) {
    return MakeError(StatusCode::kInvalidArgument, "SPZ writer: version ", packed.version, " (writes 3 or 4)");
  }
  std::vector<const std::vector<uint8_t>*> arrays;
  for (const auto& s : Streams(packed)) {
    if (!s.array->empty()) arrays.push_back(s.array);
  }
  std::vector<StatusOr<std::vector<uint8_t>>> compressed(arrays.size(), Status(StatusCode::kInternal, "not run"));
  {
    std::vector<std::thread> threads;
    auto compress = [&](size_t i) {
      compressed[i] = ZstdCompress(arrays[i]->data(), arrays[i]->size(), options.zstd_level);
    };
    try {
      for (size_t i = 1; i < arrays.size(); ++i) threads.emplace_back(compress, i);
    } catch (const std::system_error&) {
    }
    if (!arrays.empty()) compress(0);
    for (auto& t : threads) t.join();
    for (size_t i = threads.size() + 1; i < arrays.size(); ++i) compress(i);
  }
  std::vector<uint8_t> out;
  AppendLE<uint32_t>(out, kMagic);
  AppendLE<uint32_t>(out, 4);
  AppendLE<uint32_t>(out, packed.num_points);
  out.push_back(static_cast<uint8_t>(packed.sh_degree));
  out.push_back(static_cast<uint8_t>(packed.fractional_bits));
  out.push_back(packed.flags);
  out.push_back(static_cast<uint8_t>(arrays.size()));
  AppendLE<uint32_t>(out, static_cast<uint32_t>(kNgspHeaderBytes));  // no extension records
  out.resize(kNgspHeaderBytes, 0);                                    // reserved
  for (size_t i = 0; i < arrays.size(); ++i) {
    if (!compressed[i].ok()) return compressed[i].status();
    AppendLE<uint64_t>(out, compressed[i]->size());
    AppendLE<uint64_t>(out, arrays[i]->size());
  }
  for (auto& c : compressed) out.insert(out.end(), c->begin(), c->end());
  return out;
}

}  // namespace atex::converters::spz
