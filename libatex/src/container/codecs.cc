#include "container/codecs.h"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <new>
#include <thread>

#include "container/byte_io.h"
#include "container/row_blocks.h"

namespace atex::container {
namespace {

constexpr size_t kInitialOutput = size_t{64} << 10;   // first allocation of a decompression
constexpr size_t kMaxGrowthStep = size_t{256} << 20;  // growth is geometric, at most this much at once

bool ValidElementSize(uint8_t e) { return e == 1 || e == 2 || e == 4 || e == 8; }

// Byte planes of m elements of E bytes, in blocks of elements on several threads for a large
// stream (a Panoptic texel stream is 35 MB at q16; blocks write disjoint bytes).
template <size_t E>
void ShuffleFixed(const uint8_t* in, size_t m, uint8_t* out) {
  ForRowBlocks(m, RowBlocks(m, m * E), [&](int64_t, uint64_t begin, uint64_t end) {
    for (size_t j = begin; j < end; ++j) {
      for (size_t k = 0; k < E; ++k) out[k * m + j] = in[j * E + k];
    }
  });
}

template <size_t E>
void UnshuffleFixed(const uint8_t* in, size_t m, uint8_t* out) {
  ForRowBlocks(m, RowBlocks(m, m * E), [&](int64_t, uint64_t begin, uint64_t end) {
    for (size_t j = begin; j < end; ++j) {
      for (size_t k = 0; k < E; ++k) out[j * E + k] = in[k * m + j];
    }
  });
}

template <typename U>
void DeltaEncodeTyped(uint8_t* data, size_t rows, size_t components) {
  // Back to front so that each difference uses the original previous row.
  for (size_t r = rows; r-- > 1;) {
    for (size_t c = 0; c < components; ++c) {
      uint8_t* cur = data + (r * components + c) * sizeof(U);
      const uint8_t* prev = cur - components * sizeof(U);
      StoreLE<U>(cur, static_cast<U>(LoadLE<U>(cur) - LoadLE<U>(prev)));
    }
  }
}

template <typename U>
void DeltaDecodeTyped(uint8_t* data, size_t rows, size_t components) {
  for (size_t r = 1; r < rows; ++r) {
    for (size_t c = 0; c < components; ++c) {
      uint8_t* cur = data + (r * components + c) * sizeof(U);
      const uint8_t* prev = cur - components * sizeof(U);
      StoreLE<U>(cur, static_cast<U>(LoadLE<U>(cur) + LoadLE<U>(prev)));
    }
  }
}

struct CCtxDeleter {
  void operator()(ZSTD_CCtx* c) const { ZSTD_freeCCtx(c); }
};
struct DCtxDeleter {
  void operator()(ZSTD_DCtx* d) const { ZSTD_freeDCtx(d); }
};

}  // namespace

int ZstdWorkersFor(size_t size, int workers) {
  if (size < kParallelZstdBytes) return 0;
  if (workers > 0) return workers;
  const unsigned threads = std::thread::hardware_concurrency();
  return static_cast<int>(std::clamp(threads, 1u, 16u));
}

StatusOr<std::vector<uint8_t>> ZstdCompress(const uint8_t* data, size_t size, int level, int workers) {
  std::unique_ptr<ZSTD_CCtx, CCtxDeleter> cctx(ZSTD_createCCtx());
  if (!cctx) return MakeError(StatusCode::kInternal, "ZSTD_createCCtx failed");
  // Pinned parameters: the output depends only on the level, the library version and whether
  // the chunk is at least kParallelZstdBytes (then zstd's workers cut it into jobs whose size
  // follows from the level alone, so any worker count gives the same bytes; codecs_test checks).
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_contentSizeFlag, 1);
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_checksumFlag, 0);  // the TOC's CRC32C covers the bytes
  ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_dictIDFlag, 0);
  if (const int n = ZstdWorkersFor(size, workers); n > 0) {
    // A libzstd built without threads refuses: it then compresses in this thread (other bytes).
    ZSTD_CCtx_setParameter(cctx.get(), ZSTD_c_nbWorkers, n);
  }
  // An uninitialised bound-sized buffer, then an exact-size copy: cheaper than
  // zero-filling a vector of the bound.
  const size_t bound = ZSTD_compressBound(size);
  ChunkBytes buffer = ChunkBytes::Allocate(bound);
  const size_t written = ZSTD_compress2(cctx.get(), buffer.mutable_data(), bound, data, size);
  if (ZSTD_isError(written)) {
    return MakeError(StatusCode::kInternal, "zstd compression failed: ", ZSTD_getErrorName(written));
  }
  return std::vector<uint8_t>(buffer.data(), buffer.data() + written);
}

