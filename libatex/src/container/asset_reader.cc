// DecodeAsset / ReadAssetFile (format_spec/atex.md §8): structure first, then
// CRCs, then each chunk in an order where every count a later chunk relies on
// has been backed by decoded data.
#include <array>
#include <atomic>
#include <bit>
#include <cstring>
#include <list>
#include <memory>
#include <mutex>
#include <optional>

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

// Per chunk type, the most recently used versions first, each type under its own lock (the
// streams of one file are decoded in parallel, and so are the fitter's candidates). Values are
// shared, so a hit is copied out after its lock is released.
struct DecodeCache::Impl {
  struct Entry {
    std::vector<uint8_t> stored;  // the chunk's bytes as stored
    container::CodecParams codec;
    uint64_t raw_size = 0, rows = 0;
    uint32_t components = 0;
    std::shared_ptr<const std::vector<float>> values;  // what they decode to
  };
  static constexpr size_t kKinds = static_cast<size_t>(container::ChunkId::kCount);
  explicit Impl(int entries) : entries_per_chunk(entries < 1 ? 1 : entries) {}
  const int entries_per_chunk;
  mutable std::array<std::mutex, kKinds> mutexes;
  std::array<std::list<Entry>, kKinds> chunks;
  std::atomic<uint64_t> hits{0}, misses{0};

  static bool Same(const Entry& e, const uint8_t* stored, const container::TocEntry& toc, uint64_t rows,
                   uint32_t components) {
    return e.codec.codec == toc.codec.codec && e.codec.element_size == toc.codec.element_size &&
           e.codec.components == toc.codec.components && e.codec.skip == toc.codec.skip &&
           e.raw_size == toc.raw_size && e.rows == rows && e.components == components &&
           e.stored.size() == toc.stored_size && std::memcmp(e.stored.data(), stored, e.stored.size()) == 0;
  }
  bool Find(container::ChunkId id, const uint8_t* stored, const container::TocEntry& toc, uint64_t rows,
            uint32_t components, std::vector<float>* values) {
    std::shared_ptr<const std::vector<float>> found;
    {
      const size_t k = static_cast<size_t>(id);
      std::lock_guard<std::mutex> lock(mutexes[k]);
      auto& list = chunks[k];
      for (auto it = list.begin(); it != list.end(); ++it) {
        if (Same(*it, stored, toc, rows, components)) {
          found = it->values;
          list.splice(list.begin(), list, it);
          break;
        }
      }
    }
    if (!found) {
      ++misses;
      return false;
    }
    ++hits;
    *values = *found;
    return true;
  }
  void Add(container::ChunkId id, const uint8_t* stored, const container::TocEntry& toc, uint64_t rows,
           uint32_t components, const std::vector<float>& values) {
    Entry e{std::vector<uint8_t>(stored, stored + toc.stored_size), toc.codec, toc.raw_size, rows, components,
            std::make_shared<const std::vector<float>>(values)};
    const size_t k = static_cast<size_t>(id);
    std::lock_guard<std::mutex> lock(mutexes[k]);
    auto& list = chunks[k];
    list.push_front(std::move(e));
    while (list.size() > static_cast<size_t>(entries_per_chunk)) list.pop_back();
  }
};

DecodeCache::DecodeCache(int entries_per_chunk) : impl_(new Impl(entries_per_chunk)) {}
DecodeCache::~DecodeCache() { delete impl_; }
uint64_t DecodeCache::hits() const { return impl_->hits.load(); }
uint64_t DecodeCache::misses() const { return impl_->misses.load(); }

namespace container {
namespace {

constexpr size_t kChunkKinds = static_cast<size_t>(ChunkId::kCount);

class AssetDecoder {
 public:
  AssetDecoder(const uint8_t* data, size_t size, const ReadOptions& options, DecodeCache::Impl* cache)
      : data_(data), size_(size), options_(options), cache_(cache) {}

