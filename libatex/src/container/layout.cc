#include "container/layout.h"

#include <algorithm>
#include <cstring>
#include <set>

#include "atex/checksum.h"
#include "container/byte_io.h"
#include "container/format.h"

namespace atex::container {
namespace {

bool ValidTypeChar(uint8_t c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9'); }

std::string PrintableType(const uint8_t* p) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    if (p[i] >= 0x20 && p[i] < 0x7F) {
      s += static_cast<char>(p[i]);
    } else {
      s += StrCat("\\x", "0123456789abcdef"[p[i] >> 4], "0123456789abcdef"[p[i] & 15]);
    }
  }
  return s;
}

bool AllZero(const uint8_t* p, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    if (p[i] != 0) return false;
  }
  return true;
}

uint32_t HeaderCrc(const uint8_t* data, uint64_t toc_end) {
  static constexpr uint8_t kZero[4] = {0, 0, 0, 0};
  uint32_t crc = Crc32cExtend(0, data, kHeaderCrc);
  crc = Crc32cExtend(crc, kZero, 4);
  return Crc32cExtend(crc, data + kHeaderCrc + 4, static_cast<size_t>(toc_end - kHeaderCrc - 4));
}

}  // namespace

std::string ChunkLabel(const TocEntry& entry, size_t index) {
  return StrCat("chunk '", entry.type, "' (#", index, ") at byte ", entry.offset);
}

