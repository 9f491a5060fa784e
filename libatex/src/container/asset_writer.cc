// EncodeAsset / WriteAssetFile (format_spec/atex.md §9): validate, turn each part
// of the asset into chunk content, encode the chunks (independently, so in
// parallel when OpenMP is there; the bytes do not depend on it), lay them out.
#include <array>
#include <cstring>
#include <functional>
#include <list>
#include <memory>
#include <mutex>

#include "atex/checksum.h"
#include "atex/container.h"
#include "atex/file_io.h"
#include "container/attribute_stream.h"
#include "container/byte_io.h"
#include "container/chunks.h"
#include "container/codecs.h"
#include "container/draco_codec.h"
#include "container/fingerprint.h"
#include "container/format.h"
#include "container/layout.h"
#include "container/read_back.h"

namespace atex {

// Per chunk type, the most recently used versions first, each keyed by a fingerprint of
// what its uncompressed content is made from (fingerprint.h): an unchanged stream is found
// without quantising it again.
struct EncodeCache::Impl {
  struct Entry {
    container::Fingerprint content;
    container::CodecParams params;
    int zstd_level = 0;
    bool fallback_to_raw = true;
    std::shared_ptr<const container::OutputChunk> chunk;  // what Finish made of it, its CRC included
  };
  explicit Impl(int entries) : entries_per_chunk(entries < 1 ? 1 : entries) {}
  const int entries_per_chunk;
  std::mutex mutex;
  std::array<std::list<Entry>, static_cast<size_t>(container::ChunkId::kCount)> chunks;
  uint64_t hits = 0, misses = 0;

