// Public texel-atlas API: layout + sidecar (atlas_layout.cc) around the EXR codec (exr_image.cc).
#include "atex/converters/exr_atlas.h"

#include <cmath>

#include "atex/file_io.h"
#include "exr/atlas_layout.h"
#ifdef ATEX_HAVE_OPENEXR
#include "exr/exr_image.h"
#endif

namespace atex {

namespace {

constexpr float kHalfMax = 65504.0f;

Status CheckPool(const TexturePool& pool) {
  const size_t n = pool.size();
  if (pool.widths.size() != n || pool.axis_u.size() != n || pool.axis_v.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "texture pool: heights/widths/axis_u/axis_v have ", n, "/",
                     pool.widths.size(), "/", pool.axis_u.size(), "/", pool.axis_v.size(), " entries");
  }
  uint64_t texels = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint8_t h = pool.heights[i], w = pool.widths[i];
    if ((h != 1 && h != 2 && h != 4) || (w != 1 && w != 2 && w != 4)) {
      return MakeError(StatusCode::kInvalidArgument, "texture pool: Gaussian ", i, " is ", int(h), " x ", int(w));
    }
    if (pool.axis_u[i] > 2 || pool.axis_v[i] > 2 || pool.axis_u[i] == pool.axis_v[i]) {
      return MakeError(StatusCode::kInvalidArgument, "texture pool: Gaussian ", i, " has axes ", int(pool.axis_u[i]),
                       ", ", int(pool.axis_v[i]));
    }
    texels += uint64_t{h} * w;
  }
  if (pool.texels.size() != texels * kTexelChannels) {
    return MakeError(StatusCode::kInvalidArgument, "texture pool: ", pool.texels.size(), " texel values, dims need ",
                     texels * kTexelChannels);
  }
  return Status::Ok();
}

}  // namespace

std::string ExrAtlasSidecarPath(const std::string& exr_path) { return exr_path + ".json"; }

#ifdef ATEX_HAVE_OPENEXR

StatusOr<EncodedExrAtlas> EncodeExrAtlas(const TexturePool& pool_in, const ExrAtlasOptions& options) {
  using namespace converters::exr;
  ATEX_RETURN_IF_ERROR(CheckPool(pool_in));
  TexturePool pool = pool_in;  // offsets are derived data: rebuild rather than trust them
  pool.RebuildOffsets();
  const int width = options.width > 0 ? options.width : AutoAtlasWidth(pool.texel_count());
  ATEX_ASSIGN_OR_RETURN(AtlasLayout layout, PackShelves(pool.heights, pool.widths, width));

  HalfImage image;
  image.width = layout.width;
  image.height = layout.height;
  image.atlas_version = 1;
  image.atlas_count = static_cast<int64_t>(pool.size());
  image.rgba.assign(static_cast<size_t>(image.width) * image.height * 4, 0);
  for (size_t i = 0; i < pool.size(); ++i) {
    const int h = pool.heights[i], w = pool.widths[i];
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const float* texel = &pool.texels[(pool.offsets[i] + static_cast<uint64_t>(v) * w + u) * kTexelChannels];
        uint16_t* pixel = &image.rgba[((static_cast<size_t>(layout.y[i]) + v) * image.width + layout.x[i] + u) * 4];
        for (int c = 0; c < 4; ++c) {
          if (!std::isfinite(texel[c]) || std::fabs(texel[c]) > kHalfMax) {
            return MakeError(StatusCode::kOutOfRange, "EXR atlas: texel (u ", u, ", v ", v, ") channel ", c,
                             " of Gaussian ", i, " is ", texel[c], ", not representable as a finite half");
          }
          pixel[c] = FloatToHalfBits(texel[c]);
        }
      }
    }
  }
  EncodedExrAtlas encoded;
  ATEX_ASSIGN_OR_RETURN(encoded.exr, EncodeHalfImage(image));
  encoded.sidecar_json = SidecarJson(layout, pool);
  encoded.width = layout.width;
  encoded.height = layout.height;
  return encoded;
}

