// EncodeAsset / WriteAssetFile (format_spec/atex.md §9): validate, turn each part
// of the asset into chunk content, encode the chunks (independently, so in
// parallel when OpenMP is there; the bytes do not depend on it), lay them out.
#include <array>
#include <cstring>
#include <functional>
#include <list>
#include <mutex>

#include "atex/container.h"
#include "atex/file_io.h"
#include "container/attribute_stream.h"
#include "container/byte_io.h"
#include "container/chunks.h"
#include "container/codecs.h"
#include "container/draco_codec.h"
#include "container/format.h"
#include "container/layout.h"

namespace atex {

// Per chunk type, the most recently used versions first.
struct EncodeCache::Impl {
  struct Entry {
    std::vector<uint8_t> raw;  // the uncompressed content
    container::CodecParams params;
    int zstd_level = 0;
    bool fallback_to_raw = true;
    container::OutputChunk chunk;  // what Finish made of it
  };
  explicit Impl(int entries) : entries_per_chunk(entries < 1 ? 1 : entries) {}
  const int entries_per_chunk;
  std::mutex mutex;
  std::array<std::list<Entry>, static_cast<size_t>(container::ChunkId::kCount)> chunks;
  uint64_t hits = 0, misses = 0;

  bool Find(container::ChunkId id, const std::vector<uint8_t>& raw, const container::CodecParams& p,
            const WriteOptions& o, container::OutputChunk* out) {
    std::lock_guard<std::mutex> lock(mutex);
    auto& list = chunks[static_cast<size_t>(id)];
    for (auto it = list.begin(); it != list.end(); ++it) {
      if (it->zstd_level == o.zstd_level && it->fallback_to_raw == o.fallback_to_raw && it->params.codec == p.codec &&
          it->params.element_size == p.element_size && it->params.components == p.components &&
          it->params.skip == p.skip && it->raw == raw) {
        *out = it->chunk;
        list.splice(list.begin(), list, it);
        ++hits;
        return true;
      }
    }
    ++misses;
    return false;
  }
  void Add(container::ChunkId id, std::vector<uint8_t> raw, const container::CodecParams& p, const WriteOptions& o,
           const container::OutputChunk& chunk) {
    std::lock_guard<std::mutex> lock(mutex);
    auto& list = chunks[static_cast<size_t>(id)];
    list.push_front(Entry{std::move(raw), p, o.zstd_level, o.fallback_to_raw, chunk});
    while (list.size() > static_cast<size_t>(entries_per_chunk)) list.pop_back();
  }
};

EncodeCache::EncodeCache(int entries_per_chunk) : impl_(new Impl(entries_per_chunk)) {}
EncodeCache::~EncodeCache() { delete impl_; }
uint64_t EncodeCache::hits() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->hits;
}
uint64_t EncodeCache::misses() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->misses;
}

