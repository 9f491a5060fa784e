// Codec 4: Draco point-cloud coding of positions (format_spec/atex.md §5).
// Available only when libatex is built with Draco (ATEX_HAVE_DRACO); otherwise
// both functions return kUnsupportedCodec.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/status.h"

namespace atex::container {

bool HaveDraco();

// Encodes n points xyz ([n][3], finite) with `bits` quantisation bits (1..30),
// sequential method (keeps point order). Returns the Draco bitstream.
StatusOr<std::vector<uint8_t>> DracoEncodePositions(const float* xyz, size_t n, int bits);

// Decodes a Draco bitstream that must hold exactly `expected_points` points with
// one 3-component POSITION attribute; appends them to *out as little-endian f32
// ([expected_points][3] * 4 bytes). The point count is checked against the
// bitstream header before Draco allocates anything.
Status DracoDecodePositions(const uint8_t* data, size_t size, uint64_t expected_points, std::vector<uint8_t>* out);

}  // namespace atex::container
