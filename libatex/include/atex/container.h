// Reading and writing .atex containers (format_spec/atex.md is normative).
//
// Writers are deterministic: the same asset and options give the same bytes.
// Readers treat their input as hostile: every size, offset, count and value is
// checked before use, allocations grow only with data actually decoded, and
// failures name the chunk and byte offset.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/model.h"
#include "atex/file_io.h"
#include "atex/status.h"

namespace atex {

// Per-chunk compression (format_spec/atex.md, "Codecs").
enum class Codec : uint8_t {
  kRaw = 0,
  kZstd = 1,
  kShuffleZstd = 2,       // byte-plane shuffle by element size, then zstd
  kDeltaShuffleZstd = 3,  // integer delta along each component, shuffle, zstd (quantised streams)
  kDraco = 4,             // Draco point-cloud coding, positions only (optional in a build)
};

// How a float attribute stream is stored (format_spec/atex.md, "Attribute streams").
enum class ScalarEncoding : uint8_t {
  kFloat32 = 0,
  kFloat16 = 1,
  kQuant16 = 2,  // per-component min/max + 16-bit unsigned levels
  kQuant8 = 3,   // per-component min/max + 8-bit unsigned levels
};

struct WriteOptions {
  // Codec of the attribute streams. kDeltaShuffleZstd applies delta to quantised
  // streams only (float streams get kShuffleZstd); META, GHDR, TLAY and DCFG get
  // kZstd under any compressing codec. kDraco is not allowed here: see
  // draco_positions.
  Codec codec = Codec::kShuffleZstd;
  int zstd_level = 3;
  ScalarEncoding positions = ScalarEncoding::kFloat32;
  ScalarEncoding rotations = ScalarEncoding::kFloat32;
  ScalarEncoding log_scales = ScalarEncoding::kFloat32;
  ScalarEncoding opacities = ScalarEncoding::kFloat32;
  ScalarEncoding sh_dc = ScalarEncoding::kFloat32;
  ScalarEncoding sh_rest = ScalarEncoding::kFloat32;
  ScalarEncoding texels = ScalarEncoding::kFloat32;
  ScalarEncoding deformation_grids = ScalarEncoding::kFloat32;
  bool draco_positions = false;  // positions through Draco (needs a Draco build)
  int draco_position_bits = 16;  // 1..30
  // Store a chunk raw when the codec does not make it smaller (format_spec §9).
  // Turn off only to exercise a codec on data it cannot compress.
  bool fallback_to_raw = true;
  bool write_stats = true;  // write GSTA when the asset has statistics
  friend bool operator==(const WriteOptions&, const WriteOptions&) = default;
};

struct ReadOptions {
  // Off: skip the header and chunk CRC32C checks (for fuzzing and forensics; every
  // structural check still runs).
  bool verify_checksums = true;
  // Refuse files whose chunks' raw sizes add up to more than this (kLimitExceeded):
  // 32 GiB, or half the machine's RAM when smaller (MemoryLimit, file_io.h).
  uint64_t max_decoded_bytes = MemoryLimit(uint64_t{32} << 30);
  // Refuse files whose chunks' raw sizes exceed this many times the file's size once they
  // pass expansion_check_floor (a decompression bomb: kilobytes of zeros declaring gigabytes). Real
  // assets compress a few times at most; 0 turns the check off.
  uint64_t max_expansion_ratio = 1024;
  uint64_t expansion_check_floor = uint64_t{64} << 20;  // decoded sizes below this are never a bomb
  bool read_stats = true;  // decode GSTA into Asset::stats
};

// Validates the asset (ValidateAsset) and encodes it. Errors: the validation's
// (kInvalidArgument / kOutOfRange naming the array and element), kOutOfRange for a
// value that does not fit the chosen encoding (f16 overflow), kInvalidArgument for
// options out of range (zstd level, Draco bits), kUnsupportedCodec for Draco in a
// build without it. The result's size is exactly what the file will take.
// Large assets are encoded chunk-parallel (OpenMP); the bytes do not depend on it.
StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options = {});