namespace container {
namespace {

// One chunk to produce: its content and how to encode it.
struct ChunkJob {
  ChunkId id;
  std::function<StatusOr<OutputChunk>()> make;
};

bool ValidEncoding(ScalarEncoding e) {
  return static_cast<uint8_t>(e) <= static_cast<uint8_t>(ScalarEncoding::kQuant8);
}

Status CheckOptions(const WriteOptions& o) {
  if (static_cast<uint8_t>(o.codec) > static_cast<uint8_t>(Codec::kDeltaShuffleZstd)) {
    return MakeError(StatusCode::kInvalidArgument, "WriteOptions::codec must be raw, zstd, shuffle-zstd or "
                     "delta-shuffle-zstd (Draco is chosen with draco_positions)");
  }
  if (o.zstd_level < MinZstdLevel() || o.zstd_level > MaxZstdLevel()) {
    return MakeError(StatusCode::kInvalidArgument, "zstd level ", o.zstd_level, " outside ", MinZstdLevel(), "..",
                     MaxZstdLevel());
  }
  for (ScalarEncoding e : {o.positions, o.rotations, o.log_scales, o.opacities, o.sh_dc, o.sh_rest, o.texels,
                           o.deformation_grids}) {
    if (!ValidEncoding(e))
      return MakeError(StatusCode::kInvalidArgument, "unknown scalar encoding ", int{static_cast<uint8_t>(e)});
  }
  if (o.draco_positions) {
    if (!HaveDraco())
      return MakeError(StatusCode::kUnsupportedCodec, "Draco positions requested but this build has no Draco");
    if (o.draco_position_bits < 1 || o.draco_position_bits > 30) {
      return MakeError(StatusCode::kInvalidArgument, "Draco position bits ", o.draco_position_bits, " outside 1..30");
    }
  }
  return Status::Ok();
}

OutputChunk Header(ChunkId id, uint64_t raw_size) {
  OutputChunk c;
  c.type = TypeInfo(id).type;
  c.flags = TypeInfo(id).critical ? kChunkCritical : 0;
  c.raw_size = raw_size;
  return c;
}

// Encodes content with `params`, falling back to raw when that is not smaller.
StatusOr<OutputChunk> Encode(ChunkId id, std::vector<uint8_t> raw, CodecParams params, const WriteOptions& o) {
  OutputChunk chunk = Header(id, raw.size());
  if (!o.fallback_to_raw || params.codec != Codec::kRaw) {
    auto stored = EncodeChunk(raw.data(), raw.size(), params, o.zstd_level);
    if (!stored.ok()) return stored.status().WithContext(StrCat("chunk '", TypeInfo(id).type, "'"));
    if (!o.fallback_to_raw || stored->size() < raw.size()) {
      chunk.codec = params;
      chunk.stored = std::move(stored).value();
      return chunk;
    }
  }
  chunk.codec = CodecParams{};
  chunk.stored = std::move(raw);
  return chunk;
}

// The encoder of the current EncodeAsset call (set for each call, read by its jobs).
struct Context {
  const WriteOptions& options;
  EncodeCache::Impl* cache;  // may be null
};

// Encode, through the cache when there is one.
StatusOr<OutputChunk> Finish(ChunkId id, std::vector<uint8_t> raw, CodecParams params, const Context& c) {
  if (c.cache == nullptr) return Encode(id, std::move(raw), params, c.options);
  OutputChunk cached;
  if (c.cache->Find(id, raw, params, c.options, &cached)) return cached;
  std::vector<uint8_t> key = raw;
  ATEX_ASSIGN_OR_RETURN(OutputChunk chunk, Encode(id, std::move(raw), params, c.options));
  c.cache->Add(id, std::move(key), params, c.options, chunk);
  return chunk;
}

// Codec for JSON / fixed structs / TLAY: zstd unless everything is raw.
CodecParams StructuredCodec(const WriteOptions& o) {
  return CodecParams{o.codec == Codec::kRaw ? Codec::kRaw : Codec::kZstd, 0, 0, 0};
}

CodecParams StreamCodec(const WriteOptions& o, ScalarEncoding encoding, uint32_t components) {
  const auto e = static_cast<uint8_t>(EncodingBytes(encoding));
  const auto skip = static_cast<uint32_t>(StreamHeaderBytes(encoding, components));
  switch (o.codec) {
    case Codec::kRaw: return {Codec::kRaw, 0, 0, 0};
    case Codec::kZstd: return {Codec::kZstd, 0, 0, 0};
    case Codec::kShuffleZstd: return {Codec::kShuffleZstd, e, 0, skip};
    case Codec::kDeltaShuffleZstd:
      if (IsQuantised(encoding)) return {Codec::kDeltaShuffleZstd, e, components, skip};
      return {Codec::kShuffleZstd, e, 0, skip};
    case Codec::kDraco: break;
  }
  return {Codec::kRaw, 0, 0, 0};
}

ChunkJob StreamJob(ChunkId id, std::vector<float> values, uint64_t rows, uint32_t components, ScalarEncoding encoding,
                   const Context& c, const char* what) {
  return {id, [=, values = std::move(values), &c]() -> StatusOr<OutputChunk> {
            ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw,
                                  EncodeStream(values.data(), rows, components, encoding, what));
            return Finish(id, std::move(raw), StreamCodec(c.options, encoding, components), c);
          }};
}

// A stream over an existing array (no copy); the array outlives the jobs.
ChunkJob StreamJobRef(ChunkId id, const std::vector<float>& values, uint64_t rows, uint32_t components,
                      ScalarEncoding encoding, const Context& c, const char* what) {
  return {id, [=, &values, &c]() -> StatusOr<OutputChunk> {
            ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw,
                                  EncodeStream(values.data(), rows, components, encoding, what));
            return Finish(id, std::move(raw), StreamCodec(c.options, encoding, components), c);
          }};
}

