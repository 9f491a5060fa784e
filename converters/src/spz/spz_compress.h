// gzip (v1-3) and zstd (v4) codecs for SPZ with output caps. Internal.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "atex/status.h"

namespace atex::converters::spz {

// gzip-wraps `size` bytes (zlib level 1..9).
StatusOr<std::vector<uint8_t>> GzipCompress(const uint8_t* data, size_t size, int level);

// Inflates one gzip member. The output grows with the bytes actually produced
// and may not exceed `max_output` (kLimitExceeded). Trailing bytes after the
// member, a truncated or corrupt stream give kCorrupt/kTruncated.
StatusOr<std::vector<uint8_t>> GzipDecompress(const uint8_t* data, size_t size, uint64_t max_output);

// One zstd frame of `size` bytes.
StatusOr<std::vector<uint8_t>> ZstdCompress(const uint8_t* data, size_t size, int level);

// Decompresses zstd frames that must produce exactly `expected` bytes; more or
// fewer is kCorrupt, naming `what`. The output grows with the bytes actually
// produced, so a forged `expected` costs no memory.
StatusOr<std::vector<uint8_t>> ZstdDecompressExact(const uint8_t* data, size_t size, uint64_t expected,
                                                   std::string_view what);

}  // namespace atex::converters::spz