// Remembers encoded chunks so that encoding an asset again, with some chunks'
// content unchanged, compresses only the changed ones (the budget fitter encodes
// hundreds of candidates that differ in one stream). A chunk is keyed by its codec
// settings and a 128-bit fingerprint of what its content is made from (the values,
// their shape and encoding), so an unchanged stream is found without quantising it;
// a cached encode returns the bytes of an uncached one unless two different contents
// share a fingerprint (a chance of the order of 2^-64 per lookup; docs/fit.md, "What
// the fitter caches"): where the bytes must never depend on that, encode without it.
// Keeps the most recently used `entries_per_chunk` versions of each chunk type.
// Thread-safe.
class EncodeCache {
 public:
  explicit EncodeCache(int entries_per_chunk = 3);
  ~EncodeCache();
  EncodeCache(const EncodeCache&) = delete;
  EncodeCache& operator=(const EncodeCache&) = delete;
  uint64_t hits() const;
  uint64_t misses() const;
  struct Impl;

 private:
  friend StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset&, const WriteOptions&, EncodeCache*);
  friend StatusOr<uint64_t> EncodedAssetSize(const Asset&, const WriteOptions&, EncodeCache*);
  Impl* impl_;
};
// EncodeAsset through `cache` (nullptr: no cache).
StatusOr<std::vector<uint8_t>> EncodeAsset(const Asset& asset, const WriteOptions& options, EncodeCache* cache);

// EncodeAsset(asset, options, cache)->size(), with the same errors, without assembling the
// file: the chunks are encoded (through `cache`, which they fill as EncodeAsset's do) and
// laid out, not copied into one buffer. For callers that need the size of many variants.
StatusOr<uint64_t> EncodedAssetSize(const Asset& asset, const WriteOptions& options, EncodeCache* cache = nullptr);

// Remembers decoded attribute streams so that decoding a file whose chunks are partly
// byte-identical to recently decoded ones decompresses and converts only the others (the
// budget fitter decodes every candidate it measures, and most differ from the current state
// in one or two chunks). A hit is verified byte for byte against the stored chunk, its codec
// and its shape, so a cached decode returns exactly the values of an uncached one. Keeps the
// most recently used `entries_per_chunk` versions of each chunk type (their stored bytes and
// decoded values: memory of a few decoded assets). Thread-safe.
class DecodeCache {
 public:
  explicit DecodeCache(int entries_per_chunk = 3);
  ~DecodeCache();
  DecodeCache(const DecodeCache&) = delete;
  DecodeCache& operator=(const DecodeCache&) = delete;
  uint64_t hits() const;    // streams taken from the cache
  uint64_t misses() const;  // streams decoded (and then remembered)
  struct Impl;

 private:
  friend StatusOr<Asset> DecodeAsset(const uint8_t*, size_t, const ReadOptions&, DecodeCache*);
  Impl* impl_;
};

// Decodes and checks a whole file (every structural rule, every CRC, every value;
// the result passes ValidateAsset). Unknown non-critical chunks are skipped,
// unknown critical chunks refused (kUnknownCriticalChunk). Errors name the chunk
// and byte offset. Lossy encodings (f16, quant, Draco) come back as the values
// the file holds, not the values originally written.
StatusOr<Asset> DecodeAsset(const uint8_t* data, size_t size, const ReadOptions& options = {});
// DecodeAsset through `cache` (nullptr: no cache); every check still runs on the result.
StatusOr<Asset> DecodeAsset(const uint8_t* data, size_t size, const ReadOptions& options, DecodeCache* cache);
// The file's metadata (META) without decoding anything else: the header, the TOC and the
// chunk set are checked as DecodeAsset checks them, and META's CRC when options.verify_checksums;
// the other chunks are neither checked nor decoded. For a caller that needs only the scene's
// background, bounds or texture mode of a large file.
StatusOr<Metadata> DecodeMetadata(const uint8_t* data, size_t size, const ReadOptions& options = {});

