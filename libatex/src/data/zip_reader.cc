// Zip archive reader (APPNOTE 6.3): end record -> (ZIP64) -> central directory
// -> local headers. Every structure is bounds-checked before it is read.
#include <algorithm>
#include <cstring>
#include <limits>

#include <zlib.h>

#include "atex/file_io.h"
#include "atex/zip.h"
#include "data/byte_reader.h"

namespace atex {
namespace {

constexpr uint32_t kLocalHeaderSig = 0x04034b50;
constexpr uint32_t kCentralSig = 0x02014b50;
constexpr uint32_t kEndSig = 0x06054b50;
constexpr uint32_t kZip64EndSig = 0x06064b50;
constexpr uint32_t kZip64LocatorSig = 0x07064b50;
constexpr size_t kEndSize = 22;           // fixed part of the end-of-central-directory record
constexpr size_t kZip64LocatorSize = 20;
constexpr size_t kZip64EndMinSize = 56;
constexpr size_t kCentralFixedSize = 46;
constexpr size_t kLocalFixedSize = 30;
constexpr size_t kMaxComment = 0xFFFF;

// Finds the end record by scanning backwards over the (at most 64 KiB) comment.
StatusOr<size_t> FindEndRecord(const uint8_t* data, size_t size, const std::string& what) {
  if (size < kEndSize) {
    return MakeError(StatusCode::kTruncated, what, ": ", size,
                     " bytes is too small for a zip archive (22-byte end record)");
  }
  const size_t lowest = size - kEndSize >= kMaxComment ? size - kEndSize - kMaxComment : 0;
  for (size_t pos = size - kEndSize + 1; pos-- > lowest;) {
    if (LoadLE32(data + pos) == kEndSig) {
      // The comment must end exactly at the end of the archive.
      const size_t comment = LoadLE16(data + pos + 20);
      if (pos + kEndSize + comment == size) return pos;
    }
  }
  return MakeError(StatusCode::kBadMagic, what, ": no zip end-of-central-directory record in the last ",
                   size - lowest, " bytes (not a zip archive)");
}

// Applies a ZIP64 extended-information extra field (id 0x0001) to the fields
// that are saturated in the fixed record, in the APPNOTE order.
Status ApplyZip64Extra(const uint8_t* extra, size_t extra_size, ZipEntry& entry, bool need_uncompressed,
                       bool need_compressed, bool need_offset, const std::string& where) {
  size_t pos = 0;
  while (pos + 4 <= extra_size) {
    const uint16_t id = LoadLE16(extra + pos);
    const uint16_t len = LoadLE16(extra + pos + 2);
    if (pos + 4 + len > extra_size) {
      return MakeError(StatusCode::kCorrupt, where, ": extra field 0x", std::hex, id, std::dec, " of ", len,
                       " bytes overruns the extra area");
    }
    if (id == 0x0001) {
      ByteReader field(extra + pos + 4, len);
      if (need_uncompressed && !field.U64(entry.uncompressed_size)) break;
      if (need_compressed && !field.U64(entry.compressed_size)) break;
      if (need_offset && !field.U64(entry.local_header_offset)) break;
      return Status::Ok();
    }
    pos += 4 + size_t{len};
  }
  if (need_uncompressed || need_compressed || need_offset) {
    return MakeError(StatusCode::kCorrupt, where, ": sizes marked as ZIP64 but no complete ZIP64 extra field");
  }
  return Status::Ok();
}

}  // namespace

uint32_t ZipCrc32(const uint8_t* data, size_t size, uint32_t crc) {
  uLong value = crc;
  while (size > 0) {
    const uInt chunk = static_cast<uInt>(std::min<size_t>(size, 1u << 30));
    value = ::crc32(value, data, chunk);
    data += chunk;
    size -= chunk;
  }
  return static_cast<uint32_t>(value);
}

StatusOr<ZipArchive> ZipArchive::FromBytes(std::vector<uint8_t> bytes, const std::string& what,
                                           const ZipLimits& limits) {
  ZipArchive archive;
  auto owned = std::make_shared<const std::vector<uint8_t>>(std::move(bytes));
  archive.data_ = owned->data();
  archive.size_ = owned->size();
  archive.owned_ = std::move(owned);
  archive.what_ = what;
  ATEX_RETURN_IF_ERROR(archive.Parse(limits));
  return archive;
}

StatusOr<ZipArchive> ZipArchive::FromView(const uint8_t* data, size_t size, const std::string& what,
                                          const ZipLimits& limits) {
  ZipArchive archive;
  archive.data_ = data;
  archive.size_ = size;
  archive.what_ = what;
  ATEX_RETURN_IF_ERROR(archive.Parse(limits));
  return archive;
}

StatusOr<ZipArchive> ZipArchive::OpenFile(const std::string& path, const ZipLimits& limits) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes(path));
  return FromBytes(std::move(bytes), path, limits);
}

