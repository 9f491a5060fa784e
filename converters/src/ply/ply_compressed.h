// PlayCanvas compressed PLY (`.compressed.ply`, written by SuperSplat and
// splat-transform). Internal to converters/src/ply; reached through
// ReadPlyGaussians, which recognises the layout by its `packed_position` property.
//
// Layout (binary little-endian): element `chunk` (ceil(N/256) rows of float
// bounds: min_x..max_z, min_scale_x..max_scale_z, optionally min_r..max_b),
// element `vertex` (N rows of four uint32: packed_position 11/10/11 bits,
// packed_rotation 2-bit largest index + 3 x 10-bit smallest three, packed_scale
// 11/10/11 bits of log-scale, packed_color RGBA8), optionally element `sh`
// (N rows of uint8 f_rest_*, channel-major as in INRIA PLY). Gaussian i uses the
// bounds of chunk i / 256; each field is lerped between its chunk's min and max.
#pragma once

#include <cstddef>
#include <cstdint>

#include "atex/model.h"
#include "atex/status.h"
#include "ply/ply_header.h"

namespace atex::converters::ply {

// True when the header has the compressed layout (a `vertex` property named
// packed_position).
bool IsCompressedPly(const Header& header);

// Decodes the compressed layout. Errors (kCorrupt, kTruncated, kUnsupported,
// kLimitExceeded) name the element, property, row or byte offset.
StatusOr<Gaussians> ReadCompressedPly(const uint8_t* data, size_t size, const Header& header);

}  // namespace atex::converters::ply