  // The META chunk alone: the container's structure and META's checksum are checked, no
  // other chunk is read.
  StatusOr<Metadata> MetadataOnly() {
    ATEX_ASSIGN_OR_RETURN(container_, ParseContainer(data_, size_, options_.verify_checksums));
    ATEX_RETURN_IF_ERROR(IndexChunks());
    ATEX_RETURN_IF_ERROR(CheckPresence());
    const int meta_index = index_[static_cast<size_t>(ChunkId::kMeta)];
    if (options_.verify_checksums) {
      ATEX_RETURN_IF_ERROR(VerifyChunkCrc(data_, container_.entries[meta_index], static_cast<size_t>(meta_index)));
    }
    ATEX_ASSIGN_OR_RETURN(ChunkBytes meta, Content(ChunkId::kMeta));
    auto metadata = DecodeMeta(meta.data(), meta.size());
    if (!metadata.ok()) return metadata.status().WithContext(Label(ChunkId::kMeta));
    return metadata;
  }

  StatusOr<Asset> Run() {
    ATEX_ASSIGN_OR_RETURN(container_, ParseContainer(data_, size_, options_.verify_checksums));
    ATEX_RETURN_IF_ERROR(IndexChunks());
    ATEX_RETURN_IF_ERROR(CheckPresence());
    if (options_.verify_checksums) ATEX_RETURN_IF_ERROR(VerifyCrcs());
    ATEX_RETURN_IF_ERROR(CheckDecodedSize());

    Asset asset;
    {
      ATEX_ASSIGN_OR_RETURN(ChunkBytes meta, Content(ChunkId::kMeta));
      auto metadata = DecodeMeta(meta.data(), meta.size());
      if (!metadata.ok()) return metadata.status().WithContext(Label(ChunkId::kMeta));
      asset.metadata = std::move(metadata).value();
    }
    ATEX_ASSIGN_OR_RETURN(ChunkBytes ghdr, Content(ChunkId::kGhdr));
    auto header = DecodeGhdr(ghdr.data(), ghdr.size());
    if (!header.ok()) return header.status().WithContext(Label(ChunkId::kGhdr));
    const uint64_t n = header->count;
    gaussian_count_ = n;
    Gaussians& g = asset.gaussians;
    g.sh_degree = header->sh_degree;
    const uint32_t k = static_cast<uint32_t>(g.sh_coeffs());
    if ((k > 1) != Has(ChunkId::kGshr)) {
      return MakeError(StatusCode::kCorrupt, "SH degree ", g.sh_degree, " (GHDR) but GSHR is ",
                       Has(ChunkId::kGshr) ? "present" : "missing");
    }

    // GOPA first: after it, N is backed by decoded bytes (Draco's allocations depend on N).
    ATEX_RETURN_IF_ERROR(Stream(ChunkId::kGopa, 1, n, &g.opacity_logits));

    // The small chunks that give the other streams their row counts.
    std::optional<TexturePool> textures;
    if (Has(ChunkId::kTlay)) {
      textures.emplace();
      ATEX_ASSIGN_OR_RETURN(ChunkBytes layout, Content(ChunkId::kTlay));
      Status s = DecodeTextureLayout(layout.data(), layout.size(), n, &*textures);
      if (!s.ok()) return s.WithContext(Label(ChunkId::kTlay));
    }
    std::optional<DeformationField> field;
    if (Has(ChunkId::kDcfg)) {
      field.emplace();
      ATEX_ASSIGN_OR_RETURN(ChunkBytes dcfg, Content(ChunkId::kDcfg));
      auto config = DecodeDeformationConfig(dcfg.data(), dcfg.size());
      if (!config.ok()) return config.status().WithContext(Label(ChunkId::kDcfg));
      field->config = std::move(config).value();
      if (field->config.heads[kHeadSH] && field->config.sh_coeffs != static_cast<int>(k)) {
        return MakeError(StatusCode::kCorrupt, Label(ChunkId::kDcfg), ": SH head with sh_coeffs ",
                         field->config.sh_coeffs, " but the Gaussians have ", k, " coefficients");
      }
    }

    // The bulk: independent streams.
    std::vector<float> dc, rest, grids, mlp, stats_rows;  // [N][3], [N][K-1][3], [G], [P], [N][4]
    std::vector<StreamJob> jobs = {{ChunkId::kGpos, 3, n, &g.positions},
                                   {ChunkId::kGrot, 4, n, &g.rotations},
                                   {ChunkId::kGscl, 3, n, &g.log_scales},
                                   {ChunkId::kGsh0, 3, n, &dc}};
    if (k > 1) jobs.push_back({ChunkId::kGshr, 3 * (k - 1), n, &rest});
    if (Has(ChunkId::kGtwn)) jobs.push_back({ChunkId::kGtwn, 2, n, &g.time_windows});
    if (textures) jobs.push_back({ChunkId::kTexl, kTexelChannels, textures->texel_count(), &textures->texels});
    if (field) {
      jobs.push_back({ChunkId::kDgrd, 1, GridValueCount(field->config), &grids});
      jobs.push_back({ChunkId::kDmlp, 1, MlpValueCount(field->config), &mlp});
    }
    const bool read_stats = Has(ChunkId::kGsta) && options_.read_stats;
    if (read_stats) jobs.push_back({ChunkId::kGsta, 4, n, &stats_rows});
    ATEX_RETURN_IF_ERROR(Streams(jobs));

    // sh [N][K][3] from DC [N][3] and rest [N][K-1][3].
    g.sh.resize(dc.size() * k);
    for (uint64_t i = 0; i < n; ++i) {
      std::copy(dc.begin() + i * 3, dc.begin() + i * 3 + 3, g.sh.begin() + i * k * 3);
      if (k > 1)
        std::copy(rest.begin() + i * (k - 1) * 3, rest.begin() + (i + 1) * (k - 1) * 3, g.sh.begin() + i * k * 3 + 3);
    }
    if (textures) asset.textures = std::move(textures);
    if (field) {
      UnflattenGrids(grids, &*field);
      UnflattenMlp(mlp, &*field);
      asset.deformation = std::move(field);
    }
    if (read_stats) {
      GaussianStats stats;
      stats.texture_demand.resize(n);
      stats.peak_scale_u.resize(n);
      stats.peak_scale_v.resize(n);
      stats.importance.resize(n);
      for (uint64_t i = 0; i < n; ++i) {
        stats.texture_demand[i] = stats_rows[i * 4 + 0];
        stats.peak_scale_u[i] = stats_rows[i * 4 + 1];
        stats.peak_scale_v[i] = stats_rows[i * 4 + 2];
        stats.importance[i] = stats_rows[i * 4 + 3];
      }
      asset.stats = std::move(stats);
    }

    Status valid = ValidateAsset(asset);
    if (!valid.ok()) {
      const StatusCode code = valid.code() == StatusCode::kInvalidArgument ? StatusCode::kCorrupt : valid.code();
      return Status(code, StrCat("decoded asset is inconsistent: ", valid.message()));
    }
    return asset;
  }

