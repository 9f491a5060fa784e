// Writing Gaussians as an INRIA 3DGS binary little-endian PLY.
#include <cstring>
#include <string>

#include "atex/converters/ply.h"
#include "atex/file_io.h"
#include "convert/bytes.h"
#include "convert/gaussian_checks.h"

namespace atex {

StatusOr<std::vector<uint8_t>> EncodePlyGaussians(const Gaussians& g) {
  ATEX_RETURN_IF_ERROR(converters::CheckGaussianShapes(g, "PLY writer"));
  // The reader refuses NaN/Inf, so the writer does not produce them either.
  ATEX_RETURN_IF_ERROR(converters::CheckGaussiansFinite(g, "PLY writer"));
  const size_t n = g.size();
  const int k_count = g.sh_coeffs();
  const int rest = 3 * (k_count - 1);  // f_rest properties

  std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) + "\n";
  for (const char* name : {"x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"}) {
    header += std::string("property float ") + name + "\n";
  }
  for (int j = 0; j < rest; ++j) header += "property float f_rest_" + std::to_string(j) + "\n";
  for (const char* name : {"opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"}) {
    header += std::string("property float ") + name + "\n";
  }
  header += "end_header\n";

  const size_t floats_per_row = 17 + static_cast<size_t>(rest);
  std::vector<uint8_t> out(header.size() + n * floats_per_row * sizeof(float));
  std::memcpy(out.data(), header.data(), header.size());
  uint8_t* p = out.data() + header.size();
  auto put = [&p](float value) {
    converters::bytes::StoreLE(p, value);
    p += sizeof(float);
  };
  for (size_t i = 0; i < n; ++i) {
    const float* sh = g.sh.data() + i * static_cast<size_t>(k_count) * 3;  // [K][3]
    for (int k = 0; k < 3; ++k) put(g.positions[i * 3 + k]);
    for (int k = 0; k < 3; ++k) put(0.0f);  // normals: unused by 3DGS, present for compatibility
    for (int c = 0; c < 3; ++c) put(sh[c]);
    for (int c = 0; c < 3; ++c) {  // channel-major in the file
      for (int k = 1; k < k_count; ++k) put(sh[k * 3 + c]);
    }
    put(g.opacity_logits[i]);
    for (int k = 0; k < 3; ++k) put(g.log_scales[i * 3 + k]);
    for (int k = 0; k < 4; ++k) put(g.rotations[i * 4 + k]);  // rot_0 = w
  }
  return out;
}

Status WritePlyGaussians(const std::string& path, const Gaussians& g) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodePlyGaussians(g));
  return WriteFileAtomic(path, bytes).WithContext(path);
}

}  // namespace atex
