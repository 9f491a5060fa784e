// SPZ file framing: the gzip single stream of versions 1-3 and the NGSP
// header + table of contents + zstd streams of version 4. Internal.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/converters/spz.h"
#include "atex/status.h"
#include "spz/spz_packed.h"

namespace atex::converters::spz {

struct ParsedSpz {
  PackedSpz packed;
  uint32_t coordinate_system = 4;  // SPZ_ADOBE_coordinate_system value; 4 = RUB, the spec's default
  int extension_records = 0;
};

// Splits a file into its quantised arrays (any version 1..4), checking every
// size against the header before use.
StatusOr<ParsedSpz> ParseSpzContainer(const uint8_t* data, size_t size, const SpzReadOptions& options);

// Frames packed arrays as version packed.version (3: gzip, 4: zstd streams).
StatusOr<std::vector<uint8_t>> SerializeSpz(const PackedSpz& packed, const SpzWriteOptions& options);

}  // namespace atex::converters::spz
