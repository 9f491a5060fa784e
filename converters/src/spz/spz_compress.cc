#include "spz/spz_compress.h"

#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <string>

namespace atex::converters::spz {

namespace {

// Next capacity of a growing output buffer: doubling from 64 KiB, never above `cap`.
size_t GrowTo(size_t current, uint64_t cap) {
  const uint64_t doubled = std::max<uint64_t>(uint64_t{64} << 10, uint64_t{current} * 2);
  return static_cast<size_t>(std::min<uint64_t>(doubled, cap));
}

}  // namespace

StatusOr<std::vector<uint8_t>> GzipCompress(const uint8_t* data, size_t size, int level) {
  if (size > std::numeric_limits<uInt>::max()) {
    return MakeError(StatusCode::kLimitExceeded, "SPZ v3: ", size, " bytes exceed zlib's single-call input size");
  }
  z_stream stream{};
  if (deflateInit2(&stream, std::clamp(level, 1, 9), Z_DEFLATED, 16 + MAX_WBITS, 9, Z_DEFAULT_STRATEGY) != Z_OK) {
    return MakeError(StatusCode::kInternal, "SPZ v3: deflateInit2 failed");
  }
  std::vector<uint8_t> out(deflateBound(&stream, static_cast<uLong>(size)) + 64);
  stream.next_in = const_cast<Bytef*>(data);
  stream.avail_in = static_cast<uInt>(size);
  stream.next_out = out.data();
  stream.avail_out = static_cast<uInt>(std::min<size_t>(out.size(), std::numeric_limits<uInt>::max()));
  const int result = deflate(&stream, Z_FINISH);
  const size_t produced = stream.total_out;
  deflateEnd(&stream);
  if (result != Z_STREAM_END) return MakeError(StatusCode::kInternal, "SPZ v3: deflate failed (", result, ")");
  out.resize(produced);
  return out;
}

StatusOr<std::vector<uint8_t>> GzipDecompress(const uint8_t* data, size_t size, uint64_t max_output) {
  z_stream stream{};
  if (inflateInit2(&stream, 16 + MAX_WBITS) != Z_OK) {
    return MakeError(StatusCode::kInternal, "SPZ: inflateInit2 failed");
  }
  std::unique_ptr<z_stream, int (*)(z_stream*)> guard(&stream, inflateEnd);
  std::vector<uint8_t> out;
  size_t consumed = 0;
  int result = Z_OK;
  while (result != Z_STREAM_END) {
    if (stream.avail_in == 0 && consumed < size) {
      const size_t chunk = std::min<size_t>(size - consumed, std::numeric_limits<uInt>::max());
      stream.next_in = const_cast<Bytef*>(data + consumed);
      stream.avail_in = static_cast<uInt>(chunk);
      consumed += chunk;
    }
    if (stream.total_out == out.size()) {
      if (out.size() >= max_output) {
        return MakeError(StatusCode::kLimitExceeded, "SPZ gzip stream inflates to more than ", max_output,
                         " bytes (the reader's limit)");
      }
      out.resize(GrowTo(out.size(), max_output));
    }
    const size_t produced_before = stream.total_out;
    stream.next_out = out.data() + produced_before;
    stream.avail_out =
        static_cast<uInt>(std::min<size_t>(out.size() - produced_before, std::numeric_limits<uInt>::max()));
    const uInt avail_in_before = stream.avail_in;
    result = inflate(&stream, Z_NO_FLUSH);
    if (result == Z_STREAM_END) break;
    if (result == Z_BUF_ERROR && stream.avail_in == 0 && consumed == size) {
      return MakeError(StatusCode::kTruncated, "SPZ gzip stream ends early (file of ", size, " bytes, ",
                       stream.total_out, " bytes inflated)");
    }
    if (result != Z_OK && result != Z_BUF_ERROR) {
      return MakeError(StatusCode::kCorrupt, "SPZ gzip stream is corrupt near compressed byte ",
                       consumed - stream.avail_in, ": ", stream.msg ? stream.msg : "inflate error");
    }
    if (result == Z_BUF_ERROR && stream.total_out == produced_before && stream.avail_in == avail_in_before &&
        stream.avail_out != 0) {
      return MakeError(StatusCode::kTruncated, "SPZ gzip stream ends early at compressed byte ", consumed);
    }
  }
  const size_t unused = stream.avail_in + (size - consumed);
  if (unused != 0) {
    return MakeError(StatusCode::kCorrupt, "SPZ file has ", unused, " bytes after the end of its gzip stream");
  }
  out.resize(stream.total_out);
  return out;
}

StatusOr<std::vector<uint8_t>> ZstdCompress(const uint8_t* data, size_t size, int level) {
  std::vector<uint8_t> out(ZSTD_compressBound(size));
  const size_t written = ZSTD_compress(out.data(), out.size(), data, size, level);
  if (ZSTD_isError(written)) {
    return MakeError(StatusCode::kInternal, "SPZ v4: zstd compression failed: ", ZSTD_getErrorName(written));
  }
  out.resize(written);
  return out;
}

StatusOr<std::vector<uint8_t>> ZstdDecompressExact(const uint8_t* data, size_t size, uint64_t expected,
                                                   std::string_view what) {
  std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> ctx(ZSTD_createDCtx(), ZSTD_freeDCtx);
  if (!ctx) return MakeError(StatusCode::kInternal, "SPZ v4: ZSTD_createDCtx failed");
  std::vector<uint8_t> out;
  ZSTD_inBuffer in{data, size, 0};
  size_t produced = 0;
  size_t hint = 1;  // ZSTD_decompressStream's return: 0 once a frame is complete
  for (;;) {
    if (in.pos == in.size && hint == 0) break;  // every frame complete, all input used
    if (produced == out.size()) {
      if (out.size() >= expected) {
        // Full: one more byte of output would mean the stream is longer than announced.
        uint8_t probe = 0;
        ZSTD_outBuffer extra{&probe, 1, 0};
        const size_t in_before = in.pos;
        hint = ZSTD_decompressStream(ctx.get(), &extra, &in);
        if (ZSTD_isError(hint)) {
          return MakeError(StatusCode::kCorrupt, "SPZ ", what, ": zstd error: ", ZSTD_getErrorName(hint));
        }
        if (extra.pos != 0) {
          return MakeError(StatusCode::kCorrupt, "SPZ ", what, ": zstd data holds more than the ", expected,
                           " bytes the table of contents announces");
        }
        if (in.pos == in_before) break;  // no progress possible
        continue;
      }
      out.resize(GrowTo(out.size(), expected));
    }
    ZSTD_outBuffer ob{out.data(), out.size(), produced};
    const size_t in_before = in.pos;
    hint = ZSTD_decompressStream(ctx.get(), &ob, &in);
    if (ZSTD_isError(hint)) {
      return MakeError(StatusCode::kCorrupt, "SPZ ", what, ": zstd error near compressed byte ", in.pos, ": ",
                       ZSTD_getErrorName(hint));
    }
    const bool progressed = ob.pos != produced || in.pos != in_before;
    produced = ob.pos;
    if (!progressed) break;
  }
  if (hint != 0) {
    return MakeError(StatusCode::kTruncated, "SPZ ", what, ": zstd frame is incomplete (", produced, " of ",
                     expected, " bytes decoded)");
  }
  if (in.pos != in.size) {
    return MakeError(StatusCode::kCorrupt, "SPZ ", what, ": ", in.size - in.pos, " bytes after the zstd data");
  }
  if (produced != expected) {
    return MakeError(StatusCode::kCorrupt, "SPZ ", what, ": decodes to ", produced, " bytes, table of contents says ",
                     expected);
  }
  out.resize(produced);
  return out;
}

}  // namespace atex::converters::spz
