// Internal to the `atex view` writer: the compression of the payload's arrays, which the
// page undoes with the browser's DecompressionStream ("deflate").
//
// Encoding "delta-planes-deflate" of an array of F frames x E elements of 1 or 2 bytes:
//   1. delta over frames: element k of frame f > 0 becomes (v[f][k] - v[f-1][k]) modulo
//      2^(8 x element size) (smooth motion leaves small numbers);
//   2. byte planes: for 2-byte elements, every low byte (little-endian), then every high byte;
//   3. zlib's deflate (RFC 1950 stream).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/status.h"

namespace atex::view {

inline constexpr const char* kCompressedEncoding = "delta-planes-deflate";

// `data` holds frames x elements values of element_size (1 or 2) bytes, little-endian.
StatusOr<std::vector<uint8_t>> CompressArray(const uint8_t* data, size_t element_size, size_t elements, size_t frames);

// The inverse; `expected_bytes` is the size of the decompressed array (kCorrupt otherwise).
StatusOr<std::vector<uint8_t>> DecompressArray(const std::vector<uint8_t>& compressed, size_t element_size,
                                               size_t elements, size_t frames, size_t expected_bytes);

}  // namespace atex::view