StatusOr<TexturePool> DecodeExrAtlas(const uint8_t* exr, size_t exr_size, std::string_view sidecar_json,
                                     const ExrAtlasReadOptions& options) {
  using namespace converters::exr;
  AtlasLayout layout;
  TexturePool pool;
  ATEX_RETURN_IF_ERROR(ParseSidecar(sidecar_json, options, &layout, &pool));
  ATEX_ASSIGN_OR_RETURN(HalfImage image, DecodeHalfImage(exr, exr_size, options.max_pixels));
  if (image.width != layout.width || image.height != layout.height) {
    return MakeError(StatusCode::kCorrupt, "EXR atlas is ", image.width, " x ", image.height, ", its sidecar says ",
                     layout.width, " x ", layout.height);
  }
  if (image.atlas_count >= 0 && static_cast<uint64_t>(image.atlas_count) != pool.size()) {
    return MakeError(StatusCode::kCorrupt, "EXR atlas header says ", image.atlas_count, " Gaussians, its sidecar ",
                     pool.size());
  }
  pool.texels.resize(pool.texel_count() * kTexelChannels);
  for (size_t i = 0; i < pool.size(); ++i) {
    const int h = pool.heights[i], w = pool.widths[i];
    for (int v = 0; v < h; ++v) {
      for (int u = 0; u < w; ++u) {
        const uint16_t* pixel =
            &image.rgba[((static_cast<size_t>(layout.y[i]) + v) * image.width + layout.x[i] + u) * 4];
        float* texel = &pool.texels[(pool.offsets[i] + static_cast<uint64_t>(v) * w + u) * kTexelChannels];
        for (int c = 0; c < 4; ++c) {
          texel[c] = HalfBitsToFloat(pixel[c]);
          if (!std::isfinite(texel[c])) {
            return MakeError(StatusCode::kOutOfRange, "EXR atlas pixel (", layout.x[i] + u, ", ", layout.y[i] + v,
                             ") of Gaussian ", i, " channel ", c, " is not finite");
          }
        }
      }
    }
  }
  return pool;
}

#else  // no OpenEXR in this build

StatusOr<EncodedExrAtlas> EncodeExrAtlas(const TexturePool&, const ExrAtlasOptions&) {
  return MakeError(StatusCode::kUnsupportedCodec, "EXR atlases need OpenEXR, which this build does not include");
}

StatusOr<TexturePool> DecodeExrAtlas(const uint8_t*, size_t, std::string_view, const ExrAtlasReadOptions&) {
  return MakeError(StatusCode::kUnsupportedCodec, "EXR atlases need OpenEXR, which this build does not include");
}

#endif

Status WriteExrAtlas(const std::string& exr_path, const TexturePool& pool, const ExrAtlasOptions& options) {
  ATEX_ASSIGN_OR_RETURN(EncodedExrAtlas encoded, EncodeExrAtlas(pool, options));
  ATEX_RETURN_IF_ERROR(WriteFileAtomic(exr_path, encoded.exr).WithContext(exr_path));
  const std::string sidecar = ExrAtlasSidecarPath(exr_path);
  return WriteFileAtomic(sidecar, encoded.sidecar_json.data(), encoded.sidecar_json.size()).WithContext(sidecar);
}

StatusOr<TexturePool> ReadExrAtlas(const std::string& exr_path, const ExrAtlasReadOptions& options) {
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> exr, ReadFileBytes(exr_path));
  const std::string sidecar_path = ExrAtlasSidecarPath(exr_path);
  // A sidecar holds ~40 bytes per Gaussian; cap its size accordingly.
  auto sidecar = ReadFileBytes(sidecar_path, 64 * options.max_gaussians + (1 << 20));
  if (!sidecar.ok()) return sidecar.status().WithContext("atlas sidecar " + sidecar_path);
  const std::string_view text(reinterpret_cast<const char*>(sidecar->data()), sidecar->size());
  auto pool = DecodeExrAtlas(exr.data(), exr.size(), text, options);
  if (!pool.ok()) return pool.status().WithContext(exr_path);
  return pool;
}

}  // namespace atex