ChunkJob DracoPositionsJob(const std::vector<float>& positions, uint64_t n, const WriteOptions& o) {
  return {ChunkId::kGpos, [&positions, n, &o]() -> StatusOr<OutputChunk> {
            // The stream header (f32, 3 components, N rows) goes in front, untouched.
            std::vector<uint8_t> header;
            ByteWriter w(&header);
            w.Put<uint8_t>(static_cast<uint8_t>(ScalarEncoding::kFloat32));
            w.Put<uint8_t>(0);
            w.Put<uint16_t>(3);
            w.Put<uint32_t>(0);
            w.Put<uint64_t>(n);
            ATEX_ASSIGN_OR_RETURN(
                std::vector<uint8_t> draco,
                DracoEncodePositions(positions.data(), static_cast<size_t>(n), o.draco_position_bits));
            OutputChunk chunk = Header(ChunkId::kGpos, kStreamHeaderSize + 12 * n);
            if (o.fallback_to_raw && header.size() + draco.size() >= chunk.raw_size) {
              // Not smaller: store the exact floats instead (lossless).
              ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw,
                                    EncodeStream(positions.data(), n, 3, ScalarEncoding::kFloat32, "positions"));
              chunk.stored = std::move(raw);
              return chunk;
            }
            chunk.codec = {Codec::kDraco, 4, 3, static_cast<uint32_t>(kStreamHeaderSize)};
            // Prefix + bitstream. (Assembled with memcpy: vector::insert here trips a
            // gcc 12 -Warray-bounds false positive.)
            chunk.stored.resize(header.size() + draco.size());
            std::memcpy(chunk.stored.data(), header.data(), header.size());
            std::memcpy(chunk.stored.data() + header.size(), draco.data(), draco.size());
            return chunk;
          }};
}

}  // namespace
}  // namespace container

StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options) {
  return EncodeAsset(asset, options, nullptr);
}

StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options, EncodeCache* cache) {
  using namespace container;
  ATEX_RETURN_IF_ERROR(CheckOptions(options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  try {
    const Gaussians& g = asset.gaussians;
    const uint64_t n = g.size();
    const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
    const WriteOptions& o = options;
    const Context ctx{options, cache != nullptr ? cache->impl_ : nullptr};
    std::vector<ChunkJob> jobs;

    jobs.push_back({ChunkId::kMeta, [&]() -> StatusOr<OutputChunk> {
                      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, EncodeMeta(asset.metadata));
                      return Finish(ChunkId::kMeta, std::move(raw), StructuredCodec(o), ctx);
                    }});
    jobs.push_back({ChunkId::kGhdr, [&]() {
                      return Finish(ChunkId::kGhdr, EncodeGhdr({n, g.sh_degree}), StructuredCodec(o), ctx);
                    }});
    if (o.draco_positions && n > 0) {
      jobs.push_back(DracoPositionsJob(g.positions, n, o));
    } else {
      jobs.push_back(StreamJobRef(ChunkId::kGpos, g.positions, n, 3, o.positions, ctx, "positions"));
    }
    jobs.push_back(StreamJobRef(ChunkId::kGrot, g.rotations, n, 4, o.rotations, ctx, "rotations"));
    jobs.push_back(StreamJobRef(ChunkId::kGscl, g.log_scales, n, 3, o.log_scales, ctx, "log_scales"));
    jobs.push_back(StreamJobRef(ChunkId::kGopa, g.opacity_logits, n, 1, o.opacities, ctx, "opacity_logits"));
    // sh [N][K][3] splits into DC [N][3] and rest [N][K-1][3].
    std::vector<float> sh_dc(n * 3), sh_rest(n * (k - 1) * 3);
    for (uint64_t i = 0; i < n; ++i) {
      const float* row = g.sh.data() + i * k * 3;
      std::copy(row, row + 3, sh_dc.data() + i * 3);
      std::copy(row + 3, row + k * 3, sh_rest.data() + i * (k - 1) * 3);
    }
    jobs.push_back(StreamJob(ChunkId::kGsh0, std::move(sh_dc), n, 3, o.sh_dc, ctx, "sh_dc"));
    if (k > 1) jobs.push_back(StreamJob(ChunkId::kGshr, std::move(sh_rest), n, 3 * (k - 1), o.sh_rest, ctx, "sh_rest"));
    if (g.has_time_windows()) {  // f32 always: window centres are times, and a narrow window needs their precision
      jobs.push_back(
          StreamJobRef(ChunkId::kGtwn, g.time_windows, n, 2, ScalarEncoding::kFloat32, ctx, "time_windows"));
    }
    if (asset.textures) {
      const TexturePool& t = *asset.textures;
      jobs.push_back(
          {ChunkId::kTlay, [&]() { return Finish(ChunkId::kTlay, EncodeTextureLayout(t), StructuredCodec(o), ctx); }});
      jobs.push_back(StreamJobRef(ChunkId::kTexl, t.texels, t.texel_count(), kTexelChannels, o.texels, ctx, "texels"));
    }
    if (asset.deformation) {
      const DeformationField& d = *asset.deformation;
      jobs.push_back({ChunkId::kDcfg, [&]() {
                        return Finish(ChunkId::kDcfg, EncodeDeformationConfig(d.config), StructuredCodec(o), ctx);
                      }});
      std::vector<float> grids = FlattenGrids(d);
      const uint64_t grid_count = grids.size();
      jobs.push_back(
          StreamJob(ChunkId::kDgrd, std::move(grids), grid_count, 1, o.deformation_grids, ctx, "deformation grids"));
      std::vector<float> mlp = FlattenMlp(d);
      const uint64_t mlp_count = mlp.size();
      jobs.push_back(
          StreamJob(ChunkId::kDmlp, std::move(mlp), mlp_count, 1, ScalarEncoding::kFloat32, ctx, "deformation MLP"));
    }
    if (asset.stats && o.write_stats) {
      const GaussianStats& s = *asset.stats;
      std::vector<float> rows(n * 4);  // [N][4]
      for (uint64_t i = 0; i < n; ++i) {
        rows[i * 4 + 0] = s.texture_demand[i];
        rows[i * 4 + 1] = s.peak_scale_u[i];
        rows[i * 4 + 2] = s.peak_scale_v[i];
        rows[i * 4 + 3] = s.importance[i];
      }
      jobs.push_back(StreamJob(ChunkId::kGsta, std::move(rows), n, 4, ScalarEncoding::kFloat32, ctx, "stats"));
    }

    std::vector<StatusOr<OutputChunk>> results(jobs.size(), Status(StatusCode::kInternal, "chunk not encoded"));
    // Threads only pay off for large assets (a team costs tens of microseconds,
    // much more on a busy machine).
    const bool parallel = n * (k * 3 + 11) > (size_t{1} << 18);
    (void)parallel;  // unused without OpenMP
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
#endif
    for (size_t i = 0; i < jobs.size(); ++i) {
      try {
        results[i] = jobs[i].make();
      } catch (const std::bad_alloc&) {
        results[i] = Status(StatusCode::kLimitExceeded,
                            StrCat("out of memory encoding chunk '", TypeInfo(jobs[i].id).type, "'"));
      }
    }
    std::vector<OutputChunk> chunks;
    chunks.reserve(results.size());
    for (auto& result : results) {
      if (!result.ok()) return result.status();
      chunks.push_back(std::move(result).value());
    }
    return AssembleContainer(chunks);
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory while encoding an asset of ", asset.gaussians.size(),
                     " Gaussians");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "EncodeAsset: ", e.what());
  }
}

Status WriteAssetFile(const std::string& path, const Asset& asset, const WriteOptions& options) {
  auto bytes = EncodeAsset(asset, options);
  if (!bytes.ok()) return bytes.status().WithContext(path);
  return WriteFileAtomic(path, *bytes);
}

}  // namespace atex