namespace {

StatusOr<ChunkBytes> ZstdDecompress(const uint8_t* stored, size_t stored_size, uint64_t raw_size) {
  std::unique_ptr<ZSTD_DCtx, DCtxDeleter> dctx(ZSTD_createDCtx());
  if (!dctx) return MakeError(StatusCode::kInternal, "ZSTD_createDCtx failed");
  if (raw_size >= (uint64_t{1} << 62))
    return MakeError(StatusCode::kLimitExceeded, "raw size ", raw_size, " is too large");
  // One byte beyond raw_size lets us notice output that is too long.
  const uint64_t limit = raw_size + 1;
  ChunkBytes out = ChunkBytes::Allocate(static_cast<size_t>(std::min<uint64_t>(limit, kInitialOutput)));
  ZSTD_inBuffer in{stored, stored_size, 0};
  size_t produced = 0;
  for (;;) {
    ZSTD_outBuffer o{out.mutable_data(), out.size(), produced};
    const size_t in_before = in.pos;
    const size_t ret = ZSTD_decompressStream(dctx.get(), &o, &in);
    if (ZSTD_isError(ret)) {
      return MakeError(StatusCode::kCorrupt, "zstd data invalid near stored byte ", in.pos, ": ",
                       ZSTD_getErrorName(ret));
    }
    const bool progress = o.pos != produced || in.pos != in_before;
    produced = o.pos;
    if (produced > raw_size) {
      return MakeError(StatusCode::kCorrupt, "zstd data decodes to more than the raw size ", raw_size);
    }
    if (ret == 0 && in.pos == in.size) break;  // every frame complete, input used up
    if (produced == out.size()) {
      const size_t step = std::clamp(produced, kInitialOutput, kMaxGrowthStep);
      out.Resize(static_cast<size_t>(std::min<uint64_t>(limit, uint64_t{out.size()} + step)));
    } else if (in.pos == in.size || !progress) {
      return MakeError(StatusCode::kCorrupt, "zstd data ends inside a frame after ", produced, " of ", raw_size,
                       " bytes");
    }
  }
  if (produced != raw_size) {
    return MakeError(StatusCode::kCorrupt, "zstd data decodes to ", produced, " bytes, the TOC says ", raw_size);
  }
  out.Resize(produced);
  return out;
}

}  // namespace

StatusOr<std::vector<uint8_t>> DecodeChunkPrefix(const uint8_t* stored, size_t stored_size, uint64_t raw_size,
                                                 const CodecParams& p, size_t n) {
  ATEX_RETURN_IF_ERROR(CheckCodecParams(p, raw_size));
  n = static_cast<size_t>(std::min<uint64_t>(n, raw_size));
  // Only the untransformed prefix (codec_skip bytes) reads back as content.
  if ((p.codec == Codec::kShuffleZstd || p.codec == Codec::kDeltaShuffleZstd || p.codec == Codec::kDraco) &&
      n > p.skip) {
    return MakeError(StatusCode::kInvalidArgument, "only the first ", p.skip, " bytes can be read without decoding");
  }
  if (p.codec == Codec::kRaw || p.codec == Codec::kDraco) {
    if (n > stored_size) return MakeError(StatusCode::kCorrupt, "stored bytes shorter than ", n);
    return std::vector<uint8_t>(stored, stored + n);
  }
  std::unique_ptr<ZSTD_DCtx, DCtxDeleter> dctx(ZSTD_createDCtx());
  if (!dctx) return MakeError(StatusCode::kInternal, "ZSTD_createDCtx failed");
  std::vector<uint8_t> out(n);
  ZSTD_inBuffer in{stored, stored_size, 0};
  ZSTD_outBuffer o{out.data(), out.size(), 0};
  while (o.pos < o.size) {
    const size_t before_in = in.pos, before_out = o.pos;
    const size_t ret = ZSTD_decompressStream(dctx.get(), &o, &in);
    if (ZSTD_isError(ret)) return MakeError(StatusCode::kCorrupt, "zstd data invalid: ", ZSTD_getErrorName(ret));
    if (o.pos == o.size) break;
    const bool progress = in.pos != before_in || o.pos != before_out;
    if (!progress || (ret == 0 && in.pos == in.size)) {
      return MakeError(StatusCode::kCorrupt, "zstd data shorter than ", n, " bytes");
    }
  }
  return out;
}

