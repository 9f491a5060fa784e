// Chunk codecs 0-3 (format_spec/atex.md §5): raw, zstd, byte-plane shuffle +
// zstd, integer delta + shuffle + zstd. Codec 4 (Draco) is in draco_codec.h.
// These functions do not know chunk types; errors name no chunk (callers add it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <vector>

#include "atex/container.h"
#include "atex/status.h"

namespace atex::container {

// The codec fields of a TOC entry.
struct CodecParams {
  Codec codec = Codec::kRaw;
  uint8_t element_size = 0;  // codec_param: e
  uint32_t components = 0;   // codec_components: C
  uint32_t skip = 0;         // codec_skip: H, leading raw bytes the transform leaves alone
};

// Chunk content: a view of the file's bytes (codec 0, no copy) or bytes owned
// through malloc, grown with realloc (no zero-filling, and large blocks usually
// grow in place), so decoding a chunk touches each output byte once.
class ChunkBytes {
 public:
  ChunkBytes() = default;
  static ChunkBytes View(const uint8_t* data, size_t size);
  // Uninitialised bytes; throws std::bad_alloc.
  static ChunkBytes Allocate(size_t size);
  static ChunkBytes Copy(const uint8_t* data, size_t size);
  // Owned bytes only: keeps min(old, new) bytes; throws std::bad_alloc.
  void Resize(size_t size);
  const uint8_t* data() const { return owned_ ? owned_.get() : view_; }
  uint8_t* mutable_data() { return owned_.get(); }
  size_t size() const { return size_; }
  std::vector<uint8_t> ToVector() const { return std::vector<uint8_t>(data(), data() + size_); }

 private:
  struct Free {
    void operator()(uint8_t* p) const noexcept { std::free(p); }
  };
  std::unique_ptr<uint8_t, Free> owned_;
  const uint8_t* view_ = nullptr;
  size_t size_ = 0;
};

// Checks the parameter combination of §5 against raw_size (kCorrupt, or
// kUnsupportedCodec for an unknown codec number). Draco's parameters included.
Status CheckCodecParams(const CodecParams& params, uint64_t raw_size);

// Chunks of at least this many bytes (after the codec's transform) are compressed by zstd's
// worker threads: one large stream (SH, texels of a big model) is otherwise the whole encode's
// critical path while the other chunks are done.
inline constexpr size_t kParallelZstdBytes = size_t{16} << 20;

// The zstd worker count for `size` bytes: 0 (the calling thread) below kParallelZstdBytes, else
// `workers` if positive, else one per hardware thread, at most 16.
int ZstdWorkersFor(size_t size, int workers = 0);

// zstd frame of data[0, size) at `level`, workers as ZstdWorkersFor says. The bytes do not depend
// on the worker count (zstd cuts multithreaded frames into jobs sized by the level alone), so a
// file is the same on every machine; kInternal if zstd fails.
StatusOr<std::vector<uint8_t>> ZstdCompress(const uint8_t* data, size_t size, int level, int workers = 0);

// Encodes raw chunk content with codec 0-3. kInvalidArgument for codec 4.
StatusOr<std::vector<uint8_t>> EncodeChunk(const uint8_t* raw, size_t raw_size, const CodecParams& params,
                                           int zstd_level);

// Decodes stored bytes with codec 0-3 into exactly raw_size bytes (codec 0: a
// view of `stored`). Memory grows with the output actually produced; output
// beyond raw_size is refused early.
StatusOr<ChunkBytes> DecodeChunk(const uint8_t* stored, size_t stored_size, uint64_t raw_size,
                                           const CodecParams& params);

// Codecs 1-3: only the zstd stage, i.e. the transformed content (prefix of
// codec_skip bytes as stored, then the shuffled body). Lets a caller unshuffle
// straight into its destination.
StatusOr<ChunkBytes> DecodeZstdStage(const uint8_t* stored, size_t stored_size, uint64_t raw_size,
                                     const CodecParams& params);

// The first min(n, raw_size) bytes of the chunk content, decoding no more than
// needed (for reading a stream header). Codecs 0-4 (Draco's prefix is verbatim).
StatusOr<std::vector<uint8_t>> DecodeChunkPrefix(const uint8_t* stored, size_t stored_size, uint64_t raw_size,
                                                 const CodecParams& params, size_t n);

// The transforms, exposed for tests. `data` holds `size` bytes.
void ShuffleBytes(const uint8_t* in, size_t size, size_t element_size, uint8_t* out);
void UnshuffleBytes(const uint8_t* in, size_t size, size_t element_size, uint8_t* out);
// In place over rows of `components` integers of `element_size` bytes; `size`
// must be a multiple of element_size * components.
void DeltaEncode(uint8_t* data, size_t size, size_t element_size, size_t components);
void DeltaDecode(uint8_t* data, size_t size, size_t element_size, size_t components);

// zstd levels this build accepts.
int MinZstdLevel();
int MaxZstdLevel();

}  // namespace atex::container