 private:
  bool Has(ChunkId id) const { return index_[static_cast<size_t>(id)] >= 0; }
  const TocEntry& Entry(ChunkId id) const {
    return container_.entries[static_cast<size_t>(index_[static_cast<size_t>(id)])];
  }
  std::string Label(ChunkId id) const {
    return ChunkLabel(Entry(id), static_cast<size_t>(index_[static_cast<size_t>(id)]));
  }

  Status IndexChunks() {
    index_.fill(-1);
    for (size_t i = 0; i < container_.entries.size(); ++i) {
      const TocEntry& e = container_.entries[i];
      const ChunkId id = FindChunkId(e.type);
      if (id == ChunkId::kCount) {
        if (e.critical()) {
          return MakeError(StatusCode::kUnknownCriticalChunk, ChunkLabel(e, i),
                           " is marked critical and this reader (format ", kVersionMajor, ".", kVersionMinor,
                           ") does not know it; file version is ", container_.version_major, ".",
                           container_.version_minor);
        }
        continue;  // unknown, non-critical: skipped
      }
      index_[static_cast<size_t>(id)] = static_cast<int>(i);
    }
    return Status::Ok();
  }

  Status CheckPresence() const {
    for (size_t id = 0; id < kChunkKinds; ++id) {
      if (kChunkTypes[id].required && index_[id] < 0) {
        return MakeError(StatusCode::kCorrupt, "required chunk '", kChunkTypes[id].type, "' is missing");
      }
    }
    if (Has(ChunkId::kTlay) != Has(ChunkId::kTexl)) {
      return MakeError(StatusCode::kCorrupt, "TLAY and TEXL must appear together; only ",
                       Has(ChunkId::kTlay) ? "TLAY" : "TEXL", " is present");
    }
    const int deform = Has(ChunkId::kDcfg) + Has(ChunkId::kDgrd) + Has(ChunkId::kDmlp);
    if (deform != 0 && deform != 3) {
      return MakeError(StatusCode::kCorrupt, "DCFG, DGRD and DMLP must appear together; ", deform, " of 3 are present");
    }
    if (Has(ChunkId::kGtwn) && deform == 0) {
      return MakeError(StatusCode::kCorrupt, "GTWN (time windows) needs a deformation field, but DCFG is missing");
    }
    return Status::Ok();
  }