ChunkBytes ChunkBytes::View(const uint8_t* data, size_t size) {
  ChunkBytes b;
  b.view_ = data;
  b.size_ = size;
  return b;
}

ChunkBytes ChunkBytes::Allocate(size_t size) {
  ChunkBytes b;
  b.owned_.reset(static_cast<uint8_t*>(std::malloc(std::max<size_t>(size, 1))));
  if (!b.owned_) throw std::bad_alloc();
  b.size_ = size;
  return b;
}

ChunkBytes ChunkBytes::Copy(const uint8_t* data, size_t size) {
  ChunkBytes b = Allocate(size);
  CopyBytes(b.owned_.get(), data, size);
  return b;
}

void ChunkBytes::Resize(size_t size) {
  auto* grown = static_cast<uint8_t*>(std::realloc(owned_.get(), std::max<size_t>(size, 1)));
  if (grown == nullptr) throw std::bad_alloc();
  owned_.release();
  owned_.reset(grown);
  size_ = size;
}

void ShuffleBytes(const uint8_t* in, size_t size, size_t e, uint8_t* out) {
  const size_t m = size / e;
  switch (e) {
    case 2: ShuffleFixed<2>(in, m, out); break;
    case 4: ShuffleFixed<4>(in, m, out); break;
    case 8: ShuffleFixed<8>(in, m, out); break;
    default: CopyBytes(out, in, m * e); break;  // e == 1: identity
  }
  CopyBytes(out + m * e, in + m * e, size - m * e);
}

void UnshuffleBytes(const uint8_t* in, size_t size, size_t e, uint8_t* out) {
  const size_t m = size / e;
  switch (e) {
    case 2: UnshuffleFixed<2>(in, m, out); break;
    case 4: UnshuffleFixed<4>(in, m, out); break;
    case 8: UnshuffleFixed<8>(in, m, out); break;
    default: CopyBytes(out, in, m * e); break;
  }
  CopyBytes(out + m * e, in + m * e, size - m * e);
}

void DeltaEncode(uint8_t* data, size_t size, size_t e, size_t components) {
  const size_t rows = size / (e * components);
  switch (e) {
    case 1: DeltaEncodeTyped<uint8_t>(data, rows, components); break;
    case 2: DeltaEncodeTyped<uint16_t>(data, rows, components); break;
    case 4: DeltaEncodeTyped<uint32_t>(data, rows, components); break;
    case 8: DeltaEncodeTyped<uint64_t>(data, rows, components); break;
  }
}

void DeltaDecode(uint8_t* data, size_t size, size_t e, size_t components) {
  const size_t rows = size / (e * components);
  switch (e) {
    case 1: DeltaDecodeTyped<uint8_t>(data, rows, components); break;
    case 2: DeltaDecodeTyped<uint16_t>(data, rows, components); break;
    case 4: DeltaDecodeTyped<uint32_t>(data, rows, components); break;
    case 8: DeltaDecodeTyped<uint64_t>(data, rows, components); break;
  }
}

int MinZstdLevel() { return ZSTD_minCLevel(); }
int MaxZstdLevel() { return ZSTD_maxCLevel(); }

Status CheckCodecParams(const CodecParams& p, uint64_t raw_size) {
  const auto bad = [&](const char* why) {
    return MakeError(StatusCode::kCorrupt, "codec ", int{static_cast<uint8_t>(p.codec)}, " with param ",
                     int{p.element_size}, ", components ", p.components, ", skip ", p.skip, ": ", why);
  };
  switch (p.codec) {
    case Codec::kRaw:
    case Codec::kZstd:
      if (p.element_size != 0 || p.components != 0 || p.skip != 0) return bad("parameters must be 0");
      return Status::Ok();
    case Codec::kShuffleZstd:
      if (!ValidElementSize(p.element_size)) return bad("element size must be 1, 2, 4 or 8");
      if (p.components != 0) return bad("components must be 0");
      if (p.skip > raw_size) return bad("skip exceeds the raw size");
      return Status::Ok();
    case Codec::kDeltaShuffleZstd: {
      if (!ValidElementSize(p.element_size)) return bad("element size must be 1, 2, 4 or 8");
      if (p.components == 0) return bad("components must be at least 1");
      if (p.skip > raw_size) return bad("skip exceeds the raw size");
      const uint64_t row = uint64_t{p.element_size} * p.components;
      if ((raw_size - p.skip) % row != 0) return bad("raw size minus skip is not a whole number of rows");
      return Status::Ok();
    }
    case Codec::kDraco:
      if (p.element_size != 4 || p.components != 3) return bad("Draco needs element size 4 and 3 components");
      if (p.skip > raw_size || (raw_size - p.skip) % 12 != 0) return bad("raw size is not skip + 12 * points");
      return Status::Ok();
  }
  return MakeError(StatusCode::kUnsupportedCodec, "unknown codec ", int{static_cast<uint8_t>(p.codec)});
}