  bool Find(container::ChunkId id, const container::Fingerprint& content, const container::CodecParams& p,
            const WriteOptions& o, std::shared_ptr<const container::OutputChunk>* out) {
    std::lock_guard<std::mutex> lock(mutex);
    auto& list = chunks[static_cast<size_t>(id)];
    for (auto it = list.begin(); it != list.end(); ++it) {
      if (it->zstd_level == o.zstd_level && it->fallback_to_raw == o.fallback_to_raw && it->params.codec == p.codec &&
          it->params.element_size == p.element_size && it->params.components == p.components &&
          it->params.skip == p.skip && it->content == content) {
        *out = it->chunk;
        list.splice(list.begin(), list, it);
        ++hits;
        return true;
      }
    }
    ++misses;
    return false;
  }
  void Add(container::ChunkId id, const container::Fingerprint& content, const container::CodecParams& p,
           const WriteOptions& o, std::shared_ptr<const container::OutputChunk> chunk) {
    std::lock_guard<std::mutex> lock(mutex);
    auto& list = chunks[static_cast<size_t>(id)];
    list.push_front(Entry{content, p, o.zstd_level, o.fallback_to_raw, std::move(chunk)});
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

// An encoded chunk, shared with the cache: a hit is not copied.
using SharedChunk = std::shared_ptr<const OutputChunk>;

// One chunk to produce: its content and how to encode it.
struct ChunkJob {
  ChunkId id;
  std::function<StatusOr<SharedChunk>()> make;
};

SharedChunk Share(OutputChunk chunk) { return std::make_shared<const OutputChunk>(std::move(chunk)); }

bool ValidEncoding(ScalarEncoding e) {
  return static_cast<uint8_t>(e) <= static_cast<uint8_t>(ScalarEncoding::kQuant8);
}

}  // namespace

Status CheckWriteOptions(const WriteOptions& o) {
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

namespace {

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

// Encode, through the cache when there is one: `content` fingerprints everything the
// uncompressed content depends on; `make_raw` builds it, on a miss only.
using RawMaker = std::function<StatusOr<std::vector<uint8_t>>()>;
StatusOr<SharedChunk> FinishKeyed(ChunkId id, const Fingerprint& content, const RawMaker& make_raw, CodecParams params,
                                  const Context& c) {
  SharedChunk cached;
  if (c.cache->Find(id, content, params, c.options, &cached)) return cached;
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, make_raw());
  ATEX_ASSIGN_OR_RETURN(OutputChunk chunk, Encode(id, std::move(raw), params, c.options));
  // Its CRC once, here: every file that reuses the chunk takes it from the cache.
  chunk.crc = Crc32c(chunk.stored.data(), chunk.stored.size());
  SharedChunk shared = Share(std::move(chunk));
  c.cache->Add(id, content, params, c.options, shared);
  return shared;
}

// Encode content already built (small chunks), through the cache when there is one.
StatusOr<SharedChunk> Finish(ChunkId id, std::vector<uint8_t> raw, CodecParams params, const Context& c) {
  if (c.cache == nullptr) {
    ATEX_ASSIGN_OR_RETURN(OutputChunk chunk, Encode(id, std::move(raw), params, c.options));
    return Share(std::move(chunk));
  }
  const Fingerprint content = FingerprintBuilder().Add(raw).Finish();
  return FinishKeyed(id, content, [&raw]() -> StatusOr<std::vector<uint8_t>> { return std::move(raw); }, params, c);
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

// An attribute stream of `rows` × `components` floats. `fingerprint` adds what the values are
// made from to a fingerprint without building them; `values` gives them (on a cache miss, or
// always without a cache). Its content also depends on the encoding and the shape.
ChunkJob LazyStreamJob(ChunkId id, std::function<void(FingerprintBuilder*)> fingerprint,
                       std::function<const float*(std::vector<float>* storage)> values, uint64_t rows,
                       uint32_t components, ScalarEncoding encoding, const Context& c, const char* what) {
  return {id, [=, &c]() -> StatusOr<SharedChunk> {
            const CodecParams params = StreamCodec(c.options, encoding, components);
            const RawMaker make_raw = [&]() -> StatusOr<std::vector<uint8_t>> {
              std::vector<float> storage;
              return EncodeStream(values(&storage), rows, components, encoding, what);
            };
            if (c.cache == nullptr) {
              ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> raw, make_raw());
              ATEX_ASSIGN_OR_RETURN(OutputChunk chunk, Encode(id, std::move(raw), params, c.options));
              return Share(std::move(chunk));
            }
            FingerprintBuilder key;
            fingerprint(&key);
            key.AddValue(rows).AddValue(components).AddValue(encoding);
            return FinishKeyed(id, key.Finish(), make_raw, params, c);
          }};
}

// A stream of values built here (small ones: the MLP, the statistics).
ChunkJob StreamJob(ChunkId id, std::vector<float> values, uint64_t rows, uint32_t components, ScalarEncoding encoding,
                   const Context& c, const char* what) {
  auto shared = std::make_shared<const std::vector<float>>(std::move(values));
  return LazyStreamJob(
      id, [shared](FingerprintBuilder* key) { key->Add(*shared); },
      [shared](std::vector<float>*) { return shared->data(); }, rows, components, encoding, c, what);
}

// A stream over an existing array (no copy); the array outlives the jobs.
ChunkJob StreamJobRef(ChunkId id, const std::vector<float>& values, uint64_t rows, uint32_t components,
                      ScalarEncoding encoding, const Context& c, const char* what) {
  return LazyStreamJob(
      id, [&values](FingerprintBuilder* key) { key->Add(values); },
      [&values](std::vector<float>*) { return values.data(); }, rows, components, encoding, c, what);
}

ChunkJob DracoPositionsJob(const std::vector<float>& positions, uint64_t n, const WriteOptions& o) {
  return {ChunkId::kGpos, [&positions, n, &o]() -> StatusOr<SharedChunk> {
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
              return Share(std::move(chunk));
            }
            chunk.codec = {Codec::kDraco, 4, 3, static_cast<uint32_t>(kStreamHeaderSize)};
            // Prefix + bitstream. (Assembled with memcpy: vector::insert here trips a
            // gcc 12 -Warray-bounds false positive.)
            chunk.stored.resize(header.size() + draco.size());
            std::memcpy(chunk.stored.data(), header.data(), header.size());
            std::memcpy(chunk.stored.data() + header.size(), draco.data(), draco.size());
            return Share(std::move(chunk));
          }};
}

// SH jobs: sh [N][K][3] splits into DC [N][3] and rest [N][K-1][3], built only when not
// cached (both are keyed by the whole array: a change to either encodes both again).
void AddShJobs(const Gaussians& g, const WriteOptions& o, const Context& ctx, std::vector<ChunkJob>* jobs) {
  const uint64_t n = g.size();
  const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
  const auto sh_key = [&g](FingerprintBuilder* key) { key->Add(g.sh); };
  jobs->push_back(LazyStreamJob(
      ChunkId::kGsh0, sh_key,
      [&g, n, k](std::vector<float>* dc) {
        dc->resize(n * 3);
        for (uint64_t i = 0; i < n; ++i) std::copy_n(g.sh.data() + i * k * 3, 3, dc->data() + i * 3);
        return dc->data();
      },
      n, 3, o.sh_dc, ctx, "sh_dc"));
  if (k > 1) {
    jobs->push_back(LazyStreamJob(
        ChunkId::kGshr, sh_key,
        [&g, n, k](std::vector<float>* rest) {
          rest->resize(n * (k - 1) * 3);
          for (uint64_t i = 0; i < n; ++i) {
            std::copy_n(g.sh.data() + i * k * 3 + 3, (k - 1) * 3, rest->data() + i * (k - 1) * 3);
          }
          return rest->data();
        },
        n, 3 * (k - 1), o.sh_rest, ctx, "sh_rest"));
  }
}

}  // namespace
}  // namespace container

StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options) {
  return EncodeAsset(asset, options, nullptr);
}

namespace {

// Every chunk of the file, in file order (EncodeAsset lays them out).
StatusOr<std::vector<container::SharedChunk>> EncodeChunks(const Asset& asset, const WriteOptions& options,
                                                           EncodeCache::Impl* cache) {
  using namespace container;
  ATEX_RETURN_IF_ERROR(CheckWriteOptions(options));
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  try {
    const Gaussians& g = asset.gaussians;
    const uint64_t n = g.size();
    const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
    const WriteOptions& o = options;
    const Context ctx{options, cache};
    std::vector<ChunkJob> jobs;

    jobs.push_back({ChunkId::kMeta, [&]() -> StatusOr<SharedChunk> {
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
    AddShJobs(g, o, ctx, &jobs);
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
      uint64_t grid_count = 0;
      for (const auto& scale : d.planes) {
        for (const auto& plane : scale) grid_count += plane.size();
      }
      jobs.push_back(LazyStreamJob(
          ChunkId::kDgrd,
          [&d](FingerprintBuilder* key) {
            for (const auto& scale : d.planes) {
              for (const auto& plane : scale) key->Add(plane);
            }
          },
          [&d](std::vector<float>* grids) {
            *grids = FlattenGrids(d);
            return grids->data();
          },
          grid_count, 1, o.deformation_grids, ctx, "deformation grids"));
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

    std::vector<StatusOr<SharedChunk>> results(jobs.size(), Status(StatusCode::kInternal, "chunk not encoded"));
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
    std::vector<SharedChunk> shared;
    shared.reserve(results.size());
    for (auto& result : results) {
      if (!result.ok()) return result.status();
      shared.push_back(std::move(result).value());
    }
    return shared;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory while encoding an asset of ", asset.gaussians.size(),
                     " Gaussians");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "EncodeAsset: ", e.what());
  }
}

std::vector<const container::OutputChunk*> Pointers(const std::vector<container::SharedChunk>& shared) {
  std::vector<const container::OutputChunk*> chunks;
  chunks.reserve(shared.size());
  for (const auto& chunk : shared) chunks.push_back(chunk.get());
  return chunks;
}

}  // namespace

StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options, EncodeCache* cache) {
  ATEX_ASSIGN_OR_RETURN(const auto shared, EncodeChunks(asset, options, cache != nullptr ? cache->impl_ : nullptr));
  try {
    return container::AssembleContainer(Pointers(shared));
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory while laying out an asset of ", asset.gaussians.size(),
                     " Gaussians");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "EncodeAsset: ", e.what());
  }
}

StatusOr<uint64_t> EncodedAssetSize(const Asset& asset, const WriteOptions& options, EncodeCache* cache) {
  ATEX_ASSIGN_OR_RETURN(const auto shared, EncodeChunks(asset, options, cache != nullptr ? cache->impl_ : nullptr));
  return container::ContainerSize(Pointers(shared));
}

Status WriteAssetFile(const std::string& path, const Asset& asset, const WriteOptions& options) {
  auto bytes = EncodeAsset(asset, options);
  if (!bytes.ok()) return bytes.status().WithContext(path);
  return WriteFileAtomic(path, *bytes);
}

}  // namespace atex
