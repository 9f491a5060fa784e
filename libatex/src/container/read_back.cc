// DecodedAsWritten (read_back.h): the decoder's result, stream by stream, as asset_writer.cc
// encodes and asset_reader.cc decodes each chunk.
#include "container/read_back.h"

#include <functional>

#include "container/attribute_stream.h"
#include "container/chunks.h"

namespace atex::container {

ReadBackCache::Values ReadBackCache::Find(int stream, const Fingerprint& key) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = entries_.begin(); it != entries_.end(); ++it) {
    if (it->stream == stream && it->key == key) {
      entries_.splice(entries_.begin(), entries_, it);
      ++hits_;
      return entries_.front().values;
    }
  }
  ++misses_;
  return nullptr;
}

void ReadBackCache::Add(int stream, const Fingerprint& key, Values values) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (const Entry& e : entries_) {
    if (e.stream == stream && e.key == key) return;  // two candidates missed it at once
  }
  entries_.push_front({stream, key, std::move(values)});
  size_t seen = 0;
  for (auto it = entries_.begin(); it != entries_.end();) {
    if (it->stream == stream && ++seen > entries_per_stream_) {
      it = entries_.erase(it);
    } else {
      ++it;
    }
  }
}

namespace {

// The streams a cache keeps apart.
enum Stream : int { kPositions, kRotations, kLogScales, kOpacities, kSh, kTexels };

// A fingerprint of `values` and what their read back depends on (`tags`).
Fingerprint KeyOf(const std::vector<float>& values, std::initializer_list<uint64_t> tags) {
  FingerprintBuilder key;
  for (uint64_t tag : tags) key.AddValue(tag);
  key.AddValue(uint64_t{values.size()});
  key.AddValue(BlockFingerprint(values.data(), values.size() * sizeof(float)));
  return key.Finish();
}

// `make`'s values, or the cache's copy of them for the same key.
StatusOr<std::vector<float>> Cached(ReadBackCache* cache, int stream, const Fingerprint& key,
                                    const std::function<StatusOr<std::vector<float>>()>& make) {
  if (cache == nullptr) return make();
  if (ReadBackCache::Values hit = cache->Find(stream, key)) return *hit;
  ATEX_ASSIGN_OR_RETURN(std::vector<float> values, make());
  auto shared = std::make_shared<const std::vector<float>>(std::move(values));
  cache->Add(stream, key, shared);
  return *shared;
}

uint64_t Tag(ScalarEncoding e) { return static_cast<uint64_t>(e); }

// A stream of `rows` x `components` read back into a new array (through the cache when not f32).
StatusOr<std::vector<float>> ReadBack(const std::vector<float>& values, uint64_t rows, uint32_t components,
                                      ScalarEncoding encoding, const char* what, ReadBackCache* cache, int stream) {
  if (encoding == ScalarEncoding::kFloat32) return values;  // stored exactly
  const auto make = [&]() -> StatusOr<std::vector<float>> {
    std::vector<float> out(values.size());
    ATEX_RETURN_IF_ERROR(
        ReadBackStream(values.data(), components, rows, components, encoding, out.data(), components, what));
    return out;
  };
  if (cache == nullptr) return make();
  return Cached(cache, stream, KeyOf(values, {Tag(encoding), rows, components}), make);
}

Status ReadBackGaussians(const Gaussians& g, const WriteOptions& o, ReadBackCache* cache, Gaussians* out) {
  const uint64_t n = g.size();
  out->sh_degree = g.sh_degree;
  ATEX_ASSIGN_OR_RETURN(out->positions, ReadBack(g.positions, n, 3, o.positions, "positions", cache, kPositions));
  ATEX_ASSIGN_OR_RETURN(out->rotations, ReadBack(g.rotations, n, 4, o.rotations, "rotations", cache, kRotations));
  ATEX_ASSIGN_OR_RETURN(out->log_scales, ReadBack(g.log_scales, n, 3, o.log_scales, "log_scales", cache, kLogScales));
  ATEX_ASSIGN_OR_RETURN(out->opacity_logits,
                        ReadBack(g.opacity_logits, n, 1, o.opacities, "opacity_logits", cache, kOpacities));
  // sh [N][K][3] is stored as DC [N][3] and rest [N][K-1][3], each with its own encoding and
  // ranges: read back in place, as strided rows of one copy.
  const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
  const auto make_sh = [&]() -> StatusOr<std::vector<float>> {
    std::vector<float> sh = g.sh;
    ATEX_RETURN_IF_ERROR(ReadBackStream(sh.data(), k * 3, n, 3, o.sh_dc, sh.data(), k * 3, "sh_dc"));
    if (k > 1) {
      ATEX_RETURN_IF_ERROR(
          ReadBackStream(sh.data() + 3, k * 3, n, 3 * (k - 1), o.sh_rest, sh.data() + 3, k * 3, "sh_rest"));
    }
    return sh;
  };
  if (o.sh_dc == ScalarEncoding::kFloat32 && (k == 1 || o.sh_rest == ScalarEncoding::kFloat32)) {
    out->sh = g.sh;  // stored exactly
  } else if (cache == nullptr) {
    ATEX_ASSIGN_OR_RETURN(out->sh, make_sh());
  } else {
    ATEX_ASSIGN_OR_RETURN(out->sh, Cached(cache, kSh, KeyOf(g.sh, {Tag(o.sh_dc), Tag(o.sh_rest), n, k}), make_sh));
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

StatusOr<Asset> DecodedAsWritten(const Asset& asset, const WriteOptions& options, bool read_stats,
                                 ReadBackCache* cache) {
  ATEX_RETURN_IF_ERROR(CheckWriteOptions(options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  if (options.draco_positions && asset.gaussians.size() > 0) {
    return MakeError(StatusCode::kUnsupported, "DecodedAsWritten does not model Draco positions");
  }
  try {
    Asset out;
    ATEX_ASSIGN_OR_RETURN(const std::vector<uint8_t> meta, EncodeMeta(asset.metadata));
    ATEX_ASSIGN_OR_RETURN(out.metadata, DecodeMeta(meta.data(), meta.size()));
    ATEX_RETURN_IF_ERROR(ReadBackGaussians(asset.gaussians, options, cache, &out.gaussians));
    if (asset.textures) {
      const TexturePool& t = *asset.textures;
      TexturePool& pool = out.textures.emplace();
      pool.heights = t.heights;  // TLAY holds them exactly (one byte per Gaussian)
      pool.widths = t.widths;
      pool.axis_u = t.axis_u;
      pool.axis_v = t.axis_v;
      pool.offsets = t.offsets;
      ATEX_ASSIGN_OR_RETURN(
          pool.texels, ReadBack(t.texels, t.texel_count(), kTexelChannels, options.texels, "texels", cache, kTexels));
    }
    if (asset.deformation) {
      ATEX_ASSIGN_OR_RETURN(out.deformation, ReadBackDeformation(*asset.deformation, options));
    }
    if (read_stats && options.write_stats && asset.stats) out.stats = asset.stats;  // f32 always
    return out;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory reading back an asset of ", asset.gaussians.size(),
                     " Gaussians");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "DecodedAsWritten: ", e.what());
  }
}

}  // namespace atex::container