  Status CheckDecodedSize() const {
    uint64_t total = 0;
    for (size_t id = 0; id < kChunkKinds; ++id) {
      if (index_[id] < 0 || (static_cast<ChunkId>(id) == ChunkId::kGsta && !options_.read_stats)) continue;
      const TocEntry& e = container_.entries[static_cast<size_t>(index_[id])];
      if (AddOverflows(total, e.raw_size, &total) || total > options_.max_decoded_bytes) {
        return MakeError(StatusCode::kLimitExceeded, "chunks decode to more than the limit of ",
                         options_.max_decoded_bytes, " bytes (reached at ",
                         ChunkLabel(e, static_cast<size_t>(index_[id])), ", raw size ", e.raw_size, ")");
      }
    }
    // A decompression bomb: checked before anything is inflated.
    const uint64_t ratio = options_.max_expansion_ratio;
    if (ratio > 0 && total > options_.expansion_check_floor && total / ratio > size_) {
      return MakeError(StatusCode::kLimitExceeded, "chunks declare ", total, " decoded bytes from a file of ", size_,
                       " bytes, more than ", ratio, " times its size (ReadOptions::max_expansion_ratio)");
    }
    return Status::Ok();
  }

  // The chunk content (raw bytes) of a present chunk. Thread-safe.
  StatusOr<ChunkBytes> Content(ChunkId id) const {
    const TocEntry& e = Entry(id);
    const uint8_t* stored = data_ + e.offset;
    const size_t stored_size = static_cast<size_t>(e.stored_size);
    if (e.codec.codec == Codec::kDraco) {
      // Parameters were checked by ParseContainer: skip <= raw_size, (raw - skip) % 12 == 0.
      if (e.codec.skip > stored_size) {
        return MakeError(StatusCode::kCorrupt, Label(id), ": stored bytes shorter than the ", e.codec.skip,
                         "-byte prefix");
      }
      const uint64_t points = (e.raw_size - e.codec.skip) / 12;
      if (points != gaussian_count_) {
        return MakeError(StatusCode::kCorrupt, Label(id), ": raw size implies ", points, " points, the file has ",
                         gaussian_count_, " Gaussians");
      }
      std::vector<uint8_t> raw(stored, stored + e.codec.skip);
      Status s = DracoDecodePositions(stored + e.codec.skip, stored_size - e.codec.skip, points, &raw);
      if (!s.ok()) return s.WithContext(Label(id));
      return ChunkBytes::Copy(raw.data(), raw.size());
    }
    auto raw = DecodeChunk(stored, stored_size, e.raw_size, e.codec);
    if (!raw.ok()) return raw.status().WithContext(Label(id));
    return raw;
  }

