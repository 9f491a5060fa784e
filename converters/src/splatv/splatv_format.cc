// The .splatv container and its per-Gaussian texture words (splatv.h has the layout),
// read and evaluated with the rules of splaTV's hybrid.js.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "atex/converters/splatv.h"
#include "splatv/half.h"
#include "splatv/splatv_format.h"

namespace atex {
namespace splatv {

void PackGaussian(const PackedGaussian& g, uint32_t* w) {
  for (int k = 0; k < 3; ++k) w[k] = std::bit_cast<uint32_t>(g.position[k]);
  w[3] = PackHalf2(g.rotation[0], g.rotation[1]);  // (w, x)
  w[4] = PackHalf2(g.rotation[2], g.rotation[3]);  // (y, z)
  w[5] = PackHalf2(g.scale[0], g.scale[1]);
  w[6] = PackHalf2(g.scale[2], 0.0f);
  w[7] = uint32_t(g.rgba[0]) | uint32_t(g.rgba[1]) << 8 | uint32_t(g.rgba[2]) << 16 | uint32_t(g.rgba[3]) << 24;
  const float* m = g.motion;  // d1.xyz, d2.xyz, d3.xyz
  w[8] = PackHalf2(m[0], m[1]);
  w[9] = PackHalf2(m[2], m[3]);
  w[10] = PackHalf2(m[4], m[5]);
  w[11] = PackHalf2(m[6], m[7]);
  w[12] = PackHalf2(m[8], 0.0f);
  w[13] = PackHalf2(g.omega[0], g.omega[1]);
  w[14] = PackHalf2(g.omega[2], g.omega[3]);
  w[15] = PackHalf2(g.trbf_center, g.trbf_scale);
}

std::vector<uint8_t> AssembleFile(const nlohmann::json& chunks, const std::vector<uint32_t>& words) {
  const std::string text = chunks.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::vector<uint8_t> out(8 + text.size() + words.size() * 4);
  const uint32_t header[2] = {kSplatvMagic, uint32_t(text.size())};
  for (int i = 0; i < 2; ++i) {
    for (int b = 0; b < 4; ++b) out[size_t(i * 4 + b)] = uint8_t(header[i] >> (8 * b));
  }
  std::memcpy(out.data() + 8, text.data(), text.size());
  uint8_t* p = out.data() + 8 + text.size();
  for (uint32_t v : words) {
    for (int b = 0; b < 4; ++b) *p++ = uint8_t(v >> (8 * b));
  }
  return out;
}

}  // namespace splatv

StatusOr<SplatvFile> DecodeSplatv(const uint8_t* data, size_t size) {
  auto u32 = [&](size_t at) {
    return uint32_t(data[at]) | uint32_t(data[at + 1]) << 8 | uint32_t(data[at + 2]) << 16 |
           uint32_t(data[at + 3]) << 24;
  };
  if (size < 8) return MakeError(StatusCode::kTruncated, "splatv header needs 8 bytes, the file has ", size);
  if (u32(0) != splatv::kSplatvMagic) return MakeError(StatusCode::kBadMagic, "not a splatv file (magic ", u32(0), ")");
  const uint64_t json_length = u32(4);
  if (json_length > size - 8)
    return MakeError(StatusCode::kTruncated, "splatv chunk list of ", json_length, " bytes exceeds the file");
  SplatvFile file;
  file.chunks = nlohmann::json::parse(data + 8, data + 8 + json_length, nullptr, false);
  if (file.chunks.is_discarded() || !file.chunks.is_array()) {
    return MakeError(StatusCode::kCorrupt, "splatv chunk list at byte 8 is not a JSON array");
  }
  uint64_t offset = 8 + json_length;
  bool found = false;
  uint64_t splat_offset = 0, splat_size = 0;
  for (size_t i = 0; i < file.chunks.size(); ++i) {
    const auto& c = file.chunks[i];
    if (!c.is_object() || !c.contains("type") || !c["type"].is_string() || !c.contains("size") ||
        !c["size"].is_number_unsigned()) {
      return MakeError(StatusCode::kCorrupt, "splatv chunk ", i, " lacks a string 'type' and an unsigned 'size'");
    }
    const uint64_t chunk_size = c["size"].get<uint64_t>();
    if (chunk_size > size - offset) {
      return MakeError(StatusCode::kTruncated, "splatv chunk ", i, " at byte ", offset, " needs ", chunk_size,
                       " bytes; ", size - offset, " remain");
    }
    if (!found && c["type"] == "splat") {
      found = true;
      file.splat_chunk = i;
      splat_offset = offset;
      splat_size = chunk_size;
      if (!c.contains("texwidth") || !c["texwidth"].is_number_unsigned() || !c.contains("texheight") ||
          !c["texheight"].is_number_unsigned()) {
        return MakeError(StatusCode::kCorrupt, "splatv splat chunk ", i, " lacks texwidth/texheight");
      }
      const uint64_t w = c["texwidth"].get<uint64_t>(), h = c["texheight"].get<uint64_t>();
      // The viewer addresses texel (index & 1023) * 4 + k of row index >> 10: 4096 texels wide.
      if (w != 4096 || h == 0 || h > (uint64_t{1} << 20) || w * h * 16 != chunk_size) {
        return MakeError(StatusCode::kCorrupt, "splatv splat chunk ", i, ": ", w, "x", h, " texels do not match its ",
                         chunk_size, " bytes (width must be 4096)");
      }
      file.texwidth = int(w);
      file.texheight = int(h);
    }
    offset += chunk_size;
  }
  if (!found) return MakeError(StatusCode::kCorrupt, "splatv file has no 'splat' chunk");
  file.count = size_t(splat_size / 64);
  file.words.resize(file.count * 16);
  for (size_t i = 0; i < file.words.size(); ++i) file.words[i] = u32(size_t(splat_offset) + 4 * i);
  return file;
}

SplatvSample EvaluateSplatv(const SplatvFile& file, size_t index, double u) {
  using splatv::UnpackHalfHigh;
  using splatv::UnpackHalfLow;
  const uint32_t* w = &file.words[index * 16];
  SplatvSample s;
  // float arithmetic, as in the viewer's vertex shader.
  const float time = float(u);
  const float center = UnpackHalfLow(w[15]), width = UnpackHalfHigh(w[15]);
  const float dt = time - center;
  const float ratio = dt / width;
  const float topacity = std::exp(-1.0f * (ratio * ratio));
  const float m[9] = {UnpackHalfLow(w[8]),  UnpackHalfHigh(w[8]),  UnpackHalfLow(w[9]),
                      UnpackHalfHigh(w[9]), UnpackHalfLow(w[10]),  UnpackHalfHigh(w[10]),
                      UnpackHalfLow(w[11]), UnpackHalfHigh(w[11]), UnpackHalfLow(w[12])};
  for (int k = 0; k < 3; ++k) {
    s.position[size_t(k)] = std::bit_cast<float>(w[k]) + (m[k] * dt + m[3 + k] * dt * dt + m[6 + k] * dt * dt * dt);
  }
  float rot[4] = {UnpackHalfLow(w[3]), UnpackHalfHigh(w[3]), UnpackHalfLow(w[4]), UnpackHalfHigh(w[4])};
  const float omega[4] = {UnpackHalfLow(w[13]), UnpackHalfHigh(w[13]), UnpackHalfLow(w[14]), UnpackHalfHigh(w[14])};
  float len2 = 0;
  for (int k = 0; k < 4; ++k) {
    rot[k] += omega[k] * dt;
    len2 += rot[k] * rot[k];
  }
  const float inv = 1.0f / std::sqrt(len2);
  for (int k = 0; k < 4; ++k) s.rotation[size_t(k)] = rot[k] * inv;
  s.scale = {UnpackHalfLow(w[5]), UnpackHalfHigh(w[5]), UnpackHalfLow(w[6])};
  for (int k = 0; k < 4; ++k) s.rgba[size_t(k)] = uint8_t(w[7] >> (8 * k));
  // The viewer returns early (draws nothing) below 0.02; NaN compares false and is drawn.
  s.opacity = topacity < 0.02f ? 0.0f : topacity * float(s.rgba[3]) / 255.0f;
  return s;
}

}  // namespace atex
