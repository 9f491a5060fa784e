// Niantic SPZ files (github.com/nianticlabs/spz): compressed static 3D Gaussian splats.
//
// Versions read: 1, 2, 3 (a gzip stream holding a 16-byte header and the packed
// attributes) and 4 (a 32-byte plaintext "NGSP" header, optional extension
// records, a table of contents and one zstd stream per attribute).
// Versions written: 3 and 4.
//
// Quantisation (what SPZ stores, per Gaussian; the encoder rounds to nearest):
//   position  3 x 24-bit signed fixed point with `fractional_bits` fraction bits (v1: 3 halves)
//   scale     3 x u8 = (ln s + 10) * 16                  -> ln s = u8 / 16 - 10 (step 1/16)
//   rotation  v3+: smallest three of the unit quaternion: 2-bit index of the largest
//             component + 3 x (sign + 9-bit magnitude / sqrt(1/2)); v1/v2: x, y, z as
//             u8 = 127.5 q + 127.5 with w >= 0 recovered from the unit norm
//   alpha     u8 = sigmoid(logit) * 255; decoded as logit(clamp(u8/255, 1/255, 254/255))
//   colour    3 x u8 = f_dc * 0.15 * 255 + 127.5             (the SH DC coefficient, "wide" RGB)
//   SH rest   int8 stored as u8 = round(128 x) + 128, rounded to 5 bits for degree 1 and
//             4 bits for degrees 2+ (sh1_bits / sh_rest_bits); decoded as (u8 - 128) / 128
// Values outside a field's range are clamped by the format (scales to ln s in
// [-10, 5.94], SH to [-1, 127/128], colours to f_dc in [-3.33, 3.33]).
//
// Coordinate axes. The SPZ specification stores data in RUB (x right, y up,
// z back: OpenGL / three.js). libatex's world is the OpenCV-style RDF of 3DGS
// PLY files (x right, y down, z forward). With SpzAxes::kOpenCv (the default)
// the reader converts RUB -> RDF and the writer RDF -> RUB, i.e. y and z of
// positions flip, the quaternion becomes (w, x, -y, -z) and the SH coefficients
// odd in y xor z change sign; so PLY -> SPZ -> PLY keeps the orientation and
// files open upright in SPZ viewers. SpzAxes::kStored copies the stored axes
// unchanged. A v4 file that names another axis convention with the
// SPZ_ADOBE_coordinate_system extension (0xADBE0003) is converted from that
// convention (the 8 axis-flip systems; the 8 rotated ones are refused).
//
// SH degree 4 (allowed by SPZ) is truncated to degree 3, the highest libatex
// stores; SpzInfo says when that happened.
//
// Bad input never crashes: wrong magic, versions, truncated or corrupt
// gzip/zstd streams, streams whose sizes disagree with the header, counts that
// the file cannot hold, reserved bits set and decoded sizes above the caller's
// cap all give an error naming the field, stream or byte offset. Memory grows
// only with bytes actually decompressed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/model.h"
#include "atex/file_io.h"
#include "atex/status.h"

namespace atex {

enum class SpzAxes : uint8_t {
  kOpenCv = 0,  // convert between the file's axes (RUB) and libatex's RDF world
  kStored = 1,  // no conversion: Gaussians hold what the file stores
};

struct SpzReadOptions {
  SpzAxes axes = SpzAxes::kOpenCv;
  uint64_t max_points = uint64_t{1} << 28;             // refuse files announcing more Gaussians
  uint64_t max_decompressed_bytes = MemoryLimit(uint64_t{16} << 30);  // refuse files that inflate to more (<= RAM / 2)
};

struct SpzWriteOptions {
  int version = 4;          // 3 (gzip) or 4 (zstd streams)
  SpzAxes axes = SpzAxes::kOpenCv;
  int fractional_bits = 12;  // position fixed point: step 2^-12 (0.24 mm for metres), range +-2048
  // If a position does not fit 24 bits with `fractional_bits`, use the largest
  // smaller value that fits (else fail with kOutOfRange naming the Gaussian).
  bool reduce_fractional_bits_to_fit = true;
  int sh1_bits = 5;         // 1..8 bits kept for degree-1 SH
  int sh_rest_bits = 4;     // 1..8 bits kept for degree-2 and 3 SH
  int zstd_level = 12;      // v4 streams (the reference encoder's level)
  int zlib_level = 6;       // v3 gzip stream, 1..9
  bool antialiased = false;    // header flag 0x1 (trained with Mip-Splatting's filter)
};

// What a file's header says (filled by the readers when `info` is not null).
struct SpzInfo {
  int version = 0;
  uint64_t num_points = 0;
  int sh_degree = 0;           // as stored (may be 4)
  int fractional_bits = 0;
  bool antialiased = false;
  int extension_records = 0;   // v4 extension records in the header zone
  std::string stored_axes = "RUB";  // the convention the data was stored in
  bool sh_truncated = false;   // degree 4 was cut to degree 3
};

// Decodes an SPZ file held in memory.
StatusOr<Gaussians> DecodeSpz(const uint8_t* data, size_t size, const SpzReadOptions& options = {},
                              SpzInfo* info = nullptr);
// Reads an SPZ file.
StatusOr<Gaussians> ReadSpzGaussians(const std::string& path, const SpzReadOptions& options = {},
                                     SpzInfo* info = nullptr);

// Encodes Gaussians as SPZ. kInvalidArgument for inconsistent arrays or options,
// kOutOfRange for NaN/Inf, a zero quaternion or a position beyond 24 bits.
StatusOr<std::vector<uint8_t>> EncodeSpz(const Gaussians& g, const SpzWriteOptions& options = {});
// Encodes and writes atomically (temporary file + rename).
Status WriteSpzGaussians(const std::string& path, const Gaussians& g, const SpzWriteOptions& options = {});

}  // namespace atex