  // Decodes an attribute stream of `rows` x `components` into *values, which is
  // sized only after the stream header has been checked against the chunk's
  // real (decoded) size. Thread-safe for distinct outputs.
  Status Stream(ChunkId id, uint32_t components, uint64_t rows, std::vector<float>* values) const {
    const TocEntry& e = Entry(id);
    if (cache_ == nullptr) return DecodeStreamChunk(id, components, rows, values);
    // Chunks stored in draco are not cached: their header check below reads the decoded bytes.
    if (e.codec.codec == Codec::kDraco) return DecodeStreamChunk(id, components, rows, values);
    if (cache_->Find(id, data_ + e.offset, e, rows, components, values)) return Status::Ok();
    ATEX_RETURN_IF_ERROR(DecodeStreamChunk(id, components, rows, values));
    cache_->Add(id, data_ + e.offset, e, rows, components, *values);
    return Status::Ok();
  }

  Status DecodeStreamChunk(ChunkId id, uint32_t components, uint64_t rows, std::vector<float>* values) const {
    const TocEntry& e = Entry(id);
    if (std::endian::native == std::endian::little && e.codec.codec == Codec::kShuffleZstd &&
        e.codec.element_size == 4 && e.codec.skip >= kStreamHeaderSize) {
      // The common f32 case: unshuffle straight into the destination (one buffer less).
      auto transformed = DecodeZstdStage(data_ + e.offset, static_cast<size_t>(e.stored_size), e.raw_size, e.codec);
      if (!transformed.ok()) return transformed.status().WithContext(Label(id));
      Status s = UnshuffledFloats(*transformed, e.codec, components, rows, values);
      if (!s.ok()) return s.WithContext(Label(id));
      return Status::Ok();
    }
    ATEX_ASSIGN_OR_RETURN(ChunkBytes raw, Content(id));
    Status s = DecodeStream(raw.data(), raw.size(), components, rows, values);
    if (!s.ok()) return s.WithContext(Label(id));
    if (Entry(id).codec.codec == Codec::kDraco && raw.data()[kStreamEncoding] != 0) {
      return MakeError(StatusCode::kCorrupt, Label(id), ": Draco positions must have an f32 stream header");
    }
    return Status::Ok();
  }

  // Codec 2 with 4-byte elements: the stream header is in the untouched prefix;
  // when it says f32 and the prefix is exactly the header, the unshuffled body is
  // the float array itself.
  static Status UnshuffledFloats(const ChunkBytes& transformed, const CodecParams& codec, uint32_t components,
                                 uint64_t rows, std::vector<float>* values) {
    // Parse the header as if the body were plain: only its size check looks at the body length.
    ATEX_ASSIGN_OR_RETURN(const StreamInfo info, ParseStreamHeader(transformed.data(), transformed.size()));
    if (info.encoding != ScalarEncoding::kFloat32 || info.header_bytes != codec.skip) {
      // Another layout: undo the transform in full and take the general path.
      ChunkBytes raw = ChunkBytes::Allocate(transformed.size());
      CopyBytes(raw.mutable_data(), transformed.data(), codec.skip);
      UnshuffleBytes(transformed.data() + codec.skip, transformed.size() - codec.skip, 4,
                     raw.mutable_data() + codec.skip);
      return DecodeStream(raw.data(), raw.size(), components, rows, values);
    }
    if (info.components != components) {
      return MakeError(StatusCode::kCorrupt, "stream has ", info.components, " components, expected ", components);
    }
    if (info.rows != rows) return MakeError(StatusCode::kCorrupt, "stream has ", info.rows, " rows, expected ", rows);
    values->resize(static_cast<size_t>(rows * components));  // rows * components * 4 bytes were decoded
    UnshuffleBytes(transformed.data() + codec.skip, transformed.size() - codec.skip, 4,
                   reinterpret_cast<uint8_t*>(values->data()));
    return CheckFiniteValues(values->data(), rows, components);
  }

