// Writing side of the .splatv layout (splatv.h documents it). Internal header.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

namespace atex::splatv {

inline constexpr uint32_t kSplatvMagic = 0x674b;
inline constexpr int kTextureWidth = 4096;     // texels per row
inline constexpr int kGaussiansPerRow = 1024;  // 4 texels each

// One Gaussian in the viewer's terms, before half-precision packing.
struct PackedGaussian {
  float position[3];
  float rotation[4];  // (w, x, y, z), not necessarily unit
  float scale[3];     // linear
  uint8_t rgba[4];
  float motion[9];    // d1.xyz, d2.xyz, d3.xyz
  float omega[4];     // (w, x, y, z)
  float trbf_center;
  float trbf_scale;
};

// The 16 words of one Gaussian.
void PackGaussian(const PackedGaussian& g, uint32_t* words);

// Magic, JSON length, JSON, then the words (little-endian).
std::vector<uint8_t> AssembleFile(const nlohmann::json& chunks, const std::vector<uint32_t>& words);

}  // namespace atex::splatv
