// EXT_meshopt_compression's attribute codec and filters, through Debian's
// libmeshoptimizer (ATEX_HAVE_MESHOPT). Without it every function returns
// kUnsupported. Internal header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex::gltf {

// Post-decompression filters of the extension ("filter" in the bufferView extension).
enum class MeshoptFilter : uint8_t { kNone, kQuaternion, kExponential };

const char* MeshoptFilterName(MeshoptFilter filter);
// Parses "NONE" / "QUATERNION" / "EXPONENTIAL" (and "OCTAHEDRAL", which we reject with
// kUnsupported because our files never use it).
StatusOr<MeshoptFilter> ParseMeshoptFilter(const std::string& name);

bool MeshoptAvailable();

// EXPONENTIAL filter input: `data` [count][components] floats -> [count][components] int32
// words (bytes), `bits` of mantissa (1..24).
StatusOr<std::vector<uint8_t>> EncodeExponential(const float* data, size_t count, size_t components, int bits);
// QUATERNION filter input: `xyzw` [count][4] unit quaternions -> [count][4] int16 (bytes),
// `bits` 4..16.
StatusOr<std::vector<uint8_t>> EncodeQuaternion(const float* xyzw, size_t count, int bits);
// Applies the decoder side of `filter` in place to `bytes` [count][stride].
Status DecodeFilter(MeshoptFilter filter, uint8_t* bytes, size_t count, size_t stride);

// Mode ATTRIBUTES bitstream (version 0) of `bytes` [count][stride]; stride % 4 == 0, <= 256.
StatusOr<std::vector<uint8_t>> CompressAttributes(const uint8_t* bytes, size_t count, size_t stride);
// Decodes a mode ATTRIBUTES bitstream into `out` [count][stride]. kCorrupt if the stream is
// malformed or has the wrong length.
Status DecompressAttributes(const uint8_t* stream, size_t stream_size, size_t count, size_t stride, uint8_t* out);

}  // namespace atex::gltf