Status ZipArchive::Parse(const ZipLimits& limits) {
  limits_ = limits;
  ATEX_ASSIGN_OR_RETURN(const size_t end_pos, FindEndRecord(data_, size_, what_));
  const uint8_t* end = data_ + end_pos;
  const uint16_t this_disk = LoadLE16(end + 4);
  const uint16_t cd_disk = LoadLE16(end + 6);
  uint64_t entry_count = LoadLE16(end + 10);
  uint64_t cd_size = LoadLE32(end + 12);
  uint64_t cd_offset = LoadLE32(end + 16);

  const bool maybe_zip64 = entry_count == 0xFFFF || cd_size == 0xFFFFFFFFu || cd_offset == 0xFFFFFFFFu;
  if (end_pos >= kZip64LocatorSize && LoadLE32(end - kZip64LocatorSize) == kZip64LocatorSig) {
    const uint8_t* locator = end - kZip64LocatorSize;
    const uint64_t z64_pos = LoadLE64(locator + 8);
    if (z64_pos > end_pos - kZip64LocatorSize || end_pos - kZip64LocatorSize - z64_pos < kZip64EndMinSize) {
      return MakeError(StatusCode::kCorrupt, what_, ": ZIP64 end record offset ", z64_pos,
                       " is outside the archive (locator at byte ", end_pos - kZip64LocatorSize, ")");
    }
    const uint8_t* z64 = data_ + z64_pos;
    if (LoadLE32(z64) != kZip64EndSig) {
      return MakeError(StatusCode::kCorrupt, what_, ": no ZIP64 end record signature at byte ", z64_pos);
    }
    entry_count = LoadLE64(z64 + 32);
    cd_size = LoadLE64(z64 + 40);
    cd_offset = LoadLE64(z64 + 48);
  } else if (maybe_zip64) {
    return MakeError(StatusCode::kCorrupt, what_, ": end record at byte ", end_pos,
                     " has saturated (ZIP64) fields but no ZIP64 locator");
  }
  if (this_disk != 0 || cd_disk != 0) {
    return MakeError(StatusCode::kUnsupported, what_, ": multi-disk zip archives are not supported");
  }
  if (cd_offset > size_ || cd_size > size_ - cd_offset) {
    return MakeError(StatusCode::kTruncated, what_, ": central directory at byte ", cd_offset, " of ", cd_size,
                     " bytes extends past the end of the ", size_, "-byte archive");
  }
  // Each record takes at least 46 bytes: a forged count cannot allocate more than the bytes present allow.
  if (entry_count > cd_size / kCentralFixedSize) {
    return MakeError(StatusCode::kCorrupt, what_, ": ", entry_count, " entries cannot fit in a ", cd_size,
                     "-byte central directory");
  }
  if (entry_count > limits.max_entries) {
    return MakeError(StatusCode::kLimitExceeded, what_, ": ", entry_count, " entries exceed the limit of ",
                     limits.max_entries);
  }

  entries_.clear();
  entries_.reserve(entry_count);
  ByteReader cd(data_ + cd_offset, cd_size);
  for (uint64_t i = 0; i < entry_count; ++i) {
    const uint64_t record_pos = cd_offset + cd.position();
    const std::string where = StrCat(what_, ": central directory entry #", i, " at byte ", record_pos);
    if (cd.remaining() < kCentralFixedSize) {
      return MakeError(StatusCode::kTruncated, where, ": record truncated");
    }
    const uint8_t* rec = cd.current();
    if (LoadLE32(rec) != kCentralSig) return MakeError(StatusCode::kCorrupt, where, ": bad signature");
    ZipEntry entry;
    entry.flags = LoadLE16(rec + 8);
    entry.method = LoadLE16(rec + 10);
    entry.crc32 = LoadLE32(rec + 16);
    entry.compressed_size = LoadLE32(rec + 20);
    entry.uncompressed_size = LoadLE32(rec + 24);
    const size_t name_len = LoadLE16(rec + 28);
    const size_t extra_len = LoadLE16(rec + 30);
    const size_t comment_len = LoadLE16(rec + 32);
    const uint16_t start_disk = LoadLE16(rec + 34);
    entry.local_header_offset = LoadLE32(rec + 42);
    if (cd.remaining() < kCentralFixedSize + name_len + extra_len + comment_len) {
      return MakeError(StatusCode::kTruncated, where, ": name/extra/comment run past the central directory");
    }
    entry.name.assign(reinterpret_cast<const char*>(rec + kCentralFixedSize), name_len);
    const std::string member_where = StrCat(where, " ('", entry.name, "')");
    ATEX_RETURN_IF_ERROR(ApplyZip64Extra(rec + kCentralFixedSize + name_len, extra_len, entry,
                                         entry.uncompressed_size == 0xFFFFFFFFu,
                                         entry.compressed_size == 0xFFFFFFFFu,
                                         entry.local_header_offset == 0xFFFFFFFFu, member_where));
    if (start_disk != 0 && start_disk != 0xFFFF) {
      return MakeError(StatusCode::kUnsupported, member_where, ": member on disk ", start_disk);
    }
    cd.Skip(kCentralFixedSize + name_len + extra_len + comment_len);

    // Resolve the data offset through the local header (its name/extra lengths may differ).
    const uint64_t lho = entry.local_header_offset;
    if (lho > size_ || size_ - lho < kLocalFixedSize) {
      return MakeError(StatusCode::kTruncated, member_where, ": local header at byte ", lho,
                       " is outside the archive");
    }
    const uint8_t* local = data_ + lho;
    if (LoadLE32(local) != kLocalHeaderSig) {
      return MakeError(StatusCode::kCorrupt, member_where, ": no local header signature at byte ", lho);
    }
    const uint64_t data_offset = lho + kLocalFixedSize + LoadLE16(local + 26) + LoadLE16(local + 28);
    if (data_offset > size_ || entry.compressed_size > size_ - data_offset) {
      return MakeError(StatusCode::kTruncated, member_where, ": ", entry.compressed_size,
                       " bytes of data at byte ", data_offset, " extend past the end of the ", size_,
                       "-byte archive");
    }
    entry.data_offset = data_offset;
    entries_.push_back(std::move(entry));
  }
  return Status::Ok();
}

