// DecodedAsWritten (read_back.h): the decoder's result, stream by stream, as asset_writer.cc
// encodes and asset_reader.cc decodes each chunk.
#include "container/read_back.h"

#include "container/attribute_stream.h"
#include "container/chunks.h"

namespace atex::container {
namespace {

// A stream of `rows` x `components` read back into a new array.
StatusOr<std::vector<float>> ReadBack(const std::vector<float>& values, uint64_t rows, uint32_t components,
                                      ScalarEncoding encoding, const char* what) {
  if (encoding == ScalarEncoding::kFloat32) return values;  // stored exactly
  std::vector<float> out(values.size());
  ATEX_RETURN_IF_ERROR(
      ReadBackStream(values.data(), components, rows, components, encoding, out.data(), components, what));
  return out;
}

Status ReadBackGaussians(const Gaussians& g, const WriteOptions& o, Gaussians* out) {
  const uint64_t n = g.size();
  out->sh_degree = g.sh_degree;
  ATEX_ASSIGN_OR_RETURN(out->positions, ReadBack(g.positions, n, 3, o.positions, "positions"));
  ATEX_ASSIGN_OR_RETURN(out->rotations, ReadBack(g.rotations, n, 4, o.rotations, "rotations"));
  ATEX_ASSIGN_OR_RETURN(out->log_scales, ReadBack(g.log_scales, n, 3, o.log_scales, "log_scales"));
  ATEX_ASSIGN_OR_RETURN(out->opacity_logits, ReadBack(g.opacity_logits, n, 1, o.opacities, "opacity_logits"));
  // sh [N][K][3] is stored as DC [N][3] and rest [N][K-1][3], each with its own encoding and
  // ranges: read back in place, as strided rows of one copy.
  const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
  out->sh = g.sh;
  ATEX_RETURN_IF_ERROR(ReadBackStream(out->sh.data(), k * 3, n, 3, o.sh_dc, out->sh.data(), k * 3, "sh_dc"));
  if (k > 1) {
    ATEX_RETURN_IF_ERROR(
        ReadBackStream(out->sh.data() + 3, k * 3, n, 3 * (k - 1), o.sh_rest, out->sh.data() + 3, k * 3, "sh_rest"));
  }
  out->time_windows = g.time_windows;  // f32 always
  return Status::Ok();
}

StatusOr<DeformationField> ReadBackDeformation(const DeformationField& d, const WriteOptions& o) {
  DeformationField out;
  const std::vector<uint8_t> config = EncodeDeformationConfig(d.config);
  ATEX_ASSIGN_OR_RETURN(out.config, DecodeDeformationConfig(config.data(), config.size()));
  std::vector<float> grids = FlattenGrids(d);  // one stream: one range over every plane
  ATEX_RETURN_IF_ERROR(
      ReadBackStream(grids.data(), 1, grids.size(), 1, o.deformation_grids, grids.data(), 1, "deformation grids"));
  UnflattenGrids(grids, &out);
  UnflattenMlp(FlattenMlp(d), &out);  // f32 always
  return out;
}

}  // namespace

StatusOr<Asset> DecodedAsWritten(const Asset& asset, const WriteOptions& options, bool read_stats) {
  ATEX_RETURN_IF_ERROR(CheckWriteOptions(options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  if (options.draco_positions && asset.gaussians.size() > 0) {
    return MakeError(StatusCode::kUnsupported, "DecodedAsWritten does not model Draco positions");
  }
  try {
    Asset out;
    ATEX_ASSIGN_OR_RETURN(const std::vector<uint8_t> meta, EncodeMeta(asset.metadata));
    ATEX_ASSIGN_OR_RETURN(out.metadata, DecodeMeta(meta.data(), meta.size()));
    ATEX_RETURN_IF_ERROR(ReadBackGaussians(asset.gaussians, options, &out.gaussians));
    if (asset.textures) {
      const TexturePool& t = *asset.textures;
      TexturePool& pool = out.textures.emplace();
      pool.heights = t.heights;  // TLAY holds them exactly (one byte per Gaussian)
      pool.widths = t.widths;
      pool.axis_u = t.axis_u;
      pool.axis_v = t.axis_v;
      pool.offsets = t.offsets;
      ATEX_ASSIGN_OR_RETURN(pool.texels, ReadBack(t.texels, t.texel_count(), kTexelChannels, options.texels, "texels"));
    }
    if (asset.deformation) {
      ATEX_ASSIGN_OR_RETURN(out.deformation, ReadBackDeformation(*asset.deformation, options));
    }
    if (read_stats && options.write_stats && asset.stats) out.stats = asset.stats;  // f32 always
    return out;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory reading back an asset of ", asset.gaussians.size(),
                     " Gaussians");
  }
}

}  // namespace atex::container
