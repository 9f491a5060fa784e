// PlayCanvas compressed PLY decoding (see ply_compressed.h).
#include "ply/ply_compressed.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "convert/bytes.h"

namespace atex::converters::ply {
namespace {

constexpr double kShC0 = 0.28209479177387814;
constexpr uint64_t kChunkSize = 256;

const Element* FindElement(const Header& header, std::string_view name, size_t* index) {
  for (size_t e = 0; e < header.elements.size(); ++e) {
    if (header.elements[e].name == name) {
      *index = e;
      return &header.elements[e];
    }
  }
  return nullptr;
}

// Byte offset of each named property inside a row of `element` (all of type `type`).
StatusOr<std::vector<size_t>> Offsets(const Element& element, const std::vector<std::string>& names, ScalarType type,
                                      bool optional_tail = false, size_t required = 0) {
  std::vector<size_t> offsets(names.size(), SIZE_MAX);
  size_t offset = 0;
  for (const Property& p : element.properties) {
    if (p.is_list) {
      return MakeError(StatusCode::kUnsupported, "compressed PLY element '", element.name, "' property '", p.name,
                       "' is a list");
    }
    for (size_t k = 0; k < names.size(); ++k) {
      if (p.name == names[k]) {
        if (p.type != type) {
          return MakeError(StatusCode::kCorrupt, "compressed PLY element '", element.name, "' property '", p.name,
                           "' has the wrong type (expected ", type == ScalarType::kFloat32 ? "float" : "uint", ")");
        }
        offsets[k] = offset;
      }
    }
    offset += ScalarSize(p.type);
  }
  const size_t must = optional_tail ? required : names.size();
  for (size_t k = 0; k < must; ++k) {
    if (offsets[k] == SIZE_MAX) {
      return MakeError(StatusCode::kCorrupt, "compressed PLY element '", element.name, "' lacks property '", names[k],
                       "'");
    }
  }
  return offsets;
}

double Unorm(uint32_t value, int bits) {
  const uint32_t top = (1u << bits) - 1;
  return double(value & top) / double(top);
}

double Lerp(float a, float b, double t) { return double(a) + (double(b) - double(a)) * t; }

}  // namespace

bool IsCompressedPly(const Header& header) {
  for (const Element& e : header.elements) {
    if (e.name != "vertex") continue;
    for (const Property& p : e.properties) {
      if (p.name == "packed_position") return true;
    }
  }
  return false;
}

StatusOr<Gaussians> ReadCompressedPly(const uint8_t* data, size_t size, const Header& header) {
  using bytes::LoadLE;
  if (header.encoding != Encoding::kBinaryLittleEndian) {
    return MakeError(StatusCode::kUnsupported, "compressed PLY must be binary_little_endian");
  }
  size_t chunk_index = 0, vertex_index = 0, sh_index = 0;
  const Element* chunk = FindElement(header, "chunk", &chunk_index);
  const Element* vertex = FindElement(header, "vertex", &vertex_index);
  const Element* sh = FindElement(header, "sh", &sh_index);
  if (chunk == nullptr) return MakeError(StatusCode::kCorrupt, "compressed PLY has no 'chunk' element");
  const uint64_t n = vertex->count;
  if (chunk->count != (n + kChunkSize - 1) / kChunkSize) {
    return MakeError(StatusCode::kCorrupt, "compressed PLY has ", chunk->count, " chunks for ", n,
                     " vertices (expected ", (n + kChunkSize - 1) / kChunkSize, ", one per 256)");
  }
  if (sh != nullptr && sh->count != n) {
    return MakeError(StatusCode::kCorrupt, "compressed PLY 'sh' element has ", sh->count, " rows for ", n, " vertices");
  }
  const std::vector<std::string> chunk_names = {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                                                "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x",
                                                "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b",
                                                "max_r", "max_g", "max_b"};
  ATEX_ASSIGN_OR_RETURN(std::vector<size_t> chunk_at, Offsets(*chunk, chunk_names, ScalarType::kFloat32, true, 12));
  const bool chunk_colours = chunk_at[12] != SIZE_MAX && chunk_at[13] != SIZE_MAX && chunk_at[14] != SIZE_MAX &&
                             chunk_at[15] != SIZE_MAX && chunk_at[16] != SIZE_MAX && chunk_at[17] != SIZE_MAX;
  ATEX_ASSIGN_OR_RETURN(std::vector<size_t> vertex_at,
                        Offsets(*vertex, {"packed_position", "packed_rotation", "packed_scale", "packed_color"},
                                ScalarType::kUint32));
  int sh_degree = 0;
  size_t rest = 0;
  std::vector<size_t> sh_at;
  if (sh != nullptr) {
    rest = sh->properties.size();
    if (rest == 9) sh_degree = 1;
    else if (rest == 24) sh_degree = 2;
    else if (rest == 45) sh_degree = 3;
    else return MakeError(StatusCode::kCorrupt, "compressed PLY 'sh' element has ", rest, " properties (9, 24 or 45)");
    std::vector<std::string> names;
    for (size_t j = 0; j < rest; ++j) names.push_back("f_rest_" + std::to_string(j));
    ATEX_ASSIGN_OR_RETURN(sh_at, Offsets(*sh, names, ScalarType::kUint8));
  }

  // Element offsets; every element's rows must be inside the file (checked before allocating).
  std::vector<size_t> start(header.elements.size());
  uint64_t offset = header.data_offset;
  for (size_t e = 0; e < header.elements.size(); ++e) {
    const Element& el = header.elements[e];
    const size_t row = el.FixedRowSize();
    if (row == 0 && el.count > 0) {
      return MakeError(StatusCode::kUnsupported, "compressed PLY element '", el.name, "' has list properties");
    }
    start[e] = size_t(offset);
    if (el.count > 0 && (size - std::min<uint64_t>(size, offset)) / row < el.count) {
      return MakeError(StatusCode::kTruncated, "compressed PLY element '", el.name, "' announces ", el.count,
                       " rows of ", row, " bytes at byte ", offset, " but the file has ", size, " bytes");
    }
    offset += el.count * row;
  }

  Gaussians g;
  g.sh_degree = sh_degree;
  g.Resize(size_t(n));
  const int k_count = g.sh_coeffs();
  const size_t chunk_row = chunk->FixedRowSize(), vertex_row = vertex->FixedRowSize();
  const size_t sh_row = sh ? sh->FixedRowSize() : 0;
  for (uint64_t i = 0; i < n; ++i) {
    const uint8_t* c = data + start[chunk_index] + (i / kChunkSize) * chunk_row;
    auto bound = [&](int k) { return LoadLE<float>(c + chunk_at[size_t(k)]); };
    const uint8_t* v = data + start[vertex_index] + i * vertex_row;
    const uint32_t pp = LoadLE<uint32_t>(v + vertex_at[0]);
    const uint32_t pr = LoadLE<uint32_t>(v + vertex_at[1]);
    const uint32_t ps = LoadLE<uint32_t>(v + vertex_at[2]);
    const uint32_t pc = LoadLE<uint32_t>(v + vertex_at[3]);
    const double t_pos[3] = {Unorm(pp >> 21, 11), Unorm(pp >> 11, 10), Unorm(pp, 11)};
    const double t_scale[3] = {Unorm(ps >> 21, 11), Unorm(ps >> 11, 10), Unorm(ps, 11)};
    for (int k = 0; k < 3; ++k) {
      g.positions[i * 3 + k] = float(Lerp(bound(k), bound(3 + k), t_pos[k]));
      g.log_scales[i * 3 + k] = float(Lerp(bound(6 + k), bound(9 + k), t_scale[k]));
    }
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(g.positions[i * 3 + k]) || !std::isfinite(g.log_scales[i * 3 + k])) {
        return MakeError(StatusCode::kOutOfRange, "compressed PLY vertex ", i, ": chunk ", i / kChunkSize,
                         " bounds give a position or scale that is not a finite float");
      }
    }
    // Largest-of-four quaternion: three components in [-1/sqrt2, 1/sqrt2], 10 bits each.
    const double norm = std::sqrt(2.0);
    const double small[3] = {(Unorm(pr >> 20, 10) - 0.5) * norm, (Unorm(pr >> 10, 10) - 0.5) * norm,
                             (Unorm(pr, 10) - 0.5) * norm};
    const double largest =
        std::sqrt(std::max(0.0, 1 - (small[0] * small[0] + small[1] * small[1] + small[2] * small[2])));
    const int which = int(pr >> 30);  // 0 = w, 1 = x, 2 = y, 3 = z (rot_0..rot_3)
    for (int k = 0, s = 0; k < 4; ++k) g.rotations[i * 4 + k] = float(k == which ? largest : small[s++]);
    double colour[3];
    for (int k = 0; k < 3; ++k) {
      const double t = Unorm(pc >> (24 - 8 * k), 8);
      colour[k] = chunk_colours ? Lerp(bound(12 + k), bound(15 + k), t) : t;
      g.sh[i * size_t(k_count) * 3 + size_t(k)] = float((colour[k] - 0.5) / kShC0);
      if (!std::isfinite(g.sh[i * size_t(k_count) * 3 + size_t(k)])) {
        return MakeError(StatusCode::kOutOfRange, "compressed PLY vertex ", i, ": chunk ", i / kChunkSize,
                         " colour bounds are not finite");
      }
    }
    // Opacity byte: sigmoid(logit) * 255; 0 and 255 are clamped so that the logit stays finite.
    const double alpha = std::clamp(Unorm(pc, 8), 0.5 / 255, 254.5 / 255);
    g.opacity_logits[i] = float(std::log(alpha / (1 - alpha)));
    if (sh != nullptr) {
      const uint8_t* s = data + start[sh_index] + i * sh_row;
      const size_t per_channel = rest / 3;
      for (size_t j = 0; j < rest; ++j) {
        const uint8_t b = s[sh_at[j]];
        const double unit = b == 0 ? 0.0 : b == 255 ? 1.0 : (b + 0.5) / 256.0;
        const size_t channel = j / per_channel, coeff = 1 + j % per_channel;
        g.sh[(i * size_t(k_count) + coeff) * 3 + channel] = float((unit - 0.5) * 8);
      }
    }
  }
  return g;
}

}  // namespace atex::converters::ply