StatusOr<ParsedContainer> ParseContainer(const uint8_t* data, size_t size, bool verify_crc) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "null input");
  if (size == 0) return MakeError(StatusCode::kTruncated, "empty input (an .atex file starts with 32 header bytes)");
  const size_t magic_bytes = std::min<size_t>(size, kMagic.size());
  if (std::memcmp(data, kMagic.data(), magic_bytes) != 0) {
    return MakeError(StatusCode::kBadMagic, "not an .atex file: the first bytes are not 89 41 54 45 58 0D 0A 1A");
  }
  if (size < kHeaderSize) {
    return MakeError(StatusCode::kTruncated, "input of ", size, " bytes ends inside the 32-byte header");
  }
  ParsedContainer c;
  c.version_major = LoadLE<uint16_t>(data + kHeaderMajor);
  c.version_minor = LoadLE<uint16_t>(data + kHeaderMinor);
  if (c.version_major != kVersionMajor) {
    return MakeError(StatusCode::kUnsupportedVersion, "file version ", c.version_major, ".", c.version_minor,
                     " is not readable by this reader (version ", kVersionMajor, ".", kVersionMinor, ")");
  }
  c.flags = LoadLE<uint32_t>(data + kHeaderFlags);
  c.file_size = LoadLE<uint64_t>(data + kHeaderFileSize);
  const uint32_t count = LoadLE<uint32_t>(data + kHeaderChunkCount);
  c.header_crc = LoadLE<uint32_t>(data + kHeaderCrc);
  if (size < c.file_size) {
    return MakeError(StatusCode::kTruncated, "input has ", size, " bytes but the header (byte 16) says the file has ",
                     c.file_size);
  }
  if (size > c.file_size) {
    return MakeError(StatusCode::kCorrupt, "input has ", size, " bytes, ", size - c.file_size,
                     " more than the header's file size ", c.file_size, " (byte 16)");
  }
  const uint64_t toc_end = kHeaderSize + kTocEntrySize * uint64_t{count};  // < 2^38, no overflow
  if (toc_end > c.file_size) {
    return MakeError(StatusCode::kCorrupt, "chunk count ", count, " (byte 24) needs a TOC up to byte ", toc_end,
                     " beyond the file size ", c.file_size);
  }
  if (verify_crc) {
    const uint32_t actual = HeaderCrc(data, toc_end);
    if (actual != c.header_crc) {
      return MakeError(StatusCode::kChecksumMismatch, "header CRC32C (byte 28) is ", c.header_crc,
                       " but header and TOC hash to ", actual);
    }
  }
  if (c.flags != 0)
    return MakeError(StatusCode::kCorrupt, "file flags (byte 12) are ", c.flags, "; all bits are reserved");

  c.entries.resize(count);
  std::set<std::string> seen;
  uint64_t expected_offset = toc_end;
  for (uint32_t i = 0; i < count; ++i) {
    const uint8_t* e = data + kHeaderSize + kTocEntrySize * i;
    const uint64_t at = kHeaderSize + kTocEntrySize * i;
    TocEntry& t = c.entries[i];
    for (int k = 0; k < 4; ++k) {
      if (!ValidTypeChar(e[k])) {
        return MakeError(StatusCode::kCorrupt, "TOC entry #", i, " (byte ", at, ") has type '", PrintableType(e),
                         "'; types are four characters A-Z 0-9");
      }
    }
    t.type.assign(reinterpret_cast<const char*>(e), 4);
    t.flags = LoadLE<uint16_t>(e + kTocFlags);
    t.codec.codec = static_cast<Codec>(e[kTocCodec]);
    t.codec.element_size = e[kTocParam];
    t.offset = LoadLE<uint64_t>(e + kTocOffset);
    t.stored_size = LoadLE<uint64_t>(e + kTocStoredSize);
    t.raw_size = LoadLE<uint64_t>(e + kTocRawSize);
    t.crc = LoadLE<uint32_t>(e + kTocCrc);
    t.codec.components = LoadLE<uint32_t>(e + kTocComponents);
    t.codec.skip = LoadLE<uint32_t>(e + kTocSkip);
    const std::string where = StrCat("TOC entry #", i, " '", t.type, "' (byte ", at, ")");
    if (LoadLE<uint32_t>(e + kTocReserved) != 0)
      return MakeError(StatusCode::kCorrupt, where, ": reserved bytes 44-47 are not zero");
    if ((t.flags & ~kChunkCritical) != 0) {
      return MakeError(StatusCode::kCorrupt, where, ": chunk flags ", t.flags, " use reserved bits");
    }
    if (!seen.insert(t.type).second) return MakeError(StatusCode::kCorrupt, where, ": type appears twice");
    const ChunkId id = FindChunkId(t.type);
    if (id != ChunkId::kCount && t.critical() != TypeInfo(id).critical) {
      return MakeError(StatusCode::kCorrupt, where, ": critical bit is ", t.critical(), ", the format says ",
                       TypeInfo(id).critical);
    }
    if (t.offset != expected_offset) {
      return MakeError(StatusCode::kCorrupt, where, ": chunk offset ", t.offset, ", expected ", expected_offset,
                       " (chunks follow the TOC in order, 8-byte aligned, without gaps)");
    }
    uint64_t end = 0;
    if (AddOverflows(t.offset, t.stored_size, &end) || end > c.file_size) {
      return MakeError(StatusCode::kCorrupt, where, ": chunk of ", t.stored_size, " bytes at ", t.offset,
                       " runs past the end of the file (", c.file_size, ")");
    }
    const uint64_t padded = Align8(end);
    if (padded > c.file_size) {
      return MakeError(StatusCode::kCorrupt, where, ": padding after the chunk runs past the end of the file");
    }
    if (!AllZero(data + end, static_cast<size_t>(padded - end))) {
      return MakeError(StatusCode::kCorrupt, where, ": padding bytes ", end, "..", padded - 1, " are not zero");
    }
    expected_offset = padded;
    if (t.codec.codec == Codec::kRaw && t.stored_size != t.raw_size) {
      return MakeError(StatusCode::kCorrupt, where, ": raw chunk with stored size ", t.stored_size, " != raw size ",
                       t.raw_size);
    }
    if (static_cast<uint8_t>(t.codec.codec) <= static_cast<uint8_t>(Codec::kDraco)) {
      Status s = CheckCodecParams(t.codec, t.raw_size);
      if (!s.ok()) return s.WithContext(where);
      if (t.codec.codec == Codec::kDraco && id != ChunkId::kGpos) {
        return MakeError(StatusCode::kCorrupt, where, ": Draco (codec 4) is allowed for GPOS only");
      }
    }
  }
  if (expected_offset != c.file_size) {
    return MakeError(StatusCode::kCorrupt, "the last chunk ends (padded) at byte ", expected_offset,
                     " but the file size is ", c.file_size, " (trailing bytes)");
  }
  return c;
}

