#include "container/chunks.h"

#include <cmath>
#include <cstring>

#include "container/byte_io.h"
#include "container/format.h"
#include "core/model_limits.h"

namespace atex::container {
namespace {

// Deepest nesting of arrays/objects, scanning outside strings. Stops early once
// above the limit.
int JsonDepth(const uint8_t* data, size_t size, int limit) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (size_t i = 0; i < size; ++i) {
    const uint8_t c = data[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) return deepest;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return deepest;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeMeta(const Metadata& metadata) {
  try {
    const std::string text = MetadataToJson(metadata).dump(-1, ' ', false, nlohmann::json::error_handler_t::strict);
    return std::vector<uint8_t>(text.begin(), text.end());
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInvalidArgument, "metadata cannot be written as JSON: ", e.what());
  }
}

StatusOr<Metadata> DecodeMeta(const uint8_t* data, size_t size) {
  if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) {
    return MakeError(StatusCode::kCorrupt, "metadata JSON starts with a byte-order mark");
  }
  if (JsonDepth(data, size, limits::kMaxJsonDepth) > limits::kMaxJsonDepth) {
    return MakeError(StatusCode::kLimitExceeded, "metadata JSON is nested deeper than ", limits::kMaxJsonDepth,
                     " levels");
  }
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(data, data + size);
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kCorrupt, "metadata is not valid JSON: ", e.what());
  }
  return MetadataFromJson(json);
}

std::vector<uint8_t> EncodeGhdr(const GaussianHeader& header) {
  std::vector<uint8_t> out;
  ByteWriter w(&out);
  w.Put<uint64_t>(header.count);
  w.Put<uint8_t>(static_cast<uint8_t>(header.sh_degree));
  w.PutZeros(7);
  return out;
}

StatusOr<GaussianHeader> DecodeGhdr(const uint8_t* data, size_t size) {
  if (size != kGhdrSize) return MakeError(StatusCode::kCorrupt, "GHDR has ", size, " bytes, expected ", kGhdrSize);
  GaussianHeader h;
  h.count = LoadLE<uint64_t>(data);
  h.sh_degree = data[8];
  if (h.sh_degree > kMaxShDegree)
    return MakeError(StatusCode::kOutOfRange, "SH degree ", h.sh_degree, " (byte 8) is above 3");
  for (int i = 9; i < 16; ++i) {
    if (data[i] != 0) return MakeError(StatusCode::kCorrupt, "GHDR reserved byte ", i, " is not zero");
  }
  return h;
}

std::vector<uint8_t> EncodeTextureLayout(const TexturePool& t) {
  std::vector<uint8_t> out(t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    const int log2_h = t.heights[i] == 4 ? 2 : t.heights[i] == 2 ? 1 : 0;
    const int log2_w = t.widths[i] == 4 ? 2 : t.widths[i] == 2 ? 1 : 0;
    out[i] = static_cast<uint8_t>(log2_h | (log2_w << 2) | (t.axis_u[i] << 4) | (t.axis_v[i] << 6));
  }
  return out;
}

Status DecodeTextureLayout(const uint8_t* data, size_t size, uint64_t n, TexturePool* t) {
  if (size != n) return MakeError(StatusCode::kCorrupt, "TLAY has ", size, " bytes for ", n, " Gaussians");
  t->heights.resize(size);
  t->widths.resize(size);
  t->axis_u.resize(size);
  t->axis_v.resize(size);
  for (size_t i = 0; i < size; ++i) {
    const uint8_t b = data[i];
    const int log2_h = b & 3, log2_w = (b >> 2) & 3, u = (b >> 4) & 3, v = (b >> 6) & 3;
    if (log2_h == 3 || log2_w == 3) {
      return MakeError(StatusCode::kOutOfRange, "texture of Gaussian ", i, " (byte ", i, " = ", int{b},
                       ") has a side of 8 texels; sides are 1, 2 or 4");
    }
    if (u == 3 || v == 3 || u == v) {
      return MakeError(StatusCode::kOutOfRange, "texture of Gaussian ", i, " (byte ", i, " = ", int{b}, ") has axes (",
                       u, ", ", v, "); they must be distinct values in 0..2");
    }
    t->heights[i] = static_cast<uint8_t>(1 << log2_h);
    t->widths[i] = static_cast<uint8_t>(1 << log2_w);
    t->axis_u[i] = static_cast<uint8_t>(u);
    t->axis_v[i] = static_cast<uint8_t>(v);
  }
  t->RebuildOffsets();
  return Status::Ok();
}