const ZipEntry* ZipArchive::Find(std::string_view name) const {
  for (const ZipEntry& entry : entries_) {
    if (entry.name == name) return &entry;
  }
  return nullptr;
}

StatusOr<ZipArchive::View> ZipArchive::StoredView(const ZipEntry& entry, bool verify_crc) const {
  const std::string where = StrCat(what_, ": member '", entry.name, "' at byte ", entry.local_header_offset);
  if (entry.flags & 1) return MakeError(StatusCode::kUnsupported, where, ": encrypted members are not supported");
  if (entry.method != 0) {
    return MakeError(StatusCode::kUnsupported, where, ": compressed (method ", entry.method, "), not stored");
  }
  if (entry.compressed_size != entry.uncompressed_size) {
    return MakeError(StatusCode::kCorrupt, where, ": stored member with compressed size ", entry.compressed_size,
                     " != uncompressed size ", entry.uncompressed_size);
  }
  // Parse() checked data_offset + compressed_size <= size_.
  View view{data_ + entry.data_offset, static_cast<size_t>(entry.compressed_size)};
  if (verify_crc && ZipCrc32(view.data, view.size) != entry.crc32) {
    return MakeError(StatusCode::kChecksumMismatch, where, ": CRC-32 of the data does not match the directory");
  }
  return view;
}

StatusOr<std::vector<uint8_t>> ZipArchive::Extract(std::string_view name) const {
  const ZipEntry* entry = Find(name);
  if (entry == nullptr) {
    return MakeError(StatusCode::kNotFound, what_, ": no member named '", name, "'");
  }
  return Extract(*entry);
}