Status VerifyChunkCrc(const uint8_t* file, const TocEntry& entry, size_t index) {
  const uint32_t actual = Crc32c(file + entry.offset, static_cast<size_t>(entry.stored_size));
  if (actual != entry.crc) {
    return MakeError(StatusCode::kChecksumMismatch, ChunkLabel(entry, index), ": stored CRC32C ", entry.crc,
                     " but the ", entry.stored_size, " stored bytes hash to ", actual);
  }
  return Status::Ok();
}

std::vector<uint8_t> AssembleContainer(const std::vector<OutputChunk>& chunks) {
  std::vector<const OutputChunk*> pointers;
  pointers.reserve(chunks.size());
  for (const OutputChunk& chunk : chunks) pointers.push_back(&chunk);
  return AssembleContainer(pointers);
}

uint64_t ContainerSize(const std::vector<const OutputChunk*>& chunks) {
  uint64_t file_size = kHeaderSize + kTocEntrySize * chunks.size();
  for (const OutputChunk* chunk : chunks) file_size = Align8(file_size + chunk->stored.size());
  return file_size;
}

std::vector<uint8_t> AssembleContainer(const std::vector<const OutputChunk*>& chunks) {
  const uint64_t toc_end = kHeaderSize + kTocEntrySize * chunks.size();
  const uint64_t file_size = ContainerSize(chunks);
  // Header and TOC first, zeroed; the chunks are appended after (a large file is not zeroed
  // first and then overwritten).
  std::vector<uint8_t> out;
  out.reserve(static_cast<size_t>(file_size));
  out.resize(static_cast<size_t>(toc_end), 0);
  std::memcpy(out.data(), kMagic.data(), kMagic.size());
  StoreLE<uint16_t>(out.data() + kHeaderMajor, kVersionMajor);
  // The lowest minor version that has every chunk type used (format_spec/atex.md §10): GTWN came with 1.1.
  const bool uses_1_1 =
      std::any_of(chunks.begin(), chunks.end(), [](const OutputChunk* c) { return c->type == "GTWN"; });
  StoreLE<uint16_t>(out.data() + kHeaderMinor, uint16_t(uses_1_1 ? 1 : 0));
  StoreLE<uint32_t>(out.data() + kHeaderFlags, 0);
  StoreLE<uint64_t>(out.data() + kHeaderFileSize, file_size);
  StoreLE<uint32_t>(out.data() + kHeaderChunkCount, static_cast<uint32_t>(chunks.size()));
  uint64_t offset = toc_end;
  for (size_t i = 0; i < chunks.size(); ++i) {
    const OutputChunk& chunk = *chunks[i];
    uint8_t* e = out.data() + kHeaderSize + kTocEntrySize * i;
    std::memcpy(e + kTocType, chunk.type.data(), 4);
    StoreLE<uint16_t>(e + kTocFlags, chunk.flags);
    e[kTocCodec] = static_cast<uint8_t>(chunk.codec.codec);
    e[kTocParam] = chunk.codec.element_size;
    StoreLE<uint64_t>(e + kTocOffset, offset);
    StoreLE<uint64_t>(e + kTocStoredSize, chunk.stored.size());
    StoreLE<uint64_t>(e + kTocRawSize, chunk.raw_size);
    StoreLE<uint32_t>(e + kTocCrc, chunk.crc ? *chunk.crc : Crc32c(chunk.stored.data(), chunk.stored.size()));
    StoreLE<uint32_t>(e + kTocComponents, chunk.codec.components);
    StoreLE<uint32_t>(e + kTocSkip, chunk.codec.skip);
    offset = Align8(offset + chunk.stored.size());
  }
  for (const OutputChunk* chunk : chunks) {
    out.insert(out.end(), chunk->stored.begin(), chunk->stored.end());
    out.resize(static_cast<size_t>(Align8(out.size())), 0);
  }
  StoreLE<uint32_t>(out.data() + kHeaderCrc, HeaderCrc(out.data(), toc_end));
  return out;
}

}  // namespace atex::container