std::vector<uint8_t> EncodeDeformationConfig(const DeformationConfig& c) {
  std::vector<uint8_t> out;
  ByteWriter w(&out);
  w.Put<uint32_t>(static_cast<uint32_t>(c.grid.channels));
  for (int a = 0; a < 4; ++a) w.Put<uint32_t>(static_cast<uint32_t>(c.grid.base_resolution[a]));
  w.Put<uint32_t>(static_cast<uint32_t>(c.grid.scales()));
  for (int s = 0; s < kDcfgMaxScales; ++s) {
    w.Put<uint32_t>(s < c.grid.scales() ? static_cast<uint32_t>(c.grid.multires[s]) : 0u);
  }
  w.Put<uint32_t>(static_cast<uint32_t>(c.mlp_width));
  w.Put<uint32_t>(static_cast<uint32_t>(c.trunk_layers));
  uint32_t mask = 0;
  for (int h = 0; h < kNumDeformHeads; ++h) mask |= c.heads[h] ? (1u << h) : 0u;
  w.Put<uint32_t>(mask);
  w.Put<uint32_t>(static_cast<uint32_t>(c.sh_coeffs));
  for (int a = 0; a < 3; ++a) w.Put<float>(c.aabb_lo[a]);
  for (int a = 0; a < 3; ++a) w.Put<float>(c.aabb_hi[a]);
  w.Put<float>(c.time_scale);
  w.Put<float>(c.time_offset);
  return out;
}

StatusOr<DeformationConfig> DecodeDeformationConfig(const uint8_t* data, size_t size) {
  if (size != kDcfgSize) return MakeError(StatusCode::kCorrupt, "DCFG has ", size, " bytes, expected ", kDcfgSize);
  auto u32 = [&](size_t at) { return LoadLE<uint32_t>(data + at); };
  auto range = [](const char* field, size_t at, uint32_t v, uint32_t lo, uint32_t hi) {
    if (v < lo || v > hi) {
      return MakeError(StatusCode::kOutOfRange, "DCFG ", field, " (byte ", at, ") = ", v, " is outside ", lo, "..", hi);
    }
    return Status::Ok();
  };
  DeformationConfig c;
  ATEX_RETURN_IF_ERROR(range("channels", 0, u32(0), 1, limits::kMaxChannels));
  c.grid.channels = static_cast<int>(u32(0));
  for (int a = 0; a < 4; ++a) {
    ATEX_RETURN_IF_ERROR(range("base_resolution", 4 + 4 * a, u32(4 + 4 * a), 1, limits::kMaxBaseResolution));
    c.grid.base_resolution[a] = static_cast<int>(u32(4 + 4 * a));
  }
  ATEX_RETURN_IF_ERROR(range("scale_count", 20, u32(20), 1, limits::kMaxScales));
  const uint32_t scales = u32(20);
  c.grid.multires.assign(scales, 1);
  for (uint32_t s = 0; s < kDcfgMaxScales; ++s) {
    const size_t at = 24 + 4 * s;
    if (s < scales) {
      ATEX_RETURN_IF_ERROR(range("multires", at, u32(at), 1, limits::kMaxMultires));
      c.grid.multires[s] = static_cast<int>(u32(at));
      for (int a = 0; a < 3; ++a) {
        if (int64_t{c.grid.base_resolution[a]} * c.grid.multires[s] > limits::kMaxSpatialResolution) {
          return MakeError(StatusCode::kOutOfRange, "DCFG resolution of axis ", a, " at scale ", s, " is above ",
                           limits::kMaxSpatialResolution);
        }
      }
    } else if (u32(at) != 0) {
      return MakeError(StatusCode::kCorrupt, "DCFG unused multires entry ", s, " (byte ", at, ") is not zero");
    }
  }
  ATEX_RETURN_IF_ERROR(range("mlp_width", 56, u32(56), 1, limits::kMaxMlpWidth));
  c.mlp_width = static_cast<int>(u32(56));
  ATEX_RETURN_IF_ERROR(range("trunk_layers", 60, u32(60), 1, limits::kMaxTrunkLayers));
  c.trunk_layers = static_cast<int>(u32(60));
  const uint32_t mask = u32(64);
  if (mask >> kNumDeformHeads)
    return MakeError(StatusCode::kOutOfRange, "DCFG head_mask (byte 64) = ", mask, " uses bits above 4");
  for (int h = 0; h < kNumDeformHeads; ++h) c.heads[h] = (mask >> h) & 1u;
  const uint32_t k = u32(68);
  if (k != 1 && k != 4 && k != 9 && k != 16) {
    return MakeError(StatusCode::kOutOfRange, "DCFG sh_coeffs (byte 68) = ", k, " is not 1, 4, 9 or 16");
  }
  c.sh_coeffs = static_cast<int>(k);
  for (int a = 0; a < 3; ++a) {
    c.aabb_lo[a] = LoadLE<float>(data + 72 + 4 * a);
    c.aabb_hi[a] = LoadLE<float>(data + 84 + 4 * a);
    if (!std::isfinite(c.aabb_lo[a]) || !std::isfinite(c.aabb_hi[a]) || c.aabb_lo[a] == c.aabb_hi[a]) {
      return MakeError(StatusCode::kOutOfRange, "DCFG AABB axis ", a, " (bytes ", 72 + 4 * a, ", ", 84 + 4 * a,
                       ") is not finite or empty");
    }
  }
  c.time_scale = LoadLE<float>(data + 96);
  c.time_offset = LoadLE<float>(data + 100);
  if (!std::isfinite(c.time_scale) || !std::isfinite(c.time_offset)) {
    return MakeError(StatusCode::kOutOfRange, "DCFG time_scale/time_offset (bytes 96-103) not finite");
  }
  return c;
}

