// INRIA 3D Gaussian Splatting PLY files (the `point_cloud.ply` of 3DGS,
// 4DGaussians and most splat tools).
//
// Layout written: binary little-endian, one `vertex` element with float
// properties in this order:
//   x y z  nx ny nz  f_dc_0..2  f_rest_0..(3(K-1)-1)  opacity  scale_0..2  rot_0..3
// Meaning of each property in our model (atex/model.h):
//   x y z       -> positions[i]               (world units, as stored)
//   nx ny nz    -> ignored on read, written as 0
//   f_dc_c      -> sh[i][0][c]                (DC coefficient of channel c)
//   f_rest_j    -> sh[i][1 + j % (K-1)][j / (K-1)]: the file is channel-major (all R
//                  coefficients, then G, then B) while sh is [N][K][3]
//   opacity     -> opacity_logits[i]          (logit, before the sigmoid)
//   scale_k     -> log_scales[i][k]           (natural log)
//   rot_0..3    -> rotations[i] = (w, x, y, z) (rot_0 is w), unnormalised
// The SH degree follows from the number of f_rest properties (0, 9, 24 or 45).
//
// Reading accepts binary little-endian, binary big-endian and ASCII files, any
// property order, any scalar property type (converted to float), extra
// properties and extra elements (ignored). float32 properties are copied bit
// for bit, so PLY -> Gaussians -> PLY -> Gaussians is exact.
//
// Bad input never crashes: truncation, absurd counts (compared with the bytes
// present before anything is allocated), a missing required property, a
// duplicate property, an f_rest count that is not 0/9/24/45 and NaN/Inf in a
// used property all return an error naming the header line, vertex index or
// byte offset.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

// Reads a 3DGS PLY file. Errors: kNotFound/kIoError (file), kBadMagic (not a
// PLY), kCorrupt (bad header, missing/duplicate property), kTruncated,
// kLimitExceeded (counts larger than the data), kOutOfRange (NaN/Inf),
// kUnsupported (a format other than ascii/binary 1.0).
StatusOr<Gaussians> ReadPlyGaussians(const std::string& path);

// Same, from bytes already in memory.
StatusOr<Gaussians> ReadPlyGaussiansFromMemory(const uint8_t* data, size_t size);

// Writes the INRIA layout above atomically (temporary file + rename).
// kInvalidArgument if the arrays of `g` disagree with its size.
Status WritePlyGaussians(const std::string& path, const Gaussians& g);

// The bytes WritePlyGaussians writes.
StatusOr<std::vector<uint8_t>> EncodePlyGaussians(const Gaussians& g);

}  // namespace atex
