// The file header and the table of contents (format_spec/atex.md §2-4): parsing
// with every structural check, and assembling a file from encoded chunks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "atex/status.h"
#include "container/codecs.h"

namespace atex::container {

struct TocEntry {
  std::string type;  // four characters
  uint16_t flags = 0;
  CodecParams codec;
  uint64_t offset = 0;
  uint64_t stored_size = 0;
  uint64_t raw_size = 0;
  uint32_t crc = 0;
  bool critical() const { return (flags & 1u) != 0; }
};

struct ParsedContainer {
  uint16_t version_major = 0, version_minor = 0;
  uint32_t flags = 0;
  uint64_t file_size = 0;
  uint32_t header_crc = 0;
  std::vector<TocEntry> entries;
};

// Checks magic, version, size, header CRC (when verify_crc), reserved fields,
// canonical layout, zero padding, duplicate types, the critical bit of known
// types and the codec parameters of known codecs. Does not look at chunk
// payloads and does not refuse unknown chunk types (the caller decides).
StatusOr<ParsedContainer> ParseContainer(const uint8_t* data, size_t size, bool verify_crc);

// "chunk 'GPOS' (#2) at byte 1184"
std::string ChunkLabel(const TocEntry& entry, size_t index);

// Verifies the stored bytes' CRC32C (kChecksumMismatch naming the chunk).
Status VerifyChunkCrc(const uint8_t* file, const TocEntry& entry, size_t index);

// A chunk ready to be placed in a file.
struct OutputChunk {
  std::string type;
  uint16_t flags = 0;
  CodecParams codec;
  uint64_t raw_size = 0;
  std::vector<uint8_t> stored;
  // CRC32C of `stored` when the encoder knows it already (its cache keeps each chunk's); else
  // AssembleContainer computes it.
  std::optional<uint32_t> crc;
};

// The size of AssembleContainer(chunks)'s file: header, TOC and each chunk padded to 8 bytes.
uint64_t ContainerSize(const std::vector<const OutputChunk*>& chunks);

// Lays out header, TOC and chunks canonically and fills in every CRC.
std::vector<uint8_t> AssembleContainer(const std::vector<OutputChunk>& chunks);
std::vector<uint8_t> AssembleContainer(const std::vector<const OutputChunk*>& chunks);

}  // namespace atex::container