uint64_t GridValueCount(const DeformationConfig& c) {
  uint64_t total = 0;
  for (int s = 0; s < c.grid.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      total += uint64_t(c.grid.channels) * uint64_t(c.grid.resolution(s, kHexPlaneAxes[p][0])) *
               uint64_t(c.grid.resolution(s, kHexPlaneAxes[p][1]));
    }
  }
  return total;  // < 8 * 6 * 2^10 * 2^32 = 2^47.6 within the DCFG limits
}

namespace {
struct LayerShape {
  int in, out;
};
// Every layer of DMLP in order; head h's layers carry their head index.
struct MlpLayer {
  int head;  // -1 for trunk
  int index;
  LayerShape shape;
};
std::vector<MlpLayer> MlpLayers(const DeformationConfig& c) {
  std::vector<MlpLayer> layers;
  for (int l = 0; l < c.trunk_layers; ++l) {
    layers.push_back({-1, l, {l == 0 ? c.grid.feature_dim() : c.mlp_width, c.mlp_width}});
  }
  for (int h = 0; h < kNumDeformHeads; ++h) {
    if (!c.heads[h]) continue;
    layers.push_back({h, 0, {c.mlp_width, c.mlp_width}});
    layers.push_back({h, 1, {c.mlp_width, c.head_outputs(h)}});
  }
  return layers;
}
}  // namespace

uint64_t MlpValueCount(const DeformationConfig& c) {
  uint64_t total = 0;
  for (const MlpLayer& l : MlpLayers(c)) total += uint64_t(l.shape.out) * l.shape.in + l.shape.out;
  return total;
}

std::vector<float> FlattenGrids(const DeformationField& f) {
  std::vector<float> out;
  out.reserve(static_cast<size_t>(GridValueCount(f.config)));
  for (const auto& scale : f.planes) {
    for (const auto& plane : scale) out.insert(out.end(), plane.begin(), plane.end());
  }
  return out;
}

void UnflattenGrids(const std::vector<float>& grids, DeformationField* f) {
  const HexPlaneConfig& g = f->config.grid;
  f->planes.assign(g.scales(), {});
  size_t at = 0;
  for (int s = 0; s < g.scales(); ++s) {
    for (int p = 0; p < kNumHexPlanes; ++p) {
      const size_t n = size_t(g.channels) * g.resolution(s, kHexPlaneAxes[p][0]) * g.resolution(s, kHexPlaneAxes[p][1]);
      f->planes[s][p].assign(grids.begin() + at, grids.begin() + at + n);
      at += n;
    }
  }
}

std::vector<float> FlattenMlp(const DeformationField& f) {
  std::vector<float> out;
  out.reserve(static_cast<size_t>(MlpValueCount(f.config)));
  for (const MlpLayer& l : MlpLayers(f.config)) {
    const Linear& layer = l.head < 0 ? f.trunk[l.index] : f.heads[l.head][l.index];
    out.insert(out.end(), layer.weight.begin(), layer.weight.end());
    out.insert(out.end(), layer.bias.begin(), layer.bias.end());
  }
  return out;
}

void UnflattenMlp(const std::vector<float>& mlp, DeformationField* f) {
  f->trunk.assign(f->config.trunk_layers, {});
  f->heads = {};
  size_t at = 0;
  for (const MlpLayer& l : MlpLayers(f->config)) {
    Linear& layer = l.head < 0 ? f->trunk[l.index] : f->heads[l.head][l.index];
    layer.in = l.shape.in;
    layer.out = l.shape.out;
    const size_t w = size_t(l.shape.out) * l.shape.in;
    layer.weight.assign(mlp.begin() + at, mlp.begin() + at + w);
    at += w;
    layer.bias.assign(mlp.begin() + at, mlp.begin() + at + l.shape.out);
    at += l.shape.out;
  }
}

}  // namespace atex::container
