// Attribute streams: the content of every chunk that holds real numbers
// (format_spec/atex.md §6): a 16-byte header, per-component ranges for quantised
// encodings, then [rows][components] values.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/container.h"
#include "atex/status.h"

namespace atex::container {

// Bytes per stored value: 4, 2, 2, 1.
size_t EncodingBytes(ScalarEncoding encoding);
bool IsQuantised(ScalarEncoding encoding);
// 16 + 8 * components for quantised encodings, 16 otherwise.
uint64_t StreamHeaderBytes(ScalarEncoding encoding, uint32_t components);

// Encodes values ([rows][components], finite) as a stream. `what` names the
// attribute in errors (kOutOfRange for a non-finite value or an f16 overflow,
// naming the row).
StatusOr<std::vector<uint8_t>> EncodeStream(const float* values, uint64_t rows, uint32_t components,
                                            ScalarEncoding encoding, const char* what);

// Per-component minimum and maximum (lo[c], hi[c]; both 0 for no rows) of `rows` rows of
// `components` values, row r at values + r * stride: the ranges a quantised stream stores.
// Equal values resolve as in one pass in row order (the first minimum wins, -0 and +0 being
// equal), on several threads for large streams outside a parallel region.
void StreamRange(const float* values, size_t stride, uint64_t rows, uint32_t components, float* lo, float* hi);

// The values DecodeStream gives back for EncodeStream(values, rows, components, encoding),
// bit for bit, computed without building the stream: row r of the input at in + r * in_stride
// (finite values, as ValidateAsset guarantees), written to out + r * out_stride (`out` may be
// `in` with the same stride). kOutOfRange, as EncodeStream's, for a value f16 cannot hold.
// Several threads for large streams outside a parallel region.
Status ReadBackStream(const float* in, size_t in_stride, uint64_t rows, uint32_t components, ScalarEncoding encoding,
                      float* out, size_t out_stride, const char* what);

// What a stream header says, read without decoding the values.
struct StreamInfo {
  ScalarEncoding encoding = ScalarEncoding::kFloat32;
  uint32_t components = 0;
  uint64_t rows = 0;
  uint64_t header_bytes = 0;
};
// Checks the header: known encoding, reserved zero, exact raw size (kCorrupt).
StatusOr<StreamInfo> ParseStreamHeader(const uint8_t* raw, size_t size);

// Decodes a whole stream, checking components and rows against the expected
// ones (kCorrupt), the ranges (kCorrupt) and every value (kOutOfRange naming row
// and component). *values becomes [rows][components].
Status DecodeStream(const uint8_t* raw, size_t size, uint32_t expected_components, uint64_t expected_rows,
                    std::vector<float>* values);

// kOutOfRange naming the first non-finite value of [rows][components].
Status CheckFiniteValues(const float* values, uint64_t rows, uint32_t components);

// The values of a stream whose header `info` came from ParseStreamHeader on the
// same bytes: row r goes to out[r * out_stride .. r * out_stride + components).
// Checks ranges and values as DecodeStream does.
Status DecodeStreamValues(const uint8_t* raw, const StreamInfo& info, float* out, size_t out_stride);

}  // namespace atex::container
