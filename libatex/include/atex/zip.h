// A small, hostile-input-safe reader of zip archives (PKWARE APPNOTE): what
// .npz files (numpy) and PyTorch checkpoints (.pth) are made of.
//
// Supported: stored (method 0) and deflate (method 8, through zlib) members,
// ZIP64 sizes and offsets, data descriptors (the central directory is
// authoritative). Not supported: encryption, multi-disk archives, other
// compression methods (kUnsupportedCodec when such a member is extracted).
//
// Contract: every offset and size of the end record, the central directory and
// each local header is checked against the bytes present before use; member
// data is checked against its CRC-32 and its declared size; decompression
// grows its output only with bytes actually decoded, so a forged size cannot
// cause a large allocation. Errors name the archive ("what"), the member and
// the byte offset.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "atex/file_io.h"
#include "atex/status.h"

namespace atex {

struct ZipLimits {
  uint64_t max_entries = 1u << 20;                  // central directory records
  uint64_t max_member_bytes = MemoryLimit(uint64_t{16} << 30);  // uncompressed size of one member (<= RAM / 2)
};

struct ZipEntry {
  std::string name;              // as stored (forward slashes), not normalised
  uint16_t method = 0;           // 0 stored, 8 deflate, others refused on extraction
  uint16_t flags = 0;            // general-purpose bit flags (bit 0: encrypted)
  uint32_t crc32 = 0;            // CRC-32 (zlib polynomial) of the uncompressed bytes
  uint64_t compressed_size = 0;
  uint64_t uncompressed_size = 0;
  uint64_t local_header_offset = 0;  // from the start of the archive
  uint64_t data_offset = 0;          // first byte of the member's (compressed) data
};

class ZipArchive {
 public:
  // Parses an archive held in memory. FromBytes keeps the bytes; FromView does
  // not copy, and the caller keeps `data` alive as long as the archive and any
  // StoredView() result are used.
  static StatusOr<ZipArchive> FromBytes(std::vector<uint8_t> bytes, const std::string& what,
                                        const ZipLimits& limits = {});
  static StatusOr<ZipArchive> FromView(const uint8_t* data, size_t size, const std::string& what,
                                       const ZipLimits& limits = {});
  // Reads the whole file, then FromBytes.
  static StatusOr<ZipArchive> OpenFile(const std::string& path, const ZipLimits& limits = {});

  const std::vector<ZipEntry>& entries() const { return entries_; }
  // The first entry with exactly this name, or null.
  const ZipEntry* Find(std::string_view name) const;

  // Uncompressed bytes of a member, CRC-checked.
  StatusOr<std::vector<uint8_t>> Extract(const ZipEntry& entry) const;
  StatusOr<std::vector<uint8_t>> Extract(std::string_view name) const;  // kNotFound if absent

  // Zero-copy access to a stored (method 0) member, CRC-checked when `verify_crc`.
  // kUnsupported for compressed members.
  struct View {
    const uint8_t* data = nullptr;  // [size]
    size_t size = 0;
  };
  StatusOr<View> StoredView(const ZipEntry& entry, bool verify_crc = true) const;

  const std::string& what() const { return what_; }

 private:
  ZipArchive() = default;
  Status Parse(const ZipLimits& limits);

  std::shared_ptr<const std::vector<uint8_t>> owned_;  // set by FromBytes
  const uint8_t* data_ = nullptr;                      // [size_]
  size_t size_ = 0;
  std::string what_;
  ZipLimits limits_;
  std::vector<ZipEntry> entries_;
};

// CRC-32 (zlib / zip polynomial) of `size` bytes, continuing from `crc`.
uint32_t ZipCrc32(const uint8_t* data, size_t size, uint32_t crc = 0);

// Builds a zip archive in memory (used for .npz output and by tests). Members
// are stored (method 0) or deflated (method 8) in the order added; ZIP64
// records are written when a size or offset needs them.
class ZipWriter {
 public:
  Status Add(const std::string& name, const uint8_t* data, size_t size, bool deflate);
  // The finished archive (central directory + end record appended).
  std::vector<uint8_t> Finish();

 private:
  struct Record {
    std::string name;
    uint16_t method;
    uint32_t crc;
    uint64_t compressed_size, uncompressed_size, offset;
  };
  std::vector<uint8_t> out_;
  std::vector<Record> records_;
};

}  // namespace atex