StatusOr<std::vector<uint8_t>> ZipArchive::Extract(const ZipEntry& entry) const {
  const std::string where = StrCat(what_, ": member '", entry.name, "' at byte ", entry.local_header_offset);
  if (entry.uncompressed_size > limits_.max_member_bytes || entry.uncompressed_size > SIZE_MAX / 2) {
    return MakeError(StatusCode::kLimitExceeded, where, ": uncompressed size ", entry.uncompressed_size,
                     " exceeds the limit of ", limits_.max_member_bytes, " bytes");
  }
  if (entry.method == 0) {
    ATEX_ASSIGN_OR_RETURN(View view, StoredView(entry, true));
    return std::vector<uint8_t>(view.data, view.data + view.size);
  }
  if (entry.flags & 1) return MakeError(StatusCode::kUnsupported, where, ": encrypted members are not supported");
  if (entry.method != 8) {
    return MakeError(StatusCode::kUnsupportedCodec, where, ": compression method ", entry.method,
                     " (only stored and deflate are supported)");
  }
  // Deflate expands at most ~1032:1; a declared size beyond that is forged.
  if (entry.uncompressed_size / 1032 > entry.compressed_size + 1) {
    return MakeError(StatusCode::kCorrupt, where, ": declared size ", entry.uncompressed_size,
                     " is impossible for ", entry.compressed_size, " deflated bytes");
  }

  z_stream stream{};
  if (inflateInit2(&stream, -MAX_WBITS) != Z_OK) {
    return MakeError(StatusCode::kInternal, where, ": zlib inflateInit2 failed");
  }
  // Grow with decoded data: start from a bounded guess, double as needed, never
  // beyond the declared size + 1 (the extra byte detects a stream that is too long).
  const uint64_t cap = entry.uncompressed_size + 1;
  std::vector<uint8_t> out(static_cast<size_t>(std::min<uint64_t>(cap, 4 * entry.compressed_size + 4096)));
  const uint8_t* in = data_ + entry.data_offset;
  uint64_t in_left = entry.compressed_size;
  size_t produced = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (stream.avail_in == 0 && in_left > 0) {
      const uInt chunk = static_cast<uInt>(std::min<uint64_t>(in_left, 1u << 30));
      stream.next_in = const_cast<Bytef*>(in);
      stream.avail_in = chunk;
      in += chunk;
      in_left -= chunk;
    }
    if (produced == out.size()) {
      if (produced >= cap) break;  // reported below as too long
      out.resize(static_cast<size_t>(std::min<uint64_t>(cap, uint64_t{out.size()} * 2 + 4096)));
    }
    stream.next_out = out.data() + produced;
    stream.avail_out = static_cast<uInt>(std::min<size_t>(out.size() - produced, 1u << 30));
    const uInt before = stream.avail_out;
    rc = inflate(&stream, Z_NO_FLUSH);
    produced += before - stream.avail_out;
    if (rc == Z_BUF_ERROR && stream.avail_in == 0 && in_left == 0) {
      inflateEnd(&stream);
      return MakeError(StatusCode::kTruncated, where, ": deflate stream ends early after ", produced,
                       " of ", entry.uncompressed_size, " bytes");
    }
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      const std::string reason = stream.msg ? stream.msg : "error";
      inflateEnd(&stream);
      return MakeError(StatusCode::kCorrupt, where, ": deflate data invalid after ", produced,
                       " output bytes (zlib: ", reason, ")");
    }
  }
  inflateEnd(&stream);
  if (produced != entry.uncompressed_size) {
    return MakeError(
        StatusCode::kCorrupt, where, ": inflates to ", produced > entry.uncompressed_size ? "more than " : "",
        std::min<uint64_t>(produced, entry.uncompressed_size), " bytes, the directory says ", entry.uncompressed_size);
  }
  out.resize(produced);
  if (ZipCrc32(out.data(), out.size()) != entry.crc32) {
    return MakeError(StatusCode::kChecksumMismatch, where, ": CRC-32 of the inflated data does not match");
  }
  return out;
}

}  // namespace atex
