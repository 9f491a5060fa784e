// StoredValues (container.h): what DecodeAsset(EncodeAsset(asset, options)) gives,
// without the compression. The codecs of format_spec §9 other than Draco are
// lossless, so a chunk's decoded content is its uncompressed content; the values
// then come from the same stream encoder and decoder, and the small structured
// chunks from the same encoders and decoders, as a real round trip.
#include "atex/container.h"
#include "container/attribute_stream.h"
#include "container/chunks.h"

namespace atex {
namespace {

// values ← decode(encode(values)) for a lossy encoding (f32 streams are stored exactly).
Status RoundTrip(std::vector<float>* values, uint64_t rows, uint32_t components, ScalarEncoding encoding,
                 const char* what) {
  if (encoding == ScalarEncoding::kFloat32) return Status::Ok();
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw,
                        container::EncodeStream(values->data(), rows, components, encoding, what));
  return container::DecodeStream(raw.data(), raw.size(), components, rows, values);
}

}  // namespace

StatusOr<Asset> StoredValues(const Asset& asset, const WriteOptions& options) {
  using namespace container;
  if (options.draco_positions) {
    // Draco is lossy and has its own decoder: the real round trip.
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeAsset(asset, options));
    ReadOptions read;
    read.read_stats = options.write_stats;
    return DecodeAsset(bytes.data(), bytes.size(), read);
  }
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  Asset out = asset;
  if (!options.write_stats) out.stats.reset();
  {
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> meta, EncodeMeta(asset.metadata));
    ATEX_ASSIGN_OR_RETURN(out.metadata, DecodeMeta(meta.data(), meta.size()));
  }
  Gaussians& g = out.gaussians;
  const uint64_t n = g.size();
  const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
  ATEX_RETURN_IF_ERROR(RoundTrip(&g.positions, n, 3, options.positions, "positions"));
  ATEX_RETURN_IF_ERROR(RoundTrip(&g.rotations, n, 4, options.rotations, "rotations"));
  ATEX_RETURN_IF_ERROR(RoundTrip(&g.log_scales, n, 3, options.log_scales, "log_scales"));
  ATEX_RETURN_IF_ERROR(RoundTrip(&g.opacity_logits, n, 1, options.opacities, "opacity_logits"));
  if (options.sh_dc != ScalarEncoding::kFloat32 || (k > 1 && options.sh_rest != ScalarEncoding::kFloat32)) {
    // sh [N][K][3] is stored as DC [N][3] and rest [N][K-1][3].
    std::vector<float> dc(n * 3), rest(n * (k - 1) * 3);
    for (uint64_t i = 0; i < n; ++i) {
      const float* row = g.sh.data() + i * k * 3;
      std::copy(row, row + 3, dc.data() + i * 3);
      std::copy(row + 3, row + k * 3, rest.data() + i * (k - 1) * 3);
    }
    ATEX_RETURN_IF_ERROR(RoundTrip(&dc, n, 3, options.sh_dc, "sh_dc"));
    if (k > 1) ATEX_RETURN_IF_ERROR(RoundTrip(&rest, n, 3 * (k - 1), options.sh_rest, "sh_rest"));
    for (uint64_t i = 0; i < n; ++i) {
      std::copy(dc.begin() + i * 3, dc.begin() + i * 3 + 3, g.sh.begin() + i * k * 3);
      if (k > 1) std::copy(rest.begin() + i * (k - 1) * 3, rest.begin() + (i + 1) * (k - 1) * 3, g.sh.begin() + i * k * 3 + 3);
    }
  }
  if (out.textures) {
    TexturePool& t = *out.textures;
    std::vector<uint8_t> layout = EncodeTextureLayout(t);
    TexturePool decoded;
    ATEX_RETURN_IF_ERROR(DecodeTextureLayout(layout.data(), layout.size(), n, &decoded));
    decoded.texels = std::move(t.texels);
    t = std::move(decoded);
    ATEX_RETURN_IF_ERROR(RoundTrip(&t.texels, t.texel_count(), kTexelChannels, options.texels, "texels"));
  }
  if (out.deformation) {
    DeformationField& d = *out.deformation;
    std::vector<uint8_t> config = EncodeDeformationConfig(d.config);
    ATEX_ASSIGN_OR_RETURN(d.config, DecodeDeformationConfig(config.data(), config.size()));
    if (options.deformation_grids != ScalarEncoding::kFloat32) {
      std::vector<float> grids = FlattenGrids(d);
      const uint64_t count = grids.size();
      ATEX_RETURN_IF_ERROR(RoundTrip(&grids, count, 1, options.deformation_grids, "deformation grids"));
      UnflattenGrids(grids, &d);
    }
  }
  return out;
}

}  // namespace atex