  // Decodes independent streams, in parallel when they are large enough to pay
  // for threads; the error reported is that of the first job in order.
  struct StreamJob {
    ChunkId id;
    uint32_t components;
    uint64_t rows;
    std::vector<float>* values;
  };
  Status Streams(const std::vector<StreamJob>& jobs) const {
    std::vector<Status> results(jobs.size());
    uint64_t bytes = 0;
    for (const StreamJob& job : jobs) bytes += Entry(job.id).raw_size;
    const bool parallel = bytes > (uint64_t{1} << 20);
    (void)parallel;  // unused without OpenMP
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
#endif
    for (size_t i = 0; i < jobs.size(); ++i) {
      try {
        results[i] = Stream(jobs[i].id, jobs[i].components, jobs[i].rows, jobs[i].values);
      } catch (const std::bad_alloc&) {
        results[i] = Status(StatusCode::kLimitExceeded, StrCat("out of memory decoding ", Label(jobs[i].id)));
      }
    }
    for (const Status& s : results) ATEX_RETURN_IF_ERROR(s);
    return Status::Ok();
  }

  Status VerifyCrcs() const {
    const size_t count = container_.entries.size();
    std::vector<Status> results(count);
    uint64_t bytes = 0;
    for (const TocEntry& e : container_.entries) bytes += e.stored_size;
    const bool parallel = bytes > (uint64_t{16} << 20);
    (void)parallel;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) if (parallel)
#endif
    for (size_t i = 0; i < count; ++i) results[i] = VerifyChunkCrc(data_, container_.entries[i], i);
    for (const Status& s : results) ATEX_RETURN_IF_ERROR(s);
    return Status::Ok();
  }

  const uint8_t* data_;
  size_t size_;
  const ReadOptions& options_;
  ParsedContainer container_;
  std::array<int, kChunkKinds> index_{};
  uint64_t gaussian_count_ = 0;  // from GHDR, set before any stream is decoded
  DecodeCache::Impl* cache_;     // may be null
};

}  // namespace
}  // namespace container

StatusOr<Asset> DecodeAsset(const uint8_t* data, size_t size, const ReadOptions& options) {
  return DecodeAsset(data, size, options, nullptr);
}

StatusOr<Asset> DecodeAsset(const uint8_t* data, size_t size, const ReadOptions& options, DecodeCache* cache) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "DecodeAsset: null data");
  try {
    container::AssetDecoder decoder(data, size, options, cache != nullptr ? cache->impl_ : nullptr);
    return decoder.Run();
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory decoding a ", size, "-byte .atex file");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "DecodeAsset: ", e.what());
  }
}

StatusOr<Metadata> DecodeMetadata(const uint8_t* data, size_t size, const ReadOptions& options) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "DecodeMetadata: null data");
  try {
    container::AssetDecoder decoder(data, size, options, nullptr);
    return decoder.MetadataOnly();
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory reading the metadata of a ", size, "-byte .atex file");
  } catch (const std::exception& e) {
    return MakeError(StatusCode::kInternal, "DecodeMetadata: ", e.what());
  }
}

StatusOr<Asset> ReadAssetFile(const std::string& path, const ReadOptions& options) {
  auto bytes = ReadFileBytes(path);
  if (!bytes.ok()) return bytes.status();
  auto asset = DecodeAsset(bytes->data(), bytes->size(), options);
  if (!asset.ok()) return asset.status().WithContext(path);
  return asset;
}

}  // namespace atex