// File forms; writes are atomic (temporary file + rename). Errors are prefixed
// with the path.
Status WriteAssetFile(const std::string& path, const Asset& asset, const WriteOptions& options = {});
StatusOr<Asset> ReadAssetFile(const std::string& path, const ReadOptions& options = {});

// The chunk table without decoding payloads (for `atex info`).
struct ChunkInfo {
  std::string type;        // four characters, e.g. "GPOS"
  uint16_t flags = 0;      // bit 0: critical
  Codec codec = Codec::kRaw;
  uint64_t offset = 0;     // from the start of the file
  uint64_t stored_size = 0;
  uint64_t raw_size = 0;
  uint32_t checksum = 0;   // CRC32C of the stored bytes
  bool known = false;      // a chunk type this reader understands
  uint8_t codec_param = 0;        // element size for codecs 2-4
  uint32_t codec_components = 0;  // components for codecs 3-4
  uint32_t codec_skip = 0;        // leading bytes the transform leaves alone
  bool critical() const { return (flags & 1u) != 0; }
};
struct ContainerInfo {
  uint16_t version_major = 0, version_minor = 0;
  uint32_t flags = 0;
  uint64_t file_size = 0;
  std::vector<ChunkInfo> chunks;
};
// Checks the header, its CRC and the TOC (every rule of format_spec §3-4) and
// lists the chunks; payloads are neither checked nor decoded. Unknown chunk
// types, critical or not, are listed with known = false.
StatusOr<ContainerInfo> InspectContainer(const uint8_t* data, size_t size);

// ---------------------------------------------------------------------------
// Inspection helpers (for `atex info` and the budget fitter).

// The scalar encoding of an attribute-stream chunk (GPOS ... GSTA), read from its
// stream header; decodes only the first 16 bytes of the content. `chunk` comes
// from InspectContainer on the same bytes. kInvalidArgument for META, GHDR, TLAY,
// DCFG and unknown types.
StatusOr<ScalarEncoding> StreamEncodingOf(const uint8_t* data, size_t size, const ChunkInfo& chunk);

// Stable lower-case names: "raw", "zstd", "shuffle-zstd", "delta-shuffle-zstd",
// "draco" ("codec-<n>" for unknown numbers); "f32", "f16", "q16", "q8".
std::string CodecName(Codec codec);
std::string ScalarEncodingName(ScalarEncoding encoding);

// True when this build can write and read codec 4 (Draco).
bool HaveDracoCodec();

// Bytes of the file per component: "header" (32 bytes) and, per chunk group,
// the footprint of its chunks = 48-byte TOC entry + stored bytes + padding
// (format_spec §13). Groups: metadata (META, GHDR), positions, rotations,
// scales, opacities, sh_dc, sh_rest, textures (TLAY, TEXL), deformation (DCFG,
// DGRD, DMLP), stats (GSTA), unknown. Only groups present are listed, in this
// order; their bytes add up exactly to info.file_size.
struct ComponentSize {
  std::string component;
  uint64_t bytes = 0;
};
std::vector<ComponentSize> ComponentBytes(const ContainerInfo& info);

// Texture sizes of a pool: counts[log2 h][log2 w] for h, w in {1, 2, 4}.
struct TextureHistogram {
  std::array<std::array<uint64_t, 3>, 3> counts{};  // [log2 h][log2 w]
  uint64_t gaussians = 0;
  uint64_t texels = 0;                               // sum of h*w
  uint64_t uniform_texels() const { return gaussians * 16; }  // every texture 4x4
  // Texel bytes at `bytes_per_value` per channel (4 for f32), actual and if
  // every Gaussian had a 4x4 texture.
  uint64_t texel_bytes(size_t bytes_per_value) const { return texels * 4 * bytes_per_value; }
  uint64_t uniform_texel_bytes(size_t bytes_per_value) const { return uniform_texels() * 4 * bytes_per_value; }
};
TextureHistogram ComputeTextureHistogram(const TexturePool& textures);

}  // namespace atex