StatusOr<std::vector<uint8_t>> EncodeChunk(const uint8_t* raw, size_t raw_size, const CodecParams& p, int level) {
  ATEX_RETURN_IF_ERROR(CheckCodecParams(p, raw_size));
  switch (p.codec) {
    case Codec::kRaw:
      return std::vector<uint8_t>(raw, raw + raw_size);
    case Codec::kZstd:
      return ZstdCompress(raw, raw_size, level);
    case Codec::kShuffleZstd:
    case Codec::kDeltaShuffleZstd: {
      const size_t body = raw_size - p.skip;
      ChunkBytes transformed = ChunkBytes::Allocate(raw_size);
      CopyBytes(transformed.mutable_data(), raw, p.skip);
      const uint8_t* body_in = raw + p.skip;
      ChunkBytes delta;
      if (p.codec == Codec::kDeltaShuffleZstd) {
        delta = ChunkBytes::Copy(body_in, body);
        DeltaEncode(delta.mutable_data(), body, p.element_size, p.components);
        body_in = delta.data();
      }
      ShuffleBytes(body_in, body, p.element_size, transformed.mutable_data() + p.skip);
      return ZstdCompress(transformed.data(), transformed.size(), level);
    }
    case Codec::kDraco:
      break;
  }
  return MakeError(StatusCode::kInvalidArgument, "EncodeChunk does not handle codec ",
                   int{static_cast<uint8_t>(p.codec)});
}

StatusOr<ChunkBytes> DecodeZstdStage(const uint8_t* stored, size_t stored_size, uint64_t raw_size,
                                     const CodecParams& p) {
  ATEX_RETURN_IF_ERROR(CheckCodecParams(p, raw_size));
  if (p.codec != Codec::kZstd && p.codec != Codec::kShuffleZstd && p.codec != Codec::kDeltaShuffleZstd) {
    return MakeError(StatusCode::kInternal, "DecodeZstdStage needs codec 1, 2 or 3");
  }
  return ZstdDecompress(stored, stored_size, raw_size);
}

StatusOr<ChunkBytes> DecodeChunk(const uint8_t* stored, size_t stored_size, uint64_t raw_size, const CodecParams& p) {
  ATEX_RETURN_IF_ERROR(CheckCodecParams(p, raw_size));
  switch (p.codec) {
    case Codec::kRaw:
      if (stored_size != raw_size) {
        return MakeError(StatusCode::kCorrupt, "raw chunk stores ", stored_size, " bytes but says ", raw_size);
      }
      return ChunkBytes::View(stored, stored_size);
    case Codec::kZstd:
      return ZstdDecompress(stored, stored_size, raw_size);
    case Codec::kShuffleZstd:
    case Codec::kDeltaShuffleZstd: {
      ATEX_ASSIGN_OR_RETURN(ChunkBytes transformed, ZstdDecompress(stored, stored_size, raw_size));
      const size_t body = transformed.size() - p.skip;
      ChunkBytes raw = ChunkBytes::Allocate(transformed.size());
      CopyBytes(raw.mutable_data(), transformed.data(), p.skip);
      UnshuffleBytes(transformed.data() + p.skip, body, p.element_size, raw.mutable_data() + p.skip);
      if (p.codec == Codec::kDeltaShuffleZstd)
        DeltaDecode(raw.mutable_data() + p.skip, body, p.element_size, p.components);
      return raw;
    }
    case Codec::kDraco:
      break;
  }
  return MakeError(StatusCode::kInternal, "DecodeChunk does not handle codec ", int{static_cast<uint8_t>(p.codec)});
}

}  // namespace atex::container
