// numpy .npy arrays and .npz archives (zip of .npy members).
//
// Reader: .npy format versions 1.0, 2.0 and 3.0; plain numeric dtypes
// (b1, i1, u1, i2, u2, i4, u4, i8, u8, f2, f4, f8) in little- or big-endian
// byte order (converted to little-endian on load); C order only. Refused:
// Fortran order (kUnsupported), object/structured/string dtypes (which numpy
// stores as pickles: kUnsupported), and a data size that does not match the
// shape (kTruncated / kCorrupt). The header is parsed as the restricted Python
// literal numpy writes, never evaluated. Sizes are checked against the bytes
// present before anything is allocated.
//
// .npz: stored or deflated members (np.savez / np.savez_compressed), through
// atex/zip.h. Member names lose their ".npy" suffix ("images.npy" -> "images").
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "atex/status.h"
#include "atex/zip.h"

namespace atex {

enum class NpyDtype : uint8_t {
  kBool, kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kInt64, kUint64, kFloat16, kFloat32, kFloat64
};

// Bytes per element of a dtype.
size_t NpyDtypeSize(NpyDtype dtype);
// numpy's little-endian descr string, e.g. "<f4", "|u1".
const char* NpyDtypeDescr(NpyDtype dtype);

struct NpyArray {
  NpyDtype dtype = NpyDtype::kFloat32;
  std::vector<int64_t> shape;  // empty = a 0-d scalar (one element)
  std::vector<uint8_t> data;   // [element_count()][NpyDtypeSize(dtype)] little-endian, C order

  uint64_t element_count() const;
  // Every element converted to double (bool -> 0/1, float16 decoded exactly).
  std::vector<double> ToDouble() const;
  // Every element converted to float (through double).
  std::vector<float> ToFloat() const;
  // The single element of a one-element array (scalar) as double; kInvalidArgument otherwise.
  StatusOr<double> Scalar(const std::string& what) const;

  static NpyArray FromFloats(std::vector<int64_t> shape, const std::vector<float>& values);
  static NpyArray FromDoubles(std::vector<int64_t> shape, const std::vector<double>& values);
};

// Parses one .npy byte string; `what` names it in errors (file or member).
StatusOr<NpyArray> DecodeNpy(const uint8_t* data, size_t size, const std::string& what);
StatusOr<NpyArray> ReadNpyFile(const std::string& path);

// Serialises as .npy format 1.0 (2.0 when the header needs it), as np.save does.
std::vector<uint8_t> EncodeNpy(const NpyArray& array);
Status WriteNpyFile(const std::string& path, const NpyArray& array);  // atomic

// All members of an .npz archive, keyed by name without ".npy". Members whose
// names do not end in ".npy" are refused (kCorrupt).
StatusOr<std::map<std::string, NpyArray>> DecodeNpz(const uint8_t* data, size_t size, const std::string& what,
                                                    const ZipLimits& limits = {});
StatusOr<std::map<std::string, NpyArray>> ReadNpzFile(const std::string& path, const ZipLimits& limits = {});

// Writes an .npz archive (members "<name>.npy", deflated when `compress`); atomic.
std::vector<uint8_t> EncodeNpz(const std::map<std::string, NpyArray>& arrays, bool compress);
Status WriteNpzFile(const std::string& path, const std::map<std::string, NpyArray>& arrays, bool compress);

}  // namespace atex
